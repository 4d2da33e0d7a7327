#!/usr/bin/env bash
# Benchmarks (not tests). Usage: bench/run.sh BUILD_DIR [N]
# Prints points per second of the kNN step alone and of `bootsurf error`
# (K = 50, B = 50, cubic, 2 threads) on a 1,000,000-point noisy sphere:
# computation only (bench_error, bench_knn) and the whole command with file I/O.
set -euo pipefail
BUILD=${1:-build}
N=${2:-1000000}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
echo "== kNN alone (K=50, 2 threads)"
"$BUILD/bench_knn" "$N" 50 2
echo "== error, computation only"
"$BUILD/bench_error" "$N" 2 50 50 3
echo "== bootsurf error, whole command with file I/O"
"$BUILD/bootsurf" generate sphere --sampling random -n "$N" -o "$TMP/s.ply" -q
"$BUILD/bootsurf" noise "$TMP/s.ply" --level 0.5 -o "$TMP/n.ply" -q
start=$(date +%s.%N)
"$BUILD/bootsurf" error "$TMP/n.ply" -k 50 -B 50 -d 3 -j 2 -q -o "$TMP/e.ply"
end=$(date +%s.%N)
awk -v s="$start" -v e="$end" -v n="$N" 'BEGIN { t = e - s; printf "  bootsurf error   %8.3f s  %12.0f points/s\n", t, n / t }'
