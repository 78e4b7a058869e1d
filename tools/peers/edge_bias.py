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
  those classes' measurements replaced by the ground truth (`prior`: the
  heading priors' headings; `a+b` replaces both classes in one solve;
  `--exact none` solves the graph as it is, which checks that the
  re-solve reproduces the run);
* with `--influence N`, what sets the map's scale: the graph linearised
  at the ground truth (Gauss-Newton with each loop's Cauchy weight at its
  true residual, node 0 held), each edge's and heading prior's
  measurement error is carried through the normal equations to the
  final poses, and the resulting change of the map's scale along its
  long and short axes (a least-squares stretch of the positions about
  their mean, in percent) is summed per class; the N edges that shrink
  the long axis most are listed. The sums add up to the linearised
  solve's stretch, which the first line prints beside the run's own.
  Needs numpy only; a dense solve, so graphs of at most 3,000 nodes.
  Against a noisy reference (the real mission's DGPS) the linearisation
  charges the reference's own noise to the edges: there the shares say
  less than on a simulated mission's exact truth.
* with `--axes`, per edge class the scale of the measured translations
  along the map's long and short axes (the principal axes of the true
  positions): `Σ (e·u)(d·u) / Σ (d·u)²` over the class's edges, `d` the
  true displacement and `e` the measurement's error, both in the world
  frame, `u` the axis. Loops are split into those within one pass (the
  true path between the two nodes at most `SAME_PASS_RATIO` times their
  distance: the vehicle went straight from one to the other) and
  revisits. A chain of edges whose scale along an axis is negative
  shortens the map along it, whatever the edges' mean error along their
  own displacements. A partial loop's measurement along its
  unconstrained direction is the estimate's at the time it was made, so
  its rows say what the estimate held there, not what a match measured.
  With a node spacing (nodes picked by the dead reckoning's own
  displacement) the odometry row is biased low: an edge's error and its
  true length are correlated by the selection.

The re-solve uses GTSAM (Levenberg-Marquardt, Cauchy kernel of
c = 2.796 on the loop edges, heading priors as priors with free
translation), not echofield's backend: it is an independent check.
Node k of the graph is the k-th line of `trajectory_tum.txt`; its
ground truth is the ground-truth sample nearest in time.

    python3 tools/peers/edge_bias.py OUT --exact none,loop,dense
    python3 tools/peers/edge_bias.py OUT --influence 10
"""

import argparse
import csv
import math
from collections import Counter

import numpy as np

CLASSES = ("odometry", "sequential", "loop", "dense", "partial")
# The loop classes: a Cauchy kernel in the re-solve, and the one-pass /
# revisit split of `--axes`.
LOOP_CLASSES = ("loop", "dense", "partial")

# `--axes`: a loop whose nodes' true path is at most this many times their
# straight distance lies within one pass.
SAME_PASS_RATIO = 1.5


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


def truth_at(out, stamps):
    """The ground-truth pose (x, y, yaw) of each of `stamps`: the sample of
    `ground_truth_tum.txt` nearest in time."""
    gt_stamps, gt = tum(f"{out}/ground_truth_tum.txt")
    return gt[[int(np.argmin(abs(gt_stamps - t))) for t in stamps]]


def read_run(out):
    stamps, trajectory = tum(f"{out}/trajectory_tum.txt")
    truth = truth_at(out, stamps)
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


def frame_rotation(trajectory, truth):
    """The rotation (radians) of the SE(2) alignment of the truth's
    positions onto the trajectory's: the run's frame against the truth's."""
    p, q = trajectory[:, :2], truth[:, :2]
    h = (q - q.mean(0)).T @ (p - p.mean(0))
    return math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])


def align(trajectory, truth):
    """ATE after SE(2) alignment, scale, ATE after a similarity."""
    p, q = trajectory[:, :2], truth[:, :2]
    mp, mq = p.mean(0), q.mean(0)
    th = frame_rotation(trajectory, truth)
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


def principal_axes(truth):
    """The long and short axes of the true positions: the columns of a
    2x2 matrix, the long one first."""
    centred = truth[:, :2] - truth[:, :2].mean(0)
    _, axes = np.linalg.eigh(centred.T @ centred)
    return axes[:, ::-1]


def axes_scale(edges, truth):
    """Per class the scale along the map's long and short axes (`--axes`)."""
    long_axis, short_axis = principal_axes(truth).T
    steps = np.hypot(*np.diff(truth[:, :2], axis=0).T)
    path = np.concatenate([[0.0], np.cumsum(steps)])
    groups = {}
    for k, i, j, z, _ in edges:
        d = truth[j, :2] - truth[i, :2]
        distance = np.linalg.norm(d)
        if distance < 1e-3:
            continue
        c, s = math.cos(truth[i, 2]), math.sin(truth[i, 2])
        e = np.array([c * z[0] - s * z[1], s * z[0] + c * z[1]]) - d
        name = k
        if k in LOOP_CLASSES:
            same = abs(path[j] - path[i]) <= SAME_PASS_RATIO * distance
            name = f"{k} ({'one pass' if same else 'revisit'})"
        groups.setdefault(name, []).append((d, e))
    print(f"scale along the map's axes (loops within one pass: path at most {SAME_PASS_RATIO} x distance):")
    names = [n for k in CLASSES for n in (k, f"{k} (one pass)", f"{k} (revisit)") if n in groups]
    for name in names:
        rows = groups[name]
        d = np.array([r[0] for r in rows])
        e = np.array([r[1] for r in rows])
        scales = []
        for u in (long_axis, short_axis):
            du = d @ u
            # A class whose displacements are all across the axis says nothing along it.
            scales.append(f"{100 * (e @ u) @ du / (du @ du):+.3f} %" if du @ du > 1e-9 else "n/a")
        print(f"  {name:<20} {len(rows):6d}: long axis {scales[0]}, short axis {scales[1]}")


def solve(edges, priors, vertices, truth, exact, frame_rad):
    """The graph solved again from the run's poses (node 0 fixed). Exact
    heading priors are the true headings turned into the run's frame by
    `frame_rad` (`frame_rotation`), since node 0 stays where the run put
    it."""
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
        if k in LOOP_CLASSES:
            model = gtsam.noiseModel.Robust.Create(cauchy, model)
        graph.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(*z), model))
    for i, theta, info in priors:
        if "prior" in exact:
            theta = wrap(truth[i][2] + frame_rad)
        sigmas = np.array([1e6, 1e6, 1 / math.sqrt(info)])
        graph.add(
            gtsam.PriorFactorPose2(i, gtsam.Pose2(0, 0, theta), gtsam.noiseModel.Diagonal.Sigmas(sigmas))
        )
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, gtsam.LevenbergMarquardtParams()).optimize()
    return np.array([[result.atPose2(k).x(), result.atPose2(k).y(), result.atPose2(k).theta()] for k in range(n)])


def between_jacobians(a, b):
    """Jacobians of `relative(a, b)` with respect to `a` and `b` (3x3 each)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    d = b[:2] - a[:2]
    rt = np.array([[c, s], [-s, c]])
    drt = np.array([[-s, c], [-c, -s]])
    ja, jb = np.zeros((3, 3)), np.zeros((3, 3))
    ja[:2, :2], ja[:2, 2], ja[2, 2] = -rt, drt @ d, -1.0
    jb[:2, :2], jb[2, 2] = rt, 1.0
    return ja, jb


def stretch(trajectory, truth, axes):
    """The run's stretch along each of `axes` (columns), percent: the
    trajectory aligned onto the truth by SE(2), then the least-squares
    slope of its error's component along the axis on the position's."""
    p, q = trajectory[:, :2], truth[:, :2]
    mp, mq = p.mean(0), q.mean(0)
    h = (p - mp).T @ (q - mq)
    th = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    r = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    error = (r @ (p - mp).T).T - (q - mq)
    out = []
    for u in axes.T:
        c = (q - mq) @ u
        out.append(100 * (error @ u) @ c / (c @ c))
    return out


def influence(edges, priors, trajectory, truth, count):
    """Each measurement's share of the map's scale (see the module doc)."""
    n = len(truth)
    if n > 3000:
        raise SystemExit(f"--influence: {n} nodes, at most 3,000 (dense solve)")
    hessian = np.zeros((3 * n, 3 * n))
    terms = []
    for k, i, j, z, info in edges:
        t = relative(truth[i], truth[j])
        e = z - t
        e[2] = wrap(e[2])
        w = info
        if k in LOOP_CLASSES:
            w = info / (1.0 + float(e @ info @ e) / 2.796**2)
        ja, jb = between_jacobians(truth[i], truth[j])
        a = np.hstack([ja, jb])
        idx = list(range(3 * i, 3 * i + 3)) + list(range(3 * j, 3 * j + 3))
        hessian[np.ix_(idx, idx)] += a.T @ w @ a
        terms.append((k, i, j, idx, a.T @ w @ e))
    for i, theta, info in priors:
        hessian[3 * i + 2, 3 * i + 2] += info
        terms.append(("prior", i, i, [3 * i + 2], np.array([info * wrap(theta - truth[i, 2])])))
    hessian[:3, :3] += 1e8 * np.eye(3)
    # The long and short axes of the true positions; a stretch along axis
    # u is the least-squares slope of the displacement's u component on
    # the position's u coordinate.
    centred = truth[:, :2] - truth[:, :2].mean(0)
    axes = principal_axes(truth)
    functionals = []
    for u in axes.T:
        c = centred @ u
        f = np.zeros(3 * n)
        f[0::3], f[1::3] = u[0] * c / (c @ c), u[1] * c / (c @ c)
        functionals.append(f)
    adjoint = np.linalg.solve(hessian, np.array(functionals).T)
    shares = [(k, i, j, 100 * (adjoint[idx].T @ v)) for k, i, j, idx, v in terms]
    total = sum(s for *_, s in shares)
    print(
        "stretch of the map: long axis %+.3f %%, short axis %+.3f %% (as run: %+.3f %%, %+.3f %%)"
        % (tuple(total) + tuple(stretch(trajectory, truth, axes)))
    )
    for kind in CLASSES + ("prior",):
        mine = [s for k, *_, s in shares if k == kind]
        if mine:
            long_axis, short_axis = sum(mine)
            print(f"  {kind:<10} {len(mine):6d}: long axis {long_axis:+.3f} %, short axis {short_axis:+.3f} %")
    if count > 0:
        print(f"the {count} measurements that shrink the long axis most:")
    for k, i, j, s in sorted(shares, key=lambda x: x[3][0])[:count]:
        t = relative(truth[i], truth[j])
        print(f"  {k:<10} {i:5d} -> {j:5d}, {np.linalg.norm(t[:2]):6.2f} m apart: {s[0]:+.4f} %")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", help="echofield run output folder")
    ap.add_argument(
        "--exact", default="", help="comma-separated: none or classes " + ", ".join(CLASSES + ("prior",))
    )
    ap.add_argument("--influence", type=int, metavar="N", help="per-class shares of the map's scale, N largest")
    ap.add_argument("--axes", action="store_true", help="per class the scale along the map's long and short axes")
    args = ap.parse_args()
    trajectory, truth, edges, priors, vertices = read_run(args.out)
    print("as run: ATE %.3f m, scale %.4f, ATE after the scale %.3f m" % align(trajectory, truth))
    bias(edges, truth)
    for group in filter(None, args.exact.split(",")):
        exact = set(group.split("+")) - {"none"}
        unknown = exact - set(CLASSES) - {"prior"}
        if unknown:
            ap.error(f"--exact: unknown class {sorted(unknown)}")
        solved = solve(edges, priors, vertices, truth, exact, frame_rotation(trajectory, truth))
        print("exact %-24s ATE %.3f m, scale %.4f, ATE after the scale %.3f m" % ((group,) + align(solved, truth)))
    if args.axes:
        axes_scale(edges, truth)
    if args.influence is not None:
        influence(edges, priors, trajectory, truth, args.influence)


if __name__ == "__main__":
    main()
