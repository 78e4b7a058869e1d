#!/usr/bin/env python3
"""Where a run's error comes from: its final graph against ground truth.

Reads an `echofield run` output folder of a simulated mission
(`graph.g2o`, `loops.csv`, `trajectory_tum.txt`, `ground_truth_tum.txt`)
and prints

* the ATE after an SE(2) alignment, the map scale (least squares of the
  aligned ground truth onto the trajectory) and the ATE after the scale
  is removed as well;
* per edge class (odometry, sequential, mission-pass loops, densified
  loops, partial densified loops) the mean error of the measured
  translation along the true displacement, metres, and as a scale;
* with `--exact CLASS[,CLASS]`, the ATE of the graph solved again with
  those classes' measurements replaced by the ground truth
  (`--exact none` solves the graph as it is, which checks that the
  re-solve reproduces the run).

The re-solve uses GTSAM (Levenberg-Marquardt, Cauchy kernel of
c = 2.796 on the loop edges, heading priors as priors with free
translation), not echofield's backend: it is an independent check.
Node k of the graph is the k-th line of `trajectory_tum.txt`; its
ground truth is the ground-truth sample nearest in time.

    python3 tools/peers/edge_bias.py OUT --exact none,loop,dense
"""

import argparse
import csv
import math
from collections import Counter

import numpy as np

CLASSES = ("odometry", "sequential", "loop", "dense", "partial")


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def tum(path):
    rows = np.loadtxt(path, ndmin=2)
    qx, qy, qz, qw = rows[:, 4], rows[:, 5], rows[:, 6], rows[:, 7]
    yaw = np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    return rows[:, 0], np.c_[rows[:, 1], rows[:, 2], yaw]


def relative(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, wrap(b[2] - a[2])])


def read_run(out):
    stamps, trajectory = tum(f"{out}/trajectory_tum.txt")
    gt_stamps, gt = tum(f"{out}/ground_truth_tum.txt")
    truth = gt[[int(np.argmin(abs(gt_stamps - t))) for t in stamps]]
    kind_of = {}
    with open(f"{out}/loops.csv") as f:
        for r in csv.DictReader(f):
            if r["accepted"] != "true":
                continue
            if r["densified"] != "true":
                kind = "loop"
            else:
                kind = "partial" if r["partial"] == "true" else "dense"
            kind_of[(int(r["from"]), int(r["to"]))] = kind
    edges, priors, chain, vertices = [], [], Counter(), {}
    with open(f"{out}/graph.g2o") as f:
        for line in f:
            p = line.split()
            if p[0] == "VERTEX_SE2":
                vertices[int(p[1])] = [float(v) for v in p[2:5]]
            elif p[0] == "EDGE_SE2":
                i, j = int(p[1]), int(p[2])
                z = np.array([float(v) for v in p[3:6]])
                a = [float(v) for v in p[6:12]]
                info = np.array([[a[0], a[1], a[2]], [a[1], a[3], a[4]], [a[2], a[4], a[5]]])
                kind = kind_of.get((i, j)) or kind_of.get((j, i))
                if kind is None:
                    # The chain: the odometry edge comes first, then the match.
                    chain[(i, j)] += 1
                    kind = "odometry" if chain[(i, j)] == 1 else "sequential"
                edges.append((kind, i, j, z, info))
            elif p[0] == "EDGE_PRIOR_SE2":
                priors.append((int(p[1]), float(p[4]), float(p[-1])))
    return trajectory, truth, edges, priors, vertices


def align(trajectory, truth):
    """ATE after SE(2) alignment, scale, ATE after a similarity."""
    p, q = trajectory[:, :2], truth[:, :2]
    mp, mq = p.mean(0), q.mean(0)
    h = (q - mq).T @ (p - mp)
    th = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    r = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    qa = (r @ (q - mq).T).T
    pc = p - mp
    ate = math.sqrt(((pc - qa) ** 2).sum(1).mean())
    scale = (pc * qa).sum() / (qa * qa).sum()
    ate_similar = math.sqrt(((pc - scale * qa) ** 2).sum(1).mean())
    return ate, scale, ate_similar


def bias(edges, truth):
    for kind in CLASSES:
        along, length = [], []
        for k, i, j, z, _ in edges:
            if k != kind:
                continue
            t = relative(truth[i], truth[j])
            n = np.linalg.norm(t[:2])
            if n < 1e-3:
                continue
            along.append((z[:2] - t[:2]) @ t[:2] / n)
            length.append(n)
        if along:
            a, n = np.array(along), np.array(length)
            print(
                f"{kind:<10} {len(a):6d} edges, mean {n.mean():6.2f} m apart: "
                f"error along the displacement mean {a.mean():+.4f} m, "
                f"median {np.median(a):+.4f} m, scale {100 * (a * n).sum() / (n * n).sum():+.3f} %"
            )


def solve(edges, priors, vertices, truth, exact):
    """The graph solved again from the run's poses (node 0 fixed)."""
    import gtsam

    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    n = len(vertices)
    for k in range(n):
        values.insert(k, gtsam.Pose2(*vertices[k]))
    fixed = gtsam.noiseModel.Isotropic.Sigma(3, 1e-6)
    graph.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*vertices[0]), fixed))
    cauchy = gtsam.noiseModel.mEstimator.Cauchy.Create(2.796)
    for k, i, j, z, info in edges:
        if k in exact:
            z = relative(truth[i], truth[j])
        model = gtsam.noiseModel.Gaussian.Information(info)
        if k in ("loop", "dense", "partial"):
            model = gtsam.noiseModel.Robust.Create(cauchy, model)
        graph.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(*z), model))
    for i, theta, info in priors:
        sigmas = np.array([1e6, 1e6, 1 / math.sqrt(info)])
        graph.add(
            gtsam.PriorFactorPose2(i, gtsam.Pose2(0, 0, theta), gtsam.noiseModel.Diagonal.Sigmas(sigmas))
        )
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, gtsam.LevenbergMarquardtParams()).optimize()
    return np.array([[result.atPose2(k).x(), result.atPose2(k).y(), result.atPose2(k).theta()] for k in range(n)])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", help="echofield run output folder")
    ap.add_argument("--exact", default="", help="comma-separated: none or classes " + ", ".join(CLASSES))
    args = ap.parse_args()
    trajectory, truth, edges, priors, vertices = read_run(args.out)
    print("as run: ATE %.3f m, scale %.4f, ATE after the scale %.3f m" % align(trajectory, truth))
    bias(edges, truth)
    for group in filter(None, args.exact.split(",")):
        exact = set(group.split("+")) - {"none"}
        unknown = exact - set(CLASSES)
        if unknown:
            ap.error(f"--exact: unknown class {sorted(unknown)}")
        solved = solve(edges, priors, vertices, truth, exact)
        print("exact %-24s ATE %.3f m, scale %.4f, ATE after the scale %.3f m" % ((group,) + align(solved, truth)))


if __name__ == "__main__":
    main()
