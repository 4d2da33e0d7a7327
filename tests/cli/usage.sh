#!/usr/bin/env bash
# A user's audit (docs/robustness.md): bad usage in the CLI's usage style
# (exit 2, "bootsurf CMD: ..." and "Try 'bootsurf CMD --help'."), before any
# work and without output; numeric options refused where their values mean
# nothing; an empty standard input named as such.
. "$(dirname "$0")/common.inc"

IN="$T/in"
mkdir -p "$IN"
OUT="$T/out.ply"

expect 0 "generate" -- "$BSURF" generate cube -n 600 -o "$IN/c.ply" -q

# usage CMD NEEDLE -- command: exit 2, the usage style with the hint, no output
usage() {
  local cmd=$1 needle=$2
  shift 2
  bad 2 "$cmd: $needle" "bootsurf $cmd: " "$needle" "Try 'bootsurf $cmd --help'." "$@"
}

# ---- output options are usage errors, in the usage style, for every writer ----
usage convert "--format foo: unknown format" -- "$BSURF" convert "$IN/c.ply" "$OUT" --format foo
usage noise "--format tiff: unknown format" -- "$BSURF" noise "$IN/c.ply" --format tiff -o "$OUT"
usage error "--ply-names gray: expected plain" -- "$BSURF" error "$IN/c.ply" -k 20 -d 2 -B 2 --ply-names gray -o "$OUT"
usage smooth "--las-version 1.3: expected 1.2 or 1.4" -- "$BSURF" smooth "$IN/c.ply" --las-version 1.3 -o "$OUT"
grep -q "error:" "$T/err" && fail "--las-version: an error-style line" || ok
# --ascii: LAS has no text form (refused, naming the format, before any work);
# CSV and XYZ are text anyway (accepted, the same bytes as without it)
usage generate "--ascii: LAS is a binary format, it has no text form" -- "$BSURF" generate cube -n 100 --ascii -o "$T/a.las"
[ ! -e "$T/a.las" ] && ok || fail "--ascii .las: a file was written"
usage convert "--ascii: LAS is a binary format" -- "$BSURF" convert "$IN/c.ply" "$T/a.las" --ascii
usage smooth "--ascii: LAS is a binary format" -- "$BSURF" smooth "$IN/c.ply" --ascii --format las -o -
for e in csv xyz; do
  expect 0 "--ascii .$e" -- "$BSURF" convert "$IN/c.ply" "$T/a.$e" --ascii -q
  expect 0 "no --ascii .$e" -- "$BSURF" convert "$IN/c.ply" "$T/b.$e" -q
  cmp -s "$T/a.$e" "$T/b.$e" && ok || fail "--ascii .$e: other bytes"
done

# ---- a missing output, in the same words for every command that needs one ----
for c in normals smooth features noise sample; do
  usage "$c" "missing -o OUTPUT" -- "$BSURF" "$c" "$IN/c.ply"
done

# ---- thresholds and other numbers outside their meaning ----
usage features "--threshold -1: method variance takes a normal_var value, at least 0, or auto" -- \
  "$BSURF" features "$IN/c.ply" --threshold -1 -o "$OUT"
usage features "--threshold 1.5: method distance takes a fraction of max(feature_dist), 0 to 1, or auto" -- \
  "$BSURF" features "$IN/c.ply" --method distance --threshold 1.5 -o "$OUT"
usage features "--threshold -0.1: method distance" -- \
  "$BSURF" features "$IN/c.ply" --method distance --threshold -0.1 -o "$OUT"
usage features "--threshold must be a number or auto, not 'nan'" -- \
  "$BSURF" features "$IN/c.ply" --threshold nan -o "$OUT"
expect 0 "features --threshold 0 (distance)" -- "$BSURF" features "$IN/c.ply" --method distance --threshold 0 -o "$T/f0.ply" -q
expect 0 "features --threshold 0.3 (variance)" -- "$BSURF" features "$IN/c.ply" -k 12 -B 4 --threshold 0.3 -o "$T/f1.ply" -q
usage smooth "option -B needs a whole number (1 to 100000), not '0'" -- "$BSURF" smooth "$IN/c.ply" -B 0 -o "$OUT"
usage smooth "--a must be a positive number or auto, not '0'" -- "$BSURF" smooth "$IN/c.ply" --a 0 -o "$OUT"
usage smooth "--a must be a positive number or auto, not 'nan'" -- "$BSURF" smooth "$IN/c.ply" --a nan -o "$OUT"
# K_i = k_min points carry a plane fit: 3 at least (the library refuses fewer too)
usage smooth "option --k-min needs a whole number (3 to 65535), not '1'" -- "$BSURF" smooth "$IN/c.ply" --k-min 1 -o "$OUT"
usage smooth "option --k-min needs a whole number (3 to 65535), not '2'" -- "$BSURF" smooth "$IN/c.ply" --k-min 2 -o "$OUT"

# ---- an empty standard input is named, as an empty file is ----
bad 1 "empty stdin, info" "-: standard input is empty" -- "$BSURF" info - </dev/null
bad 1 "empty stdin, error" "-: standard input is empty" -- "$BSURF" error - -k 20 -d 2 -B 2 -o "$OUT" </dev/null
bad 1 "empty stdin, convert" "-: standard input is empty" -- "$BSURF" convert - "$OUT" </dev/null
grep -q "fewer than K" "$T/err" && fail "empty stdin: 'fewer than K'" || ok
# a non-empty standard input is read whole (the byte looked at is put back)
"$BSURF" convert - "$T/back.csv" -q <"$IN/c.ply" && "$BSURF" convert "$IN/c.ply" "$T/ref.csv" -q &&
  cmp -s "$T/back.csv" "$T/ref.csv" && ok || fail "standard input: not the file's points"

# ---- a CSV header naming some of x y z elsewhere than the first three columns ----
printf 'i,x,y\n7,1,2\n8,3,4\n' >"$IN/ixy.csv"
bad 1 "csv i,x,y" "$IN/ixy.csv:1: the header names x in column 2 but not all of x, y and z" -- "$BSURF" convert "$IN/ixy.csv" "$OUT"
printf 'x,y,elevation\n1,2,3\n' >"$T/xye.csv" # the first three columns, as named
expect 0 "csv x,y,elevation" -- "$BSURF" convert "$T/xye.csv" "$T/xye_back.csv" -q
[ "$(tail -1 "$T/xye_back.csv")" = "1,2,3" ] && ok || fail "x,y,elevation: $(cat "$T/xye_back.csv")"

# ---- the text summary's words ----
printf '1 2 3\n' >"$T/one.xyz"
expect 0 "info, one point" -- "$BSURF" info "$T/one.xyz"
grep -q "^  h          - (no spacing: fewer than 2 points)$" "$T/out" && ok || fail "info of one point: $(grep ' h ' "$T/out")"
expect 0 "smooth, one pass" -- "$BSURF" smooth "$IN/c.ply" -k 20 -d 2 -B 2 --method multipass --iterations 1 -o "$T/s1.ply"
grep -q ", 1 pass, h1" "$T/out" && ok || fail "smooth --iterations 1: $(grep order "$T/out")"

finish
