#!/usr/bin/env bash
# Checks `echofield eval` against the evo package (https://pypi.org/project/evo/):
# for each (estimate, reference) pair, `evo_ape tum REF EST` with and without
# `-a` must give the same ATE RMSE as `echofield eval --align se2|none` to
# 1e-6 relative.
#
# Usage: tools/check_evo.sh [EST.txt REF.txt]...
# Without arguments it checks synthetic drifting trajectories made by
# tools/check_evo_fixtures.py, plus any run output found under out/.
# evo is installed from PyPI into tools/.venv-evo (gitignored) on first use.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
venv="$here/.venv-evo"
if [ ! -x "$venv/bin/evo_ape" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --upgrade pip
  "$venv/bin/pip" install --quiet evo
fi
cargo build --quiet --release -p echofield --manifest-path "$root/Cargo.toml"
echofield="$root/target/release/echofield"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

pairs=("$@")
if [ ${#pairs[@]} -eq 0 ]; then
  "$venv/bin/python" "$here/check_evo_fixtures.py" "$work"
  pairs=("$work/est_a.txt" "$work/ref_a.txt" "$work/est_b.txt" "$work/ref_b.txt")
  for run in "$root"/out/*/; do
    if [ -f "$run/trajectory_tum.txt" ] && [ -f "$run/ground_truth_tum.txt" ]; then
      pairs+=("$run/trajectory_tum.txt" "$run/ground_truth_tum.txt")
      pairs+=("$run/dead_reckoning_tum.txt" "$run/ground_truth_tum.txt")
    fi
  done
fi

status=0
printf '%-45s %-6s %-14s %-14s %s\n' estimate align echofield evo rel_diff
for ((k = 0; k < ${#pairs[@]}; k += 2)); do
  est="${pairs[k]}"
  ref="${pairs[k + 1]}"
  for align in se2 none; do
    flag=()
    [ "$align" = se2 ] && flag=(-a)
    rm -f "$work/res.zip" "$work/ours.json"
    "$venv/bin/evo_ape" tum "$ref" "$est" "${flag[@]}" --save_results "$work/res.zip" >/dev/null
    "$echofield" eval --estimate "$est" --reference "$ref" --align "$align" --json "$work/ours.json" >/dev/null
    line=$("$venv/bin/python" - "$work/res.zip" "$work/ours.json" <<'PY'
import json, sys, zipfile
with zipfile.ZipFile(sys.argv[1]) as z:
    theirs = json.loads(z.read("stats.json"))["rmse"]
ours = json.load(open(sys.argv[2]))["ate"]["rmse_m"]
rel = abs(ours - theirs) / max(abs(theirs), 1e-300)
print(f"{ours:<14.9g} {theirs:<14.9g} {rel:.2e} {'ok' if rel <= 1e-6 else 'MISMATCH'}")
PY
)
    printf '%-45s %-6s %s\n' "$(basename "$(dirname "$est")")/$(basename "$est")" "$align" "$line"
    case "$line" in *MISMATCH*) status=1 ;; esac
  done
done
exit $status
