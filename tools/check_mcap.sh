#!/usr/bin/env bash
# Reads every message of echofield MCAP files with the official Python `mcap`
# package (https://pypi.org/project/mcap/) and checks each one against its
# channel's schema; see tools/check_mcap.py for the list of checks. Exits
# non-zero on any error.
#
# Usage: tools/check_mcap.sh [FILE.mcap]...
# Without arguments it checks freshly written samples (an echofield mission
# with Foxglove output channels, and the same mission as ROS 2 CDR messages,
# written by the ignored test `write_samples_for_python_check`) and every
# .mcap committed under datasets/ except the deliberately broken test files.
# mcap, mcap-ros2-support and jsonschema are installed from PyPI into
# tools/.venv-mcap (gitignored) on first use.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
venv="$here/.venv-mcap"
# shellcheck source=peers/venv.sh
. "$here/peers/venv.sh"
peer_venv "$venv" "mcap, mcap_ros2, jsonschema" mcap mcap-ros2-support jsonschema

files=("$@")
if [ ${#files[@]} -eq 0 ]; then
  work="$(mktemp -d)"
  trap 'rm -rf "$work"' EXIT
  ECHOFIELD_MCAP_SAMPLES="$work" cargo test --quiet --manifest-path "$root/Cargo.toml" \
    -p echofield-datasets --test mcap_foxglove -- --ignored write_samples_for_python_check \
    >/dev/null
  files=("$work"/*.mcap)
  while IFS= read -r -d '' f; do files+=("$f"); done \
    < <(find "$root/datasets" -name '*.mcap' -not -path '*/tests/*' -print0)
fi
exec "$venv/bin/python" "$here/check_mcap.py" "${files[@]}"
