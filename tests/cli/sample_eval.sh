#!/usr/bin/env bash
# sample (mesh -> points with ground truth), eval (against ground truth) and
# noise --sigma-diag: outputs, JSON keys, exit codes.
. "$(dirname "$0")/common.inc"

# json_get FILE EXPR: prints the value of a python expression on the JSON object d
json_get() { python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print($2)" "$1"; }

cat >"$T/cube.off" <<'END_OF_MESH'
OFF
# cube [-1,1]^3, quads (fan-triangulated by the reader)
8 6 0
-1 -1 -1
1 -1 -1
1 1 -1
-1 1 -1
-1 -1 1
1 -1 1
1 1 1
-1 1 1
4 0 3 2 1
4 4 5 6 7
4 0 1 5 4
4 3 7 6 2
4 0 4 7 3
4 1 2 6 5
END_OF_MESH

for c in sample eval; do expect 0 "$c --help" -- "$BSURF" $c --help; done
"$BSURF" sample --help | grep -q "sharp-angle DEG.*(default: 30)" && ok || fail "sample --help shows the angle default"
"$BSURF" sample --help | grep -q "feature-width W.*(default: 2)" && ok || fail "sample --help shows the width default"

# vertices (default): 8 points, 12 sharp edges, all on an edge
expect 0 "sample vertices" -- "$BSURF" sample "$T/cube.off" -o "$T/v.ply" --json
for key in '"command":"sample"' '"points":8' '"faces":12' '"sharp_edges":12' '"edges":18' '"boundary_edges":0' \
  '"feature_points":8' '"mode":"vertices"' '"seconds":'; do
  grep -qF "$key" "$T/out" && ok || fail "sample json lacks $key"
done
python3 -c "import json,sys; json.load(open('$T/out'))" 2>/dev/null && ok || fail "sample --json is one JSON object"
grep -a -q "property float feature_dist" "$T/v.ply" && grep -a -q "property uchar feature" "$T/v.ply" && ok ||
  fail "sample writes feature_dist and feature"
grep -a -q "element face" "$T/v.ply" && fail "sample output has faces" || ok

# area sampling: deterministic for any thread count, seed matters
expect 0 "sample -n -j1" -- "$BSURF" sample "$T/cube.off" -n 4000 -j 1 -o "$T/a1.ply" --json
grep -qF '"points":4000' "$T/out" && grep -qF '"mode":"area"' "$T/out" && ok || fail "sample -n json"
expect 0 "sample -n -j2" -- "$BSURF" sample "$T/cube.off" -n 4000 -j 2 -o "$T/a2.ply" -q
cmp -s "$T/a1.ply" "$T/a2.ply" && ok || fail "sample -j 1 and -j 2 differ"
expect 0 "sample other seed" -- "$BSURF" sample "$T/cube.off" -n 4000 --seed 9 -o "$T/a3.ply" -q
cmp -s "$T/a1.ply" "$T/a3.ply" && fail "sample seed has no effect" || ok
expect 0 "sample sharp angle 95" -- "$BSURF" sample "$T/cube.off" --sharp-angle 95 -o "$T/v95.ply" --json
grep -qF '"sharp_edges":0' "$T/out" && grep -qF '"feature_points":0' "$T/out" && ok || fail "no sharp edge above 90 deg"
# the output options of every writing command (--format for -, --float32 for PCL's typed loaders)
"$BSURF" sample "$T/cube.off" -o - --format pcd -q >"$T/v.pcd" && ok || fail "sample -o - --format pcd"
grep -a -q "^FIELDS x y z normal_x normal_y normal_z feature_dist feature" "$T/v.pcd" && ok ||
  fail "sample --format pcd keeps feature_dist and feature"
expect 0 "sample --float32" -- "$BSURF" sample "$T/cube.off" -o "$T/f32.ply" --float32 -q
grep -a -q "property float x" "$T/f32.ply" && ok || fail "sample --float32 writes float coordinates"
expect 0 "sample text" -- "$BSURF" sample "$T/cube.off" -n 100 -o "$T/a4.xyz"
grep -q "12 sharp" "$T/out" && ok || fail "sample text names the sharp edges"
stderr_has "cannot store" "xyz output warns that the fields are lost"

# sample errors
printf '0 0 0\n1 0 0\n0 1 0\n' >"$T/pts.xyz"
expect 1 "sample without faces" -- "$BSURF" sample "$T/pts.xyz" -o "$T/x.ply"
stderr_has "has no faces" "sample without faces"
[ -e "$T/x.ply" ] && fail "sample wrote an output for a bad mesh" || ok
expect 2 "sample --vertices with -n" -- "$BSURF" sample "$T/cube.off" --vertices -n 10 -o "$T/x.ply"
expect 2 "sample without -o" -- "$BSURF" sample "$T/cube.off"
expect 2 "sample bad angle" -- "$BSURF" sample "$T/cube.off" --sharp-angle 200 -o "$T/x.ply"
expect 1 "sample missing mesh" -- "$BSURF" sample "$T/none.off" -o "$T/x.ply"
stderr_has "$T/none.off" "missing mesh is named"

# eval: a cloud against itself -- its normals and labels are the truth's own bits,
# passed along, not results: not scored (the position is: zero)
expect 0 "eval self" -- "$BSURF" eval "$T/a1.ply" --truth "$T/a1.ply" --json
for key in '"command":"eval"' '"points":4000' '"position":{' '"max":0' '"seconds":'; do
  grep -qF "$key" "$T/out" && ok || fail "eval json lacks $key"
done
grep -qF '"normals":{' "$T/out" && fail "eval scored the truth's own normals" || ok
stderr_has "normals are bit-identical to those of $T/a1.ply" "eval self refuses the normals"
grep -qF '"split"' "$T/out" && fail "eval without --split has a split" || ok
python3 -c "import json,sys; json.load(open('$T/out'))" 2>/dev/null && ok || fail "eval --json is one JSON object"

# eval --split on a noisy copy: 15% high
expect 0 "noise sigma-diag" -- "$BSURF" noise "$T/a1.ply" --sigma-diag 0.01 -o "$T/n1.ply" --json
grep -qF '"sigma_diag":0.01' "$T/out" && ok || fail "noise json lacks sigma_diag"
sigma=$(json_get "$T/out" "d['sigma']")
python3 -c "import sys; s=float(sys.argv[1]); sys.exit(0 if abs(s-0.01*2*3**0.5)<1e-3 else 1)" "$sigma" && ok ||
  fail "sigma = 0.01 x diagonal (got $sigma)"
# (noise moves points, not normals; another sample's normals differ from a1's:
# the points do not correspond, but the metric must see the difference)
expect 0 "eval split" -- "$BSURF" eval "$T/a3.ply" --truth "$T/a1.ply" --split feature_dist:0.85 --json
cp "$T/out" "$T/split.json"
for key in '"split":{' '"field":"feature_dist"' '"quantile":0.85' '"threshold":' '"high":{"points":600,"normals":{' \
  '"low":{"points":3400,"normals":{'; do
  grep -qF "$key" "$T/split.json" && ok || fail "eval --split json lacks $key"
done
[ "$(json_get "$T/split.json" "sorted(d['split']['high']['normals'].keys()) == sorted(d['normals'].keys())")" = True ] &&
  ok || fail "split groups have the same keys as normals"
[ "$(json_get "$T/split.json" "d['normals']['mean_rad'] > 0")" = True ] && ok || fail "other normals: mean_rad > 0"
expect 0 "eval split text" -- "$BSURF" eval "$T/a3.ply" --truth "$T/a1.ply" --split feature_dist:0.85
grep -q "high" "$T/out" && grep -q "low" "$T/out" && grep -q "mean rad" "$T/out" && ok || fail "eval text output"

# eval errors
# (different counts: only the position error can compare them, and pts.xyz
# has no normals, faces or shape to give a surface; eval_position.sh tests it)
expect 1 "eval point-count mismatch" -- "$BSURF" eval "$T/a1.ply" --truth "$T/pts.xyz"
stderr_has "$T/a1.ply has 4000 points but $T/pts.xyz" "mismatch names both files"
stderr_has "no true surface" "mismatch: no surface for the position error"
expect 1 "eval result without normals" -- "$BSURF" eval "$T/pts.xyz" --truth "$T/pts.xyz"
stderr_has "no normals" "result without normals"
expect 1 "eval split unknown field" -- "$BSURF" eval "$T/a1.ply" --truth "$T/a1.ply" --split nope:0.85
stderr_has "'nope'" "unknown split field named"
expect 2 "eval bad split" -- "$BSURF" eval "$T/a1.ply" --truth "$T/a1.ply" --split normal_var
expect 2 "eval bad split quantile" -- "$BSURF" eval "$T/a1.ply" --truth "$T/a1.ply" --split normal_var:1.5
expect 2 "eval split not a number" -- "$BSURF" eval "$T/a1.ply" --truth "$T/a1.ply" --split normal_var:abc
expect 2 "eval without --truth" -- "$BSURF" eval "$T/a1.ply"

# noise: --level and --sigma-diag are exclusive; sigma-diag is gaussian
expect 2 "noise level and sigma-diag" -- "$BSURF" noise "$T/a1.ply" --level 0.5 --sigma-diag 0.01 -o "$T/x.ply"
stderr_has "exclusive" "noise exclusive options"
expect 2 "noise sigma-diag uniform" -- "$BSURF" noise "$T/a1.ply" --sigma-diag 0.01 --model uniform -o "$T/x.ply"
expect 0 "noise sigma-diag 0" -- "$BSURF" noise "$T/a1.ply" --sigma-diag 0 -o "$T/n0.ply" -q
expect 0 "eval unmoved" -- "$BSURF" eval "$T/n0.ply" --truth "$T/a1.ply" --json
grep -qF '"max":0' "$T/out" && ! grep -qF '"normals":{' "$T/out" && ok || fail "sigma-diag 0 leaves the points; the truth goes on as true_*"
expect 0 "noise level json has sigma" -- "$BSURF" noise "$T/a1.ply" --level 0.5 -o "$T/n2.ply" --json
grep -qF '"sigma":' "$T/out" && grep -qF '"level":0.5' "$T/out" && ok || fail "noise --level json"
ls -A "$T" | grep -q '\.tmp\.' && fail "temporary files left behind" || ok
finish
