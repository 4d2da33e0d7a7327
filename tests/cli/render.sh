#!/usr/bin/env bash
# bootsurf render, histogram and compare through the command line.
. "$(dirname "$0")/common.inc"

png_size() { # prints "W H" of a PNG from its IHDR chunk
  od -An -tu1 -j16 -N8 "$1" | awk '{ print $1*16777216+$2*65536+$3*256+$4, $5*16777216+$6*65536+$7*256+$8 }'
}
is_png() { head -c 8 "$1" | od -An -tx1 | tr -d ' \n' | grep -q '^89504e470d0a1a0a$'; }

for c in render histogram compare; do expect 0 "$c --help" -- "$BSURF" $c --help; done
expect 0 "generate" -- "$BSURF" generate cube -n 4000 -o "$T/c.ply" -q
expect 0 "generate torus" -- "$BSURF" generate torus -n 4000 -o "$T/t.ply" -q

# render: shaded, by a field, 2x2 views, sizes, JSON
expect 0 "render shaded" -- "$BSURF" render "$T/c.ply" -o "$T/a.png" -q
is_png "$T/a.png" && ok || fail "render writes a PNG"
[ "$(png_size "$T/a.png")" = "1024 768" ] && ok || fail "default size 1024x768, got $(png_size "$T/a.png")"
expect 0 "render field" -- "$BSURF" render "$T/c.ply" --field feature_dist --colormap magma --view front --size 640x480 -o "$T/f.png" --json
[ "$(png_size "$T/f.png")" = "640 480" ] && ok || fail "--size 640x480"
for key in '"command":"render"' '"field":"feature_dist"' '"colormap":"magma"' '"range":[' '"width":640' '"height":480' '"seconds":'; do
  grep -qF "$key" "$T/out" && ok || fail "render json lacks $key"
done
expect 0 "render -j1" -- "$BSURF" render "$T/c.ply" --field feature_dist --views 4 --range 0:0.5 -j 1 -o "$T/j1.png" -q
expect 0 "render -j2" -- "$BSURF" render "$T/c.ply" --field feature_dist --views 4 --range 0:0.5 -j 2 -o "$T/j2.png" -q
cmp -s "$T/j1.png" "$T/j2.png" && ok || fail "render -j 1 and -j 2 differ"
expect 0 "render azimuth" -- "$BSURF" render "$T/t.ply" --azimuth 30 --elevation -20 --point-size 3 --square --title torus -o "$T/az.png" -q
expect 0 "render --up y" -- "$BSURF" render "$T/t.ply" --view front --up y -o "$T/up.png" -q
expect 2 "bad --up" -- "$BSURF" render "$T/t.ply" --up w -o "$T/x.png"
expect 0 "render xyz without normals" -- "$BSURF" noise "$T/c.ply" --level 0.3 -o "$T/n.xyz" -q
expect 0 "render depth-shaded" -- "$BSURF" render "$T/n.xyz" -o "$T/xyz.png" -q

# render errors
expect 1 "unknown field" -- "$BSURF" render "$T/c.ply" --field nope -o "$T/x.png"
stderr_has "no field 'nope'" "unknown field named"
stderr_has "feature_dist" "available fields listed"
[ -e "$T/x.png" ] && fail "output written for an unknown field" || ok
expect 2 "bad range" -- "$BSURF" render "$T/c.ply" --field feature_dist --range 2:1 -o "$T/x.png"
expect 2 "bad range text" -- "$BSURF" render "$T/c.ply" --field feature_dist --range abc -o "$T/x.png"
expect 2 "bad size" -- "$BSURF" render "$T/c.ply" --size 100 -o "$T/x.png"
expect 2 "tiny size" -- "$BSURF" render "$T/c.ply" --size 10x10 -o "$T/x.png"
expect 2 "bad view" -- "$BSURF" render "$T/c.ply" --view sideways -o "$T/x.png"
expect 2 "view and azimuth" -- "$BSURF" render "$T/c.ply" --view top --azimuth 10 -o "$T/x.png"
expect 2 "bad colormap" -- "$BSURF" render "$T/c.ply" --colormap jet -o "$T/x.png"
expect 2 "bad views" -- "$BSURF" render "$T/c.ply" --views 2 -o "$T/x.png"
expect 2 "no output" -- "$BSURF" render "$T/c.ply"
expect 1 "missing input" -- "$BSURF" render "$T/none.ply" -o "$T/x.png"
expect 1 "unwritable directory" -- "$BSURF" render "$T/c.ply" -o "$T/nodir/x.png"
[ -e "$T/x.png" ] && fail "an image was left behind by a failed run" || ok

# histogram
expect 0 "histogram" -- "$BSURF" histogram "$T/c.ply" --field feature_dist --bins 30 --threshold 0.2 --log -o "$T/h.png" --json
[ "$(png_size "$T/h.png")" = "800 500" ] && ok || fail "histogram default size"
grep -qF '"above_threshold":' "$T/out" && grep -qF '"command":"histogram"' "$T/out" && ok || fail "histogram json"
expect 0 "histogram size" -- "$BSURF" histogram "$T/c.ply" --field feature_dist --size 400x300 -o "$T/h2.png" -q
[ "$(png_size "$T/h2.png")" = "400 300" ] && ok || fail "histogram --size"
expect 2 "histogram without field" -- "$BSURF" histogram "$T/c.ply" -o "$T/x.png"
expect 1 "histogram unknown field" -- "$BSURF" histogram "$T/c.ply" --field nope -o "$T/x.png"
stderr_has "available fields" "histogram lists fields"
expect 2 "histogram bad bins" -- "$BSURF" histogram "$T/c.ply" --field feature_dist --bins 0 -o "$T/x.png"

# compare
expect 0 "compare" -- "$BSURF" compare "$T/c.ply" "$T/t.ply" --titles "cube,torus" --size 300x300 -o "$T/cmp.png" -q
[ "$(png_size "$T/cmp.png")" = "600 300" ] && ok || fail "compare is two 300x300 panels, got $(png_size "$T/cmp.png")"
expect 0 "compare field" -- "$BSURF" compare "$T/c.ply" "$T/c.ply" --field feature_dist --view front --size 300x300 -o "$T/cmpf.png" --json
grep -qF '"command":"compare"' "$T/out" && grep -qF '"range":[' "$T/out" && ok || fail "compare json"
expect 1 "compare unknown field" -- "$BSURF" compare "$T/c.ply" "$T/t.ply" --field feature_dist -o "$T/x.png"
stderr_has "no field 'feature_dist'" "compare names the missing field"
expect 2 "compare without inputs" -- "$BSURF" compare -o "$T/x.png"
expect 2 "compare bad size" -- "$BSURF" compare "$T/c.ply" --size 0x0 -o "$T/x.png"
finish
