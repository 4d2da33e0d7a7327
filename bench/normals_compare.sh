#!/usr/bin/env bash
# bootsurf normals beside PCL, Open3D and CGAL: time, points/s, angle errors, RSS.
#
# usage: bench/normals_compare.sh BUILD_DIR [N=1000000]
#   env: NOISE="0.5 1.0"  noise levels xi (units of h) for every input
#        MODELS="fandisk_large bunny00"  CGAL meshes (libcgal-demo's data.tar.gz); "" = none
#        THREADS=2 REPS=3 K=30
#        WORK=DIR             scratch directory (default: a fresh mktemp -d, removed at exit)
#        PEERS_DIR=DIR        where bench/peers/build.sh puts the peers (default WORK/peers)
#        JSON_OUT=FILE        also write every table as JSON
#
# BUILD_DIR is a bootsurf CMake build (bootsurf, libbootsurf.a). Run as root on
# Debian 12: the peers' packages are installed with apt-get when missing
# (bench/peers/build.sh). Inputs, made in the scratch directory, never in the repo:
#   sphere    `bootsurf generate sphere --sampling random -n N` + `bootsurf noise`
#   meshes    `bootsurf sample MESH` (vertices, area-weighted vertex normals) + noise
# Every program gets the same K (the point itself included) and thread count;
# bench/peers/compare.py runs them alternately REPS times and prints the tables
# (it explains each column). See bench/README.md.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=bench/common.sh
. "$HERE/common.sh"
if [ $# -lt 1 ]; then
  bench_usage "$0"
fi
BUILD=$(cd "$1" && pwd)
N=${2:-1000000}
NOISE=${NOISE:-"0.5 1.0"}
MODELS=${MODELS-"fandisk_large bunny00"}
THREADS=${THREADS:-2}
REPS=${REPS:-3}
K=${K:-30}
BS="$BUILD/bootsurf"
[ -x "$BS" ] || { echo "normals_compare: $BS not found (build bootsurf first)" >&2; exit 1; }

bench_work

# libcgal-demo holds the meshes; the peers' packages are checked by build.sh
if [ -n "$MODELS" ] && [ ! -f /usr/share/doc/libcgal-dev/data.tar.gz ]; then
  if [ "$(id -u)" -eq 0 ]; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libcgal-demo >&2
  else
    echo "normals_compare: libcgal-demo missing; MODELS=\"\" to skip the meshes" >&2
    exit 1
  fi
fi
PEERS_DIR=${PEERS_DIR:-"$WORK/peers"}
"$HERE/peers/build.sh" "$PEERS_DIR" "$BUILD"

echo "== inputs in $WORK" >&2
inputs=()
"$BS" generate sphere --sampling random -n "$N" -o "$WORK/sphere.ply" -q
truths=("sphere:$WORK/sphere.ply")
if [ -n "$MODELS" ]; then
  members=()
  for m in $MODELS; do members+=("data/meshes/$m.off"); done
  tar -xzf /usr/share/doc/libcgal-dev/data.tar.gz -C "$WORK" "${members[@]}"
  for m in $MODELS; do
    "$BS" sample "$WORK/data/meshes/$m.off" -o "$WORK/$m.ply" -q
    truths+=("$m:$WORK/$m.ply")
  done
fi
for lv in $NOISE; do
  for t in "${truths[@]}"; do
    name=${t%%:*}
    "$BS" noise "${t#*:}" --level "$lv" -o "$WORK/${name}_noise$lv.ply" -q
    inputs+=("${name}_noise$lv=$WORK/${name}_noise$lv.ply")
  done
done

echo "== machine: $(nproc) cores; $(uptime)" >&2
/usr/bin/python3 "$HERE/peers/compare.py" --bootsurf "$BS" --peers "$PEERS_DIR" \
  --threads "$THREADS" --reps "$REPS" --k "$K" --work "$WORK/runs" \
  ${JSON_OUT:+--json-out "$JSON_OUT"} "${inputs[@]}"
echo "== done; $(uptime)" >&2
