#!/usr/bin/env bash
# eval: position error against the true surface -- the generated shape (kept
# in the PLY header), a mesh (--surface), the tangent planes of the truth --
# by index or nearest-point correspondence; JSON keys, text, errors.
. "$(dirname "$0")/common.inc"

# checks: one python run for a block of lines "DESCRIPTION :: EXPRESSION" read
# from stdin; J('name') is the JSON object of $T/name.json, P('name') its
# "position" (one process per block keeps the test fast on a busy machine)
checks() {
  local line done=0
  while IFS= read -r line; do
    case $line in ok) ok ;; done) done=1 ;; *) fail "$line" ;; esac
  done < <(python3 -c '
import json, os, sys
T = sys.argv[1]
cache = {}
def J(name):
    if name not in cache:
        cache[name] = json.load(open(os.path.join(T, name + ".json")))
    return cache[name]
def P(name):
    return J(name)["position"]
for line in sys.stdin.read().splitlines():
    if "::" not in line:
        continue
    what, expr = (x.strip() for x in line.split("::", 1))
    try:
        good = bool(eval(expr))
    except Exception as e:
        good, what = False, "%s (%s: %s)" % (what, type(e).__name__, e)
    print("ok" if good else "%s: %s" % (what, expr))
print("done")
' "$T")
  [ "$done" = 1 ] || fail "checks: python did not finish"
}
# keep: saves the last command's stdout as $T/NAME.json
keep() { cp "$T/out" "$T/$1.json"; }

# the cube [-1,1]^3 as 12 triangles (the reader's polygons are tested elsewhere)
{
  echo "OFF"
  echo "8 12 0"
  for z in -1 1; do for y in -1 1; do for x in -1 1; do echo "$x $y $z"; done; done; done
  # vertex v = x + 2y + 4z with 0/1 for -1/+1; two triangles per side
  for t in "0 2 3" "0 3 1" "4 5 7" "4 7 6" "0 1 5" "0 5 4" "2 6 7" "2 7 3" "0 4 6" "0 6 2" "1 3 7" "1 7 5"; do
    echo "3 $t"
  done
} >"$T/cube.off"

"$BSURF" eval --help | grep -q -- "--surface MESH" && ok || fail "eval --help shows --surface"
"$BSURF" eval --help | grep -q "tangent plane" && ok || fail "eval --help explains the surfaces"

# generate records the shape; noise keeps it (binary and ascii PLY)
expect 0 "generate cube" -- "$BSURF" generate cube -n 6000 -o "$T/cube.ply" -q
grep -a -q "^comment bootsurf shape cube$" "$T/cube.ply" && ok || fail "generate writes the shape comment"
for lv in 0 0.5 1; do
  expect 0 "noise $lv" -- "$BSURF" noise "$T/cube.ply" --level $lv -o "$T/n$lv.ply" -q
done
grep -a -q "^comment bootsurf shape cube$" "$T/n0.5.ply" && ok || fail "noise keeps the shape comment"
expect 0 "noise ascii" -- "$BSURF" noise "$T/cube.ply" --level 0 --ascii -o "$T/ascii.ply" -q
grep -q "^comment bootsurf shape cube$" "$T/ascii.ply" && ok || fail "ascii PLY keeps the shape comment"

# 1. the generated shape
for lv in 0 0.5 1; do
  expect 0 "eval shape $lv" -- "$BSURF" eval "$T/n$lv.ply" --truth "$T/cube.ply" --json
  keep shape$lv
done
checks <<'END'
position json keys :: sorted(P('shape0.5')) == sorted(['surface', 'source', 'correspondence', 'h', 'mean', 'rms', 'max', 'mean_h', 'rms_h', 'max_h', 'feature', 'non_feature'])
feature keys :: sorted(P('shape0.5')['feature']) == sorted(['points', 'mean', 'rms', 'max', 'mean_h', 'rms_h', 'max_h'])
non-feature keys :: sorted(P('shape0.5')['non_feature']) == sorted(P('shape0.5')['feature'])
surface is the shape :: P('shape0.5')['surface'] == 'shape' and P('shape0.5')['source'] == 'cube'
same counts: by index :: P('shape0.5')['correspondence'] == 'index'
feature + non-feature = all points :: P('shape0.5')['feature']['points'] + P('shape0.5')['non_feature']['points'] == J('shape0.5')['points']
the cube has feature points :: P('shape0.5')['feature']['points'] > 0
h is the truth's spacing :: 0.05 < P('shape0.5')['h'] < 0.07
mean_h = mean / h :: abs(P('shape0.5')['mean_h'] * P('shape0.5')['h'] - P('shape0.5')['mean']) < 1e-9
noise 0.5 h: rms about 0.5 h :: 0.4 < P('shape0.5')['rms_h'] < 0.6
truth passed along (true_*) is not scored :: 'normals' not in J('shape0.5') and 'features' not in J('shape0.5')
zero noise: zero position error (shape) :: P('shape0')['max'] < 1e-12
more noise, more error (shape) :: P('shape1')['mean'] > 1.5 * P('shape0.5')['mean']
END
expect 0 "eval shape text" -- "$BSURF" eval "$T/n0.5.ply" --truth "$T/cube.ply"
grep -q "position error: surface shape (cube), correspondence index, h = " "$T/out" && ok ||
  fail "text names surface and correspondence"
grep -q "all non-feature" "$T/out" && grep -q "mean/h" "$T/out" && ok || fail "text has the feature rows"

# 2. a mesh via --surface: the same cube, the same distances
for lv in 0 0.5 1; do
  expect 0 "eval mesh $lv" -- "$BSURF" eval "$T/n$lv.ply" --truth "$T/cube.ply" --surface "$T/cube.off" --json
  keep mesh$lv
done
# threads never change the numbers
expect 0 "eval mesh -j1" -- "$BSURF" eval "$T/n0.5.ply" --truth "$T/cube.ply" --surface "$T/cube.off" -j 1 --json
keep j1
expect 0 "eval mesh -j2" -- "$BSURF" eval "$T/n0.5.ply" --truth "$T/cube.ply" --surface "$T/cube.off" -j 2 --json
keep j2
# a truth with faces is its own surface
expect 0 "eval mesh truth" -- "$BSURF" eval "$T/cube.off" --truth "$T/cube.off" --json
keep meshtruth
checks <<'END'
surface is the mesh :: P('mesh0.5')['surface'] == 'mesh' and P('mesh0.5')['source'].endswith('cube.off')
zero noise: zero position error (mesh) :: P('mesh0')['max'] < 1e-12
mesh cube = shape cube :: all(abs(P('mesh0.5')[k] - P('shape0.5')[k]) < 1e-12 for k in ('mean', 'rms', 'max'))
mesh cube = shape cube, feature split :: all(abs(P('mesh0.5')[p][k] - P('shape0.5')[p][k]) < 1e-12 for p in ('feature', 'non_feature') for k in ('mean', 'max'))
more noise, more error (mesh) :: P('mesh1')['mean'] > 1.5 * P('mesh0.5')['mean']
-j 1 and -j 2 agree :: P('j1') == P('j2') and J('j1')['threads'] == 1 and J('j2')['threads'] == 2
truth's faces :: P('meshtruth')['surface'] == 'mesh' and P('meshtruth')['max'] == 0
END

# 3. tangent planes: a truth with normals but no shape (the comment removed)
grep -v "^comment bootsurf shape" "$T/ascii.ply" >"$T/plain.ply"
for lv in 0 0.5 1; do
  expect 0 "eval plane $lv" -- "$BSURF" eval "$T/n$lv.ply" --truth "$T/plain.ply" --json
  keep plane$lv
done
# noise moves points along the normals: the plane distance is |t| h, the
# shape distance the same or less near the edges
checks <<'END'
surface is the tangent plane :: P('plane0.5')['surface'] == 'tangent_plane'
zero noise: zero position error (plane) :: P('plane0')['max'] < 1e-12
tangent plane close to the shape distance :: 0 <= P('plane0.5')['mean'] - P('shape0.5')['mean'] < 1e-3
more noise, more error (plane) :: P('plane1')['mean'] > 1.5 * P('plane0.5')['mean']
END

# 4. different point counts: nearest truth point; normals and features need index
expect 0 "generate other" -- "$BSURF" generate cube -n 3000 --sampling random --seed 7 -o "$T/other.ply" -q
expect 0 "noise other" -- "$BSURF" noise "$T/other.ply" --level 0.5 -o "$T/other_n.ply" -q
expect 0 "eval nearest plane" -- "$BSURF" eval "$T/other_n.ply" --truth "$T/plain.ply" --json
keep near
expect 0 "eval nearest text" -- "$BSURF" eval "$T/other_n.ply" --truth "$T/plain.ply"
grep -q "correspondence nearest" "$T/out" && ok || fail "text says nearest"
grep -q "normals: not evaluated: .* has 3000 points but" "$T/out" && ok || fail "text says why normals are left out"
expect 0 "eval nearest shape" -- "$BSURF" eval "$T/other_n.ply" --truth "$T/cube.ply" --json
keep nearshape
expect 0 "noise xyz" -- "$BSURF" noise "$T/cube.ply" --level 0 -o "$T/cube.xyz" -q
expect 0 "eval mesh no labels" -- "$BSURF" eval "$T/other_n.ply" --truth "$T/cube.xyz" --surface "$T/cube.off" --json
keep nolabels
# --split by a field of the truth through the correspondence
expect 0 "eval split nearest" -- "$BSURF" eval "$T/other_n.ply" --truth "$T/plain.ply" --split feature_dist:0.85 --json
keep split
checks <<'END'
nearest correspondence :: P('near')['correspondence'] == 'nearest' and P('near')['surface'] == 'tangent_plane'
normals and features left out :: J('near')['points'] == 3000 and J('near')['truth_points'] != 3000 and 'normals' not in J('near') and 'features' not in J('near')
nearest tangent plane: error of the order of the noise :: 0 < P('near')['mean_h'] < 1
shape with feature labels: nearest :: P('nearshape')['surface'] == 'shape' and P('nearshape')['correspondence'] == 'nearest'
mesh without labels and other counts: no correspondence :: P('nolabels')['correspondence'] == 'none' and 'feature' not in P('nolabels')
split groups :: J('split')['split']['high']['points'] + J('split')['split']['low']['points'] == 3000
split groups have position :: 'mean' in J('split')['split']['high']['position'] and 'feature' in J('split')['split']['low']['position']
END

# errors
expect 1 "surface without faces" -- "$BSURF" eval "$T/n0.5.ply" --truth "$T/cube.ply" --surface "$T/cube.xyz"
stderr_has "has no faces" "surface without faces"
expect 1 "surface missing" -- "$BSURF" eval "$T/n0.5.ply" --truth "$T/cube.ply" --surface "$T/none.off"
stderr_has "$T/none.off" "missing surface named"
printf '0 0 0\n1 0 0\n0 1 0\n0 0 1\n' >"$T/pts.xyz"
expect 1 "no surface" -- "$BSURF" eval "$T/pts.xyz" --truth "$T/pts.xyz"
stderr_has "no true surface" "no surface explained"
ls -A "$T" | grep -q '\.tmp\.' && fail "temporary files left behind" || ok
finish
