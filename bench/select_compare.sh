#!/usr/bin/env bash
# Per-point K selection, bootstrap normals and whole commands as ratios (issue 25).
#
# usage: bench/select_compare.sh BUILD_DIR [N=200000]
#   env: REPS=3 THREADS=2
#        SD_N=20000   points for the --select-degree ratio (both sides of that pair run
#                     on this smaller cloud: 45 candidates (10:80:5 x 1,2,3) with three
#                     times select-k's angles of Eq. 5.10 take minutes at 200k points)
#        WORK=DIR     scratch directory (default: a fresh mktemp -d, removed at exit)
#        OPEN3D=0     skip the Open3D whole-command ratio
#
# Inputs (made in WORK): a sphere of N points, `generate --sampling regular`
# (points in spatially coherent order, as scans usually come) with uniform noise
# 0.5 h. Every pair is run alternately (A B A B ...) REPS times; the table gives
# the median wall and CPU (user + sys) seconds of each command and the ratio of
# the medians, so a shared machine's load hits both sides alike. The ratios:
#   select-k / one PCA pass    normals --select-k 10:80:5 --select-rule test-error -B 50
#                              vs  normals -k 30 -B 0 (the thesis's rule, the nested pass)
#   normals B50 / error B50    normals -k 50 -B 50  vs  error -k 50 -d 3 -B 50
#   select-degree / select-k   normals --fit poly --select-k 10:80:5 --select-degree 1,2,3 -B 50
#                              vs  normals --select-k 10:80:5 --select-rule test-error -B 50
#                              (PCA), on SD_N points
#   whole command vs Open3D    normals -k 30 -B 0 (read, kNN, fit, write)  vs
#                              bench/peers/normals_open3d.py -k 30 (Python start-up,
#                              import, read, estimate_normals, write): the processes' wall time
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=bench/common.sh
. "$HERE/common.sh"
if [ $# -lt 1 ]; then
  bench_usage "$0"
fi
BUILD=$(cd "$1" && pwd)
N=${2:-200000}
REPS=${REPS:-3}
THREADS=${THREADS:-2}
SD_N=${SD_N:-20000}
OPEN3D=${OPEN3D:-1}
BS="$BUILD/bootsurf"
[ -x "$BS" ] || { echo "select_compare: $BS not found (build bootsurf first)" >&2; exit 1; }
bench_work

"$BS" generate sphere --sampling regular -n "$N" -o "$WORK/s.ply" -q
"$BS" noise "$WORK/s.ply" --model uniform --level 0.5 --seed 1 -o "$WORK/sn.ply" -q
"$BS" generate sphere --sampling regular -n "$SD_N" -o "$WORK/t.ply" -q
"$BS" noise "$WORK/t.ply" --model uniform --level 0.5 --seed 1 -o "$WORK/tn.ply" -q

# timed NAME CMD...: appends "wall cpu" to WORK/NAME.times
timed() {
  local name=$1
  shift
  /usr/bin/time -f "%e %U %S" -o "$WORK/time.txt" "$@" >/dev/null 2>"$WORK/err.txt" ||
    { cat "$WORK/err.txt" >&2; exit 1; }
  awk '{ printf "%s %.3f\n", $1, $2 + $3 }' "$WORK/time.txt" >>"$WORK/$name.times"
}

median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

# pair LABEL NAME_A NAME_B: the medians and the ratios A / B
pair() {
  local wa wb ca cb
  wa=$(awk '{ print $1 }' "$WORK/$2.times" | median)
  wb=$(awk '{ print $1 }' "$WORK/$3.times" | median)
  ca=$(awk '{ print $2 }' "$WORK/$2.times" | median)
  cb=$(awk '{ print $2 }' "$WORK/$3.times" | median)
  awk -v l="$1" -v wa="$wa" -v wb="$wb" -v ca="$ca" -v cb="$cb" \
    'BEGIN { printf "| %s | %.2f / %.2f | %.2f / %.2f | %.3f | %.3f |\n", l, wa, wb, ca, cb, wa / wb, ca / cb }'
}

J=(-j "$THREADS" -q)
O3D="$HERE/peers/normals_open3d.py"
echo "== machine: $(nproc) cores; $(uptime)" >&2
for r in $(seq "$REPS"); do
  echo "== rep $r" >&2
  timed pca "$BS" normals "$WORK/sn.ply" -k 30 -B 0 -o "$WORK/o.ply" "${J[@]}"
  timed select "$BS" normals "$WORK/sn.ply" --select-k 10:80:5 --select-rule test-error -B 50 -o "$WORK/o.ply" "${J[@]}"
  timed boot "$BS" normals "$WORK/sn.ply" -k 50 -B 50 -o "$WORK/o.ply" "${J[@]}"
  timed error "$BS" error "$WORK/sn.ply" -k 50 -d 3 -B 50 -o "$WORK/o.ply" "${J[@]}"
  timed sel_small "$BS" normals "$WORK/tn.ply" --select-k 10:80:5 --select-rule test-error -B 50 -o "$WORK/o.ply" "${J[@]}"
  timed seldeg "$BS" normals "$WORK/tn.ply" --fit poly --select-k 10:80:5 --select-degree 1,2,3 -B 50 \
    -o "$WORK/o.ply" "${J[@]}"
  if [ "$OPEN3D" = 1 ]; then
    timed pca_whole "$BS" normals "$WORK/sn.ply" -k 30 -B 0 -o "$WORK/o.ply" "${J[@]}"
    timed open3d /usr/bin/python3 "$O3D" "$WORK/sn.ply" -o "$WORK/o3d.ply" -k 30 -j "$THREADS"
  fi
done
echo "N = $N points (select-degree: $SD_N), $REPS alternating runs, -j $THREADS; load after: $(uptime | sed 's/.*load/load/')"
echo
echo "| ratio | wall A / B (s) | cpu A / B (s) | wall ratio | cpu ratio |"
echo "|---|---|---|---|---|"
pair "select-k / one PCA pass" select pca
pair "normals -B 50 / error -B 50" boot error
pair "select-degree / select-k ($SD_N points)" seldeg sel_small
if [ "$OPEN3D" = 1 ]; then pair "normals -k 30 -B 0 / Open3D (whole commands)" pca_whole open3d; fi
echo
# the issue's absolute targets are for N = 1M on 2 cores (a quiet Zen 3): the medians' wall time
w_select=$(awk '{ print $1 }' "$WORK/select.times" | median)
w_error=$(awk '{ print $1 }' "$WORK/error.times" | median)
echo "wall (s), N = $N: normals --select-k 10:80:5 -B 50: $w_select (target at 1M: <= 60); error -k 50 -d 3 -B 50: $w_error (target at 1M: <= 10)"
