"""echofield.optimize on a standard g2o benchmark with its known optimum,
and on arrays."""

import math

import numpy as np
import pytest

import echofield
from conftest import ROOT

INTEL = ROOT / "datasets" / "posegraph" / "intel.g2o"
# datasets/posegraph/REFERENCE.md: best chi2 of intel.g2o with g2o's error,
# found by GTSAM and g2o.
INTEL_BEST_CHI2 = 45.00469581


def test_intel_reaches_the_reference_optimum(tmp_path):
    out = tmp_path / "intel-opt.g2o"
    r = echofield.optimize(INTEL, output=out)
    assert r.poses.shape == (1728, 3)
    assert r.ids.shape == (1728,)
    assert r.final_chi2 == pytest.approx(INTEL_BEST_CHI2, rel=1e-6)
    assert r.initial_chi2 > 10 * r.final_chi2
    assert r.converged and r.termination == r.summary["termination"]
    assert r.summary["final_chi2"] == r.final_chi2
    # The written graph holds the returned poses.
    vertices = [line.split() for line in out.read_text().splitlines() if line.startswith("VERTEX_SE2")]
    assert len(vertices) == 1728
    written = np.array([[float(v) for v in row[2:5]] for row in vertices])
    np.testing.assert_allclose(written, r.poses, atol=1e-9)


def test_arrays_triangle_with_one_inconsistent_loop():
    # Three poses, odometry 0->1 and 1->2 of 1 m forward then a left turn
    # of 90 degrees, and a loop 0->2 that says (1, 1, 90 deg) as well: the
    # measurements agree, so the optimum has chi2 0 and node 2 at (1, 1).
    identity = [1.0, 0.0, 0.0, 1.0, 0.0, 1.0]
    edges = np.array(
        [
            [0, 1, 1.0, 0.0, math.pi / 2, *identity],
            [1, 2, 1.0, 0.0, 0.0, *identity],
            [0, 2, 1.0, 1.0, math.pi / 2, *identity],
        ]
    )
    start = np.array([[0.0, 0.0, 0.0], [0.8, 0.3, 1.0], [1.5, 0.7, 1.2]])
    r = echofield.optimize(poses=start, edges=edges, fixed=[0], init="file")
    np.testing.assert_allclose(r.poses[0], [0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(r.poses[1], [1.0, 0.0, math.pi / 2], atol=1e-6)
    np.testing.assert_allclose(r.poses[2], [1.0, 1.0, math.pi / 2], atol=1e-6)
    assert r.final_chi2 == pytest.approx(0.0, abs=1e-10)
    np.testing.assert_array_equal(r.ids, [0, 1, 2])


def test_robust_switches_a_false_loop_off():
    # A ring of 12 poses (30 degree steps of 1 m) with its true loop 11->0
    # and one false loop 0->6 claiming the two are 0.5 m apart.
    n = 12
    info = [100.0, 0.0, 0.0, 100.0, 0.0, 400.0]
    step = [1.0, 0.0, 2 * math.pi / n]
    edges = [[i, i + 1, *step, *info] for i in range(n - 1)]
    edges.append([n - 1, 0, *step, *info])
    edges.append([0, 6, 0.5, 0.0, 0.0, *info])
    start = np.zeros((n, 3))
    for i in range(1, n):
        x, y, t = start[i - 1]
        start[i] = [x + math.cos(t), y + math.sin(t), t + step[2]]
    edges = np.array(edges)
    plain = echofield.optimize(poses=start, edges=edges, fixed=[0])
    robust = echofield.optimize(poses=start, edges=edges, fixed=[0], robust="dcs")
    assert robust.switched_off == [len(edges) - 1]
    assert robust.final_chi2 < 1e-6 < plain.final_chi2


def test_bad_graphs_raise(tmp_path):
    bad = tmp_path / "bad.g2o"
    bad.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 nan\n")
    with pytest.raises(echofield.Error, match=r"bad\.g2o:2: field `theta`: `nan` is not finite"):
        echofield.optimize(bad)
    with pytest.raises(echofield.Error, match="missing.g2o"):
        echofield.optimize(tmp_path / "missing.g2o")
    with pytest.raises(ValueError, match="either graph"):
        echofield.optimize()
    with pytest.raises(ValueError, match="edges: row 0"):
        echofield.optimize(poses=np.zeros((2, 3)), edges=np.array([[0, 5, 1, 0, 0, 1, 0, 0, 1, 0, 1.0]]))
    with pytest.raises(ValueError, match="robust"):
        echofield.optimize(INTEL, robust="tukey")
