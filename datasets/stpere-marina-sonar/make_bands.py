#!/usr/bin/env python3
"""Writes bands.csv, the lossless compact form of the St Pere point sets.

Usage: python3 make_bands.py SHARED_SONAR_DIR > bands.csv

Every point of `pclKeyFrameK.pcd` is one bin of one beam: its angle
`atan2(y, x)` is `angle_index · 0.0314159` rad and its range `hypot(x, y)`
is `bin · 0.1` m (the far end of 1-based bin `bin`). The points of one beam
that sit in consecutive bins are written as one band `first_bin..last_bin`
(inclusive); expanding every band gives back exactly the file's point set.
Standard library only.
"""
import math
import os
import sys

STEP = 0.0314159
BIN = 0.1


def points(path):
    with open(path) as f:
        lines = f.read().splitlines()
    data = lines.index("DATA ascii") + 1
    for line in lines[data:]:
        if line.strip():
            x, y, _ = (float(v) for v in line.split())
            yield x, y


def main(folder):
    print("keyframe,angle_index,first_bin,last_bin")
    with open(os.path.join(folder, "keyFrameTimeStamps.csv")) as f:
        keyframes = [int(l.split(",")[0]) for l in f.read().splitlines()[1:] if l]
    for k in keyframes:
        beams = {}
        for x, y in points(os.path.join(folder, f"pclKeyFrame{k}.pcd")):
            a = round(math.atan2(y, x) / STEP) % 200
            b = round(math.hypot(x, y) / BIN)
            beams.setdefault(a, set()).add(b)
        for a in sorted(beams):
            bins = sorted(beams[a])
            start = prev = bins[0]
            for b in bins[1:] + [None]:
                if b is not None and b == prev + 1:
                    prev = b
                    continue
                print(f"{k},{a},{start},{prev}")
                if b is not None:
                    start = prev = b


if __name__ == "__main__":
    main(sys.argv[1])
