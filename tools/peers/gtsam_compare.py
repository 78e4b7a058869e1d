"""Time GTSAM's Levenberg-Marquardt and `echofield optimize` on the same 2D
pose-graph files and print one side-by-side table.

Run through gtsam_compare.sh, which creates the virtualenv. Both solvers run
single-threaded (the PyPI gtsam wheel is built without TBB; echofield gets
--threads 1) with the same relative cost tolerance and iteration cap.

Starting points: GTSAM starts from the file's VERTEX_SE2 lines, or, for
files without vertices, from poses composed along the odometry chain
i -> i+1 (the start echofield's reader builds for those files). readG2o adds
no prior, so the first pose is held by a tight prior (the noise model of
GTSAM's own Pose2SLAMExample_g2o). echofield starts from the same file and
applies its default chordal initialisation, whose time is part of its
measurement.

chi2: echofield reports the g2o error (x, y, theta of Z^-1 X_i^-1 X_j);
GTSAM minimises the Lie error Log(Z^-1 X_i^-1 X_j). The table gives each
solver's final chi2 under both definitions, computed here on the poses each
one returned (the prior excluded), so the comparison does not depend on
which error a solver minimises.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import gtsam
import numpy as np


def chain_start(graph):
    """Poses composed along the odometry chain i -> i+1, first pose at the
    identity."""
    steps = {}
    for k in range(graph.size()):
        factor = graph.at(k)
        if isinstance(factor, gtsam.BetweenFactorPose2):
            i, j = factor.keys()
            if j == i + 1:
                steps[i] = factor.measured()
    keys = sorted({key for k in range(graph.size()) for key in graph.at(k).keys()})
    values = gtsam.Values()
    pose = gtsam.Pose2()
    values.insert(keys[0], pose)
    for key in keys[1:]:
        if key - 1 not in steps:
            raise SystemExit(f"no odometry edge {key - 1} -> {key}: cannot chain-initialise")
        pose = pose.compose(steps[key - 1])
        values.insert(key, pose)
    return values


def load(path):
    graph, initial = gtsam.readG2o(path, False)
    if initial.size() == 0:
        initial = chain_start(graph)
    return graph, initial


def g2o_chi2(graph, values):
    """Sum of e^T Omega e with g2o's error: e = (x, y, wrap(theta)) of
    Z^-1 (X_i^-1 X_j) for a between factor, Z^-1 X_i for a pose prior
    (g2o's EDGE_PRIOR_SE2); other factors are left out."""
    total = 0.0
    for k in range(graph.size()):
        factor = graph.at(k)
        if isinstance(factor, gtsam.BetweenFactorPose2):
            i, j = factor.keys()
            measured = factor.measured()
            predicted = values.atPose2(i).between(values.atPose2(j))
        elif isinstance(factor, gtsam.PriorFactorPose2):
            measured = factor.prior()
            predicted = values.atPose2(factor.keys()[0])
        else:
            continue
        residual = measured.inverse().compose(predicted)
        theta = math.atan2(math.sin(residual.theta()), math.cos(residual.theta()))
        e = np.array([residual.x(), residual.y(), theta])
        # The noise model's R is the square-root information: Omega = R^T R.
        r = factor.noiseModel().R()
        total += float(e @ (r.T @ r) @ e)
    return total


def lie_chi2(graph, values):
    """GTSAM's own error (0.5 chi2 per factor) doubled."""
    return 2.0 * graph.error(values)


def time_gtsam(graph, initial, tolerance, max_iterations, repeats):
    with_prior = gtsam.NonlinearFactorGraph(graph)
    first = min(initial.keys())
    prior_noise = gtsam.noiseModel.Diagonal.Variances(np.array([1e-6, 1e-6, 1e-8]))
    with_prior.add(gtsam.PriorFactorPose2(first, initial.atPose2(first), prior_noise))
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(tolerance)
    params.setAbsoluteErrorTol(0.0)
    params.setErrorTol(0.0)
    params.setMaxIterations(max_iterations)
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        optimizer = gtsam.LevenbergMarquardtOptimizer(with_prior, initial, params)
        result = optimizer.optimize()
        best = min(best, time.perf_counter() - start)
    return best, result, optimizer.iterations()


def time_echofield(binary, path, graph, repeats, workdir):
    output = os.path.join(workdir, "out.g2o")
    summary_path = os.path.join(workdir, "summary.json")
    # Timed like GTSAM: `repeats` solves in one process, the fastest counts.
    subprocess.run(
        [binary, "optimize", path, "--output", output, "--summary", summary_path,
         "--threads", "1", "--repeat", str(repeats)],
        check=True, stdout=subprocess.DEVNULL,
    )
    with open(summary_path) as f:
        summary = json.load(f)
    _, solution = gtsam.readG2o(output, False)
    return summary["time_s"], summary, solution


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--echofield", required=True, help="path of the echofield binary")
    parser.add_argument("--repeats", type=int, default=5, help="runs per file; the fastest counts")
    parser.add_argument("--tolerance", type=float, default=1e-10,
                        help="relative cost decrease that ends both solvers (echofield's default)")
    parser.add_argument("--max-iterations", type=int, default=100)
    args = parser.parse_args()

    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        for path in args.files:
            name = os.path.basename(path)
            graph, initial = load(path)
            g_time, g_result, g_iterations = time_gtsam(
                graph, initial, args.tolerance, args.max_iterations, args.repeats)
            e_time, e_summary, e_solution = time_echofield(
                args.echofield, path, graph, args.repeats, workdir)
            rows.append({
                "file": name,
                "echofield_s": e_time,
                "gtsam_s": g_time,
                "ratio": e_time / g_time,
                "echofield_iterations": e_summary["iterations"],
                "gtsam_iterations": g_iterations,
                "echofield_chi2_g2o": g2o_chi2(graph, e_solution),
                "echofield_chi2_lie": lie_chi2(graph, e_solution),
                "gtsam_chi2_g2o": g2o_chi2(graph, g_result),
                "gtsam_chi2_lie": lie_chi2(graph, g_result),
            })
            print(f"{name}: done", file=sys.stderr)

    print(f"Single-threaded, best of {args.repeats} solves in one process on each side; both stop when an iteration lowers "
          f"the cost by less than {args.tolerance:g} of it (GTSAM relativeErrorTol, "
          f"absolute and error tolerances 0) or after {args.max_iterations} iterations.")
    print("echofield: `echofield optimize --threads 1 --repeat N`, time_s of its summary (chordal "
          "initialisation + LM, file IO excluded); GTSAM: LevenbergMarquardtOptimizer "
          "construction + optimize() from the file's start, first pose held by a prior.")
    print("chi2 g2o: sum e^T Omega e with g2o's error (x, y, theta); chi2 Lie: with GTSAM's "
          "Log error. Both evaluated here on each solver's returned poses.")
    print()
    print("| file | echofield s | GTSAM s | ratio | echofield it | GTSAM it "
          "| echofield chi2 g2o | GTSAM chi2 g2o | echofield chi2 Lie | GTSAM chi2 Lie |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['file']} | {r['echofield_s']:.4f} | {r['gtsam_s']:.4f} | {r['ratio']:.3f} "
              f"| {r['echofield_iterations']} | {r['gtsam_iterations']} "
              f"| {r['echofield_chi2_g2o']:.7f} | {r['gtsam_chi2_g2o']:.7f} "
              f"| {r['echofield_chi2_lie']:.7f} | {r['gtsam_chi2_lie']:.7f} |")


if __name__ == "__main__":
    main()
