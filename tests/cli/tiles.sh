#!/usr/bin/env bash
# Tiled (--tile-points, --memory-limit) and MPI runs give the in-memory
# run's bytes; what cannot be tiled is refused with exit 1 and no output.
# (Non-uniform density, outliers, duplicates, big-endian input: test_tiles.)
. "$(dirname "$0")/common.inc"

# the summary's keys $3.. in $T/out as in the summary file $1 ($2 names the run)
same_keys() {
  local ref=$1 what=$2 key
  shift 2
  for key in "$@"; do
    grep -o "\"$key\":[^,]*" "$T/out" | cmp -s - <(grep -o "\"$key\":[^,]*" "$ref") && ok || fail "$what: $key differs"
  done
}
expect 0 "generate" -- "$BSURF" generate sphere -n 12000 --sampling random -o "$T/s.ply" -q
expect 0 "noise" -- "$BSURF" noise "$T/s.ply" --level 0.5 -o "$T/n.ply" -q
expect 0 "generate cube" -- "$BSURF" generate cube -n 8000 -o "$T/c.ply" -q

# error: in memory, then tiles of 60 (hundreds of tile borders) and 3000 points
expect 0 "error in memory" -- "$BSURF" error "$T/n.ply" -k 20 -B 8 -o "$T/e.ply" --json
cp "$T/out" "$T/e.json"
for tp in 60 3000; do
  expect 0 "error tiles $tp" -- "$BSURF" error "$T/n.ply" -k 20 -B 8 -o "$T/e$tp.ply" --tile-points $tp --json
  cmp -s "$T/e.ply" "$T/e$tp.ply" && ok || fail "error --tile-points $tp: output differs from the in-memory run"
  grep -o '"h":[^,]*' "$T/out" | cmp -s - <(grep -o '"h":[^,]*' "$T/e.json") && ok || fail "error --tile-points $tp: h differs"
  grep -o '"replicates_skipped":[^,]*' "$T/out" | cmp -s - <(grep -o '"replicates_skipped":[^,]*' "$T/e.json") && ok ||
    fail "error --tile-points $tp: skipped replicates differ"
  grep -q '"tiles":' "$T/out" && ok || fail "error --tile-points: json lacks tiles"
done
# automatic: the input needs more than --memory-limit (the warning: not with -q,
# which silences warnings too)
expect 0 "error --memory-limit" -- "$BSURF" error "$T/n.ply" -k 20 -B 8 -o "$T/ea.ply" --memory-limit 2M
stderr_has "tiles of" "automatic tiling warns"
cmp -s "$T/e.ply" "$T/ea.ply" && ok || fail "error --memory-limit 2M: output differs"
# the job's arrays count in the estimate (bsurf_normals_job_memory), the MSE
# rule's with its tie-break's record (40 bytes a candidate, every one counted
# as tied): 7M (7.3e6 bytes) holds the test-error run (1.7 MB of file x 3 +
# 352 bytes a point: 5.9e6) but not the MSE rule's (684 bytes a point:
# 9.9e6), so the default rule tiles, where it is the same rule with the
# in-memory bytes (two stages); the test error's own run fits in memory
expect 0 "normals select-k auto, --memory-limit" -- "$BSURF" normals "$T/n.ply" --select-k 10:40:10 -B 0 -o "$T/ma.ply" --memory-limit 7M --json
stderr_has "tiles of" "the MSE rule's candidates counted: tiles"
grep -q '"select_rule":"mse"' "$T/out" && ok || fail "select-k auto over the memory limit: not the mse rule in tiles"
expect 0 "normals select-k auto in memory" -- "$BSURF" normals "$T/n.ply" --select-k 10:40:10 -B 0 -o "$T/mm.ply" -q
cmp -s "$T/mm.ply" "$T/ma.ply" && ok || fail "select-k auto, --memory-limit: output differs from the in-memory run"
expect 0 "normals select-k test-error, --memory-limit" -- "$BSURF" normals "$T/n.ply" --select-k 10:40:10 -B 0 --select-rule test-error -o "$T/mb.ply" --memory-limit 7M --json
grep -q '"tiles":' "$T/out" && fail "select-k test-error within the memory limit: tiled" || ok
# an input that already has fields (the cube's feature_dist, feature), normals
for args in "-k 20 -B 10" "--fit poly -d 2 -k 15 -B 5" "-k 10 -B 0"; do
  expect 0 "normals $args" -- "$BSURF" normals "$T/c.ply" $args -o "$T/m.ply" -q
  expect 0 "normals $args tiles" -- "$BSURF" normals "$T/c.ply" $args -o "$T/mt.ply" --tile-points 100 -q
  cmp -s "$T/m.ply" "$T/mt.ply" && ok || fail "normals $args: tiled output differs"
done
# smooth (naive; bilateral in parallel order) and features --method variance run
# in two stages (a first tiled pass for the global means / threshold, then
# the local pass; bilateral's with a halo of reverse neighbours): the same bytes
# and the same summary numbers as in memory
for m in naive bilateral; do
  for args in "-k 15 -B 6" "-k 12 -d 2 -B 4 --h1 2h --h2 1W --threshold 0.5h"; do
    expect 0 "smooth $m $args" -- "$BSURF" smooth "$T/n.ply" --method $m $args -o "$T/sm.ply" --json
    cp "$T/out" "$T/sm.json"
    for tp in 60 3000; do
      expect 0 "smooth $m $args tiles $tp" -- "$BSURF" smooth "$T/n.ply" --method $m $args -o "$T/st.ply" \
        --tile-points $tp --json
      cmp -s "$T/sm.ply" "$T/st.ply" && ok || fail "smooth $m $args --tile-points $tp: output differs from the in-memory run"
      same_keys "$T/sm.json" "smooth $m --tile-points $tp" h mean_error threshold projected h1 h2 moved_points moved_mean moved_max replicates_skipped mean
    done
  done
done
# the cube: sharp edges, an input with fields of its own; automatic tiling
# the default (auto) tiles as bilateral: the in-memory bilateral bytes
expect 0 "smooth cube" -- "$BSURF" smooth "$T/c.ply" --method bilateral -k 10 -d 2 -B 4 -o "$T/sc.ply" -q
expect 0 "smooth cube tiles" -- "$BSURF" smooth "$T/c.ply" -k 10 -d 2 -B 4 -o "$T/sct.ply" --memory-limit 1M
stderr_has "tiles of" "smooth: automatic tiling warns"
cmp -s "$T/sc.ply" "$T/sct.ply" && ok || fail "smooth cube --memory-limit 1M: output differs"
for f in c n; do
  for args in "" "--tail-rule otsu" "--tail-rule mad" "--threshold 0.002"; do
    expect 0 "features $f $args" -- "$BSURF" features "$T/$f.ply" --method variance -k 15 -B 5 $args -o "$T/fm.ply" --json
    cp "$T/out" "$T/fm.json"
    cp "$T/err" "$T/fm.err"
    expect 0 "features $f $args tiles" -- "$BSURF" features "$T/$f.ply" --method variance -k 15 -B 5 $args \
      -o "$T/ft.ply" --tile-points 70 --json
    cmp -s "$T/fm.ply" "$T/ft.ply" && ok || fail "features $f $args --tile-points 70: output differs"
    cmp -s "$T/fm.err" "$T/err" && ok || fail "features $f $args: tiled warnings differ"
    same_keys "$T/fm.json" "features $f --tile-points 70" threshold feature_points h k kept_input_fields
  done
done
# the quadric check (features_variance.c, step 7) runs on a torus at light
# noise (K_q found, points cleared): its noise passes and its stage at K_q, tiled,
# give the in-memory bytes and numbers
expect 0 "generate torus" -- "$BSURF" generate torus -n 12000 --sampling random -o "$T/t.ply" -q
expect 0 "noise torus" -- "$BSURF" noise "$T/t.ply" --level 0.25 -o "$T/tn.ply" -q
expect 0 "features quadric check" -- "$BSURF" features "$T/tn.ply" -k 15 -B 5 -o "$T/fq.ply" --json
cp "$T/out" "$T/fq.json"
grep -q '"quadric_k":[1-9]' "$T/fq.json" && ok || fail "features torus: the quadric check did not run"
grep -q '"quadric_cleared":0,' "$T/fq.json" && fail "features torus: the quadric check cleared nothing" || ok
for tp in 70 3000; do
  expect 0 "features quadric check tiles $tp" -- "$BSURF" features "$T/tn.ply" -k 15 -B 5 -o "$T/ft.ply" \
    --tile-points $tp --json
  cmp -s "$T/fq.ply" "$T/ft.ply" && ok || fail "features quadric check --tile-points $tp: output differs"
  same_keys "$T/fq.json" "features quadric check --tile-points $tp" threshold feature_points quadric_k quadric_threshold quadric_power quadric_noise quadric_cleared border_points
done
# features --method distance (the default, 7.1) in stages: the sample's
# medians of f(K), the raw map, max radius, --iterations passes of the
# bilateral filter (Eq. 7.1) each reading the previous pass's values, T_h
# over every value: the same bytes and summary numbers as in memory, with
# tiles of 2 k_max points (hundreds of borders); the cube has sharp edges
for f in c n; do
  for args in "" "--iterations 3 --filter-k 9" "--threshold 0.2 --iterations 0" \
    "--noise-factor 0 --derivative 0.5 --k-max 30 --alpha 0.8 --iterations 2"; do
    expect 0 "features distance $f $args" -- "$BSURF" features "$T/$f.ply" --method distance $args -o "$T/fm.ply" --json
    cp "$T/out" "$T/fm.json"
    cp "$T/err" "$T/fm.err"
    expect 0 "features distance $f $args tiles" -- "$BSURF" features "$T/$f.ply" --method distance $args -o "$T/ft.ply" \
      --tile-points 120 --json
    cmp -s "$T/fm.ply" "$T/ft.ply" && ok || fail "features distance $f $args --tile-points 120: output differs"
    cmp -s "$T/fm.err" "$T/err" && ok || fail "features distance $f $args: tiled warnings differ"
    same_keys "$T/fm.json" "features distance $f $args --tile-points 120" threshold feature_points h max_radius immediate ratio_threshold_kmin kept_input_fields
  done
done
# a features output as input (its feature_dist is replaced), tiled automatically
expect 0 "features distance again" -- "$BSURF" features "$T/fm.ply" --method distance -o "$T/fm2.ply" -q
expect 0 "features distance again tiles" -- "$BSURF" features "$T/fm.ply" --method distance -o "$T/ft2.ply" --memory-limit 1M
stderr_has "tiles of" "features distance: automatic tiling warns"
cmp -s "$T/fm2.ply" "$T/ft2.ply" && ok || fail "features distance on a features output, --memory-limit 1M: output differs"
# the medians from every second point: 338 sizes leave room for 11,834 of the 12,000
args="--k-min 3 --k-max 340 --k-step 1 --iterations 1"
expect 0 "features distance sampled" -- "$BSURF" features "$T/n.ply" --method distance $args -o "$T/fm.ply" -q
expect 0 "features distance sampled tiles" -- "$BSURF" features "$T/n.ply" --method distance $args -o "$T/ft.ply" --tile-points 3000 -q
cmp -s "$T/fm.ply" "$T/ft.ply" && ok || fail "features distance, a sample of every second point: tiled output differs"
expect 0 "normals without input normals" -- "$BSURF" error "$T/n.ply" -k 10 -B 2 -o "$T/nn.ply" -q

# refused: exit 1, a message, nothing written
"$BSURF" generate sphere -n 2000 --ascii -o "$T/ascii.ply" -q
expect 1 "ascii input" -- "$BSURF" error "$T/ascii.ply" -k 10 -o "$T/x.ply" --tile-points 100
stderr_has "binary PLY" "ascii input refused"
expect 1 "xyz input" -- "$BSURF" error "$T/s.ply" -k 10 -o "$T/x.xyz" --tile-points 100
expect 1 "ascii output" -- "$BSURF" error "$T/n.ply" -k 10 -o "$T/x.ply" --ascii --tile-points 100
expect 1 "no output" -- "$BSURF" error "$T/n.ply" -k 10 --tile-points 100
expect 1 "test sample" -- "$BSURF" error "$T/n.ply" -k 10 -o "$T/x.ply" --test-sample "$T/s.ply" --tile-points 100
# normal_err and the K selection: two stages (the reference normals of every
# point, then the tiles with their halos' reference normals): the in-memory bytes
for args in "-k 12 -B 6 --test-error --k-ref 10" "--select-k 6:20:7 -B 5 --k-ref 9" \
  "--fit poly --select-k 10:15:5 --select-degree 1,2 -B 3 --select-rule test-error"; do
  expect 0 "normals $args" -- "$BSURF" normals "$T/c.ply" $args -o "$T/m.ply" -q
  expect 0 "normals $args tiles" -- "$BSURF" normals "$T/c.ply" $args -o "$T/mt.ply" --tile-points 100 -q
  cmp -s "$T/m.ply" "$T/mt.ply" && ok || fail "normals $args: tiled output differs"
done
# the MSE rule (the default of --select-k) in four stages: the noise fits, their
# pool over the K_max neighbours (the halo rows carry the fits) and its median
# over the cloud, the first choices, then the choice with the neighbours' first
# choices: the in-memory bytes and summary for any tile size and thread count,
# with either noise pool, on the noisy sphere and on the cube's edges
# a ring-sampled cylinder (20 rings of 60 points, 0.8 apart: a point's 12
# nearest are one ring's arc), so that the noise level is the cross-section
# estimate's (kselect_noise.c; the tiles carry two pooled values a point)
awk 'BEGIN { print "ply\nformat ascii 1.0\nelement vertex 1200"
  print "property double x\nproperty double y\nproperty double z"
  print "property double nx\nproperty double ny\nproperty double nz\nend_header"
  for (j = 0; j < 20; j++) for (i = 0; i < 60; i++) { t = 2 * 3.141592653589793 * i / 60
    printf "%.17g %.17g %.17g %.17g %.17g 0\n", cos(t), sin(t), 0.8 * j, cos(t), sin(t) } }' >"$T/ring.ply"
expect 0 "noise rings" -- "$BSURF" noise "$T/ring.ply" --level 0.1 -o "$T/r.ply" -q
for case in "n|--select-k 10:40:10 -B 6" "c|--select-k 10:40:10 -B 6" "c|--select-k 7:30:4 -B 0 --noise-pool local" \
  "r|--select-k 10:80:5 -B 0" "r|--select-k 10:80:5 -B 0 --noise-pool local" \
  "n|--select-k 10:25:5 --noise-k 30 -k 12 -B 3 --select-rule mse" \
  "c|--fit poly --select-k 10:30:10 --select-degree 1,2 -B 3"; do
  f=${case%%|*} args=${case#*|}
  expect 0 "normals $f $args" -- "$BSURF" normals "$T/$f.ply" $args -o "$T/m.ply" --json
  cp "$T/out" "$T/m.json"
  for tj in "400 1" "2500 2"; do
    tp=${tj% *} j=${tj#* }
    expect 0 "normals $f $args tiles $tp -j $j" -- "$BSURF" normals "$T/$f.ply" $args -j $j -o "$T/mt.ply" \
      --tile-points $tp --json
    cmp -s "$T/m.ply" "$T/mt.ply" && ok || fail "normals $f $args --tile-points $tp -j $j: output differs"
    same_keys "$T/m.json" "normals $f $args --tile-points $tp" h select_rule noise_pool mean replicates_skipped
  done
done
grep -q '"select_rule":"mse"' "$T/out" && ok || fail "tiled --select-rule mse: json select_rule"
expect 1 "normals --curve tiles" -- "$BSURF" normals "$T/n.ply" --select-k 10:20:5 --curve "$T/x.csv" -o "$T/x.ply" \
  --tile-points 100
stderr_has "not available in tiled runs" "normals --curve refused"
for opt in "--orient mst" "--smooth-iterations 2"; do
  expect 1 "normals $opt" -- "$BSURF" normals "$T/n.ply" -k 10 $opt -o "$T/x.ply" --tile-points 100
  stderr_has "not available in tiled runs" "normals $opt refused"
done
expect 1 "smooth sequential" -- "$BSURF" smooth "$T/n.ply" -k 10 --order sequential -o "$T/x.ply" --tile-points 100
stderr_has "sequential is not available in tiled runs: its sweep" "smooth --order sequential refused with the reason"
expect 1 "smooth multipass" -- "$BSURF" smooth "$T/n.ply" -k 10 --method multipass -o "$T/x.ply" --tile-points 100
stderr_has "multipass is not available in tiled runs: it runs --iterations passes" "smooth multipass refused with the reason"
expect 1 "smooth ascii input" -- "$BSURF" smooth "$T/ascii.ply" -k 10 -o "$T/x.ply" --tile-points 100
stderr_has "binary PLY" "smooth: ascii input refused"
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n' >"$T/short.ply"
printf 'abcd' >>"$T/short.ply"
expect 1 "truncated input" -- "$BSURF" error "$T/short.ply" -k 3 -d 1 -B 2 -o "$T/x.ply" --tile-points 100
stderr_has "short.ply: byte" "truncated input names the byte"
expect 1 "features distance bad input" -- "$BSURF" features "$T/short.ply" --method distance -o "$T/x.ply" --tile-points 130
stderr_has "short.ply: byte" "features distance: a truncated input names the byte"
expect 2 "bad memory limit" -- "$BSURF" error "$T/n.ply" -o "$T/x.ply" --memory-limit lots
[ -e "$T/x.ply" ] && fail "output left after refusals" || ok
ls -A "$T" | grep -q "bootsurf-tiles\|\.tmp\." && fail "scratch or temporary files left" || ok
for c in error smooth features; do
  expect 0 "help $c names the option" -- "$BSURF" help $c
  grep -q -- "--tile-points" "$T/out" && ok || fail "help $c lacks --tile-points"
done

# MPI: 1, 2 and 4 ranks give the serial bytes (when built with MPI)
if ! command -v mpirun >/dev/null 2>&1; then
  echo "SKIP: mpirun not found; the MPI runs are not tested (apt-get install openmpi-bin libopenmpi-dev)"
else
  root=()
  [ "$(id -u)" = 0 ] && root=(--allow-run-as-root)
  # Under AddressSanitizer (.ci/run's second stage) LeakSanitizer reports
  # Open MPI's own allocations that it never frees (libmpi and its dlopen'ed
  # components); our code's leaks are checked by every other test, so leak
  # detection is off for the MPI processes only.
  export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
  root+=(-x ASAN_OPTIONS)
  expect 0 "mpirun -n 2" -- mpirun "${root[@]}" --oversubscribe -n 2 "$BSURF" error "$T/n.ply" -k 20 -B 8 -j 1 \
    -o "$T/mpi2.ply" --tile-points 2000 --json
  if ! grep -q '"ranks":2' "$T/out"; then
    echo "SKIP: bootsurf was built without MPI (cmake found no MPI library); the MPI runs are not tested"
  else
    for P in 1 2 4; do
      expect 0 "mpirun -n $P" -- mpirun "${root[@]}" --oversubscribe -n $P "$BSURF" error "$T/n.ply" -k 20 -B 8 -j 1 \
        -o "$T/mpi$P.ply" --tile-points 700 --json
      cmp -s "$T/e.ply" "$T/mpi$P.ply" && ok || fail "mpirun -n $P: output differs from the serial run"
      [ "$(grep -c '"command":"error"' "$T/out")" = 1 ] && ok || fail "mpirun -n $P: one summary expected"
      grep -o '"h":[^,]*' "$T/out" | cmp -s - <(grep -o '"h":[^,]*' "$T/e.json") && ok || fail "mpirun -n $P: h differs"
    done
    # The passes and the assembly split over the ranks, several ranges per
    # rank (tiles of 200 points, ranges of at most 300: 64 ranges): the
    # serial bytes, and the summary of a serial run with the same tiles
    # (every field but the output's name, ranks and time: h, the counters and
    # the field means).
    summary() { tr ',' '\n' <"$1" | grep -v -E '^"(output|ranks|seconds)"'; }
    expect 0 "serial ranges" -- "$BSURF" error "$T/n.ply" -k 20 -B 8 -j 1 -o "$T/sr.ply" --tile-points 200 \
      --range-points 300 --json
    cp "$T/out" "$T/sr.json"
    cmp -s "$T/e.ply" "$T/sr.ply" && ok || fail "--range-points 300: output differs from the in-memory run"
    for P in 2 3 4; do
      expect 0 "mpirun -n $P ranges" -- mpirun "${root[@]}" --oversubscribe -n $P "$BSURF" error "$T/n.ply" -k 20 -B 8 \
        -j 1 -o "$T/mr$P.ply" --tile-points 200 --range-points 300 --json
      cmp -s "$T/e.ply" "$T/mr$P.ply" && ok || fail "mpirun -n $P --range-points 300: output differs"
      summary "$T/out" | cmp -s - <(summary "$T/sr.json") && ok ||
        fail "mpirun -n $P --range-points 300: summary differs: $(diff <(summary "$T/out") <(summary "$T/sr.json") | head -4)"
    done
    # a NaN and an infinity late in the file (points 10,500 and 11,990 of
    # 12,000: in the last rank's share): the serial message, nothing written
    cp "$T/n.ply" "$T/nan.ply"
    body=$(($(grep -abo end_header "$T/nan.ply" | head -1 | cut -d: -f1) + 11))
    record=$((($(stat -c %s "$T/nan.ply") - body) / 12000))
    printf '\000\000\000\000\000\000\370\177' | dd of="$T/nan.ply" bs=1 seek=$((body + 10500 * record + 8)) conv=notrunc status=none
    printf '\000\000\000\000\000\000\360\177' | dd of="$T/nan.ply" bs=1 seek=$((body + 11990 * record)) conv=notrunc status=none
    expect 1 "serial NaN" -- "$BSURF" error "$T/nan.ply" -k 20 -B 8 -o "$T/x.ply" --tile-points 200
    cp "$T/err" "$T/nan.err"
    stderr_has "nan.ply: point 10500 (0-based) has a NaN" "serial NaN names the point"
    for P in 2 4; do
      expect 1 "mpirun -n $P NaN" -- mpirun "${root[@]}" --oversubscribe -n $P "$BSURF" error "$T/nan.ply" -k 20 -B 8 \
        -o "$T/x.ply" --tile-points 200
      grep "nan.ply" "$T/err" | cmp -s - "$T/nan.err" && ok ||
        fail "mpirun -n $P NaN: message differs: $(grep nan.ply "$T/err" | head -2)"
      [ -e "$T/x.ply" ] && fail "mpirun -n $P NaN: output left" || ok
    done
    expect 0 "mpirun normals" -- mpirun "${root[@]}" --oversubscribe -n 3 "$BSURF" normals "$T/c.ply" -k 10 -B 0 -j 1 \
      -o "$T/mpin.ply" -q
    expect 0 "normals serial" -- "$BSURF" normals "$T/c.ply" -k 10 -B 0 -o "$T/sern.ply" -q
    cmp -s "$T/sern.ply" "$T/mpin.ply" && ok || fail "mpirun normals: output differs"
    expect 0 "mpirun normals select-k" -- mpirun "${root[@]}" --oversubscribe -n 3 "$BSURF" normals "$T/c.ply" \
      --select-k 6:20:7 -B 4 -j 1 -o "$T/mpis.ply" -q --tile-points 150
    expect 0 "normals select-k serial" -- "$BSURF" normals "$T/c.ply" --select-k 6:20:7 -B 4 -o "$T/sers.ply" -q
    cmp -s "$T/sers.ply" "$T/mpis.ply" && ok || fail "mpirun normals --select-k: output differs"
    # the MSE rule's stages: every rank reads the pooled noise back for the median
    expect 0 "normals select-k mse serial" -- "$BSURF" normals "$T/c.ply" --select-k 10:30:5 -B 4 -o "$T/serm.ply" -q
    for P in 2 3; do
      expect 0 "mpirun -n $P normals select-k mse" -- mpirun "${root[@]}" --oversubscribe -n $P "$BSURF" normals \
        "$T/c.ply" --select-k 10:30:5 -B 4 -j 1 -o "$T/mpim.ply" -q --tile-points 150
      cmp -s "$T/serm.ply" "$T/mpim.ply" && ok || fail "mpirun -n $P normals --select-k (mse): output differs"
    done
    # two stages under MPI: the values of the first are shared by every rank
    for m in naive bilateral; do
      expect 0 "smooth $m serial" -- "$BSURF" smooth "$T/n.ply" --method $m -k 12 -B 4 -o "$T/sser.ply" -q
      expect 0 "mpirun smooth $m" -- mpirun "${root[@]}" --oversubscribe -n 3 "$BSURF" smooth "$T/n.ply" --method $m \
        -k 12 -B 4 -j 1 -o "$T/smpi.ply" --tile-points 900 -q
      cmp -s "$T/sser.ply" "$T/smpi.ply" && ok || fail "mpirun smooth $m: output differs"
    done
    expect 0 "features serial" -- "$BSURF" features "$T/n.ply" --method variance -k 12 -B 4 -o "$T/fser.ply" -q
    expect 0 "mpirun features" -- mpirun "${root[@]}" --oversubscribe -n 2 "$BSURF" features "$T/n.ply" \
      --method variance -k 12 -B 4 -j 1 -o "$T/fmpi.ply" -q
    cmp -s "$T/fser.ply" "$T/fmpi.ply" && ok || fail "mpirun features: output differs"
    # the quadric check's noise passes and stage under MPI
    expect 0 "mpirun features quadric check" -- mpirun "${root[@]}" --oversubscribe -n 2 "$BSURF" features \
      "$T/tn.ply" -k 15 -B 5 -j 1 -o "$T/fmpi.ply" --tile-points 3000 -q
    cmp -s "$T/fq.ply" "$T/fmpi.ply" && ok || fail "mpirun features quadric check: output differs"
    # features distance: the sample's medians summed over the ranks, the filter passes' values shared
    args="--iterations 2 --filter-k 9 --k-max 40"
    expect 0 "features distance serial" -- "$BSURF" features "$T/c.ply" --method distance $args -o "$T/fser.ply" -q
    for P in 2 3; do
      expect 0 "mpirun features distance $P" -- mpirun "${root[@]}" --oversubscribe -n $P "$BSURF" features "$T/c.ply" --method distance \
        $args -j 1 -o "$T/fmpi.ply" --tile-points 500 -q
      cmp -s "$T/fser.ply" "$T/fmpi.ply" && ok || fail "mpirun -n $P features distance: output differs"
    done
    expect 1 "mpirun bad input" -- mpirun "${root[@]}" --oversubscribe -n 2 "$BSURF" error "$T/short.ply" -k 3 -d 1 -o "$T/x.ply"
    [ -e "$T/x.ply" ] && fail "mpirun: output left after a failure" || ok
    ls -A "$T" | grep -q "bootsurf-tiles\|\.tmp\." && fail "mpirun: scratch or temporary files left" || ok
  fi
fi
finish
