#!/usr/bin/env bash
# The side-by-side benchmark harness (`make bench`, `./build.sh bench`): bootsurf
# and its peers in the same run, on the same inputs, with the same thread count,
# alternating programs, medians of REPS rounds, peak RSS, accuracy checks, and a
# summary of the ratios bootsurf / peer against the performance issue's targets.
# Benchmarks, not tests: nothing fails because a number is slow.
#
# usage: bench/run.sh BUILD_DIR [N=1000000]   (or N in the environment: `make bench N=100000 REPS=1`)
#   parts (PARTS, default "normals knn error smooth"; run in this order):
#     normals  bench/normals_compare.sh: PCA (K = 30) vs PCL NormalEstimationOMP, Open3D
#              estimate_normals, CGAL pca_estimate_normals; quadratic fit vs CGAL
#              jet_estimate_normals d2; sphere N + fandisk + bunny, noise 0.5
#     knn      all-kNN (K = 50) alone vs nanoflann and Open3D (core batched search and
#              the KDTreeFlann Python loop); neighbour distances checked equal
#     error    bootsurf error (K = 50, B = 50, cubic) vs CGAL jet_estimate_normals
#              (same K, JET_DEGREES): how many jet passes the bootstrap costs; the <= 10 s line
#     smooth   bench/smooth_compare.sh --bench: smooth --method multipass vs CGAL
#              jet_smooth_point_set at K = 50 (sphere of SMOOTH_N points)
#     self     (not in the default) bench_knn + bench_error + `bootsurf error` with file
#              I/O on bench_error's own sphere: bootsurf alone, no peer
#   env: THREADS=2 REPS=3 NOISE=0.5 MODELS="fandisk_large bunny00" ("" = sphere only)
#        K_NORMALS=30 K_KNN=50 K_ERROR=50 B=50 DEGREE=3 JET_DEGREES="3 2"
#        KNN_LEGACY=1 (0: skip Open3D's Python loop)  KNN_MODELS=1 ERROR_MODELS=1 (0: sphere only)
#        SMOOTH_N=N SMOOTH_METHODS=multipass SMOOTH_PEERS=jet (see smooth_compare.sh)
#        WORK=DIR (scratch; default a fresh mktemp -d, removed at exit)
#        PEERS_DIR=DIR (the peers' build; default WORK/peers; kept dirs save ~3 min)
#        RESULTS=DIR (also keep every table: bench.md, and the parts' JSON)
#
# Quick look (about 3 minutes on 2 free cores, plus the peers' first build):
#   REPS=1 JET_DEGREES=3 bench/run.sh build 100000      (or: make bench N=100000 REPS=1)
# Debian 12, as root: missing packages (build.sh: libpcl-dev libcgal-dev
# libeigen3-dev libtbb-dev libnanoflann-dev python3-open3d python3-numpy; get-data.sh:
# libcgal-demo) are installed with apt-get first. See docs/performance.md and bench/README.md.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=bench/common.sh
. "$HERE/common.sh"
if [ $# -lt 1 ] || [ "$1" = -h ] || [ "$1" = --help ]; then
  bench_usage "$0"
fi
ROOT=$(cd "$HERE/.." && pwd)
BUILD=$(cd "$1" && pwd)
N=${2:-${N:-1000000}}
PARTS=${PARTS:-"normals knn error smooth"}
THREADS=${THREADS:-2}
REPS=${REPS:-3}
NOISE=${NOISE:-0.5}
MODELS=${MODELS-"fandisk_large bunny00"}
K_NORMALS=${K_NORMALS:-30}
K_KNN=${K_KNN:-50}
K_ERROR=${K_ERROR:-50}
B=${B:-50}
DEGREE=${DEGREE:-3}
JET_DEGREES=${JET_DEGREES:-"3 2"}
KNN_LEGACY=${KNN_LEGACY:-1}
KNN_MODELS=${KNN_MODELS:-1}
ERROR_MODELS=${ERROR_MODELS:-1}
SMOOTH_N=${SMOOTH_N:-$N}
SMOOTH_METHODS=${SMOOTH_METHODS:-multipass}
SMOOTH_PEERS=${SMOOTH_PEERS:-jet}
BS="$BUILD/bootsurf"
[ -x "$BS" ] || { echo "bench/run.sh: $BS not found (build bootsurf first)" >&2; exit 1; }
for p in $PARTS; do
  case $p in normals|knn|error|smooth|self) ;; *) echo "bench/run.sh: unknown part '$p'" >&2; exit 2 ;; esac
done

bench_work
JS="$WORK/json"
mkdir -p "$JS" "$WORK/inputs"
rm -f "$JS"/*.json
if [ -n "${RESULTS:-}" ]; then
  mkdir -p "$RESULTS"
  exec > >(tee "$RESULTS/bench.md")
fi
PY=/usr/bin/python3
has() { case " $PARTS " in *" $1 "*) return 0 ;; esac; return 1; }
start=$(date +%s)
echo "# bootsurf side-by-side benchmarks"
echo
echo "\`bench/run.sh $1 $N\`: PARTS=\"$PARTS\" THREADS=$THREADS REPS=$REPS NOISE=$NOISE; $(nproc) cores;" \
  "$(git -C "$ROOT" describe --always --dirty 2>/dev/null || echo '?'); $(date '+%Y-%m-%d %H:%M');" \
  "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"

# --- peers and inputs
if [ "$PARTS" != self ]; then
  PEERS_DIR=${PEERS_DIR:-"$WORK/peers"}
  "$HERE/peers/build.sh" "$PEERS_DIR" "$BUILD"
  PEERS_DIR=$(cd "$PEERS_DIR" && pwd)
  # the same commands (and default seeds) as normals_compare.sh and smooth_compare.sh,
  # so every part reads the same points (checked at the end)
  IN="$WORK/inputs"
  "$BS" generate sphere --sampling random -n "$N" -o "$IN/sphere.ply" -q
  "$BS" noise "$IN/sphere.ply" --level "$NOISE" -o "$IN/sphere_noise$NOISE.ply" -q
  inputs=("sphere_noise$NOISE=$IN/sphere_noise$NOISE.ply")
  if [ -n "$MODELS" ]; then
    "$ROOT/scripts/get-data.sh" "$IN" >&2
    for m in $MODELS; do
      "$BS" sample "$IN/$m.off" -o "$IN/$m.ply" -q
      "$BS" noise "$IN/$m.ply" --level "$NOISE" -o "$IN/${m}_noise$NOISE.ply" -q
      inputs+=("${m}_noise$NOISE=$IN/${m}_noise$NOISE.ply")
    done
  fi
fi
common=(--bootsurf "$BS" --peers "${PEERS_DIR:-}" --threads "$THREADS" --reps "$REPS")

if has normals; then
  echo
  echo "## Normals (bench/normals_compare.sh, K = $K_NORMALS)"
  WORK="$WORK/normals" PEERS_DIR="$PEERS_DIR" NOISE="$NOISE" MODELS="$MODELS" THREADS="$THREADS" \
    REPS="$REPS" K="$K_NORMALS" JSON_OUT="$JS/normals.json" "$HERE/normals_compare.sh" "$BUILD" "$N"
fi
if has knn; then
  echo
  echo "## All-kNN alone (K = $K_KNN)"
  kin=("${inputs[@]}")
  [ "$KNN_MODELS" = 1 ] || kin=("${inputs[0]}")
  extra=()
  [ "$KNN_LEGACY" = 1 ] || extra=(--no-legacy)
  $PY "$HERE/peers/kernels.py" knn "${common[@]}" --k "$K_KNN" --work "$WORK/runs" \
    --json-out "$JS/knn.json" "${extra[@]}" "${kin[@]}"
fi
if has error; then
  echo
  echo "## Bootstrap error beside CGAL's jet fit (K = $K_ERROR, B = $B, degree $DEGREE)"
  ein=("${inputs[@]}")
  [ "$ERROR_MODELS" = 1 ] || ein=("${inputs[0]}")
  $PY "$HERE/peers/kernels.py" error "${common[@]}" --k "$K_ERROR" --bootstrap "$B" --degree "$DEGREE" \
    --jet-degrees "${JET_DEGREES// /,}" --work "$WORK/runs" --json-out "$JS/error.json" "${ein[@]}"
fi
if has smooth; then
  echo
  echo "## Smoothing (bench/smooth_compare.sh --bench, K = 50, $SMOOTH_N points)"
  WORK="$WORK/smooth" PEERS_DIR="$PEERS_DIR" THREADS="$THREADS" REPS="$REPS" N_BENCH="$SMOOTH_N" \
    BENCH_NOISE="$NOISE" METHODS="$SMOOTH_METHODS" PEER_METHODS="$SMOOTH_PEERS" JSON_OUT="$JS/smooth.json" \
    "$HERE/smooth_compare.sh" --bench "$BUILD"
fi
if has self; then
  echo
  echo "## bootsurf alone (bench_knn, bench_error: their own sphere of $N points, noise 0.5)"
  echo
  echo '```'
  echo "== kNN alone (K=$K_KNN, $THREADS threads)"
  "$BUILD/bench_knn" "$N" "$K_KNN" "$THREADS"
  echo "== error, computation only"
  "$BUILD/bench_error" "$N" "$THREADS" "$K_ERROR" "$B" "$DEGREE"
  echo "== bootsurf error, whole command with file I/O"
  "$BS" generate sphere --sampling random -n "$N" -o "$WORK/self_s.ply" -q
  "$BS" noise "$WORK/self_s.ply" --level 0.5 -o "$WORK/self_n.ply" -q
  t0=$(date +%s.%N)
  "$BS" error "$WORK/self_n.ply" -k "$K_ERROR" -B "$B" -d "$DEGREE" -j "$THREADS" -q -o "$WORK/self_e.ply"
  t1=$(date +%s.%N)
  awk -v s="$t0" -v e="$t1" -v n="$N" 'BEGIN { t = e - s; printf "  bootsurf error   %8.3f s  %12.0f points/s\n", t, n / t }'
  echo '```'
fi

# --- the same inputs everywhere, then the summary
if [ "$PARTS" != self ]; then
  echo
  checks=("$WORK/normals/sphere_noise$NOISE.ply")
  [ "$SMOOTH_N" != "$N" ] || checks+=("$WORK/smooth/sphere_bench_noise$NOISE.ply")
  for f in "${checks[@]}"; do
    [ -f "$f" ] || continue
    if cmp -s "$f" "$IN/sphere_noise$NOISE.ply"; then same=identical; else same="**DIFFERENT**"; fi
    echo "- input check: ${f#"$WORK/"} is $same to inputs/sphere_noise$NOISE.ply"
  done
  sum=()
  for p in normals knn error smooth; do [ -f "$JS/$p.json" ] && sum+=(--"$p" "$JS/$p.json"); done
  $PY "$HERE/peers/kernels.py" summary "${sum[@]}"
fi
echo
echo "$(( ($(date +%s) - start) / 60 )) min; load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
if [ -n "${RESULTS:-}" ]; then
  cp "$JS"/*.json "$RESULTS/" 2>/dev/null || true
fi
