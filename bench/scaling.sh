#!/usr/bin/env bash
# Scaling of `bootsurf error` (issue "performance", item 3): time against N, B and
# K, the speed-up from 1 to 2 threads, peak memory per point, and optionally a
# 10,000,000-point run. Prints markdown tables for docs/performance.md. A
# benchmark, not a test.
#
# usage: bench/scaling.sh BUILD_DIR
#   env: PARTS="n b k threads"      which tables
#        NS="100000 1000000 4000000" the N table
#        SWEEP_N=1000000              N of the B, K and threads tables
#        BS="10 50 200" KS="20 50 100" THREADS_LIST="1 2"
#        K=50 B=50 DEGREE=3 THREADS=2 (the fixed values of the other tables)
#        REPS=1                       runs per configuration (median)
#        BIG_N=0                      e.g. 10000000: add that N to the N table (bench_error)
#        BIG_CLI=0                    1: also run the command `bootsurf error` on a BIG_N-point
#                                     file (generate + noise first, untimed): process wall, CPU,
#                                     peak RSS and its JSON "seconds" (read + compute + write)
#        WORK=DIR (scratch; default a fresh mktemp -d, removed at exit)  JSON_OUT=FILE
#
# Every number comes from BUILD_DIR/bench_error (the library calls of `bootsurf
# error` on an in-memory noisy sphere, no file I/O), under bench/peers/rss_exec for
# the peak RSS; see bench/peers/scaling.py. Quick look:
#   NS="20000 100000" SWEEP_N=50000 bench/scaling.sh build
# The default run takes about 10 minutes on 2 free cores (BIG_N=10000000 adds ~4, BIG_CLI ~5).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=bench/common.sh
. "$HERE/common.sh"
if [ $# -lt 1 ] || [ "$1" = -h ] || [ "$1" = --help ]; then
  bench_usage "$0"
fi
BUILD=$(cd "$1" && pwd)
[ -x "$BUILD/bench_error" ] || { echo "scaling.sh: $BUILD/bench_error not found (build first)" >&2; exit 1; }
K=${K:-50}
B=${B:-50}
DEGREE=${DEGREE:-3}
THREADS=${THREADS:-2}
BIG_N=${BIG_N:-0}
bench_work
${CC:-gcc} -O2 -std=c11 -Wall -Wextra "$HERE/peers/rss_exec.c" -o "$WORK/rss_exec"

echo "## Scaling of bootsurf error"
echo
echo "\`bench/scaling.sh $1\`: $(nproc) cores; $(git -C "$HERE/.." describe --always --dirty 2>/dev/null || echo '?');" \
  "$(date '+%Y-%m-%d %H:%M')"
echo
python3 "$HERE/peers/scaling.py" --bench-error "$BUILD/bench_error" --launcher "$WORK/rss_exec" \
  --work "$WORK/runs" --parts "${PARTS:-n b k threads}" --ns "${NS:-100000 1000000 4000000}" \
  --sweep-n "${SWEEP_N:-1000000}" --bs "${BS:-10 50 200}" --ks "${KS:-20 50 100}" \
  --threads-list "${THREADS_LIST:-1 2}" --k "$K" --b "$B" --degree "$DEGREE" --threads "$THREADS" \
  --reps "${REPS:-1}" --big-n "$BIG_N" ${JSON_OUT:+--json-out "$JSON_OUT"}

if [ "${BIG_CLI:-0}" = 1 ] && [ "$BIG_N" -gt 0 ]; then
  BS="$BUILD/bootsurf"
  "$BS" generate sphere --sampling random -n "$BIG_N" -o "$WORK/big.ply" -q
  "$BS" noise "$WORK/big.ply" --level 0.5 -j "$THREADS" -o "$WORK/big_noise.ply" -q
  rm -f "$WORK/big.ply"
  load=$(cut -d' ' -f1-3 /proc/loadavg)
  "$WORK/rss_exec" "$WORK/big.stats" "$BS" error "$WORK/big_noise.ply" -o "$WORK/big_err.ply" \
    -k "$K" -B "$B" -d "$DEGREE" -j "$THREADS" --json -q >"$WORK/big.json"
  read -r wall rss cpu <"$WORK/big.stats"
  secs=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["seconds"])' "$WORK/big.json")
  echo
  echo "### The command on $BIG_N points"
  echo
  echo "\`bootsurf error big_noise.ply -o big_err.ply -k $K -B $B -d $DEGREE -j $THREADS\` (noisy sphere," \
    "binary PLY $(du -m "$WORK/big_noise.ply" | cut -f1) MB in, $(du -m "$WORK/big_err.ply" | cut -f1) MB out);" \
    "load average before $load"
  echo
  echo "| points | process s | process CPU s | JSON seconds (read + compute + write) | points/s | peak RSS MB | RSS bytes / point |"
  echo "|---:|---:|---:|---:|---:|---:|---:|"
  awk -v n="$BIG_N" -v w="$wall" -v c="$cpu" -v s="$secs" -v r="$rss" 'BEGIN {
    printf "| %d | %.2f | %.2f | %.2f | %.0f | %.0f | %.0f |\n", n, w, c, s, n / w, r / 1024, r * 1024 / n }'
  rm -f "$WORK/big_noise.ply" "$WORK/big_err.ply"
fi
