#!/usr/bin/env bash
# Checks echofield's ROS 2 reader against recordings written by an
# independent writer, the Python `rosbags` package
# (https://pypi.org/project/rosbags/): tools/check_rosbags.py writes a
# rosbag2 (MCAP storage) of a simulated tank crossing with
# echofield_msgs/msg/SonarBeam (registered from the package's own .msg
# file in tools/ros/echofield_msgs), TwistWithCovarianceStamped, Imu and
# Odometry; `echofield run` must read every rotation of it and track the
# ground truth.
#
# Usage: tools/check_rosbags.sh
# rosbags is installed from PyPI into tools/.venv-rosbags (gitignored) on
# first use.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
venv="$here/.venv-rosbags"
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import rosbags, numpy" 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --upgrade pip
  "$venv/bin/pip" install --quiet rosbags numpy
fi
cargo build --quiet --release -p echofield --manifest-path "$root/Cargo.toml"
echofield="$root/target/release/echofield"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$venv/bin/python" "$here/check_rosbags.py" "$here/ros/echofield_msgs/msg/SonarBeam.msg" "$work/bag"
# The rosbag2 folder itself (metadata.yaml + MCAP storage).
"$echofield" run "$work/bag" --output "$work/run" -q
"$venv/bin/python" - "$work/run/report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
# 114 s of beams at 0.07 s, 200 per rotation: 8 whole rotations, each a node.
checks = [
    ("rotations read", r["rotations"], r["rotations"] == 8),
    ("nodes", r["nodes"], r["nodes"] == 8),
    ("sequential matches accepted", r["sequential_accepted"], r["sequential_accepted"] >= 6),
    ("ATE (m)", round(r["ate_rmse_m"], 4), r["ate_rmse_m"] < 0.05),
]
ok = True
for name, value, good in checks:
    print(f"{name:30} {value!s:>10} {'ok' if good else 'MISMATCH'}")
    ok &= good
sys.exit(0 if ok else 1)
PY
