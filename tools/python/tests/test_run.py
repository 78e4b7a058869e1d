"""echofield.run and load_mission: the pipeline of `echofield run` with
numpy results."""

import json

import numpy as np
import pytest

import echofield


def read_tum(path):
    """TUM rows as [stamp, x, y, yaw] (planar: yaw from qz, qw)."""
    rows = np.loadtxt(path, ndmin=2)
    yaw = 2.0 * np.arctan2(rows[:, 6], rows[:, 7])
    return np.column_stack([rows[:, 0], rows[:, 1], rows[:, 2], yaw])


def wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def test_mission_streams(tank):
    # datasets/samples/README.md: 2096 beams, 427 DVL, 1426 attitude and
    # 1426 ground-truth samples.
    assert tank.name == "tank (simulated, seed 1)"
    beams = tank.beams
    assert beams["stamp_s"].shape == (2096,)
    assert len(beams["intensities"]) == 2096
    assert beams["intensities"][0].dtype == np.uint8
    assert beams["intensities"][0].shape == (500,)
    assert np.all(np.diff(beams["stamp_s"]) >= 0)
    assert tank.dvl.shape == (427, 5)
    assert set(np.unique(tank.dvl[:, 4])) <= {0.0, 1.0}
    assert tank.attitude.shape == (1426, 5)
    assert tank.ground_truth.shape == (1426, 4)
    assert tank.dvl_covariance.shape == (427, 3, 3)
    # Mounted at (0.33 m, 0, pi).
    sonar = tank.mounting["vehicle_from_sonar"]
    assert json.dumps(sonar)  # plain Python values
    assert "Mission" in repr(tank)


def test_run_returns_the_nodes_as_arrays(tank_result):
    r = tank_result
    n = len(r)
    assert n >= 8
    assert r.stamps.shape == (n,)
    assert r.poses.shape == (n, 3)
    assert r.trajectory.shape == (n, 4)
    np.testing.assert_array_equal(r.trajectory[:, 0], r.stamps)
    np.testing.assert_array_equal(r.trajectory[:, 1:], r.poses)
    assert r.dead_reckoning_poses.shape == (n, 3)
    assert r.emitted is None
    # Node 0 is fixed at its dead-reckoning pose.
    np.testing.assert_allclose(r.poses[0], r.dead_reckoning_poses[0], atol=1e-9)
    # Navigation rate: 10 Hz dead reckoning, passing through every node.
    nav = r.navigation_rate
    assert nav.shape[1] == 4 and nav.shape[0] > 10 * n
    for stamp, pose in zip(r.stamps, r.poses):
        k = np.argmin(np.abs(nav[:, 0] - stamp))
        assert abs(nav[k, 0] - stamp) < 1e-9
        np.testing.assert_allclose(nav[k, 1:3], pose[:2], atol=1e-6)
    assert r.ground_truth is not None and r.ground_truth.shape[1] == 4
    report = r.report
    assert report["nodes"] == n
    assert report["ate_rmse_m"] < report["ate_rmse_dead_reckoning_m"]
    loops = r.loops
    k = len(loops["from"])
    assert k == report["loop_candidates"]
    for key in ("to", "accepted", "score", "rejected_by", "true_positive"):
        assert len(loops[key]) == k
    assert loops["measurement"].shape == (k, 3)
    accepted = loops["accepted"]
    assert accepted.dtype == bool
    assert int(np.sum(accepted)) == report["loops_accepted"] > 0
    # The config reached the loop gate: no loop spans fewer than 3 rotations.
    assert np.all(loops["to"] - loops["from"] >= 3)
    assert np.isfinite(loops["measurement"][accepted]).all()
    assert all(reason is None for reason, a in zip(loops["rejected_by"], accepted) if a)
    precision = np.sum(loops["true_positive"][accepted]) / np.sum(accepted)
    assert precision == pytest.approx(report["loop_precision"], abs=1e-12)
    assert r.config["loops"]["densify"] is True


def test_report_ate_equals_evaluate_on_the_arrays(tank_result):
    r = tank_result
    ev = echofield.evaluate(r.trajectory, r.ground_truth)
    assert ev["ate"]["pairs"] == len(r.ground_truth)
    np.testing.assert_allclose(ev["ate"]["rmse_m"], r.report["ate_rmse_m"], rtol=1e-12)


def test_output_folder_holds_the_same_trajectory(tank_path, tmp_path):
    out = tmp_path / "run"
    r = echofield.run(str(tank_path), config={"loops": {"densify": False}}, output=out)
    assert r.output == out
    assert r.config["loops"]["densify"] is False
    tum = read_tum(out / "trajectory_tum.txt")
    np.testing.assert_allclose(tum[:, 0], r.stamps, atol=1e-6)
    np.testing.assert_allclose(tum[:, 1:3], r.poses[:, :2], atol=1e-6)
    np.testing.assert_allclose(wrap(tum[:, 3] - r.poses[:, 2]), 0.0, atol=1e-6)
    report = json.loads((out / "report.json").read_text())
    assert report["nodes"] == len(r)
    assert report["run"]["command"] == "run (python)"
    # The config file the run wrote reads back as the same run.
    again = echofield.run(tank_path, config=out / "config.toml")
    np.testing.assert_array_equal(again.poses, r.poses)


def test_simulated_mission_runs_and_saves(tmp_path):
    m = echofield.simulate("tank", seed=2)
    assert m.ground_truth.shape[0] > 1000
    m.save(tmp_path / "tank2.mcap")
    back = echofield.load_mission(tmp_path / "tank2.mcap")
    np.testing.assert_array_equal(back.beams["stamp_s"], m.beams["stamp_s"])
    np.testing.assert_array_equal(back.dvl, m.dvl)
    # Deterministic: the same seed gives the same mission.
    np.testing.assert_array_equal(echofield.simulate("tank", seed=2).attitude, m.attitude)


def test_default_config():
    config = echofield.default_config()
    assert config["loops"]["densify"] is True
    text = echofield.default_config(documented=True)
    assert "[loops]" in text and "densify" in text
