"""Reads echofield's graph.g2o with GTSAM and compares chi2 with echofield's.

Usage: check_gtsam.py GRAPH.g2o SUMMARY.json OPTIMISED.g2o

GRAPH.g2o is a file echofield wrote; SUMMARY.json and OPTIMISED.g2o are what
`echofield optimize GRAPH.g2o --output OPTIMISED.g2o --summary SUMMARY.json`
wrote for it. GTSAM's `readG2o` reads VERTEX_SE2 and EDGE_SE2 and stops at the
first record it does not know; echofield writes those first and its priors
(`EDGE_PRIOR_SE2`, g2o's tag) and `FIX` last, so this script adds exactly
those trailing records itself. Checks, printing one line each:
1. GTSAM read every vertex and every EDGE_SE2 of the file;
2. the chi2 of what GTSAM read, at the file's poses, with g2o's residual
   (the (x, y, theta) of measured^-1 * (x_i^-1 * x_j), echofield's and
   g2o's definition), equals echofield's initial chi2 to 1e-9: GTSAM read
   every measurement and information matrix as echofield wrote it;
3. GTSAM's Levenberg-Marquardt optimum against `echofield optimize` (plain
   least squares): chi2 to 1e-3 relative, positions to 0.05 m after both are
   expressed in the frame of the first vertex (a graph without FIX or priors
   has a free gauge). GTSAM's residual is Pose2's Logmap, which differs from
   g2o's at second order, so its optimum differs slightly; its chi2 at the
   file's poses is printed for information.
Exit status 1 if any check fails.
"""

import json
import sys
from pathlib import Path

import gtsam
import numpy as np

# g2o's residual, shared with the peer benchmark (tools/peers).
sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
from gtsam_compare import g2o_chi2  # noqa: E402


def trailing_records(path):
    """The EDGE_PRIOR_SE2 and FIX records, which GTSAM's reader does not know."""
    priors, fixed, counts = [], [], {"VERTEX_SE2": 0, "EDGE_SE2": 0}
    with open(path) as f:
        for line in f:
            tokens = line.split()
            if not tokens:
                continue
            if tokens[0] in counts:
                counts[tokens[0]] += 1
            elif tokens[0] in ("EDGE_PRIOR_SE2", "EDGE_SE2_PRIOR"):
                v = [float(t) for t in tokens[1:]]
                info = np.array([[v[4], v[5], v[6]], [v[5], v[7], v[8]], [v[6], v[8], v[9]]])
                priors.append((int(v[0]), gtsam.Pose2(v[1], v[2], v[3]), info))
            elif tokens[0] == "FIX":
                fixed.extend(int(t) for t in tokens[1:])
    return priors, fixed, counts


def poses_of(path):
    poses = {}
    with open(path) as f:
        for line in f:
            t = line.split()
            if t and t[0] == "VERTEX_SE2":
                poses[int(t[1])] = np.array([float(x) for x in t[2:5]])
    return poses


def main(graph_path, summary_path, optimised_path):
    graph, initial = gtsam.readG2o(graph_path, False)
    priors, fixed, counts = trailing_records(graph_path)
    ok = True

    read_all = initial.size() == counts["VERTEX_SE2"] and graph.size() == counts["EDGE_SE2"]
    ok &= read_all
    print(
        f"read: {initial.size()} of {counts['VERTEX_SE2']} vertices, "
        f"{graph.size()} of {counts['EDGE_SE2']} EDGE_SE2 "
        f"(+ {len(priors)} priors, {len(fixed)} FIX added here) {'ok' if read_all else 'MISMATCH'}"
    )
    for key, pose, info in priors:
        graph.add(gtsam.PriorFactorPose2(key, pose, gtsam.noiseModel.Gaussian.Information(info)))

    summary = json.load(open(summary_path))
    ours = summary["initial_chi2"]
    theirs = g2o_chi2(graph, initial)
    rel = abs(ours - theirs) / max(abs(ours), 1e-300)
    ok &= rel <= 1e-9
    print(f"chi2 at the file's poses, g2o residual: echofield {ours:.9g}, GTSAM's factors {theirs:.9g}, rel {rel:.1e} {'ok' if rel <= 1e-9 else 'MISMATCH'}")
    own = 2.0 * graph.error(initial)
    rel = abs(ours - own) / max(abs(ours), 1e-300)
    print(f"chi2 at the file's poses, GTSAM's Logmap residual: {own:.9g}, rel {rel:.1e} (information only)")

    # The fixed nodes hold their pose: a very stiff prior at the file's pose.
    stiff = gtsam.noiseModel.Isotropic.Sigma(3, 1e-9)
    for key in fixed:
        graph.add(gtsam.PriorFactorPose2(key, initial.atPose2(key), stiff))
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-12)
    params.setMaxIterations(200)
    result = gtsam.LevenbergMarquardtOptimizer(graph, initial, params).optimize()
    theirs = 2.0 * graph.error(result)
    ours = summary["final_chi2"]
    rel = abs(ours - theirs) / max(abs(ours), 1e-300)
    optimised = {k: gtsam.Pose2(*v) for k, v in poses_of(optimised_path).items()}
    first = min(optimised)
    moved = 0.0
    for k, pose in optimised.items():
        a = optimised[first].between(pose)
        b = result.atPose2(first).between(result.atPose2(k))
        moved = max(moved, float(np.hypot(a.x() - b.x(), a.y() - b.y())))
    good = rel <= 1e-3 and moved <= 0.05
    ok &= good
    print(
        f"chi2 at the optimum: echofield {ours:.9g}, GTSAM {theirs:.9g}, rel {rel:.1e}; "
        f"largest position difference {moved:.1e} m {'ok' if good else 'MISMATCH'}"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:4]))
