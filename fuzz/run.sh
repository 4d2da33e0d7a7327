#!/usr/bin/env bash
# Builds one libFuzzer target (clang, -DBSURF_FUZZ=ON) and runs it for a while.
#
#   fuzz/run.sh TARGET [SECONDS] [libFuzzer options...]
#   fuzz/run.sh all [SECONDS]        every target in turn, SECONDS each
#   fuzz/run.sh build                only build every target
#
# TARGET: ply_ascii ply_binary off obj xyz pcd las csv cli_args (with or without "fuzz_").
# SECONDS defaults to 60. One fuzzer process at a time (no -jobs/-workers).
# The committed seeds in fuzz/corpus/fuzz_TARGET are only read; new inputs go
# to $BUILD/corpus/fuzz_TARGET and crashes, leaks and timeouts to
# $BUILD/artifacts/fuzz_TARGET/ (BUILD: $BSURF_FUZZ_BUILD or build-fuzz/).
# Reproduce a crash: $BUILD/fuzz/fuzz_TARGET FILE. See docs/fuzzing.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${BSURF_FUZZ_BUILD:-$ROOT/build-fuzz}
CC_FUZZ=${CC_FUZZ:-clang}
TARGETS="ply_ascii ply_binary off obj xyz pcd las csv cli_args cli_read"

usage() {
  echo "usage: fuzz/run.sh TARGET|all|build [SECONDS] [libFuzzer options...]" >&2
  echo "targets: $TARGETS" >&2
  exit 2
}

configure() {
  if ! command -v "$CC_FUZZ" >/dev/null 2>&1; then
    echo "fuzz/run.sh: $CC_FUZZ not found: apt-get install clang libclang-rt-14-dev" >&2
    exit 1
  fi
  if [ ! -f "$BUILD/CMakeCache.txt" ]; then
    CC=$CC_FUZZ cmake -S "$ROOT" -B "$BUILD" -DBSURF_FUZZ=ON -DBSURF_TESTS=OFF \
      -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  fi
}

build_target() { cmake --build "$BUILD" --target "$1" -j "${BSURF_FUZZ_JOBS:-2}" >/dev/null; }

run_target() {
  local name=fuzz_${1#fuzz_} seconds=$2
  shift 2
  case " $TARGETS " in *" ${name#fuzz_} "*) ;; *) usage ;; esac
  build_target "$name"
  local work=$BUILD/corpus/$name artifacts=$BUILD/artifacts/$name
  mkdir -p "$work" "$artifacts"
  local dict=()
  case $name in
    fuzz_ply_ascii | fuzz_ply_binary) dict=(-dict="$ROOT/fuzz/ply.dict") ;;
    fuzz_off) dict=(-dict="$ROOT/fuzz/off.dict") ;;
    fuzz_obj) dict=(-dict="$ROOT/fuzz/obj.dict") ;;
    fuzz_cli_args) dict=(-dict="$ROOT/fuzz/cli_args.dict") ;;
    fuzz_cli_read) dict=(-dict="$ROOT/fuzz/ply.dict" -max_len=1048576) ;; # headers beyond 4096 bytes
  esac
  echo "fuzz/run.sh: $name for ${seconds}s (corpus $work, artifacts $artifacts/)" >&2
  "$BUILD/fuzz/$name" "${dict[@]}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" "$@" "$work" "$ROOT/fuzz/corpus/$name"
}

[ $# -ge 1 ] || usage
configure
case $1 in
  build) cmake --build "$BUILD" --target fuzz -j "${BSURF_FUZZ_JOBS:-2}" ;;
  all)
    seconds=${2:-60}
    for t in $TARGETS; do run_target "$t" "$seconds"; done ;;
  *)
    t=$1
    seconds=${2:-60}
    shift
    [ $# -ge 1 ] && shift
    run_target "$t" "$seconds" "$@" ;;
esac
