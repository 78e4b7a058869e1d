#!/usr/bin/env python3
"""Do a run's scans prefer the truth's geometry to the run's own?

Reads an `echofield run` output folder of a mission with ground truth:
each node's scan `S_k` and optimised pose from `mission.mcap` (topic
`/slam/scan`, points in the node's vehicle frame, the pose their
placement), and the ground truth from `ground_truth_tum.txt` (the sample
nearest in time to each node, turned into the run's frame by the SE(2)
alignment of the positions). It scores a configuration of node poses by
how well every scan fits the map of the others:

    C = Σ_k Σ_{p ∈ S_k} log(F_k(T_k ⊕ p) / F̄ + ε)

`F_k` is a kernel density of the other nodes' points placed by their
poses (a Gaussian of `--sigma` metres per point on a raster of `--cell`
metres, bilinear between cells), leaving out the nodes within
`--exclude` of `k` in the node order (the same pass: a scan fits its
neighbours whatever the map's shape), `F̄` the median of the full density
at the placed points and `ε` = `--floor` the score of a point with
nothing near it. It prints, for the run's poses and for the truth:

* `C` at the poses and with the positions scaled about their mean by
  0.99 … 1.01 (does the score see a map that is too small or too large?);
* after each of `--iterations` relaxations, each moving every node at once to
  the local maximum of its own term of `C` (a pattern search of 0.2 m /
  0.5° steps halved down to 0.025 m / 0.05°, the others held): the ATE
  (SE(2) alignment), the map scale (least squares of the aligned truth
  onto the positions) and `C`.

If the relaxed truth and the relaxed run score alike while their ATEs
differ, the scans' points do not tell the two geometries apart: the
difference lies along directions the scans do not observe (a quay
without features), and what places the run there is not the scans'
consistency but the matches' biases and the other sensors. The score
reads the scans' points only (one range per beam), not the acoustic
images, so it is one criterion's view, not a bound on every matcher.

Needs numpy and mcap (PyPI `mcap`). Node k is the k-th line of
`trajectory_tum.txt`; a node without a scan in `mission.mcap` adds
nothing to `C` and stays where it is.

    python3 tools/peers/scan_consistency.py OUT --exclude 10 --iterations 3
"""

import argparse
import base64
import json
import math
import os
import sys

import numpy as np

from edge_bias import align, frame_rotation, truth_at, tum, wrap


def read_scans(out, stamps):
    """The points of each node's scan (vehicle frame), matched to the
    trajectory's nodes by stamp; nodes without a scan get none."""
    from mcap.reader import make_reader

    scans = [np.zeros((0, 2)) for _ in stamps]
    with open(f"{out}/mission.mcap", "rb") as f:
        for _schema, _channel, message in make_reader(f).iter_messages(topics=["/slam/scan"]):
            m = json.loads(message.data)
            t = m["timestamp"]["sec"] + 1e-9 * m["timestamp"]["nsec"]
            k = int(np.argmin(abs(stamps - t)))
            if abs(stamps[k] - t) > 1e-3:
                sys.exit(f"{out}/mission.mcap: a scan at {t:.3f} s matches no node of trajectory_tum.txt")
            raw = np.frombuffer(base64.b64decode(m["data"]), dtype="<f4").reshape(-1, 4)
            scans[k] = raw[:, :2].astype(float)
    return scans


def placed(pose, points):
    c, s = math.cos(pose[2]), math.sin(pose[2])
    x, y = points[:, 0], points[:, 1]
    return np.c_[pose[0] + c * x - s * y, pose[1] + s * x + c * y]


class Density:
    """The kernel density of every node's placed points, each node's
    contribution kept (flat raster indices and weights) so that it can be
    left out and put back."""

    def __init__(self, clouds, sigma, cell):
        self.cell = cell
        r = int(math.ceil(3 * sigma / cell))
        offsets = np.arange(-r, r + 1)
        di, dj = np.meshgrid(offsets, offsets, indexing="ij")
        self.di, self.dj = di.ravel(), dj.ravel()
        self.weights = np.exp(-0.5 * (self.di**2 + self.dj**2) * (cell / sigma) ** 2)
        every = np.vstack([c for c in clouds if len(c)])
        self.origin = every.min(0) - (r + 2) * cell
        self.shape = tuple(np.ceil((every.max(0) - self.origin) / cell).astype(int) + r + 3)
        self.grid = np.zeros(self.shape)
        self.parts = [self.contribution(c) for c in clouds]
        for k in range(len(clouds)):
            self.add(k, 1.0)

    def contribution(self, points):
        ij = np.round((points - self.origin) / self.cell).astype(np.int64)
        rows = (ij[:, 0, None] + self.di[None, :]).ravel()
        cols = (ij[:, 1, None] + self.dj[None, :]).ravel()
        return rows * self.shape[1] + cols, np.tile(self.weights, len(points))

    def add(self, k, sign):
        index, weights = self.parts[k]
        np.add.at(self.grid.ravel(), index, sign * weights)

    def at(self, q):
        f = (q - self.origin) / self.cell
        i = np.clip(np.floor(f).astype(int), 0, np.array(self.shape) - 2)
        t = np.clip(f - i, 0.0, 1.0)
        g = self.grid
        a, b = g[i[:, 0], i[:, 1]], g[i[:, 0] + 1, i[:, 1]]
        c, d = g[i[:, 0], i[:, 1] + 1], g[i[:, 0] + 1, i[:, 1] + 1]
        return (a * (1 - t[:, 0]) + b * t[:, 0]) * (1 - t[:, 1]) + (c * (1 - t[:, 0]) + d * t[:, 0]) * t[:, 1]


STEPS = [(0.2, math.radians(0.5)), (0.1, math.radians(0.25)), (0.05, math.radians(0.1)), (0.025, math.radians(0.05))]


def node_term(density, k, pose, scans, norm, floor):
    """Node k's term of `C` with its scan placed by `pose`."""
    v = density.at(placed(pose, scans[k]))
    return float(np.log(np.maximum(v, 0.0) / norm + floor).sum())


def climb(density, k, pose, scans, norm, floor):
    """Node k's pose at the local maximum of its term, by a pattern search
    over the 26 neighbours of the pose at each of `STEPS` (at most 20
    moves per step)."""
    best = pose.copy()
    score = node_term(density, k, best, scans, norm, floor)
    for step_m, step_rad in STEPS:
        for _ in range(20):
            trials = [
                best + np.array([dx * step_m, dy * step_m, dt * step_rad])
                for dx in (-1, 0, 1)
                for dy in (-1, 0, 1)
                for dt in (-1, 0, 1)
                if (dx, dy, dt) != (0, 0, 0)
            ]
            scores = [node_term(density, k, p, scans, norm, floor) for p in trials]
            i = int(np.argmax(scores))
            if scores[i] <= score + 1e-9:
                break
            best, score = trials[i], scores[i]
    return best


def consistency(poses, scans, args, relax=False):
    """`C` of the module doc at `poses`, and (with `relax`) every node's
    pose climbed to the local maximum of its own term, the others held."""
    clouds = [placed(poses[k], scans[k]) for k in range(len(poses))]
    density = Density(clouds, args.sigma, args.cell)
    norm = float(np.median(density.at(np.vstack([c for c in clouds if len(c)]))))
    total, moved = 0.0, poses.copy()
    n = len(poses)
    for k in range(n):
        if len(scans[k]) == 0:
            continue
        near = range(max(0, k - args.exclude), min(n, k + args.exclude + 1))
        for j in near:
            density.add(j, -1.0)
        total += node_term(density, k, poses[k], scans, norm, args.floor)
        if relax:
            moved[k] = climb(density, k, poses[k], scans, norm, args.floor)
        for j in near:
            density.add(j, 1.0)
    return total, moved


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", help="an `echofield run` output folder with mission.mcap and ground truth")
    parser.add_argument("--exclude", type=int, default=10, help="nodes on either side left out of a node's map")
    parser.add_argument("--iterations", type=int, default=3, help="relaxations from each start")
    parser.add_argument("--sigma", type=float, default=0.15, help="kernel standard deviation, metres")
    parser.add_argument("--cell", type=float, default=0.05, help="raster cell, metres")
    parser.add_argument("--floor", type=float, default=0.05, help="ε: the score of a point with nothing near it")
    args = parser.parse_args()
    for name in ("trajectory_tum.txt", "ground_truth_tum.txt", "mission.mcap"):
        if not os.path.isfile(f"{args.out}/{name}"):
            sys.exit(f"{args.out}: no {name} (an `echofield run` folder of a mission with ground truth)")

    stamps, run = tum(f"{args.out}/trajectory_tum.txt")
    truth = truth_at(args.out, stamps)
    scans = read_scans(args.out, stamps)
    # The truth in the run's frame (positions aligned as `align` does).
    th = frame_rotation(run, truth)
    r = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    xy = (r @ (truth[:, :2] - truth[:, :2].mean(0)).T).T + run[:, :2].mean(0)
    truth_in_run = np.c_[xy, [wrap(t + th) for t in truth[:, 2]]]
    print(f"{len(run)} nodes, {sum(len(s) for s in scans)} scan points; exclude ±{args.exclude}, sigma {args.sigma} m")

    for name, start in (("run", run), ("truth", truth_in_run)):
        # Each configuration's C is computed once: the pass that relaxes
        # a configuration also scores it.
        c, poses = consistency(start, scans, args, relax=args.iterations > 0)
        scaled = {1.0: c}
        mean = start[:, :2].mean(0)
        for s in (0.99, 0.995, 1.005, 1.01):
            p = start.copy()
            p[:, :2] = mean + s * (start[:, :2] - mean)
            scaled[s] = consistency(p, scans, args)[0]
        print(f"{name}: C with the positions scaled by " + ", ".join(f"{s}: {scaled[s]:.1f}" for s in sorted(scaled)))
        for it in range(1, args.iterations + 1):
            c, moved = consistency(poses, scans, args, relax=it < args.iterations)
            ate, scale, _ = align(poses, truth)
            print(f"  {name} relaxed {it}: ATE {ate:.3f} m, scale {scale:.4f}, C {c:.1f}")
            poses = moved

if __name__ == "__main__":
    main()
