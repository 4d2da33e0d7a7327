#!/usr/bin/env bash
# Selection quality of normals --select-k / --select-degree: the protocol of
# docs/normals.md ("How --select-k and --select-degree compute").
#
# usage: bench/select_quality.sh DATA_DIR BOOTSURF [BOOTSURF2 ...] -- OPTIONS...
#   DATA_DIR holds fandisk_large.off and bunny00.off (scripts/get-data.sh).
#   env: LEVELS="0.5 1.0"  MODELS="fandisk_large bunny00"  WORK=DIR  THREADS=1
#
# For every model and uniform noise level (seed 1): `bootsurf sample`, `noise`,
# then with each binary `normals NOISY -o R.ply OPTIONS -j THREADS --json` and
# `eval R.ply --truth T.ply --json`. Prints one markdown row per (model, level,
# binary): the mean angle error (rad) of the selected normals against the mesh's
# vertex normals, the mean selected K and degree, and the CPU seconds (user +
# sys) of the normals command.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=bench/common.sh
. "$HERE/common.sh"
[ $# -ge 3 ] || bench_usage "$0"
DATA=$1
shift
BINS=()
while [ $# -gt 0 ] && [ "$1" != -- ]; do
  BINS+=("$1")
  shift
done
[ "${1:-}" = -- ] || bench_usage "$0"
shift
OPTS=("$@")
LEVELS=${LEVELS:-"0.5 1.0"}
MODELS=${MODELS:-"fandisk_large bunny00"}
THREADS=${THREADS:-1}
bench_work
PY=/usr/bin/python3
BS0=${BINS[0]}
echo "| model | noise | binary | angle (rad) | mean K | mean degree | CPU s |"
echo "|---|---|---|---|---|---|---|"
for m in $MODELS; do
  "$BS0" sample "$DATA/$m.off" -o "$WORK/$m.ply" -q
  for xi in $LEVELS; do
    "$BS0" noise "$WORK/$m.ply" --model uniform --level "$xi" --seed 1 -o "$WORK/n.ply" -q
    for b in "${BINS[@]}"; do
      /usr/bin/time -f "%U %S" -o "$WORK/t.txt" "$b" normals "$WORK/n.ply" -o "$WORK/r.ply" \
        "${OPTS[@]}" -j "$THREADS" --json -q >"$WORK/n.json"
      "$b" eval "$WORK/r.ply" --truth "$WORK/$m.ply" --json >"$WORK/e.json"
      "$PY" - "$WORK/n.json" "$WORK/e.json" "$WORK/t.txt" "$m" "$xi" "$b" <<'PYEOF'
import json, sys
n = json.load(open(sys.argv[1]))
e = json.load(open(sys.argv[2]))
u, s = open(sys.argv[3]).read().split()[:2]
ang = e["normals"]["mean_rad"]
ks = n["mean"].get("k_selected")
dg = n["mean"].get("degree_selected")
f = lambda x: "%.4f" % x if isinstance(x, (int, float)) else str(x)
print("| %s | %s | %s | %s | %s | %s | %.2f |" % (sys.argv[4], sys.argv[5], sys.argv[6], f(ang), f(ks), f(dg), float(u) + float(s)))
PYEOF
    done
  done
done
