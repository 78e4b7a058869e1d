#!/usr/bin/env bash
# Times GTSAM's Levenberg-Marquardt (from PyPI, in a local virtualenv) and
# `echofield optimize` on the standard 2D pose graphs and prints one table.
#
#   tools/peers/gtsam_compare.sh                 # the bundled benchmark files
#   tools/peers/gtsam_compare.sh a.g2o b.g2o     # other files
#   REPEATS=10 TOLERANCE=1e-8 tools/peers/gtsam_compare.sh
#
# Needs python3 (with venv) and network access to PyPI on the first run.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="$here/.venv"
# shellcheck source=venv.sh
. "$here/venv.sh"
peer_venv "$venv" "gtsam, numpy" gtsam numpy

echo "building echofield (release)" >&2
echofield_release "$root"
binary="$echofield"

if [[ $# -eq 0 ]]; then
    data="$root/datasets/posegraph"
    set -- "$data/M3500.g2o" "$data/intel.g2o" "$data/MIT.g2o" "$data/city10000.g2o" \
        "$data/manhattan.g2o" "$data/CSAIL.g2o" \
        "$data/vertigo-manhattan/manhattanOlson3500.g2o" "$data/vertigo-ring/ring.g2o"
fi

# Single-threaded on both sides (the gtsam wheel has no TBB; these keep
# numpy's BLAS and any OpenMP code on one thread too).
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
"$venv/bin/python" "$here/gtsam_compare.py" --echofield "$binary" \
    --repeats "${REPEATS:-5}" --tolerance "${TOLERANCE:-1e-10}" "$@"
