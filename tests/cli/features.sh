#!/usr/bin/env bash
# bootsurf features (thesis chapter 7) and eval's features section.
. "$(dirname "$0")/common.inc"

expect 0 "generate" -- "$BSURF" generate cube -n 6000 --feature-width 1 -o "$T/c.ply" -q
expect 0 "distance -j1" -- "$BSURF" features "$T/c.ply" -j 1 -o "$T/a.ply" -q
expect 0 "distance -j2" -- "$BSURF" features "$T/c.ply" -j 2 -o "$T/b.ply" --json
cmp -s "$T/a.ply" "$T/b.ply" && ok || fail "features -j 1 and -j 2 differ"
for key in '"command":"features"' '"points":' '"h":' '"method":"distance"' '"parameters":{' '"k_min":15' \
  '"threshold":0' '"feature_points":' '"seconds":'; do
  grep -qF "$key" "$T/out" && ok || fail "features json lacks $key"
done
grep -a -q "property uchar feature$" "$T/a.ply" && ok || fail "feature written"
grep -a -q "property float feature_dist$" "$T/a.ply" && ok || fail "feature_dist written"
expect 0 "eval features" -- "$BSURF" eval "$T/a.ply" --truth "$T/c.ply" --json
grep -qF '"features":{"precision":' "$T/out" && ok || fail "eval json has features"
grep -qF '"recall":' "$T/out" && grep -qF '"f1":' "$T/out" && ok || fail "eval json has recall and f1"
f1=$(sed 's/.*"f1":\([0-9.e-]*\).*/\1/' "$T/out")
awk -v f="$f1" 'BEGIN { exit !(f > 0.9) }' && ok || fail "cube edges F1 $f1 <= 0.9"
expect 0 "eval features text" -- "$BSURF" eval "$T/a.ply" --truth "$T/c.ply"
grep -q "precision" "$T/out" && ok || fail "eval text has the features table"
expect 0 "fixed fraction" -- "$BSURF" features "$T/c.ply" --threshold 0.3 --derivative 1 --iterations 2 -o "$T/f.ply" -q
expect 0 "noise" -- "$BSURF" noise "$T/c.ply" --level 0.5 --model uniform -o "$T/n.ply" -q
expect 0 "variance auto" -- "$BSURF" features "$T/n.ply" --method variance -k 20 -B 10 -o "$T/v.ply" --json
grep -qF '"method":"variance"' "$T/out" && grep -qF '"tail_rule":"otsu"' "$T/out" && ok || fail "variance json"
grep -a -q "property float normal_var$" "$T/v.ply" && ok || fail "normal_var written"
expect 0 "variance mad + value" -- "$BSURF" features "$T/n.ply" --method variance -B 5 --tail-rule mad -o "$T/w.ply" -q
expect 0 "variance value" -- "$BSURF" features "$T/n.ply" --method variance -B 5 --threshold 0.01 -o "$T/w.ply" --json
grep -qF '"threshold":0.01' "$T/out" && ok || fail "given threshold reported"
expect 0 "eval a file whose feature came from the truth" -- "$BSURF" eval "$T/n.ply" --truth "$T/c.ply"
expect 2 "bad method" -- "$BSURF" features "$T/c.ply" --method curvature -o "$T/x.ply"
expect 2 "bad threshold" -- "$BSURF" features "$T/c.ply" --threshold high -o "$T/x.ply"
expect 2 "k-max below k-min" -- "$BSURF" features "$T/c.ply" --k-min 20 --k-max 10 -o "$T/x.ply"
expect 2 "bad tail rule" -- "$BSURF" features "$T/c.ply" --tail-rule knee -o "$T/x.ply"
expect 2 "missing output" -- "$BSURF" features "$T/c.ply"
printf '0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 0\n' >"$T/tiny.xyz"
expect 1 "fewer points than k-max" -- "$BSURF" features "$T/tiny.xyz" -o "$T/x.ply"
[ -e "$T/x.ply" ] && fail "output left after failures" || ok
finish
