#!/usr/bin/env bash
# Checks that GTSAM (https://pypi.org/project/gtsam/) reads echofield's
# graph.g2o completely and finds the same chi2 (tools/check_gtsam.py says
# what is compared and to which tolerance).
#
# Usage: tools/check_gtsam.sh [GRAPH.g2o]...
# Without arguments it runs `echofield run` on a simulated tank mission and
# checks its graph.g2o, plus every out/*/graph.g2o. GTSAM is installed from
# PyPI into tools/peers/.venv (gitignored; the peer benchmark's) on first use.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
venv="$here/peers/.venv"
# shellcheck source=peers/venv.sh
. "$here/peers/venv.sh"
peer_venv "$venv" "gtsam, numpy" gtsam numpy
echofield_release "$root"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

graphs=("$@")
if [ ${#graphs[@]} -eq 0 ]; then
  "$echofield" simulate --scenario tank --seed 1 --output "$work/tank.mcap" >/dev/null
  "$echofield" run "$work/tank.mcap" --output "$work/tank" >/dev/null
  graphs=("$work/tank/graph.g2o")
  for run in "$root"/out/*/; do
    [ -f "$run/graph.g2o" ] && graphs+=("$run/graph.g2o")
  done
fi

status=0
for graph in "${graphs[@]}"; do
  echo "$graph"
  "$echofield" optimize "$graph" --output "$work/optimised.g2o" --summary "$work/summary.json" >/dev/null
  "$venv/bin/python" "$here/check_gtsam.py" "$graph" "$work/summary.json" "$work/optimised.g2o" || status=1
done
exit $status
