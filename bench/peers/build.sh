#!/usr/bin/env bash
# Builds the peer programs of the side-by-side benchmarks (bench/run.sh and the
# scripts it calls: normals_compare.sh, smooth_compare.sh, peers/kernels.py).
#
# usage: bench/peers/build.sh [OUT_DIR=build/peers] [BOOTSURF_BUILD_DIR]
#
# OUT_DIR gets rss_exec (the harness's launcher); normals_pcl, normals_cgal,
# smooth_pcl, smooth_cgal, features_pcl, features_cgal (g++ -O3 against Debian
# 12's libpcl-dev, libcgal-dev + libeigen3-dev, libtbb-dev); knn_nanoflann
# (libnanoflann-dev); and, when BOOTSURF_BUILD_DIR holds libbootsurf.a, the
# library drivers normals_bootsurf, knn_bootsurf and error_bootsurf (bootsurf
# timed without file I/O). Missing Debian packages are installed with apt-get
# first (as root; idempotent: nothing is installed when dpkg already has them).
# The Open3D peer is a Python script (python3-open3d, run with /usr/bin/python3).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
OUT=${1:-build/peers}
BS=${2:-}
mkdir -p "$OUT"

need=()
for p in g++ pkg-config libpcl-dev libcgal-dev libeigen3-dev libtbb-dev libnanoflann-dev python3-open3d \
  python3-numpy; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if ((${#need[@]})); then
  if [ "$(id -u)" -ne 0 ]; then
    echo "build.sh: missing packages: ${need[*]} (run as root to install them)" >&2
    exit 1
  fi
  echo "build.sh: installing ${need[*]}" >&2
  DEBIAN_FRONTEND=noninteractive apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" >&2
fi

CXX=${CXX:-g++}
CXXFLAGS=${CXXFLAGS:-"-O3 -DNDEBUG -std=c++17"}
# Only PCL's C++ targets needed by NormalEstimationOMP (pkg-config pulls in flann etc.).
PCL_FLAGS=$(pkg-config --cflags --libs pcl_features pcl_search pcl_kdtree pcl_common)

# up to date: the program exists and is newer than every file it is made from
fresh() {
  local t=$1
  shift
  [ -x "$t" ] || return 1
  for f in "$@"; do [ "$f" -nt "$t" ] && return 1; done
  return 0
}
COMMON=("$HERE/ply_io.hpp" "$HERE/peer_util.hpp" "$HERE/pcl_util.hpp" "$HERE/build.sh")

if ! fresh "$OUT/normals_pcl" "$HERE/normals_pcl.cpp" "${COMMON[@]}"; then
  echo "build.sh: normals_pcl" >&2
  # shellcheck disable=SC2086
  $CXX $CXXFLAGS -fopenmp -I"$HERE" "$HERE/normals_pcl.cpp" -o "$OUT/normals_pcl" $PCL_FLAGS
fi

if ! fresh "$OUT/normals_cgal" "$HERE/normals_cgal.cpp" "${COMMON[@]}"; then
  echo "build.sh: normals_cgal (TBB: Parallel_if_available_tag = Parallel_tag)" >&2
  # CGAL 5.5 is header-only; CGAL_LINKED_WITH_TBB selects TBB for Parallel_if_available_tag,
  # CGAL_EIGEN3_ENABLED lets jet fitting and PCA use Eigen.
  EIGEN_FLAGS=$(pkg-config --cflags eigen3)
  TBB_LIBS=$(pkg-config --libs tbb)
  # shellcheck disable=SC2086
  $CXX $CXXFLAGS -I"$HERE" $EIGEN_FLAGS -DCGAL_EIGEN3_ENABLED -DCGAL_LINKED_WITH_TBB \
    "$HERE/normals_cgal.cpp" -o "$OUT/normals_cgal" $TBB_LIBS -lgmp -lmpfr -lpthread
fi

if ! fresh "$OUT/rss_exec" "$HERE/rss_exec.c" "$HERE/build.sh"; then
  echo "build.sh: rss_exec (launcher: wall time and peak RSS of one command)" >&2
  ${CC:-gcc} -O2 -std=c11 -Wall -Wextra "$HERE/rss_exec.c" -o "$OUT/rss_exec"
fi

if [ -n "$BS" ]; then
  if [ -f "$BS/libbootsurf.a" ]; then
    # the library drivers: always rebuilt (the library under test changes between runs)
    for d in normals_bootsurf knn_bootsurf error_bootsurf; do
      echo "build.sh: $d (against $BS/libbootsurf.a)" >&2
      ${CC:-gcc} -O3 -DNDEBUG -std=c11 -Wall -Wextra -fopenmp -I"$ROOT/include" -I"$HERE" \
        "$HERE/$d.c" -o "$OUT/$d" "$BS/libbootsurf.a" -lm
    done
  else
    echo "build.sh: $BS/libbootsurf.a not found: the library drivers (*_bootsurf) not built" >&2
    exit 1
  fi
fi
# --- smoothing peers (bench/smooth_compare.sh): smooth_pcl (MovingLeastSquares,
# libpcl-dev's pcl_surface) and smooth_cgal (jet_smooth_point_set,
# bilateral_smooth_point_set; jet_estimate_normals + mst_orient_normals for the
# latter's normals). Same packages as above.
if ! fresh "$OUT/smooth_pcl" "$HERE/smooth_pcl.cpp" "${COMMON[@]}"; then
  echo "build.sh: smooth_pcl" >&2
  PCL_SURFACE_FLAGS=$(pkg-config --cflags --libs pcl_surface pcl_search pcl_kdtree pcl_common)
  # shellcheck disable=SC2086
  $CXX $CXXFLAGS -fopenmp -I"$HERE" "$HERE/smooth_pcl.cpp" -o "$OUT/smooth_pcl" $PCL_SURFACE_FLAGS
fi
if ! fresh "$OUT/smooth_cgal" "$HERE/smooth_cgal.cpp" "${COMMON[@]}"; then
  echo "build.sh: smooth_cgal (TBB: Parallel_if_available_tag = Parallel_tag)" >&2
  EIGEN_FLAGS=$(pkg-config --cflags eigen3)
  TBB_LIBS=$(pkg-config --libs tbb)
  # shellcheck disable=SC2086
  $CXX $CXXFLAGS -I"$HERE" $EIGEN_FLAGS -DCGAL_EIGEN3_ENABLED -DCGAL_LINKED_WITH_TBB \
    "$HERE/smooth_cgal.cpp" -o "$OUT/smooth_cgal" $TBB_LIBS -lgmp -lmpfr -lpthread
fi

# --- kNN peer (bench/peers/kernels.py knn): knn_nanoflann, Debian's libnanoflann-dev
# (header-only), OpenMP over the queries.
if ! fresh "$OUT/knn_nanoflann" "$HERE/knn_nanoflann.cpp" "${COMMON[@]}"; then
  echo "build.sh: knn_nanoflann" >&2
  # shellcheck disable=SC2086
  $CXX $CXXFLAGS -fopenmp -I"$HERE" "$HERE/knn_nanoflann.cpp" -o "$OUT/knn_nanoflann"
fi

# --- feature-detection baselines (scripts/validate_features.py): features_pcl
# (NormalEstimationOMP's curvature = surface variation) and features_cgal
# (compute_vcm + the vcm_is_on_feature_edge ratio). Same packages as above.
if ! fresh "$OUT/features_pcl" "$HERE/features_pcl.cpp" "${COMMON[@]}"; then
  echo "build.sh: features_pcl" >&2
  # shellcheck disable=SC2086
  $CXX $CXXFLAGS -fopenmp -I"$HERE" "$HERE/features_pcl.cpp" -o "$OUT/features_pcl" $PCL_FLAGS
fi
if ! fresh "$OUT/features_cgal" "$HERE/features_cgal.cpp" "${COMMON[@]}"; then
  echo "build.sh: features_cgal" >&2
  EIGEN_FLAGS=$(pkg-config --cflags eigen3)
  # shellcheck disable=SC2086
  $CXX $CXXFLAGS -I"$HERE" $EIGEN_FLAGS -DCGAL_EIGEN3_ENABLED "$HERE/features_cgal.cpp" \
    -o "$OUT/features_cgal" -lgmp -lmpfr -lpthread
fi

echo "build.sh: peers in $OUT" >&2
