#!/usr/bin/env bash
# Every fault named right, every output path respected (docs/robustness.md):
# headers checked before any memory estimate, linear-time PLY headers, the
# output-path policy (read-only, symbolic links, FIFOs and devices, stale
# temporary files), signals (130 / 143 within a second, a shell loop stops),
# the last line of a text file, error -B 0, a full disk in a tiled run, a
# binary header ending in a lone CR; and the habits: truth passed along only
# as true_* fields, OMP_NUM_THREADS, -q, no "(default: nan)", the version.
. "$(dirname "$0")/common.inc"

IN="$T/in"
mkdir -p "$IN"
OUT="$T/out.ply"
PY=/usr/bin/python3
[ -x "$PY" ] || PY=$(command -v python3 || true)

expect 0 "generate" -- "$BSURF" generate cube -n 3000 -o "$IN/c.ply" -q
expect 0 "noise" -- "$BSURF" noise "$IN/c.ply" --level 0.5 -o "$IN/n.ply" -q

# ---- the header before any memory estimate (error, normals, smooth, features) ----
{ ply_head ascii 4294967295; printf '0 0 0\n'; } >"$IN/a32.ply"
{ ply_head ascii 1000000000000000; printf '0 0 0\n'; } >"$IN/a15.ply"
{ ply_head ascii -5; printf '0 0 0\n'; } >"$IN/neg.ply"
{ ply_head ascii 99999999999999999999999; printf '0 0 0\n'; } >"$IN/over.ply"
{ ply_head binary_little_endian 1000000000000000; head -c 12 /dev/zero; } >"$IN/b15.ply"
for c in "error -k 20 -d 2 -B 4" "normals -k 20" "smooth -k 20 -d 2 -B 4" "features -k 12 --k-min 6 --k-max 12"; do
  # shellcheck disable=SC2086
  bad 1 "ascii 2^32-1 ($c)" "$IN/a32.ply:9: vertex 1: unexpected end of file (header declares 4294967295 vertices)" -- "$BSURF" $c "$IN/a32.ply" -o "$OUT"
  grep -q "needs about\|tiled runs" "$T/err" && fail "$c: an estimate before the header's fault" || ok
  # shellcheck disable=SC2086
  bad 1 "ascii 10^15 ($c)" "header declares 1000000000000000 vertices" -- "$BSURF" $c "$IN/a15.ply" -o "$OUT"
  # shellcheck disable=SC2086
  bad 1 "negative count ($c)" "$IN/neg.ply:3: element count '-5' is not a non-negative integer" -- "$BSURF" $c "$IN/neg.ply" -o "$OUT"
  # shellcheck disable=SC2086
  bad 1 "overflowing count ($c)" "$IN/over.ply:3: element count '99999999999999999999999' is too large" -- "$BSURF" $c "$IN/over.ply" -o "$OUT"
  # shellcheck disable=SC2086
  bad 1 "binary 10^15 ($c)" "$IN/b15.ply: byte" "header declares 1000000000000000 vertices" -- "$BSURF" $c "$IN/b15.ply" -o "$OUT"
done
bad 1 "info names the ascii fault" "$IN/a32.ply:" -- "$BSURF" info "$IN/a32.ply"

# ---- a header of 100,000 properties: read in linear time (docs/robustness.md) ----
awk 'BEGIN { n = 100000
  print "ply"; print "format ascii 1.0"; print "element vertex 2"
  print "property float x"; print "property float y"; print "property float z"
  for (i = 0; i < n; i++) print "property float p" i
  print "end_header"
  for (r = 1; r <= 2; r++) { s = r " " r " " r; for (i = 0; i < n; i++) s = s " " i % 7; print s } }' >"$IN/wide.ply"
expect 0 "100,000 properties" -- "$BSURF" info "$IN/wide.ply" --json
grep -qF '"points":2' "$T/out" && grep -qF '"p99999"' "$T/out" && ok || fail "100,000 properties not read"
sed 's/property float p99999$/property float p7/' "$IN/wide.ply" >"$IN/wide_dup.ply"
bad 1 "100,000 properties, one twice" "$IN/wide_dup.ply:100006: vertex property 'p7' is declared twice" -- "$BSURF" info "$IN/wide_dup.ply"

# ---- binary header ending in a lone CR, first data byte 0x0A ----------------------
printf 'ply\rformat binary_little_endian 1.0\relement vertex 1\rproperty uchar x\rproperty uchar y\rproperty uchar z\rend_header\r\n\001\002' >"$IN/cr.ply"
expect 0 "lone CR header, data 0x0A" -- "$BSURF" info "$IN/cr.ply" --json
grep -qF '"min":[10,1,2]' "$T/out" && ok || fail "lone CR header read one byte off: $(cat "$T/out")"

# ---- the last line of a text file, without its line break, checked like the rest ----
printf '0 0 0\n1 0 0\n1 1' >"$IN/cut.xyz"
bad 1 "xyz last line short" "$IN/cut.xyz:3: expected 3 values" -- "$BSURF" info "$IN/cut.xyz"
printf '0 0 0\n1 0 0\n1 1 1e' >"$IN/cut_e.xyz"
bad 1 "xyz last line cut in an exponent" "$IN/cut_e.xyz:3: '1e' is not a number" -- "$BSURF" info "$IN/cut_e.xyz"
printf '0 0 0\n1 0 0\n1 1 -' >"$IN/cut_s.xyz"
bad 1 "xyz last line cut after a sign" "$IN/cut_s.xyz:3: '-' is not a number" -- "$BSURF" info "$IN/cut_s.xyz"
printf 'v 0 0 0\nv 1 0 0\nv 1 1' >"$IN/cut.obj"
bad 1 "obj last line short" "$IN/cut.obj:3:" "found 2" -- "$BSURF" info "$IN/cut.obj"
printf 'v 0 0 0\nv 1 0 0\nv 1 1 2.5e+' >"$IN/cut_e.obj"
bad 1 "obj last line cut in an exponent" "$IN/cut_e.obj:3: '2.5e+'" -- "$BSURF" info "$IN/cut_e.obj"

# ---- error -B 0 ------------------------------------------------------------------------
bad 2 "error -B 0" "-B 0: the bootstrap estimators need at least one replicate" -- "$BSURF" error "$IN/n.ply" -B 0 -o "$OUT"

# ---- where the output goes: the policy ----------------------------------------------
bad 1 "-o DIR" "$T: is a directory" -- "$BSURF" noise "$IN/c.ply" -o "$T"
printf 'read-only\n' >"$T/ro.ply"
chmod 444 "$T/ro.ply"
bad 1 "read-only output" "$T/ro.ply: the output file is read-only (mode 0444); refusing to replace it (use --force)" -- \
  "$BSURF" noise "$IN/c.ply" -o "$T/ro.ply"
[ "$(cat "$T/ro.ply")" = "read-only" ] && ok || fail "read-only output changed"
expect 0 "read-only output with --force" -- "$BSURF" noise "$IN/c.ply" -o "$T/ro.ply" --force -q
grep -a -q "^end_header" "$T/ro.ply" && ok || fail "--force did not replace the read-only output"
rm -f "$T/ro.ply"
mkdir -p "$T/real"
printf 'old\n' >"$T/real/target.ply"
ln -sf real/target.ply "$T/link.ply"
expect 0 "through a symbolic link" -- "$BSURF" noise "$IN/c.ply" -o "$T/link.ply" -q
[ -L "$T/link.ply" ] && ok || fail "the symbolic link became a regular file"
grep -a -q "^end_header" "$T/real/target.ply" && ok || fail "the link's target was not written"
ln -sf real/new.ply "$T/dangling.ply"
expect 0 "through a dangling link" -- "$BSURF" noise "$IN/c.ply" -o "$T/dangling.ply" -q
[ -L "$T/dangling.ply" ] && [ -f "$T/real/new.ply" ] && ok || fail "a dangling link's target was not created"
no_temporaries "symbolic links"
expect 0 "-o /dev/null" -- "$BSURF" noise "$IN/c.ply" -o /dev/null -q
[ -c /dev/null ] && ok || fail "/dev/null is no longer a device"
if mkfifo "$T/fifo.ply" 2>/dev/null; then
  timeout 60 cat "$T/fifo.ply" >"$T/fifo.out" &
  reader=$!
  expect 0 "a FIFO" -- timeout 60 "$BSURF" noise "$IN/c.ply" -o "$T/fifo.ply" -q
  wait "$reader"
  [ -p "$T/fifo.ply" ] && ok || fail "the FIFO was replaced"
  mv "$T/fifo.out" "$T/fifo_out.ply"
  expect 0 "the FIFO's bytes are a PLY file" -- "$BSURF" info "$T/fifo_out.ply"
else
  echo "SKIP: mkfifo failed here, the FIFO output case is skipped"
fi
dead=$(sh -c 'echo $$')
while kill -0 "$dead" 2>/dev/null; do dead=$((dead + 100000)); done
printf x >"$T/.old.ply.bsurf-tmp.$dead.abcdef"
printf x >"$T/.live.ply.bsurf-tmp.$$.abcdef"
expect 0 "a write beside stale temporaries" -- "$BSURF" noise "$IN/c.ply" -o "$T/w.ply" -q
[ ! -e "$T/.old.ply.bsurf-tmp.$dead.abcdef" ] && ok || fail "a dead process's temporary file was kept"
[ -e "$T/.live.ply.bsurf-tmp.$$.abcdef" ] && ok || fail "a live process's temporary file was removed"
rm -f "$T/.live.ply.bsurf-tmp.$$.abcdef"

# ---- a full disk during a tiled run names the output ---------------------------------
expect 0 "a cloud for tiles" -- "$BSURF" generate sphere -n 20000 -o "$IN/s20k.ply" -q
full() { (trap '' XFSZ; ulimit -f 300; exec "$@"); }
bad 1 "full disk, tiled" "$OUT: cannot write" -- full "$BSURF" normals "$IN/s20k.ply" -k 10 -B 0 --tile-points 5000 -o "$OUT"

# ---- signals: 130 / 143 within a second, nothing left ---------------------------------
now() { date +%s.%N; }
# The signal must reach the command while it works, on any machine: a fixed
# sleep (2 s before) outlasted the whole `generate -n 3000000` (0.5 s) on an
# idle Zen 5, which then exited 0. Wait instead until the process has used
# 5 clock ticks of CPU time (/proc/PID/stat's utime + stime; the generation
# needs about 100), then signal.
cpu_ticks() { sed 's/.*) //' "/proc/$1/stat" 2>/dev/null | awk '{ print $12 + $13 }'; }
wait_working() {
  local t
  for _ in $(seq 3000); do
    t=$(cpu_ticks "$1")
    [ -z "$t" ] && return 0
    [ "$t" -ge 5 ] && return 0
    sleep 0.01
  done
}
for sig in INT TERM; do
  rm -f "$T/g.ply"
  "$BSURF" generate sphere -n 3000000 -o "$T/g.ply" 2>"$T/err" &
  pid=$!
  wait_working "$pid"
  t0=$(now)
  kill -"$sig" "$pid"
  wait "$pid"
  rc=$?
  t1=$(now)
  want=130
  [ "$sig" = TERM ] && want=143
  [ "$rc" -eq "$want" ] && ok || fail "generate SIG$sig: exit $rc, expected $want"
  awk -v a="$t0" -v b="$t1" 'BEGIN { exit !(b - a < 1.0) }' && ok || fail "generate SIG$sig: exit $(awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }') s after the signal"
  [ -e "$T/g.ply" ] && fail "generate SIG$sig: output written" || ok
  no_temporaries "generate SIG$sig"
done
# a shell loop over files stops at Ctrl-C: SIGINT to the loop's process group,
# as a terminal sends it; bash stops only when its child died of the signal
if [ -n "$PY" ]; then
  cat >"$T/loop.py" <<'PYEOF'
import os, signal, subprocess, sys, time
bsurf, tdir = sys.argv[1], sys.argv[2]
script = 'for f in 1 2 3; do "$0" generate sphere -n 3000000 -o "$1/loop$f.ply" || st=$?; echo "after $f" >>"$1/loop.log"; done'
p = subprocess.Popen(["bash", "-c", script, bsurf, tdir], start_new_session=True, stderr=subprocess.DEVNULL)
# signal once the loop's first generate has used 5 clock ticks of CPU (a
# fixed sleep could outlast it on a fast machine; see wait_working above)
def ticks(pid):
    try:
        with open("/proc/%d/stat" % pid) as f:
            rest = f.read().rsplit(")", 1)[1].split()
        return int(rest[11]) + int(rest[12])
    except (OSError, IndexError, ValueError):
        return -1
def children(pid):
    try:
        with open("/proc/%d/task/%d/children" % (pid, pid)) as f:
            return [int(c) for c in f.read().split()]
    except OSError:
        return []
for _ in range(3000):
    if p.poll() is not None or any(ticks(c) >= 5 for c in children(p.pid)):
        break
    time.sleep(0.01)
os.killpg(p.pid, signal.SIGINT)
rc = p.wait()
print(rc)
PYEOF
  rc=$("$PY" "$T/loop.py" "$BSURF" "$T")
  [ "$rc" = "-2" ] || [ "$rc" = "130" ] && ok || fail "shell loop: bash ended with $rc, not by SIGINT"
  [ -e "$T/loop.log" ] && fail "shell loop went on after Ctrl-C: $(cat "$T/loop.log")" || ok
  [ -e "$T/loop2.ply" ] && fail "shell loop started the next file" || ok
  no_temporaries "shell loop"
else
  echo "SKIP: no python3, the shell-loop case is skipped"
fi

# ---- honest truth: noise keeps it as true_*, eval never scores it as a result ----------
expect 0 "noise fields" -- "$BSURF" info "$IN/n.ply" --json
grep -qF '"normals":false' "$T/out" && grep -qF '"true_nx","true_ny","true_nz"' "$T/out" &&
  grep -qF '"true_feature"' "$T/out" && grep -qF '"true_feature_dist"' "$T/out" && ! grep -qF '"feature"' "$T/out" &&
  ok || fail "noise output fields: $(cat "$T/out")"
expect 0 "normals of the noisy cube" -- "$BSURF" normals "$IN/n.ply" -k 20 -o "$T/nrm.ply" -q
expect 0 "eval against the noise output (true_* truth)" -- "$BSURF" eval "$T/nrm.ply" --truth "$IN/n.ply" --json
grep -qF '"normals":{' "$T/out" && ! grep -qF '"features":{' "$T/out" && ok || fail "eval: $(cat "$T/out")"
expect 0 "eval against the generate output" -- "$BSURF" eval "$T/nrm.ply" --truth "$IN/c.ply" --json
grep -qF '"normals":{' "$T/out" && ok || fail "eval against generate: $(cat "$T/out")"
expect 0 "eval of the truth itself" -- "$BSURF" eval "$IN/c.ply" --truth "$IN/c.ply" --json
stderr_has "normals are bit-identical to those of $IN/c.ply: ground truth passed along, not a result" "eval of the truth"
grep -qF '"normals":{' "$T/out" || grep -qF '"features":{' "$T/out" && fail "eval scored the truth: $(cat "$T/out")" || ok
expect 0 "noise of a noisy file" -- "$BSURF" noise "$IN/n.ply" -o "$T/nn.ply" -q
expect 0 "smooth" -- "$BSURF" smooth "$IN/c.ply" -k 20 -d 2 -B 4 -o "$T/sm.ply" --json
expect 0 "smooth output" -- "$BSURF" info "$T/sm.ply" --json
grep -qF '"normals":false' "$T/out" && ok || fail "smooth kept normals that no longer match"

# ---- habits ----------------------------------------------------------------------
expect 0 "OMP_NUM_THREADS" -- env OMP_NUM_THREADS=1 "$BSURF" info "$IN/c.ply" --json
grep -qF '"threads":1' "$T/out" && ok || fail "OMP_NUM_THREADS=1 ignored: $(cat "$T/out")"
expect 0 "-j over OMP_NUM_THREADS" -- env OMP_NUM_THREADS=1 "$BSURF" info "$IN/c.ply" -j 2 --json
grep -qF '"threads":2' "$T/out" && ok || fail "-j 2 not used"
grep -qF '"version":"' "$T/out" && ok || fail "no version in the JSON summary"
grep -a -q "^comment generated by bootsurf [0-9]" "$IN/c.ply" && ok || fail "no version in the PLY comment"
for c in info generate noise error normals sample eval render histogram compare smooth features; do
  "$BSURF" help "$c" | grep -q "default: nan" && fail "$c: (default: nan) in the help" || ok
done
printf 'OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n' >"$IN/tet.off"
quiet_runs=("info $IN/c.ply" "generate plane -n 400 -o $T/q.ply" "noise $IN/c.ply -o $T/q.xyz" "error $IN/n.ply -k 20 -d 2 -B 4 -o $T/q.ply"
  "normals $IN/n.ply -k 20 -o $T/q.ply" "sample $IN/tet.off -n 500 -o $T/q.ply" "eval $T/nrm.ply --truth $IN/c.ply"
  "render $IN/c.ply -o $T/q.png" "histogram $T/nrm.ply --field normal_var -o $T/q.png" "compare $IN/c.ply $IN/n.ply -o $T/q.png"
  "smooth $IN/n.ply -k 20 -d 2 -B 4 -o $T/q.ply" "features $IN/n.ply -k 12 --k-min 6 --k-max 12 -o $T/q.ply")
for r in "${quiet_runs[@]}"; do
  # shellcheck disable=SC2086
  expect 0 "-q $r" -- "$BSURF" $r -q
  [ -s "$T/out" ] || [ -s "$T/err" ] && fail "-q $r: printed $(head -c 200 "$T/out" "$T/err")" || ok
done


# ---- output options are usage, checked before any work; pictures to a pipe ----------------
bad 2 "--las-version 1.3" "--las-version 1.3: expected 1.2 or 1.4" -- "$BSURF" smooth "$IN/n.ply" -k 20 -d 2 -B 4 --las-version 1.3 -o "$T/s.las"
[ -e "$T/s.las" ] && fail "--las-version 1.3: an output was written" || ok
bad 2 "--ply-names bad" "--ply-names gray: expected plain, cloudcompare or meshlab" -- "$BSURF" noise "$IN/c.ply" --ply-names gray -o "$T/p.ply"
bad 2 "--format bad" "--format tiff: unknown format" -- "$BSURF" noise "$IN/c.ply" --format tiff -o "$T/p.ply"
for pic in "render $IN/n.ply --size 120x90" "histogram $IN/c.ply --field feature_dist --size 200x120"; do
  # shellcheck disable=SC2086
  "$BSURF" $pic -o - -q >"$T/pic.png" 2>"$T/pic.err" && ok || fail "$pic -o -: exit $?"
  head -c 8 "$T/pic.png" | od -An -c | grep -q "P   N   G" && ok || fail "$pic -o -: standard output is not a PNG"
  [ -s "$T/pic.err" ] && fail "$pic -o -: the picture went to standard error" || ok
done

# ---- wide and long-named fields: refused by LAS, kept whole by PCD ----------------------------
{
  printf 'x,y,z'
  for i in $(seq 1 400); do printf ',f%d' "$i"; done
  printf '\n'
  for p in 1 2 3; do
    printf '%d,0,0' "$p"
    for i in $(seq 1 400); do printf ',%d' "$i"; done
    printf '\n'
  done
} >"$IN/wide.csv"
bad 1 "LAS with 400 fields" "$T/wide.las: 400 fields: LAS holds at most 341 extra-bytes fields" -- "$BSURF" convert "$IN/wide.csv" "$T/wide.las"
[ -e "$T/wide.las" ] && fail "LAS with 400 fields: a file was written" || ok
long=field_name_of_sixty_characters_for_the_pcd_round_trip_check
printf 'x,y,z,%s,%sb\n1,2,3,4,5\n2,3,4,5,6\n' "$long" "$long" >"$IN/long.csv"
expect 0 "PCD long names" -- "$BSURF" convert "$IN/long.csv" "$T/long.pcd" -q
expect 0 "PCD long names back" -- "$BSURF" convert "$T/long.pcd" "$T/long.csv" -q
[ "$(head -1 "$T/long.csv")" = "$(head -1 "$IN/long.csv")" ] && ok || fail "PCD long names: $(head -1 "$T/long.csv")"
finish
