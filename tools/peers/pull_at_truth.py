#!/usr/bin/env python3
"""What pulls the matches of `bench-matcher` along their displacement.

Reads the CSV of `echofield bench-matcher --pull-at-truth FILE` (one row per
scan point of every evaluated pair, at the true pose) and prints, per kind
of pair and band of true displacement, the derivative of eq. (5)'s score
along the true displacement summed over each pair's points, split by the
points' margin to the rim of the image's reach:

    rim      margin below RIM_BAND_M (or outside): the points a longer
             displacement carries out of the image, where I is 0;
    inside   the rest (the walls the image shares with the scan).

Negative sums pull the scan towards the image's centre (a shorter
displacement), positive ones away from it. Each cell is the mean over the
pairs with its standard error (a pair's sum is dominated by its walls'
noise: only a mean several standard errors from 0 is a pull), for the
search raster and for the image interpolated from the samples ("fine").

    python3 tools/peers/pull_at_truth.py pull.csv [--bands 0,3,10,25,1000]

Only the standard library; no venv needed.
"""

import argparse
import csv
import math
import sys
from collections import defaultdict

# Points within this many metres of the rim (or outside it) count as the rim's.
RIM_BAND_M = 3.0
GROUPS = ("rim", "inside")


def mean_se(values):
    n = len(values)
    if n == 0:
        return math.nan, math.nan
    m = sum(values) / n
    if n == 1:
        return m, math.nan
    var = sum((v - m) ** 2 for v in values) / (n - 1)
    return m, math.sqrt(var / n)


def read_pairs(path):
    """{(kind, scan, image): {"d": m, "rim"/"inside": [search, fine], "n": {...}}}."""
    pairs = {}
    with open(path, newline="") as f:
        for line, row in enumerate(csv.DictReader(f), start=2):
            try:
                key = (row["kind"], int(row["scan"]), int(row["image"]))
                margin = row["rim_margin_m"]
                slope = float(row["slope_along_per_m"])
                fine = float(row["fine_slope_along_per_m"])
                d = float(row["displacement_m"])
            except (KeyError, ValueError) as e:
                sys.exit(f"{path}: line {line}: {e!r}")
            group = "rim" if margin != "" and float(margin) < RIM_BAND_M else "inside"
            p = pairs.setdefault(
                key, {"d": d, "rim": [0.0, 0.0], "inside": [0.0, 0.0], "n": defaultdict(int)}
            )
            p[group][0] += slope
            p[group][1] += fine
            p["n"][group] += 1
    return pairs


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("csv")
    ap.add_argument("--bands", default="0,3,10,25,1000",
                    help="edges of the true-displacement bands, metres")
    args = ap.parse_args()
    edges = [float(v) for v in args.bands.split(",")]
    pairs = read_pairs(args.csv)
    if not pairs:
        sys.exit(f"{args.csv}: no rows")
    print(f"slope of the score along the true displacement, summed per pair "
          f"(1/m; mean ± standard error over the pairs; rim: margin < {RIM_BAND_M:g} m)")
    for kind in sorted({k[0] for k in pairs}):
        for lo, hi in zip(edges, edges[1:]):
            sel = [p for k, p in pairs.items() if k[0] == kind and lo <= p["d"] < hi]
            if not sel:
                continue
            points = {g: sum(p["n"][g] for p in sel) / len(sel) for g in GROUPS}
            cells = []
            for g in GROUPS:
                for i, raster in enumerate(("search", "fine")):
                    m, se = mean_se([p[g][i] for p in sel])
                    cells.append(f"{g} {raster} {m:+.2f} ± {se:.2f}")
            print(f"{kind:16s} {lo:g}-{hi:g} m, {len(sel)} pairs "
                  f"({points['rim']:.0f} rim / {points['inside']:.0f} inside points): "
                  + "; ".join(cells))


if __name__ == "__main__":
    main()
