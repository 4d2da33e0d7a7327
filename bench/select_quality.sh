#!/usr/bin/env bash
# Selection quality of normals --select-k / --select-degree: the protocol of
# docs/normals.md ("How --select-k and --select-degree compute"), and the
# issue-25 table (fixed K, selected K, selected K and degree, Open3D, CGAL jet).
#
# usage: bench/select_quality.sh DATA_DIR BOOTSURF [BOOTSURF2 ...] -- OPTIONS... [-- OPTIONS...]
#   DATA_DIR holds fandisk_large.off and bunny00.off (scripts/get-data.sh).
#   Each `-- OPTIONS...` group is one row per binary (several groups: several rows).
#   env: LEVELS="0.5 1.0"  MODELS="fandisk_large bunny00"  WORK=DIR  THREADS=1
#        PEERS=DIR  also rows for Open3D's PCA (bench/peers/normals_open3d.py) and
#                   CGAL's jet fit (DIR/normals_cgal --method jet), both K = PEER_K
#                   (default 30); DIR as built by bench/peers/build.sh (/work/peers)
#
# For every model and uniform noise level (seed 1): `bootsurf sample`, `noise`,
# then with each binary and option group `normals NOISY -o R.ply OPTIONS -j THREADS
# --json` and `eval R.ply --truth T.ply --json` (the peers' outputs are evaluated
# by the first binary's `eval`). Prints one markdown row per (model, level,
# binary, options): the mean angle error (rad) of the normals against the mesh's
# vertex normals, the mean selected K and degree (where selected), and the CPU
# seconds (user + sys) of the normals command (the peers': of the whole process,
# Python start-up and reading included).
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
# the option groups, each stored as one string of NUL-free words joined by \x1f
GROUPS_=()
cur=""
shift
for a in "$@"; do
  if [ "$a" = -- ]; then
    GROUPS_+=("$cur")
    cur=""
  else
    cur+="$a"$'\x1f'
  fi
done
GROUPS_+=("$cur")
LEVELS=${LEVELS:-"0.5 1.0"}
MODELS=${MODELS:-"fandisk_large bunny00"}
THREADS=${THREADS:-1}
PEERS=${PEERS:-}
PEER_K=${PEER_K:-30}
bench_work
PY=/usr/bin/python3
BS0=${BINS[0]}

# row MODEL LEVEL LABEL OPTIONS-TEXT: prints the row of WORK/r.ply (n.json may be empty)
row() {
  "$BS0" eval "$WORK/r.ply" --truth "$WORK/$1.ply" --json >"$WORK/e.json"
  "$PY" - "$WORK/n.json" "$WORK/e.json" "$WORK/t.txt" "$1" "$2" "$3" "$4" <<'PYEOF'
import json, sys
try:
    n = json.load(open(sys.argv[1]))
except ValueError:
    n = {"mean": {}}
e = json.load(open(sys.argv[2]))
u, s = open(sys.argv[3]).read().split()[:2]
ang = e["normals"]["mean_rad"]
ks = n.get("mean", {}).get("k_selected")
dg = n.get("mean", {}).get("degree_selected")
f = lambda x: "%.4f" % x if isinstance(x, (int, float)) else ("" if x is None else str(x))
print("| %s | %s | %s | %s | %s | %s | %s | %.2f |" % (sys.argv[4], sys.argv[5], sys.argv[6], sys.argv[7], f(ang), f(ks), f(dg), float(u) + float(s)))
PYEOF
}

echo "| model | noise | binary | options | angle (rad) | mean K | mean degree | CPU s |"
echo "|---|---|---|---|---|---|---|---|"
for m in $MODELS; do
  "$BS0" sample "$DATA/$m.off" -o "$WORK/$m.ply" -q
  for xi in $LEVELS; do
    "$BS0" noise "$WORK/$m.ply" --model uniform --level "$xi" --seed 1 -o "$WORK/n.ply" -q
    for g in "${GROUPS_[@]}"; do
      IFS=$'\x1f' read -r -a OPTS <<<"$g"
      for b in "${BINS[@]}"; do
        /usr/bin/time -f "%U %S" -o "$WORK/t.txt" "$b" normals "$WORK/n.ply" -o "$WORK/r.ply" \
          "${OPTS[@]}" -j "$THREADS" --json -q >"$WORK/n.json"
        row "$m" "$xi" "$b" "\`${OPTS[*]}\`"
      done
    done
    if [ -n "$PEERS" ]; then
      : >"$WORK/n.json"
      /usr/bin/time -f "%U %S" -o "$WORK/t.txt" "$PY" "$HERE/peers/normals_open3d.py" "$WORK/n.ply" \
        -o "$WORK/r.ply" -k "$PEER_K" -j "$THREADS" >/dev/null
      row "$m" "$xi" "Open3D" "PCA, K = $PEER_K"
      /usr/bin/time -f "%U %S" -o "$WORK/t.txt" "$PEERS/normals_cgal" "$WORK/n.ply" -o "$WORK/r.ply" \
        --method jet -k "$PEER_K" -j "$THREADS" >/dev/null
      row "$m" "$xi" "CGAL" "jet, K = $PEER_K"
    fi
  done
done
