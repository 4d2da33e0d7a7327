#!/usr/bin/env bash
# bootsurf features (thesis chapter 7) and eval's features section.
. "$(dirname "$0")/common.inc"

expect 0 "generate" -- "$BSURF" generate cube -n 6000 --feature-width 1 -o "$T/c.ply" -q
expect 0 "distance -j1" -- "$BSURF" features "$T/c.ply" --method distance -j 1 -o "$T/a.ply" -q
expect 0 "distance -j2" -- "$BSURF" features "$T/c.ply" --method distance -j 2 -o "$T/b.ply" --json
cmp -s "$T/a.ply" "$T/b.ply" && ok || fail "features -j 1 and -j 2 differ"
for key in '"command":"features"' '"points":' '"h":' '"method":"distance"' '"parameters":{' '"k_min":15' \
  '"noise_factor":1.75' '"ratio_threshold_kmin":0.1,' '"threshold_mode":"auto"' '"threshold":0.' \
  '"feature_points":' '"seconds":' \
  '"kept_input_fields":{"feature":"feature_in","feature_dist":"feature_dist_in"}' '"replaced_input_fields":[]'; do
  grep -qF "$key" "$T/out" && ok || fail "features json lacks $key"
done
grep -a -q "property uchar feature$" "$T/a.ply" && ok || fail "feature written"
grep -a -q "property float feature_dist$" "$T/a.ply" && ok || fail "feature_dist written"
# the input's (truth) feature and feature_dist are kept as feature_in and feature_dist_in
grep -a -q "property uchar feature_in$" "$T/a.ply" && ok || fail "the input's feature kept as feature_in"
grep -a -q "property float feature_dist_in$" "$T/a.ply" && ok || fail "the input's feature_dist kept"
expect 0 "features, text: says what it kept" -- "$BSURF" features "$T/c.ply" --method distance -j 2 -o "$T/k.ply"
stderr_has "the input's feature is kept as feature_in" "kept notice"
expect 0 "features on a features output" -- "$BSURF" features "$T/a.ply" --method distance -j 2 -o "$T/a2.ply" --json
grep -qF '"kept_input_fields":{},"replaced_input_fields":["feature","feature_dist"]' "$T/out" && ok ||
  fail "a features output's feature is replaced, feature_in kept"
[ "$(grep -a -c "property uchar feature" "$T/a2.ply")" -eq 2 ] && ok || fail "feature and feature_in once each"
expect 0 "eval of the rerun against the truth" -- "$BSURF" eval "$T/a2.ply" --truth "$T/c.ply" --json
grep -qF '"features":{"precision":' "$T/out" && ok || fail "eval of the rerun"
expect 2 "negative noise factor" -- "$BSURF" features "$T/c.ply" --method distance --noise-factor -1 -o "$T/x.ply"
expect 0 "eval features" -- "$BSURF" eval "$T/a.ply" --truth "$T/c.ply" --json
grep -qF '"features":{"precision":' "$T/out" && ok || fail "eval json has features"
grep -qF '"recall":' "$T/out" && grep -qF '"f1":' "$T/out" && ok || fail "eval json has recall and f1"
# the thesis's T_h = 0 finds the points within 1 spacing of an edge (feature width 1),
# the automatic T_h those within 2 (width 2, generate's default)
expect 0 "thesis rule: fixed T_{a/c}, T_h = 0" -- "$BSURF" features "$T/c.ply" --method distance --noise-factor 0 --threshold 0 -o "$T/z.ply" --json
grep -qF '"threshold":0,' "$T/out" && grep -qF '"noise_factor":0' "$T/out" && ok || fail "thesis rule json"
expect 0 "eval thesis rule" -- "$BSURF" eval "$T/z.ply" --truth "$T/c.ply" --json
f1=$(sed 's/.*"f1":\([0-9.e-]*\).*/\1/' "$T/out")
awk -v f="$f1" 'BEGIN { exit !(f > 0.9) }' && ok || fail "cube edges (width 1), T_h = 0: F1 $f1 <= 0.9"
expect 0 "generate, feature width 2" -- "$BSURF" generate cube -n 6000 -o "$T/c2.ply" -q
expect 0 "distance auto" -- "$BSURF" features "$T/c2.ply" --method distance -o "$T/a3.ply" -q
expect 0 "eval auto" -- "$BSURF" eval "$T/a3.ply" --truth "$T/c2.ply" --json
f1=$(sed 's/.*"f1":\([0-9.e-]*\).*/\1/' "$T/out")
awk -v f="$f1" 'BEGIN { exit !(f > 0.95) }' && ok || fail "cube edges (width 2), auto: F1 $f1 <= 0.95"
expect 0 "eval features text" -- "$BSURF" eval "$T/a.ply" --truth "$T/c.ply"
grep -q "precision" "$T/out" && ok || fail "eval text has the features table"
expect 0 "fixed fraction" -- "$BSURF" features "$T/c.ply" --method distance --threshold 0.3 --derivative 1 --iterations 2 -o "$T/f.ply" -q
expect 0 "noise" -- "$BSURF" noise "$T/c.ply" --level 0.5 --model uniform -o "$T/n.ply" -q
# uniform noise 1.0: the thesis's T_{a/c} = 0.1 would stop every point at k_min; the adapted one is higher
expect 0 "noise 1.0" -- "$BSURF" noise "$T/c2.ply" --level 1.0 --model uniform -o "$T/n1.ply" -q
expect 0 "distance at noise 1.0" -- "$BSURF" features "$T/n1.ply" --method distance -o "$T/d1.ply" --json
tk=$(sed 's/.*"ratio_threshold_kmin":\([0-9.e-]*\).*/\1/' "$T/out")
awk -v t="$tk" 'BEGIN { exit !(t > 0.15) }' && ok || fail "adapted T_{a/c} $tk <= 0.15 at noise 1.0"
expect 0 "eval at noise 1.0" -- "$BSURF" eval "$T/d1.ply" --truth "$T/c2.ply" --json
f1=$(sed 's/.*"f1":\([0-9.e-]*\).*/\1/' "$T/out")
awk -v f="$f1" 'BEGIN { exit !(f > 0.7) }' && ok || fail "noise 1.0 cube edges F1 $f1 <= 0.7"
expect 0 "variance auto" -- "$BSURF" features "$T/n.ply" --method variance -k 20 -B 10 -o "$T/v.ply" --json
grep -qF '"method":"variance"' "$T/out" && grep -qF '"tail_rule":"null"' "$T/out" &&
  grep -qF '"false_positive_rate":0.01' "$T/out" && grep -qF '"variance_filter_k":10' "$T/out" &&
  grep -qF '"noise_level":' "$T/out" && ok || fail "variance json"
grep -a -q "property float variance_z$" "$T/v.ply" && ok || fail "variance_z written (null rule)"
expect 0 "variance otsu" -- "$BSURF" features "$T/n.ply" --method variance -k 20 -B 10 --tail-rule otsu -o "$T/v.ply" --json
grep -qF '"tail_rule":"otsu"' "$T/out" && ok || fail "variance otsu json"
grep -a -q "property float normal_var$" "$T/v.ply" && ok || fail "normal_var written (otsu)"
# the default: variance, null rule, the neighbourhood from the noise (--feature-angle 90)
expect 0 "defaults" -- "$BSURF" features "$T/n.ply" -B 10 -o "$T/v.ply" --json
grep -qF '"method":"variance"' "$T/out" && grep -qF '"feature_angle":90' "$T/out" &&
  grep -qF '"k_base":30' "$T/out" && grep -qF '"edge_power":' "$T/out" && ok || fail "defaults json"
expect 0 "fixed K" -- "$BSURF" features "$T/n.ply" -B 10 --feature-angle 0 -o "$T/v.ply" --json
grep -qF '"k":30' "$T/out" && ! grep -qF '"edge_power"' "$T/out" && ok || fail "--feature-angle 0 keeps -k"
expect 2 "feature angle 180" -- "$BSURF" features "$T/n.ply" --feature-angle 180 -o "$T/x.ply"
stderr_has "option --feature-angle needs a number (0 to 179.999), not '180'" "feature angle message"
expect 2 "feature angle -5" -- "$BSURF" features "$T/n.ply" --feature-angle -5 -o "$T/x.ply"
stderr_has "--feature-angle needs a number (0 to 179.999), not '-5'" "negative feature angle message"
expect 2 "quadric angle 180" -- "$BSURF" features "$T/n.ply" --quadric-angle 180 -o "$T/x.ply"
stderr_has "option --quadric-angle needs a number (0 to 179.999), not '180'" "quadric angle message"
[ ! -e "$T/x.ply" ] && ok || fail "a refused --quadric-angle writes no output"
expect 0 "quadric check off" -- "$BSURF" features "$T/n.ply" -B 10 --quadric-angle 0 -o "$T/v0.ply" --json
grep -qF '"quadric_k":0,' "$T/out" && grep -qF '"quadric_angle":0,' "$T/out" && ok ||
  fail "--quadric-angle 0: the check does not run"
expect 2 "variance k max -1" -- "$BSURF" features "$T/n.ply" --variance-k-max -1 -o "$T/x.ply"
stderr_has "option --variance-k-max needs a whole number (0 to 65535), not '-1'" "variance k max message"
expect 2 "false-positive rate 1" -- "$BSURF" features "$T/n.ply" --method variance --false-positive-rate 1 -o "$T/x.ply"
expect 0 "variance mad + value" -- "$BSURF" features "$T/n.ply" --method variance -B 5 --tail-rule mad -o "$T/w.ply" -q
expect 0 "variance value" -- "$BSURF" features "$T/n.ply" --method variance -B 5 --threshold 0.01 -o "$T/w.ply" --json
grep -qF '"threshold":0.01' "$T/out" && ok || fail "given threshold reported"
expect 0 "eval a file whose feature came from the truth" -- "$BSURF" eval "$T/n.ply" --truth "$T/c.ply"
expect 2 "bad method" -- "$BSURF" features "$T/c.ply" --method curvature -o "$T/x.ply"
expect 2 "bad threshold" -- "$BSURF" features "$T/c.ply" --method distance --threshold high -o "$T/x.ply"
expect 2 "k-max below k-min" -- "$BSURF" features "$T/c.ply" --method distance --k-min 20 --k-max 10 -o "$T/x.ply"
expect 2 "bad tail rule" -- "$BSURF" features "$T/c.ply" --method distance --tail-rule knee -o "$T/x.ply"
expect 2 "missing output" -- "$BSURF" features "$T/c.ply" --method distance
printf '0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 0\n' >"$T/tiny.xyz"
expect 1 "fewer points than k-max" -- "$BSURF" features "$T/tiny.xyz" --method distance -o "$T/x.ply"
[ -e "$T/x.ply" ] && fail "output left after failures" || ok
finish
