#!/usr/bin/env bash
# A new user's audit (docs/robustness.md): every number a point carries is
# a field to render, count and compare (the coordinates x y z and normals
# nx ny nz as the files name them); the view's ranges are the library's
# (bsurf_render_options_check), in the CLI's and Python's same words.
. "$(dirname "$0")/common.inc"

IN="$T/in"
mkdir -p "$IN"
OUT="$T/bad.png"
expect 0 "generate" -- "$BSURF" generate sphere -n 2000 -o "$IN/s.ply" -q
expect 0 "xyz" -- "$BSURF" convert "$IN/s.ply" "$T/n.xyz" -q
cut -d' ' -f1-3 "$T/n.xyz" >"$IN/s.xyz" # without normals

# ---- render / histogram / compare --field x y z nx ny nz ----
for f in x y z nx ny nz; do
  expect 0 "render --field $f" -- "$BSURF" render "$IN/s.ply" --field "$f" --range -1:1 -o "$T/$f.png" --json
  grep -q "\"field\":\"$f\"" "$T/out" && ok || fail "render --field $f: json $(head -c 200 "$T/out")"
done
cmp -s "$T/nx.png" "$T/ny.png" && fail "render --field nx and ny: the same image" || ok
expect 0 "render shaded" -- "$BSURF" render "$IN/s.ply" -o "$T/shade.png" -q
cmp -s "$T/nx.png" "$T/shade.png" && fail "render --field nx: the shaded image" || ok
# the values are the normals': on the unit sphere nx = x, the same range
expect 0 "render --field nx, range" -- "$BSURF" render "$IN/s.ply" --field nx -o "$T/nx2.png" --json
nxr=$(grep -o '"range":\[[^]]*\]' "$T/out")
expect 0 "render --field x, range" -- "$BSURF" render "$IN/s.ply" --field x -o "$T/x2.png" --json
xr=$(grep -o '"range":\[[^]]*\]' "$T/out")
[ -n "$nxr" ] && [ "$nxr" = "$xr" ] && ok || fail "nx range '$nxr', x range '$xr'"
expect 0 "histogram --field nz" -- "$BSURF" histogram "$IN/s.ply" --field nz -o "$T/h.png" --json
grep -q '"points":2000' "$T/out" && ok || fail "histogram --field nz: $(head -c 200 "$T/out")"
expect 0 "compare --field z" -- "$BSURF" compare "$IN/s.ply" "$IN/s.ply" --field z -o "$T/c.png" -q
# without normals: nx is not offered, x y z are
bad 1 "no normals, --field nx" "no field 'nx'; available fields: x, y, z" -- \
  "$BSURF" render "$IN/s.xyz" --field nx -o "$OUT"
grep -q "nz" "$T/err" && fail "no normals: nz offered" || ok
bad 1 "unknown field" "no field 'nope'; available fields: x, y, z, nx, ny, nz" -- \
  "$BSURF" render "$IN/s.ply" --field nope -o "$OUT"

finish
