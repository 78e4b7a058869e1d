#!/usr/bin/env bash
# Checks echofield's ROS readers against recordings written by an
# independent writer, the Python `rosbags` package
# (https://pypi.org/project/rosbags/): tools/check_rosbags.py writes a
# simulated tank crossing in several variants (rosbag2 with MCAP or sqlite3
# storage, a ROS 1 bag with lz4 chunks; the sonar as echofield_msgs
# SonarBeam, Ping360 SonarEcho, RawSonarImage or LaserScan sweeps; the DVL
# as TwistWithCovarianceStamped, marine_acoustic_msgs/Dvl or the Water
# Linked message; Imu or QuaternionStamped; the sonar mounting on
# /tf_static); `echofield run` must read every rotation of each and track
# the ground truth.
#
# Usage: tools/check_rosbags.sh
# rosbags is installed from PyPI into tools/.venv-rosbags (gitignored) on
# first use.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
venv="$here/.venv-rosbags"
# shellcheck source=peers/venv.sh
. "$here/peers/venv.sh"
peer_venv "$venv" "rosbags, numpy" rosbags numpy
echofield_release "$root"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

for variant in echofield-mcap ping360-sqlite3 rawimage-mcap laserscan-mcap ros1-ping360-lz4; do
  input="$work/$variant"
  case "$variant" in ros1-*) input="$input.bag" ;; esac
  "$venv/bin/python" "$here/check_rosbags.py" "$here/ros/echofield_msgs/msg/SonarBeam.msg" "$input" "$variant"
  echo "== $variant"
  # The rosbag2 folder (or ROS 1 bag) itself; the run prints each topic's use.
  "$echofield" run "$input" --output "$work/run-$variant" --allow-suspect
  "$venv/bin/python" - "$work/run-$variant/report.json" "$variant" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
variant = sys.argv[2]
# 114 s of beams at 0.07 s, 200 per rotation: 8 whole rotations, each a node.
# A LaserScan carries ranges only (scan-only data): a looser ATE bound.
ate_max = 0.10 if variant.startswith("laserscan") else 0.05
checks = [
    ("rotations read", r["rotations"], r["rotations"] == 8),
    ("nodes", r["nodes"], r["nodes"] == 8),
    ("sequential matches accepted", r["sequential_accepted"], r["sequential_accepted"] >= 6),
    ("ATE (m)", round(r["ate_rmse_m"], 4), r["ate_rmse_m"] < ate_max),
]
ok = True
for name, value, good in checks:
    print(f"{name:30} {value!s:>10} {'ok' if good else 'MISMATCH'}")
    ok &= good
sys.exit(0 if ok else 1)
PY
done
