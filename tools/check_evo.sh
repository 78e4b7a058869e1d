#!/usr/bin/env bash
# Checks `echofield eval` against the evo package (https://pypi.org/project/evo/):
# for each (estimate, reference) pair, `evo_ape tum REF EST` with and without
# `-a` must give the same ATE RMSE as `echofield eval --align se2|none`, and
# `evo_rpe tum REF EST --delta D --delta_unit m --all_pairs
# --pairs_from_reference` (translation part, and `-r angle_deg`) the same RPE
# RMSEs as `echofield eval --rpe-distances D`, for D = 10 and 50 m, each to
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
# shellcheck source=peers/venv.sh
. "$here/peers/venv.sh"
peer_venv "$venv" evo evo
echofield_release "$root"
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
printf '%-45s %-10s %-14s %-14s %s\n' estimate metric echofield evo rel_diff
compare() { # label ours theirs
  "$venv/bin/python" - "$2" "$3" <<'PY'
import sys
ours, theirs = float(sys.argv[1]), float(sys.argv[2])
rel = abs(ours - theirs) / max(abs(theirs), 1e-300)
print(f"{ours:<14.9g} {theirs:<14.9g} {rel:.2e} {'ok' if rel <= 1e-6 else 'MISMATCH'}")
PY
}
evo_rmse() { # zip
  "$venv/bin/python" -c 'import json, sys, zipfile; print(json.loads(zipfile.ZipFile(sys.argv[1]).read("stats.json"))["rmse"])' "$1"
}
for ((k = 0; k < ${#pairs[@]}; k += 2)); do
  est="${pairs[k]}"
  ref="${pairs[k + 1]}"
  name="$(basename "$(dirname "$est")")/$(basename "$est")"
  for align in se2 none; do
    flag=()
    [ "$align" = se2 ] && flag=(-a)
    rm -f "$work/res.zip" "$work/ours.json"
    "$venv/bin/evo_ape" tum "$ref" "$est" "${flag[@]}" --save_results "$work/res.zip" >/dev/null
    "$echofield" eval --estimate "$est" --reference "$ref" --align "$align" --json "$work/ours.json" >/dev/null
    ours=$("$venv/bin/python" -c 'import json, sys; print(json.load(open(sys.argv[1]))["ate"]["rmse_m"])' "$work/ours.json")
    line=$(compare ate "$ours" "$(evo_rmse "$work/res.zip")")
    printf '%-45s %-10s %s\n' "$name" "ate-$align" "$line"
    case "$line" in *MISMATCH*) status=1 ;; esac
  done
  "$echofield" eval --estimate "$est" --reference "$ref" --rpe-distances 10,50 --json "$work/ours.json" >/dev/null
  for d in 10 50; do
    for relation in trans_part angle_deg; do
      rm -f "$work/res.zip"
      if ! "$venv/bin/evo_rpe" tum "$ref" "$est" --delta "$d" --delta_unit m --all_pairs \
        --pairs_from_reference -r "$relation" --save_results "$work/res.zip" >/dev/null 2>&1; then
        printf '%-45s %-10s %s\n' "$name" "rpe-$d" "(path shorter than $d m: skipped)"
        continue
      fi
      key=translation_rmse_m
      [ "$relation" = angle_deg ] && key=rotation_rmse_deg
      ours=$("$venv/bin/python" -c 'import json, sys; r = [x for x in json.load(open(sys.argv[1]))["rpe"] if x["distance_m"] == float(sys.argv[2])]; print(r[0][sys.argv[3]] if r else "nan")' "$work/ours.json" "$d" "$key")
      line=$(compare rpe "$ours" "$(evo_rmse "$work/res.zip")")
      printf '%-45s %-10s %s\n' "$name" "rpe-$d-${relation%%_*}" "$line"
      case "$line" in *MISMATCH*) status=1 ;; esac
    done
  done
done
exit $status
