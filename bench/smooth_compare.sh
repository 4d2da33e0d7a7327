#!/usr/bin/env bash
# bootsurf smooth beside CGAL (jet_smooth_point_set, bilateral_smooth_point_set)
# and PCL (MovingLeastSquares) on the same noisy inputs: distance to the true
# surface in units of h (overall, feature, non-feature), and speed.
#
# usage: bench/smooth_compare.sh [--bench] [--peers-only] BUILD_DIR [DATA_DIR]
#   quality (default)  cube and sphere (`bootsurf generate --sampling random -n N`),
#                      fandisk_large and bunny00 (`bootsurf sample MESH -n N`), each
#                      at every NOISE level (`bootsurf noise --level XI --seed SEED`);
#                      bootsurf smooth naive|bilateral|multipass (defaults) and the
#                      peers (K), each output scored by `bootsurf eval --truth T
#                      [--surface MESH] --json`; one table, with the noisy input as
#                      the "before" row.
#   --bench            one noisy sphere of N_BENCH points (1,000,000), noise 0.5: every
#                      method and peer REPS times, alternating, medians of points/s and
#                      the ratios bootsurf / peer.
#   --peers-only       skip bootsurf smooth (tests the peer half alone); without eval's
#                      position section the sphere/cube rows use bench/peers/position_error.py
#   DATA_DIR           holds fandisk_large.off and bunny00.off (default: the repo's data/,
#                      where scripts/get-data.sh puts them; fetched with it when missing)
#   env: N=40000 NOISE="0.25 0.5" SHAPES="cube sphere" MODELS="fandisk_large bunny00"
#        THREADS=2 K=50 SEED=1 REPS=3 N_BENCH=1000000 BENCH_NOISE=0.5
#        WORK=DIR (scratch; default a fresh mktemp -d, removed at exit)  JSON_OUT=FILE
#        PEERS_DIR=DIR (where bench/peers/build.sh puts the peers; default WORK/peers;
#        build.sh skips programs that are up to date, so a kept directory saves ~2 min)
#        METHODS="naive bilateral multipass" (bootsurf smooth methods to run)
#        PEER_METHODS="jet bilateral mls" (CGAL jet, CGAL bilateral, PCL MLS)
#
# BUILD_DIR is a bootsurf CMake build with the `smooth` command and eval's
# position section (--surface). Debian 12 packages for the peers are installed
# by bench/peers/build.sh when missing (as root). See bench/README.md.
set -euo pipefail
MODE=quality
PEERS_ONLY=
while [ $# -gt 0 ]; do
  case $1 in
    --bench) MODE=bench; shift ;;
    --peers-only) PEERS_ONLY=1; shift ;;
    -h|--help) sed -n '2,31p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
if [ $# -lt 1 ]; then
  sed -n '2,31p' "$0" >&2
  exit 2
fi
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=bench/common.sh
. "$HERE/common.sh"
ROOT=$(cd "$HERE/.." && pwd)
BUILD=$(cd "$1" && pwd)
DATA=${2:-"$ROOT/data"}
N=${N:-40000}
NOISE=${NOISE:-"0.25 0.5"}
SHAPES=${SHAPES-"cube sphere"}
MODELS=${MODELS-"fandisk_large bunny00"}
THREADS=${THREADS:-2}
K=${K:-50}
SEED=${SEED:-1}
REPS=${REPS:-3}
N_BENCH=${N_BENCH:-1000000}
BENCH_NOISE=${BENCH_NOISE:-0.5}
METHODS=${METHODS:-"naive bilateral multipass"}
PEER_METHODS=${PEER_METHODS:-"jet bilateral mls"}
BS="$BUILD/bootsurf"
[ -x "$BS" ] || { echo "smooth_compare: $BS not found (build bootsurf first)" >&2; exit 1; }

# what this bootsurf can do
if [ -z "$PEERS_ONLY" ]; then
  if ! "$BS" smooth --help >/dev/null 2>&1; then
    echo "smooth_compare: $BS has no 'smooth' command (bootsurf smooth, thesis chapter 6)." >&2
    echo "  Build a tree that has cli/cmd_smooth.c, or run the peers alone: $0 --peers-only $*" >&2
    exit 1
  fi
  if ! "$BS" eval --help 2>/dev/null | grep -q -- '--surface'; then
    echo "smooth_compare: '$BS eval' has no position error (--surface) yet; it is needed to score" >&2
    echo "  the outputs. Build a newer tree, or: $0 --peers-only $* (sphere/cube scored analytically)" >&2
    exit 1
  fi
fi

bench_work

if [ "$MODE" = quality ] && [ -n "$MODELS" ]; then
  for m in $MODELS; do
    if [ ! -f "$DATA/$m.off" ]; then
      echo "smooth_compare: $DATA/$m.off missing; fetching with scripts/get-data.sh" >&2
      "$ROOT/scripts/get-data.sh" "$DATA"
      break
    fi
  done
fi
PEERS_DIR=${PEERS_DIR:-"$WORK/peers"}
"$HERE/peers/build.sh" "$PEERS_DIR"

args=()
echo "== inputs in $WORK" >&2
if [ "$MODE" = bench ]; then
  "$BS" generate sphere --sampling random -n "$N_BENCH" --seed "$SEED" -o "$WORK/sphere_bench.ply" -q
  "$BS" noise "$WORK/sphere_bench.ply" --level "$BENCH_NOISE" --seed "$SEED" -j "$THREADS" \
    -o "$WORK/sphere_bench_noise$BENCH_NOISE.ply" -q
  args+=(--bench --reps "$REPS" --input sphere "$BENCH_NOISE" "$WORK/sphere_bench_noise$BENCH_NOISE.ply"
         "$WORK/sphere_bench.ply" -)
else
  truths=()
  for s in $SHAPES; do
    "$BS" generate "$s" --sampling random -n "$N" --seed "$SEED" -o "$WORK/$s.ply" -q
    truths+=("$s:$WORK/$s.ply:-")
  done
  for m in $MODELS; do
    "$BS" sample "$DATA/$m.off" -n "$N" --seed "$SEED" -j "$THREADS" -o "$WORK/$m.ply" -q
    truths+=("$m:$WORK/$m.ply:$DATA/$m.off")
  done
  for t in "${truths[@]}"; do
    IFS=: read -r name truth surface <<<"$t"
    for lv in $NOISE; do
      "$BS" noise "$truth" --level "$lv" --seed "$SEED" -j "$THREADS" -o "$WORK/${name}_noise$lv.ply" -q
      args+=(--input "$name" "$lv" "$WORK/${name}_noise$lv.ply" "$truth" "$surface")
    done
  done
fi

echo "== machine: $(nproc) cores; $(uptime)" >&2
/usr/bin/python3 "$HERE/peers/smooth_compare.py" --bootsurf "$BS" --peers "$PEERS_DIR" \
  --work "$WORK/runs" --threads "$THREADS" --k "$K" --seed "$SEED" \
  --methods "${METHODS// /,}" --peer-methods "${PEER_METHODS// /,}" \
  ${PEERS_ONLY:+--peers-only} ${JSON_OUT:+--json-out "$JSON_OUT"} "${args[@]}"
echo "== done; $(uptime)" >&2
