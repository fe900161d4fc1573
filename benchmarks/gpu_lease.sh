#!/usr/bin/env bash
# One lease of a lent GPU (issue #14, "Accelerators"), run from the repository root by the
# `device` tool (no registry there: the checkout runs from PYTHONPATH on the image's own
# jax/diffrax/equinox/optax). Stages, each under its own time limit so that one failing or
# slow stage leaves the others' logs: versions; the README main job (45 speeds, 3D, three
# formulations); the same scenario at 4,500 speeds. $OUT gets versions.txt, main.log,
# big.log, each sweep's results.csv and summary.json (as main_*, big_*) and the big
# sweep's response_curves.png: the 8 files the tool brings back.
#
#   bash benchmarks/gpu_lease.sh [MAIN_LIMIT_S] [BIG_LIMIT_S] [BIG_SPEEDS]
set -u
OUT=${OUT:-/tmp/gearjax-gpu}
mkdir -p "$OUT"
export PYTHONPATH=$PWD PYTHONUNBUFFERED=1
export XDG_CACHE_HOME=$(mktemp -d)  # empty caches: a first run
MAIN_LIMIT=${1:-200}
BIG_LIMIT=${2:-330}
BIG_SPEEDS=${3:-4500}

gj() { python3 -c 'import sys; from gearjax.cli import main; sys.exit(main())' "$@"; }

{
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv
  python3 -c 'import sys, jax, jaxlib, diffrax, equinox, optax, lineax, numpy
print(sys.version.split()[0], "jax", jax.__version__, "jaxlib", jaxlib.__version__,
      "diffrax", diffrax.__version__, "equinox", equinox.__version__, "optax",
      optax.__version__, "lineax", lineax.__version__, "numpy", numpy.__version__)
print(jax.devices())'
  git log --oneline -1 2>/dev/null || true
} > "$OUT/versions.txt" 2>&1
cat "$OUT/versions.txt"

stage() {  # name limit args...
  local name=$1 limit=$2; shift 2
  local t0=$(date +%s.%N)
  timeout "$limit" bash -c "$(declare -f gj); gj $*" > "$OUT/$name.log" 2>&1
  local rc=$?
  local t1=$(date +%s.%N)
  echo "== $name: rc $rc, $(python3 -c "print(round($t1 - $t0, 1))") s whole command"
  grep -v "compiling and integrating" "$OUT/$name.log" | tail -24
  for f in results.csv summary.json; do cp "/tmp/gj/$name/$f" "$OUT/${name}_$f" 2>/dev/null; done
}

stage main "$MAIN_LIMIT" sweep --out /tmp/gj/main --overwrite
stage big "$BIG_LIMIT" sweep --speeds "20:900:$BIG_SPEEDS" --out /tmp/gj/big --overwrite
cp /tmp/gj/big/response_curves.png "$OUT/big_response_curves.png" 2>/dev/null
ls -la "$OUT"
