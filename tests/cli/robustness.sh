#!/usr/bin/env bash
# The bad-input contract of docs/robustness.md, case by case through the CLI:
# every bad input or failed write ends with exit 1 (bad input, failed
# computation or write) or 2 (bad usage), one message naming the file and the
# place (line, byte or point index), no crash, no output and no temporary
# file, and the input untouched. Also: degenerate neighbourhoods give defined
# outputs (never NaN), --drop-invalid, interrupts, and byte-identical outputs
# for -j 1 / -j 2 and across runs of every command that draws random numbers.
. "$(dirname "$0")/common.inc"

IN="$T/in"
mkdir -p "$IN"
OUT="$T/out.ply"
# ascii_values FILE: the data lines of an ascii PLY file
ascii_values() { sed '1,/^end_header/d' "$1"; }
no_nan() { # no_nan FILE DESCRIPTION: no NaN or infinity in an ascii PLY's data
  if ascii_values "$1" | grep -q -i -E 'nan|inf'; then fail "$2: NaN or infinity in the output"; else ok; fi
}

# ---- a good cloud to start from ------------------------------------------------
expect 0 "generate" -- "$BSURF" generate sphere -n 3000 -o "$IN/s.ply" -q
expect 0 "noise" -- "$BSURF" noise "$IN/s.ply" --level 0.5 -o "$IN/n.ply" -q
ERR=(error -k 20 -d 2 -B 4)

# ---- empty and truncated files -------------------------------------------------
: >"$IN/empty.ply"
: >"$IN/empty.xyz"
bad 1 "empty ply" "$IN/empty.ply: the file is empty" -- "$BSURF" "${ERR[@]}" "$IN/empty.ply" -o "$OUT"
bad 1 "empty xyz" "$IN/empty.xyz: the file is empty" -- "$BSURF" "${ERR[@]}" "$IN/empty.xyz" -o "$OUT"
bad 1 "empty, info" "$IN/empty.ply: the file is empty" -- "$BSURF" info "$IN/empty.ply"
ply_head ascii 3 >"$IN/header_only.ply"
bad 1 "header only" "$IN/header_only.ply:8:" "vertex 0: unexpected end of file" -- \
  "$BSURF" "${ERR[@]}" "$IN/header_only.ply" -o "$OUT"
{ ply_head ascii 5; printf '0 0 0\n1 0 0\n'; } >"$IN/short.ply"
bad 1 "counts exceed the data (ascii)" "$IN/short.ply:10:" "vertex 2: unexpected end of file (header declares 5 vertices)" -- \
  "$BSURF" "${ERR[@]}" "$IN/short.ply" -o "$OUT"
{ ply_head binary_little_endian 10; head -c 36 /dev/zero; } >"$IN/short_bin.ply"
bad 1 "counts exceed the data (binary)" "$IN/short_bin.ply: byte 152:" "declares 10 vertices (120 bytes) but only 36 bytes follow: the data ends inside vertex 3" -- \
  "$BSURF" "${ERR[@]}" "$IN/short_bin.ply" -o "$OUT"
{ ply_head ascii 2; printf '0 0 0\n1 0\n'; } >"$IN/short_line.ply"
bad 1 "a short record" "$IN/short_line.ply:9:" "vertex 1: expected 3 values, found 2" -- "$BSURF" info "$IN/short_line.ply"
{ ply_head ascii 1; printf '0 zero 0\n'; } >"$IN/word.ply"
bad 1 "not a number" "$IN/word.ply:8:" "'zero' is not a number" -- "$BSURF" info "$IN/word.ply"
printf '0 0 0\n1 0 0\n1 1\n' >"$IN/short.xyz"
bad 1 "xyz short line" "$IN/short.xyz:3:" "expected 3 values" -- "$BSURF" info "$IN/short.xyz"

# ---- absurd counts: no huge allocation, an answer at once ----------------------
{ ply_head ascii 99999999999; printf '0 0 0\n'; } >"$IN/absurd.ply"
{ ply_head binary_little_endian 99999999999; head -c 12 /dev/zero; } >"$IN/absurd_bin.ply"
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 99999999999\nproperty list uchar int vertex_indices\nend_header\n' >"$IN/absurd_faces.ply"
head -c 36 /dev/zero >>"$IN/absurd_faces.ply"
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n' >"$IN/absurd_list.ply"
{ head -c 36 /dev/zero; printf '\377\377\377\377'; } >>"$IN/absurd_list.ply"
printf 'OFF\n99999999999 1 0\n0 0 0\n' >"$IN/absurd.off"
peak_kb() { # peak_kb COMMAND...: the command's peak resident memory in KiB (0 if unknown)
  if [ -x /usr/bin/time ]; then
    /usr/bin/time -f '%M' -o "$T/peak" "$@" >/dev/null 2>&1
    tail -1 "$T/peak"
  else
    "$@" >/dev/null 2>&1
    echo 0
  fi
}
for f in absurd.ply absurd_bin.ply absurd_faces.ply absurd_list.ply absurd.off; do
  bad 1 "absurd count $f" "$IN/$f" -- "$BSURF" "${ERR[@]}" "$IN/$f" -o "$OUT"
  kb=$(peak_kb "$BSURF" info "$IN/$f")
  [ "${kb:-0}" -lt 400000 ] && ok || fail "absurd count $f: peak memory ${kb} KiB"
done
bad 1 "absurd vertex count names it" "declares 99999999999 vertices" -- "$BSURF" info "$IN/absurd_bin.ply"
bad 1 "absurd list length" "$IN/absurd_list.ply: byte" "a list of 4294967295 values" -- "$BSURF" info "$IN/absurd_list.ply"

# ---- property types and lists -----------------------------------------------------
printf 'ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nproperty float y\nproperty float z\nend_header\n0 0 0\n' >"$IN/type.ply"
bad 1 "unknown property type" "$IN/type.ply:4:" "unknown property type 'float128'" -- "$BSURF" "${ERR[@]}" "$IN/type.ply" -o "$OUT"
printf 'ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty list uchar float texcoord\nend_header\n0 0 0 2 0.5 0.5\n' >"$IN/list.ply"
bad 1 "list property on vertices" "$IN/list.ply:7:" "list property 'texcoord'" -- "$BSURF" "${ERR[@]}" "$IN/list.ply" -o "$OUT"
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list float int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n' >"$IN/listcount.ply"
bad 1 "list length of type float" "$IN/listcount.ply:8:" "must have an integer type" -- "$BSURF" info "$IN/listcount.ply"
printf 'ply\nformat binary_middle_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n' >"$IN/enc.ply"
bad 1 "unknown encoding" "$IN/enc.ply:2:" "unknown PLY encoding" -- "$BSURF" info "$IN/enc.ply"
printf 'ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n' >"$IN/noz.ply"
bad 1 "no z" "$IN/noz.ply:3:" "no 'z' property" -- "$BSURF" info "$IN/noz.ply"
# types other tools write are read: int8..float64 aliases, other elements, unknown vertex fields kept
printf 'ply\nformat ascii 1.0\ncomment made by hand\nobj_info x\nelement vertex 2\nproperty float32 x\nproperty float64 y\nproperty int16 z\nproperty uint8 red\nproperty int32 label\nelement material 1\nproperty list uchar float coeffs\nend_header\n0 0 0 255 -7\n1 0.5 2 0 7\n2 1 2\n' >"$IN/types.ply"
expect 0 "aliases and other elements" -- "$BSURF" info "$IN/types.ply" --json
grep -qF '"points":2' "$T/out" && grep -qF '"fields":["red","label"]' "$T/out" && ok || fail "types.ply read"

# ---- line endings and comments ------------------------------------------------------
printf 'ply\nformat ascii 1.0\ncomment lf\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n1 1 1\n' >"$IN/lf.ply"
printf 'ply\r\nformat ascii 1.0\rcomment crlf and cr\r\nelement vertex 4\nproperty float x\rproperty float y\r\nproperty float z\nend_header\r0 0 0\r\n1 0 0\r0 1 0\n1 1 1\r' >"$IN/mixed.ply"
printf 'ply\rformat ascii 1.0\rcomment cr only\relement vertex 4\rproperty float x\rproperty float y\rproperty float z\rend_header\r0 0 0\r1 0 0\r0 1 0\r1 1 1\r' >"$IN/cr.ply"
printf '# comment\r\n// another\r0 0 0\r\n1 0 0\n\n0,1,0\r1;1;1\r' >"$IN/mixed.xyz"
printf 'OFF\r# comment\r\n4 1 0\r0 0 0\n1 0 0\r\n0 1 0\r1 1 1\r3 0 1 2\r\n' >"$IN/mixed.off"
expect 0 "LF" -- "$BSURF" info "$IN/lf.ply" --json
sed 's/"input":"[^"]*",//; s/"seconds":[^,}]*//' "$T/out" >"$T/lf.json"
for f in mixed.ply cr.ply mixed.xyz mixed.off; do
  expect 0 "line endings $f" -- "$BSURF" info "$IN/$f" --json
  sed 's/"input":"[^"]*",//; s/"seconds":[^,}]*//; s/"faces":1/"faces":0/' "$T/out" >"$T/this.json"
  cmp -s "$T/lf.json" "$T/this.json" && ok || fail "$f does not read like the LF file: $(cat "$T/this.json")"
done
printf 'ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\r1 0\r\n' >"$IN/cr_short.ply"
bad 1 "CR lines are counted" "$IN/cr_short.ply:9:" "vertex 1: expected 3 values, found 2" -- "$BSURF" info "$IN/cr_short.ply"

# ---- NaN and infinity: rejected naming the point, or dropped ---------------------------
{ ply_head ascii 6; printf '0 0 0\n1 0 0\n0 1 0\nnan 1 1\n1 1 0\n0 0 inf\n'; } >"$IN/nan.ply"
printf '0 0 0\n1 0 0\n0 1 -Infinity\n' >"$IN/inf.xyz"
bad 1 "NaN coordinate" "$IN/nan.ply: point 3 (0-based)" "--drop-invalid" -- "$BSURF" "${ERR[@]}" "$IN/nan.ply" -o "$OUT"
bad 1 "infinite coordinate" "$IN/inf.xyz: point 2 (0-based)" -- "$BSURF" info "$IN/inf.xyz"
for c in info noise error normals smooth features sample eval render histogram compare; do
  "$BSURF" help $c | grep -q -- "--drop-invalid" && ok || fail "$c has no --drop-invalid"
done
expect 0 "info --drop-invalid" -- "$BSURF" info "$IN/nan.ply" --drop-invalid --json
grep -qF '"points":4' "$T/out" && grep -qF '"dropped_invalid":2' "$T/out" && ok || fail "info --drop-invalid json: $(cat "$T/out")"
stderr_has "dropped 2 point(s) with a NaN or infinite coordinate or normal (the first: point 3" "drop warning"
expect 0 "info --drop-invalid text" -- "$BSURF" info "$IN/nan.ply" --drop-invalid
grep -qF "2 input points with a NaN or infinite coordinate or normal were dropped" "$T/out" && ok || fail "info text lacks the dropped count"
# a NaN normal in a binary file, through error; the rest of the cloud is processed
"$BSURF" generate plane -n 400 -o "$T/p.ply" --ascii -q
awk 'done || !/^end_header/ {print; next} {print; getline; $4 = "nan"; print; done = 1}' "$T/p.ply" >"$IN/nan_normal.ply"
bad 1 "NaN normal" "$IN/nan_normal.ply: point 0 (0-based)" -- "$BSURF" "${ERR[@]}" "$IN/nan_normal.ply" -o "$OUT"
expect 0 "error --drop-invalid" -- "$BSURF" "${ERR[@]}" "$IN/nan_normal.ply" --drop-invalid -o "$OUT" --json
grep -qF '"points":399' "$T/out" && grep -qF '"dropped_invalid":1' "$T/out" && ok || fail "error --drop-invalid json"
expect 0 "error --drop-invalid text" -- "$BSURF" "${ERR[@]}" "$IN/nan_normal.ply" --drop-invalid -o "$OUT"
grep -qF "1 input points with a NaN" "$T/out" && ok || fail "error text lacks the dropped count"
rm -f "$OUT"
# a mesh: faces using a dropped vertex go too
printf 'OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\nnan 0 0\n1 1 0\n3 0 1 2\n3 1 3 2\n3 1 4 2\n' >"$IN/nan.off"
expect 0 "mesh --drop-invalid" -- "$BSURF" info "$IN/nan.off" --drop-invalid --json
grep -qF '"points":4,"faces":2' "$T/out" && ok || fail "faces of a dropped vertex kept: $(cat "$T/out")"

# ---- degenerate neighbourhoods: defined outputs, counted, never NaN ---------------------
awk 'BEGIN { for (i = 0; i < 120; i++) print "1 2 3" }' >"$IN/same.xyz"
awk 'BEGIN { for (i = 0; i < 120; i++) print i * 0.01, i * 0.02, i * 0.03 }' >"$IN/line.xyz"
awk 'BEGIN { for (i = 0; i < 144; i++) print (i % 12) * 0.1, int(i / 12) * 0.1, 0.5 }' >"$IN/plane.xyz"
awk '/^end_header/ {h = 1; next} h && NF {print $1, $2, $3; print $1, $2, $3}' "$T/p.ply" >"$IN/dup.xyz"
runs=("error -k 12 -d 2 -B 4" "normals -k 12 -B 4" "smooth -k 12 -d 2 -B 4" "smooth --method multipass -k 12 -d 1 --k-min 6 -B 4"
  "smooth --method naive -k 12 -d 2 -B 4" "features --method distance -k 12 --k-min 6 --k-max 12" "features --method variance -k 12 -B 4")
for f in same line plane dup; do
  for r in "${runs[@]}"; do
    # shellcheck disable=SC2086
    expect 0 "$f: $r" -- "$BSURF" $r "$IN/$f.xyz" -o "$T/deg.ply" --ascii --json
    no_nan "$T/deg.ply" "$f: $r"
    grep -q -i -E 'nan|inf' "$T/out" && fail "$f: $r: NaN in the summary" || ok
  done
done
"$BSURF" error -k 12 -d 2 -B 4 "$IN/same.xyz" -o "$T/deg.ply" --json >"$T/out"
grep -qF '"duplicate_points":120' "$T/out" && grep -qF '"degree_reduced":120' "$T/out" && grep -qF '"mean_h":{"err_train":null' "$T/out" &&
  ok || fail "identical points counted: $(cat "$T/out")"
"$BSURF" error -k 12 -d 2 -B 4 "$IN/same.xyz" -o "$T/deg.ply" >"$T/out"
grep -q "120 points coincide with another point" "$T/out" && grep -q "120 points had degenerate neighbourhoods" "$T/out" &&
  ! grep -q -i nan "$T/out" && ok || fail "identical points, text summary: $(cat "$T/out")"
"$BSURF" normals -k 12 -B 4 "$IN/line.xyz" -o "$T/deg.ply" --json >"$T/out"
grep -qF '"degenerate":120' "$T/out" && grep -qF '"duplicate_points":0' "$T/out" && ok || fail "collinear points counted: $(cat "$T/out")"
"$BSURF" error -k 12 -d 2 -B 4 "$IN/dup.xyz" -o "$T/deg.ply" --json >"$T/out"
grep -qF '"duplicate_points":800' "$T/out" && ok || fail "duplicates counted: $(cat "$T/out")"
"$BSURF" error -k 12 -d 2 -B 4 "$IN/plane.xyz" -o "$T/deg.ply" --json >"$T/out"
grep -qF '"degree_reduced":0' "$T/out" && grep -qF '"duplicate_points":0' "$T/out" && ok || fail "a plane is not degenerate"

# ---- K and the degree ---------------------------------------------------------------
printf '0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 0\n' >"$IN/tiny.xyz"
bad 1 "fewer points than K" "$IN/tiny.xyz: has 5 points, fewer than K = 20" -- "$BSURF" "${ERR[@]}" "$IN/tiny.xyz" -o "$OUT"
bad 1 "fewer points than K (normals)" "$IN/tiny.xyz: has 5 points, fewer than K = 30" -- "$BSURF" normals "$IN/tiny.xyz" -k 30 -o "$OUT"
bad 1 "fewer points than k-max (features)" "$IN/tiny.xyz: has 5 points" -- "$BSURF" features "$IN/tiny.xyz" --method distance -o "$OUT"
bad 2 "K too small for the degree" "K = 9 is too small for degree 3" -- "$BSURF" error -k 9 -d 3 "$IN/n.ply" -o "$OUT"
bad 2 "K too small for the degree (smooth)" "too small for degree 4" -- "$BSURF" smooth -k 14 -d 4 "$IN/n.ply" -o "$OUT"
bad 2 "K too small for the degree (normals)" "K = 5 is too small for degree 2" -- "$BSURF" normals --fit poly -k 5 -d 2 "$IN/n.ply" -o "$OUT"

# ---- where the output goes ------------------------------------------------------------
bad 1 "missing output directory" "$T/nodir/x.ply: cannot write in directory '$T/nodir'" -- "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$T/nodir/x.ply"
bad 1 "output directory is a file" "$IN/n.ply/x.ply: cannot write in directory" -- "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$IN/n.ply/x.ply"
mkdir -p "$T/dir.ply"
bad 1 "output is a directory" "$T/dir.ply: is a directory" -- "$BSURF" generate sphere -n 100 -o "$T/dir.ply"
if [ "$(id -u)" != 0 ]; then
  mkdir -p "$T/ro" && chmod 555 "$T/ro"
  bad 1 "read-only directory" "cannot write in directory '$T/ro'" -- "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$T/ro/x.ply"
  chmod 755 "$T/ro"
else
  echo "note: running as root, the read-only directory case is skipped (root may write anywhere)"
fi
bad 1 "output is the input" "$IN/n.ply: the output is the input file; refusing to overwrite it (use --force)" -- \
  "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$IN/n.ply"
ln -sf n.ply "$IN/link.ply"
bad 1 "output is a link to the input" "refusing to overwrite" -- "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$IN/link.ply"
bad 1 "output is the test sample" "refusing to overwrite" -- "$BSURF" "${ERR[@]}" "$IN/n.ply" --test-sample "$IN/s.ply" -o "$IN/s.ply"
bad 1 "output is the truth" "refusing to overwrite" -- "$BSURF" normals "$IN/n.ply" --select-k 10:12:2 --curve "$T/c.csv" --truth "$IN/s.ply" -o "$IN/s.ply"
cp "$IN/n.ply" "$IN/cloud.png" # a PLY file named .png: read by its content
bad 1 "png output is the input" "refusing to overwrite" -- "$BSURF" render "$IN/cloud.png" -o "$IN/cloud.png"
for c in render histogram compare; do
  args=("$IN/n.ply")
  [ $c = histogram ] && args+=(--field err)
  [ $c = compare ] && args+=("$IN/n.ply")
  bad 2 "$c -o with another type's extension" "-o $T/img.ply: the output is a PNG image: name it .png" -- \
    "$BSURF" $c "${args[@]}" -o "$T/img.ply"
  [ ! -e "$T/img.ply" ] && ok || fail "$c wrote PNG bytes into $T/img.ply"
done
bad 1 "unknown output type" "$T/x.dat: unknown output file type" -- "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$T/x.dat"
mkdir -p "$T/outdir"
bad 1 "output is a directory without an extension" "$T/outdir: is a directory" -- "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$T/outdir"
cp "$IN/n.ply" "$T/inplace.ply"
expect 0 "--force writes over the input" -- "$BSURF" "${ERR[@]}" "$T/inplace.ply" -o "$T/inplace.ply" --force -q
grep -a -q "property float err_632plus" "$T/inplace.ply" && ok || fail "--force: the input was not replaced"
expect 0 "--force result reads" -- "$BSURF" info "$T/inplace.ply"
rm -f "$T/inplace.ply"
no_temporaries "--force"

# ---- failed writes: a full disk (RLIMIT_FSIZE; SIGXFSZ ignored so write() fails) -----
printf 'old contents\n' >"$T/keep.ply"
full() { (trap '' XFSZ; ulimit -f 64; exec "$@"); }
bad 1 "file size limit (error)" "$OUT: write failed: File too large" -- full "$BSURF" "${ERR[@]}" "$IN/n.ply" -o "$OUT" --ascii
bad 1 "file size limit (generate)" "$OUT: write failed" -- full "$BSURF" generate sphere -n 20000 -o "$OUT"
bad 1 "file size limit (xyz)" "$T/out.xyz: write failed" -- full "$BSURF" noise "$IN/s.ply" -o "$T/out.xyz"
bad 1 "file size limit (png)" "$T/out.png: write failed" -- full "$BSURF" render "$IN/n.ply" --size 2000x2000 -o "$T/out.png"
[ -e "$T/out.xyz" ] || [ -e "$T/out.png" ] && fail "partial xyz or png written" || ok
bad 1 "failed write keeps the old file" "$T/keep.ply: write failed" -- full "$BSURF" generate sphere -n 20000 -o "$T/keep.ply"
[ "$(cat "$T/keep.ply")" = "old contents" ] && ok || fail "a failed write changed the existing output"
if [ -w /dev/full ]; then
  bad 1 "stdout is /dev/full" "standard output" -- sh -c '"$0" info "$1" >/dev/full' "$BSURF" "$IN/n.ply"
fi

# ---- SIGINT / SIGTERM during a long run -----------------------------------------------
expect 0 "big cloud" -- "$BSURF" generate sphere -n 40000 -o "$IN/big.ply" -q
for sig in INT TERM; do
  before=$(checksums)
  printf 'old contents\n' >"$T/keep.ply"
  "$BSURF" error "$IN/big.ply" -k 50 -B 100 -j 1 -o "$T/keep.ply" -q 2>"$T/err" &
  pid=$!
  sleep 1
  kill -"$sig" "$pid"
  wait "$pid"
  rc=$?
  want=130
  [ "$sig" = TERM ] && want=143
  [ "$rc" -eq "$want" ] && ok || fail "SIG$sig: exit $rc, expected $want"
  stderr_has "interrupted" "SIG$sig says interrupted"
  [ "$(cat "$T/keep.ply")" = "old contents" ] && ok || fail "SIG$sig: the existing output changed"
  no_temporaries "SIG$sig"
  [ "$(checksums)" = "$before" ] && ok || fail "SIG$sig: an input file changed"
done
rm -f "$T/keep.ply"

# ---- determinism: -j 1 = -j 2 = a second run, for every command that draws random numbers
same3() { # same3 DESCRIPTION FILE1 FILE2 FILE3
  cmp -s "$2" "$3" && ok || fail "$1: -j 1 and -j 2 differ"
  cmp -s "$2" "$4" && ok || fail "$1: two runs differ"
}
for k in 1 2 2b; do
  j=${k%b}
  expect 0 "generate random" -- "$BSURF" generate torus --sampling random -n 3000 --seed 5 -o "$T/d.gen.$k.ply" -q
  expect 0 "noise -j$j" -- "$BSURF" noise "$T/d.gen.$k.ply" --level 1 -j "$j" -o "$T/d.noise.$k.ply" -q
  expect 0 "noise uniform -j$j" -- "$BSURF" noise "$T/d.gen.$k.ply" --model uniform -j "$j" -o "$T/d.unoise.$k.ply" -q
  expect 0 "error -j$j" -- "$BSURF" error "$T/d.noise.$k.ply" -k 20 -B 8 -j "$j" -o "$T/d.error.$k.ply" -q
  expect 0 "normals -j$j" -- "$BSURF" normals "$T/d.noise.$k.ply" -k 20 -B 8 --test-error -j "$j" -o "$T/d.normals.$k.ply" -q
  expect 0 "smooth -j$j" -- "$BSURF" smooth "$T/d.noise.$k.ply" -k 20 -B 8 -j "$j" -o "$T/d.smooth.$k.ply" -q
  expect 0 "features variance -j$j" -- "$BSURF" features "$T/d.noise.$k.ply" --method variance -k 20 -B 8 -j "$j" -o "$T/d.feat.$k.ply" -q
done
printf 'OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n' >"$IN/tet.off"
for k in 1 2 2b; do
  expect 0 "sample -n" -- "$BSURF" sample "$IN/tet.off" -n 2000 -j "${k%b}" -o "$T/d.sample.$k.ply" -q
done
for what in gen noise unoise error normals smooth feat sample; do
  same3 "$what" "$T/d.$what.1.ply" "$T/d.$what.2.ply" "$T/d.$what.2b.ply"
done
cmp -s "$T/d.gen.1.ply" "$T/d.gen.2.ply" && ok || fail "generate random differs between runs"

# ---- PCD and LAS (docs/robustness.md, docs/formats.md) -------------------------
# every case through convert: exit 1, one message naming the file and the
# line or byte, nothing written
pcd_head() { # pcd_head FIELDS SIZE TYPE COUNT POINTS DATA
  printf 'VERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %s\nHEIGHT 1\nPOINTS %s\nDATA %s\n' \
    "$1" "$2" "$3" "$4" "$5" "$5" "$6"
}
pcd_head "x y z" "4 4 4" "F F F" "1 1 1" 2 ascii >"$IN/good.pcd"
printf '1 2 3\n4 5 6\n' >>"$IN/good.pcd"
expect 0 "good pcd" -- "$BSURF" convert "$IN/good.pcd" "$T/good_pcd.csv" -q
# bad_convert FILE DESCRIPTION PLACE MESSAGE: FILE (in $IN) through convert:
# one message with "$IN/FILE" + PLACE and MESSAGE
bad_convert() { bad 1 "$2" "$IN/$1$3" "$4" -- "$BSURF" convert "$IN/$1" "$OUT" </dev/null; }
printf 'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n' >"$IN/p_trunc.pcd"
bad_convert p_trunc.pcd "pcd truncated header" ":3:" "without a DATA line"
{ pcd_head "x y z" "4 4 4" "F F F" "1 1 1" 100 binary; head -c 240 /dev/zero; } >"$IN/p_count.pcd"
bad_convert p_count.pcd "pcd points beyond the file" ": byte" "POINTS 100 needs 1200 bytes"
printf 'VERSION 0.7\nFIELDS x y z\nCOLOUR red\n' >"$IN/p_kw.pcd"
bad_convert p_kw.pcd "pcd unknown keyword" ":3:" "unknown keyword 'COLOUR'"
# a header (pcd_head's arguments) and data (printf's format) per case
while IFS='|' read -r name fields size type count points data body what place message; do
  { pcd_head "$fields" "$size" "$type" "$count" "$points" "$data"; printf "$body"; } >"$IN/$name"
  bad_convert "$name" "$what" "$place" "$message"
done <<'CASES'
p_count0.pcd|x y z|4 4 4|F F F|1 0 1|1|ascii|1 2 3\n|pcd COUNT 0|:5:|COUNT '0' of field 2
p_data.pcd|x y z|4 4 4|F F F|1 1 1|1|zipped|1 2 3\n|pcd bad DATA kind|:9:|unknown DATA kind 'zipped'
p_sizetype.pcd|x y z|4 2 4|F F F|1 1 1|1|ascii|1 2 3\n|pcd SIZE/TYPE mismatch|:9:|TYPE F needs SIZE 4 or 8
p_sizes.pcd|x y z|4 4|F F F|1 1 1|1|ascii|1 2 3\n|pcd SIZE entries|:3:|SIZE has 2 entries for 3 FIELDS
p_noz.pcd|x y|4 4|F F|1 1|1|ascii|1 2\n|pcd without z|:|needs one each of the fields x, y and z
p_short.pcd|x y z|4 4 4|F F F|1 1 1|3|ascii|1 2 3\n4 5 6\n|pcd ascii points missing|:12:|POINTS 3 but the data end after 2 points
p_range.pcd|x y z|1 1 1|U U U|1 1 1|1|ascii|1 2 300\n|pcd value out of its type|:10:|'300' is not a U1 integer
p_lzf.pcd|x y z|4 4 4|F F F|1 1 1|1|binary_compressed|\005\000\000\000\014\000\000\000\001\001\001\001\001|pcd corrupt LZF|: byte|corrupt LZF data
CASES

# LAS: a good file written by bootsurf (1.4, format 6, extra bytes), then
# one byte or length changed at a time
expect 0 "good las" -- "$BSURF" convert "$IN/good.pcd" "$IN/good.las" -q
las_patch() { # las_patch NAME OFFSET BYTES(printf): a copy of good.las with bytes replaced
  cp "$IN/good.las" "$IN/$1"
  printf "$3" | dd of="$IN/$1" bs=1 seek="$2" conv=notrunc status=none
}
head -c 120 "$IN/good.las" >"$IN/l_trunc.las"
bad_convert l_trunc.las "las truncated header" ": byte 120:" "truncated header"
# las_cases: a copy of good.las with bytes replaced (printf's format) per case
las_cases() {
  while IFS='|' read -r name offset bytes what place message; do
    las_patch "$name" "$offset" "$bytes"
    bad_convert "$name" "$what" "$place" "$message"
  done
}
las_cases <<'CASES'
l_fmt.las|104|\014|las unknown point format|: byte 104:|unknown point data record format 12
l_laz.laz|104|\206|las LAZ|: byte 104:|LAZ (compressed LAS) is not supported
l_count.las|247|\377\377|las point count beyond the file|: byte|point count beyond the file
l_version.las|25|\007|las version|: byte 24:|LAS version 1.7 is not supported
l_record.las|105|\020\000|las short records|: byte 105:|less than point format 6's 30 bytes
l_scale.las|131|\000\000\000\000\000\000\000\000|las zero scale|: byte 131:|x scale factor or offset is zero
l_offset.las|96|\377\377\000\000|las point offset beyond the file|: byte 96:|beyond the end of the file
l_hsize.las|94|\100\000|las header size|: byte 94:|header size 64 is less than
CASES
# a cloud with a field: the extra bytes VLR right after the 375-byte header
printf 'x y z w\n1 2 3 0.5\n4 5 6 0.25\n' >"$IN/w.txt"
expect 0 "las with extra bytes" -- "$BSURF" convert "$IN/w.txt" "$IN/good.las" -q
las_cases <<'CASES'
l_vlr.las|395|\377\377|las wrong VLR length|: byte 395:|wrong VLR length
l_eb.las|395|\277\000|las extra bytes length|: byte 429:|not a multiple of 192
l_ebtype.las|431|\077|las extra bytes type|: byte 431:|unknown data type 63
CASES

finish
