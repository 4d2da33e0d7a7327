#!/usr/bin/env bash
# bootsurf's front door. Usage: ./build.sh [build|test|quick|demo|python|bench|clean]
#   build  configure and compile (Release) into build/
#   test   build, then run the whole test suite through ctest
#   quick  build, then run the tests labelled quick (about a minute on 2 cores)
#   demo   build, then generate a noisy cube, estimate its errors, print the summary
#   python build, then install the Python package bootsurf into /usr/bin/python3
#          (pip install --no-build-isolation .; Debian's python3-dev, python3-numpy,
#          python3-setuptools, python3-pytest are installed first when missing)
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
  # the Python package (python/, docs/python.md) and its tests: Debian's python3
  local py=/usr/bin/python3
  compgen -G "/usr/include/python3*/Python.h" >/dev/null || missing+=(python3-dev)
  "$py" -c 'import numpy' >/dev/null 2>&1 || missing+=(python3-numpy)
  "$py" -c 'import setuptools' >/dev/null 2>&1 || missing+=(python3-setuptools)
  "$py" -c 'import pytest' >/dev/null 2>&1 || missing+=(python3-pytest)
  "$py" -m pip --version >/dev/null 2>&1 || missing+=(python3-pip)
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
  python)
    build
    # Debian marks its python3 externally managed (PEP 668): pip needs
    # --break-system-packages to install into it
    brk=""
    /usr/bin/python3 -m pip install --help 2>/dev/null | grep -q -- --break-system-packages &&
      brk=--break-system-packages
    /usr/bin/python3 -m pip install --no-build-isolation --no-index --no-deps $brk "$ROOT"
    (cd / && /usr/bin/python3 -c 'import bootsurf; print("bootsurf", bootsurf.__version__, "installed:", bootsurf.__file__)') ;;
  bench)
    build
    bash "$ROOT/bench/run.sh" "$BUILD" ;;
  clean) rm -rf "$BUILD" ;;
  *) echo "usage: ./build.sh [build|test|quick|demo|python|bench|clean]" >&2; exit 2 ;;
esac
