"""echofield.evaluate against ATE and RPE computed by hand on tiny
trajectories."""

import math

import numpy as np
import pytest

import echofield


def stamped(xy_yaw, t0=0.0):
    xy_yaw = np.asarray(xy_yaw, dtype=float)
    stamps = t0 + np.arange(len(xy_yaw), dtype=float)
    return np.column_stack([stamps, xy_yaw])


SQUARE = [[1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, -1.0, 0.0]]


def test_ate_without_alignment_is_the_offset():
    reference = stamped(SQUARE)
    estimate = reference.copy()
    estimate[:, 1] += 0.3
    estimate[:, 2] += 0.4
    ev = echofield.evaluate(estimate, reference, align="none")
    # Every position is off by (0.3, 0.4): 0.5 m each.
    assert ev["ate"]["pairs"] == 4
    assert ev["ate"]["rmse_m"] == pytest.approx(0.5, abs=1e-12)
    assert ev["ate"]["max_m"] == pytest.approx(0.5, abs=1e-12)
    # With the rigid alignment the offset disappears.
    assert echofield.evaluate(estimate, reference)["ate"]["rmse_m"] == pytest.approx(0.0, abs=1e-12)


def test_ate_after_alignment_keeps_what_no_rigid_motion_explains():
    # The corners pushed outward by 0.1 m along their diagonals: by symmetry
    # the best rigid motion is the identity, and every error is 0.1 m. Then
    # the whole estimate moved by a rotation of 30 degrees and a translation,
    # which the alignment takes away.
    reference = stamped(SQUARE)
    pushed = np.array(SQUARE)
    pushed[:, :2] *= 1.0 + 0.1 / math.sqrt(2.0)
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    moved = pushed.copy()
    moved[:, 0] = c * pushed[:, 0] - s * pushed[:, 1] + 5.0
    moved[:, 1] = s * pushed[:, 0] + c * pushed[:, 1] - 2.0
    ev = echofield.evaluate(stamped(moved), reference)
    assert ev["alignment"] == "se2"
    for key in ("rmse_m", "mean_m", "median_m", "max_m"):
        assert ev["ate"][key] == pytest.approx(0.1, abs=1e-9)


def test_association_by_nearest_stamp_within_the_tolerance():
    reference = stamped(SQUARE)
    estimate = reference.copy()
    estimate[:, 0] += 0.005  # within the default 0.01 s
    estimate[0, 1] += 2.0  # one pose 2 m off
    ev = echofield.evaluate(estimate, reference, align="none")
    assert ev["ate"]["pairs"] == 4
    assert ev["ate"]["rmse_m"] == pytest.approx(math.sqrt(4.0 / 4.0), abs=1e-12)
    estimate[:, 0] += 0.01  # now 0.015 s apart: nothing pairs up
    with pytest.raises(echofield.Error, match="no pose of the estimate"):
        echofield.evaluate(estimate, reference)


def test_rpe_over_ten_metres_on_a_stretched_line():
    # Reference: 21 poses 1 m apart along x. Estimate: 10% longer steps.
    # Over 10 m: pairs (i, i + 10) for i = 0..10, each 1.0 m too long, and
    # (11, 20), 9 m apart: the nearest to 10 m from pose 11 and within the
    # tolerance d / 10 = 1 m (inclusive, as evo's), 0.9 m too long. No
    # rotation error.
    reference = stamped([[float(i), 0.0, 0.0] for i in range(21)])
    estimate = stamped([[1.1 * i, 0.0, 0.0] for i in range(21)])
    ev = echofield.evaluate(estimate, reference, rpe_distances=[10.0, 50.0])
    assert len(ev["rpe"]) == 1  # 50 m is longer than the path
    rpe = ev["rpe"][0]
    assert rpe["distance_m"] == 10.0
    assert rpe["pairs"] == 12
    rmse = math.sqrt((11 * 1.0**2 + 0.9**2) / 12)
    assert rpe["translation_rmse_m"] == pytest.approx(rmse, abs=1e-9)
    assert rpe["translation_rmse_percent"] == pytest.approx(10.0 * rmse, abs=1e-7)
    assert rpe["rotation_rmse_deg"] == pytest.approx(0.0, abs=1e-12)


def test_rpe_rotation_error():
    # The estimate turns 1 degree more per step than the reference (which
    # goes straight): over the eleven 10 m pairs the relative heading is 10
    # degrees off, over the pair (11, 20) (9 m, see above) 9 degrees.
    reference = stamped([[float(i), 0.0, 0.0] for i in range(21)])
    estimate = reference.copy()
    estimate[:, 3] = np.radians(np.arange(21, dtype=float))
    ev = echofield.evaluate(estimate, reference, align="none", rpe_distances=[10.0])
    rmse_deg = math.sqrt((11 * 10.0**2 + 9.0**2) / 12)
    assert ev["rpe"][0]["rotation_rmse_deg"] == pytest.approx(rmse_deg, abs=1e-9)


def test_tum_files_and_arrays_give_the_same(tmp_path):
    reference = stamped(SQUARE, t0=100.0)
    estimate = reference.copy()
    estimate[:, 1] += 0.25

    def write(path, rows):
        with open(path, "w") as f:
            for t, x, y, yaw in rows:
                f.write(f"{t} {x} {y} 0 0 0 {math.sin(yaw / 2)} {math.cos(yaw / 2)}\n")

    write(tmp_path / "est.txt", estimate)
    write(tmp_path / "ref.txt", reference)
    from_files = echofield.evaluate(tmp_path / "est.txt", str(tmp_path / "ref.txt"), align="none")
    assert from_files["ate"]["rmse_m"] == pytest.approx(0.25, abs=1e-12)
    assert from_files == echofield.evaluate(estimate, reference, align="none")


def test_bad_trajectories_are_value_errors():
    reference = stamped(SQUARE)
    with pytest.raises(ValueError, match="estimate: expected 4 columns"):
        echofield.evaluate(reference[:, :3].copy(), reference)
    bad = reference.copy()
    bad[2, 0] = bad[1, 0]
    with pytest.raises(ValueError, match="estimate: row 2.*not after"):
        echofield.evaluate(bad, reference)
    bad = reference.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="reference: row 1, column 2"):
        echofield.evaluate(reference, bad)
    with pytest.raises(ValueError, match="align"):
        echofield.evaluate(reference, reference, align="sim3")
