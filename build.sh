#!/usr/bin/env bash
# bootsurf's front door. Usage: ./build.sh [build|test|quick|demo|bench|clean]
#   build  configure and compile (Release) into build/
#   test   build, then run the whole test suite through ctest
#   quick  build, then run the tests labelled quick (about a minute on 2 cores)
#   demo   build, then generate a noisy cube, estimate its errors, print the summary
#   bench  build, then run the side-by-side benchmark harness bench/run.sh: bootsurf
#          beside PCL, Open3D, CGAL and nanoflann (their Debian packages installed
#          when missing, as root); env N, REPS, PARTS, ... (see docs/performance.md)
# On a Debian/Ubuntu machine where this runs as root, missing build
# dependencies are installed with apt-get first.
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(pwd)
BUILD=${BSURF_BUILD_DIR:-$ROOT/build}
JOBS=$(nproc 2>/dev/null || echo 2)

# Debian packages the build needs, and a file or command that shows each is present.
need_packages() {
  local missing=()
  command -v cc >/dev/null 2>&1 || missing+=(gcc libc6-dev)
  command -v make >/dev/null 2>&1 || missing+=(make)
  command -v cmake >/dev/null 2>&1 || missing+=(cmake)
  command -v pkg-config >/dev/null 2>&1 || missing+=(pkg-config)
  [ -f /usr/include/cmocka.h ] || missing+=(libcmocka-dev)
  [ -f /usr/include/png.h ] || missing+=(libpng-dev)
  echo "${missing[@]:-}"
}

install_deps() {
  local missing
  missing=$(need_packages)
  [ -z "${missing// /}" ] && return 0
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "build.sh: installing missing packages: $missing" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >&2
    # shellcheck disable=SC2086
    apt-get install -y -qq --no-install-recommends $missing >&2
  else
    echo "build.sh: missing packages: $missing (install them with apt-get as root)" >&2
    exit 1
  fi
}

build() {
  install_deps
  cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release ${BSURF_CMAKE_ARGS:-} >/dev/null
  cmake --build "$BUILD" -j "$JOBS"
}

cmd=${1:-build}
case "$cmd" in
  build) build ;;
  test)
    build
    ctest --test-dir "$BUILD" --output-on-failure -j "$JOBS" ;;
  quick)
    build
    ctest --test-dir "$BUILD" --output-on-failure -j "$JOBS" -L quick ;;
  demo)
    build
    BSURF="$BUILD/bootsurf" bash "$ROOT/scripts/demo.sh" ;;
  bench)
    build
    bash "$ROOT/bench/run.sh" "$BUILD" ;;
  clean) rm -rf "$BUILD" ;;
  *) echo "usage: ./build.sh [build|test|quick|demo|bench|clean]" >&2; exit 2 ;;
esac
