#!/usr/bin/env bash
# bootsurf smooth (thesis chapter 6): every method and order, determinism,
# fields kept, the JSON summary, bad usage and bad input.
. "$(dirname "$0")/common.inc"

expect 0 "generate" -- "$BSURF" generate cube -n 4000 -o "$T/c.ply" -q
expect 0 "noise" -- "$BSURF" noise "$T/c.ply" --level 0.5 -o "$T/n.ply" -q
sum_before=$(cksum <"$T/n.ply")
for m in naive bilateral multipass; do
  expect 0 "$m -j1" -- "$BSURF" smooth "$T/n.ply" --method $m -k 30 -B 20 --iterations 30 -j 1 -o "$T/$m.1.ply" -q
  expect 0 "$m -j2" -- "$BSURF" smooth "$T/n.ply" --method $m -k 30 -B 20 --iterations 30 -j 2 -o "$T/$m.2.ply" --json
  cmp -s "$T/$m.1.ply" "$T/$m.2.ply" && ok || fail "$m: -j 1 and -j 2 differ"
  for key in '"command":"smooth"' "\"method\":\"$m\"" '"points":' '"h":' '"mean_error":' '"moved_points":' \
    '"moved_mean_h":' '"moved_max_h":' '"compute_seconds":' '"seconds":'; do
    grep -qF "$key" "$T/out" && ok || fail "$m json lacks $key"
  done
  # input fields kept (noise's true_*); the input's normals dropped (they belong to the unmoved points)
  grep -a -q "property [a-z0-9]* nx$" "$T/$m.1.ply" && fail "$m output keeps normals that no longer match" || ok
  for field in true_nx true_feature true_feature_dist err_632 err_632plus moved; do
    grep -a -q "property [a-z0-9]* $field$" "$T/$m.1.ply" && ok || fail "$m output lacks $field"
  done
done
grep -a -q "property float k_hat$" "$T/multipass.1.ply" && ok || fail "multipass writes k_hat"
grep -a -q "property float d_local$" "$T/multipass.1.ply" && ok || fail "multipass writes d_local"
expect 0 "naive json" -- "$BSURF" smooth "$T/n.ply" --method naive -k 30 -B 20 --threshold 0.5h -o "$T/x.ply" --json
grep -qF '"threshold_h":0.5' "$T/out" && grep -qF '"projected":' "$T/out" && ok || fail "naive threshold in json"
expect 0 "naive none" -- "$BSURF" smooth "$T/n.ply" --method naive -k 30 -B 20 --threshold none -o "$T/x.ply" --json
grep -qF '"projected":4' "$T/out" && ok || fail "threshold none projects every point"
for order in parallel sequential; do
  expect 0 "bilateral $order" -- "$BSURF" smooth "$T/n.ply" --method bilateral --order $order -k 30 -B 20 --h1 1.5h \
    --h2 1W -o "$T/b.$order.ply" --json
  grep -qF "\"order\":\"$order\"" "$T/out" && grep -qF '"h1_h":1.5' "$T/out" && ok || fail "bilateral $order json"
done
cmp -s "$T/b.parallel.ply" "$T/b.sequential.ply" && fail "the two orders gave the same bytes" || ok
expect 0 "multipass sequential" -- "$BSURF" smooth "$T/n.ply" --order sequential --iterations 3 -k 30 -B 20 \
  --a 0.5 --h2 0.01 --k-min 12 --k-error 0.5h -o "$T/x.ply" -q
expect 0 "multipass k-error in W" -- "$BSURF" smooth "$T/n.ply" --method multipass --iterations 2 -k 30 -B 20 --k-error 2W -o "$T/x.ply" -q
# the default method, auto: multipass in memory, bilateral in tiles (multipass is not tiled)
expect 0 "auto" -- "$BSURF" smooth "$T/n.ply" -k 30 -B 20 -o "$T/auto.ply" --json
grep -qF '"method":"multipass"' "$T/out" && ok || fail "auto in memory is not multipass"
expect 0 "multipass named" -- "$BSURF" smooth "$T/n.ply" --method multipass -k 30 -B 20 -o "$T/mp.ply" -q
cmp -s "$T/auto.ply" "$T/mp.ply" && ok || fail "auto in memory differs from --method multipass"
expect 0 "auto tiled" -- "$BSURF" smooth "$T/n.ply" -k 30 -B 20 --tile-points 1500 -o "$T/auto_t.ply" --json
grep -qF '"method":"bilateral"' "$T/out" && ok || fail "auto in tiles is not bilateral"
expect 0 "bilateral named" -- "$BSURF" smooth "$T/n.ply" --method bilateral -k 30 -B 20 -o "$T/bil.ply" -q
cmp -s "$T/auto_t.ply" "$T/bil.ply" && ok || fail "auto in tiles differs from --method bilateral"
expect 1 "multipass tiled" -- "$BSURF" smooth "$T/n.ply" --method multipass -k 30 -B 20 --tile-points 1500 -o "$T/x.ply"
stderr_has "not available in tiled runs" "multipass tiled message"
[ "$(cksum <"$T/n.ply")" = "$sum_before" ] && ok || fail "input modified"
# bad usage (exit 2) and bad input (exit 1), never an output
rm -f "$T/x.ply"
expect 2 "bad method" -- "$BSURF" smooth "$T/n.ply" --method mls -o "$T/x.ply"
stderr_has "--method must be naive, bilateral, multipass or auto" "bad method message"
expect 2 "bad order" -- "$BSURF" smooth "$T/n.ply" --order random -o "$T/x.ply"
expect 2 "bad threshold" -- "$BSURF" smooth "$T/n.ply" --threshold low -o "$T/x.ply"
expect 2 "bad h1" -- "$BSURF" smooth "$T/n.ply" --h1 0 -o "$T/x.ply"
expect 2 "bad h2" -- "$BSURF" smooth "$T/n.ply" --h2 -1 -o "$T/x.ply"
expect 2 "k-min above K" -- "$BSURF" smooth "$T/n.ply" -k 20 --k-min 30 -o "$T/x.ply"
expect 2 "K too small for the degree" -- "$BSURF" smooth "$T/n.ply" -k 8 -d 3 -o "$T/x.ply"
expect 2 "missing output" -- "$BSURF" smooth "$T/n.ply"
expect 1 "output is the input" -- "$BSURF" smooth "$T/n.ply" -o "$T/n.ply"
printf '0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 0\n' >"$T/tiny.xyz"
expect 1 "fewer points than K" -- "$BSURF" smooth "$T/tiny.xyz" -o "$T/x.ply"
stderr_has "tiny.xyz" "names the file"
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n' >"$T/trunc.ply"
expect 1 "truncated input" -- "$BSURF" smooth "$T/trunc.ply" -o "$T/x.ply"
[ -e "$T/x.ply" ] && fail "output left after failures" || ok
finish
