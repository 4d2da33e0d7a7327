#!/usr/bin/env bash
# The command-line contract: outputs, summaries, exit codes, determinism.
. "$(dirname "$0")/common.inc"

expect 0 "help" -- "$BSURF" --help
expect 0 "help error" -- "$BSURF" help error
grep -q -- "-k, --neighbors K" "$T/out" && grep -q "(default: 50)" "$T/out" && ok || fail "help error shows -k with its default"
for c in info generate noise error; do expect 0 "$c --help" -- "$BSURF" $c --help; done
expect 2 "no command" -- "$BSURF"
expect 2 "unknown command" -- "$BSURF" frobnicate
expect 2 "unknown option" -- "$BSURF" error --frob x.ply
stderr_has "unknown option '--frob'" "unknown option"
expect 2 "bad number" -- "$BSURF" error -k abc x.ply
stderr_has "-k needs a whole number" "bad number"
expect 2 "K too small for degree" -- "$BSURF" error -k 12 -d 4 x.ply
stderr_has "too small for degree 4" "K too small"
expect 2 "bad gamma" -- "$BSURF" error --gamma median x.ply
expect 2 "bad shape" -- "$BSURF" generate teapot -o "$T/t.ply"

# generate, noise, error, info
expect 0 "generate sphere" -- "$BSURF" generate sphere -n 3000 -o "$T/s.ply" -q
expect 0 "generate cube" -- "$BSURF" generate cube -n 3000 -o "$T/c.ply" --ascii -q
head -c 200 "$T/c.ply" | grep -q "format ascii 1.0" && ok || fail "--ascii writes ascii PLY"
head -c 200 "$T/s.ply" | grep -q "format binary_little_endian 1.0" && ok || fail "binary PLY by default"
grep -a -q "property uchar feature" "$T/c.ply" && grep -a -q "property float feature_dist" "$T/c.ply" && ok || fail "cube has feature fields"
expect 0 "noise" -- "$BSURF" noise "$T/s.ply" --level 0.5 -o "$T/n.ply" --json
grep -q '"command":"noise"' "$T/out" && grep -q '"h":' "$T/out" && ok || fail "noise json"
expect 0 "error -j1" -- "$BSURF" error "$T/n.ply" -k 30 -B 20 -j 1 -o "$T/e1.ply" -q
expect 0 "error -j2" -- "$BSURF" error "$T/n.ply" -k 30 -B 20 -j 2 -o "$T/e2.ply" --json
cmp -s "$T/e1.ply" "$T/e2.ply" && ok || fail "error -j 1 and -j 2 outputs differ"
for key in '"command":"error"' '"points":3000' '"k":30' '"degree":3' '"bootstrap":20' '"seed":1' '"threads":2' '"seconds":' '"mean":{' '"mean_h":{' '"err_632plus":' '"replicates_skipped":'; do
  grep -qF "$key" "$T/out" && ok || fail "error json lacks $key"
done
if command -v python3 >/dev/null 2>&1; then
  python3 -c "import json,sys; json.load(open('$T/out'))" 2>/dev/null && ok || fail "error --json is one JSON object"
else
  echo "note: python3 absent, JSON syntax check skipped"
fi
for f in err_train err_boot err_loo err_loo_center err_632 err_632plus gamma overfit_rate; do
  grep -a -q "property float $f\$" "$T/e1.ply" && ok || fail "output lacks field $f"
done
# noise carries the exact normals on as true_* fields, which error keeps (no nx ny nz)
for f in true_nx true_ny true_nz; do grep -a -q "property double $f\$" "$T/e1.ply" && ok || fail "truth $f kept"; done
expect 0 "error again" -- "$BSURF" error "$T/n.ply" -k 30 -B 20 -j 2 -o "$T/e3.ply" -q
cmp -s "$T/e1.ply" "$T/e3.ply" && ok || fail "two runs differ"
expect 0 "error other seed" -- "$BSURF" error "$T/n.ply" -k 30 -B 20 --seed 7 -o "$T/e4.ply" -q
cmp -s "$T/e1.ply" "$T/e4.ply" && fail "seed has no effect" || ok
expect 0 "noise is deterministic" -- "$BSURF" noise "$T/s.ply" --level 0.5 -o "$T/n2.ply" -q
cmp -s "$T/n.ply" "$T/n2.ply" && ok || fail "noise differs between runs"
expect 0 "info json" -- "$BSURF" info "$T/e1.ply" --json
grep -q '"points":3000' "$T/out" && grep -q '"normals":false' "$T/out" && grep -q '"true_nx"' "$T/out" && ok || fail "info json"
expect 0 "uniform noise" -- "$BSURF" noise "$T/s.ply" --model uniform --level 1 -o "$T/u.xyz" -q
expect 0 "error on xyz" -- "$BSURF" error "$T/u.xyz" -k 20 -B 5 -o "$T/u_err.ply" -q
expect 0 "test sample" -- "$BSURF" error "$T/n.ply" -k 30 -B 5 --test-sample "$T/n2.ply" -o "$T/t.ply" -q
grep -a -q "property float err_test$" "$T/t.ply" && ok || fail "err_test written"

# the README's library example (built beside the tool)
EX="$(dirname "$BSURF")/example_estimate_error"
if [ -x "$EX" ]; then
  expect 0 "library example" -- "$EX" "$T/n.ply" "$T/ex.ply"
  grep -a -q "property float err_632plus$" "$T/ex.ply" && ok || fail "example writes err_632plus"
fi

# bad input: exit 1, file named, no output left behind
cp "$T/n.ply" "$T/before.ply"
expect 1 "output is the input" -- "$BSURF" error "$T/n.ply" -o "$T/n.ply" -k 20 -B 2
stderr_has "refusing to overwrite" "output is the input"
cmp -s "$T/n.ply" "$T/before.ply" && ok || fail "input was modified"
expect 1 "missing input" -- "$BSURF" error "$T/none.ply" -o "$T/x.ply"
stderr_has "$T/none.ply" "missing input names the file"
[ -e "$T/x.ply" ] && fail "output created for a missing input" || ok
expect 1 "unwritable directory" -- "$BSURF" error "$T/n.ply" -k 20 -B 2 -o "$T/nodir/x.ply"
stderr_has "nodir" "unwritable directory named"
printf 'ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n' >"$T/trunc.ply"
expect 1 "truncated ply" -- "$BSURF" error "$T/trunc.ply" -o "$T/y.ply" -k 3 -d 1
stderr_has "$T/trunc.ply:" "truncated names the file"
[ -e "$T/y.ply" ] && fail "output created for a bad input" || ok
expect 1 "noise needs normals" -- "$BSURF" noise "$T/trunc.ply" -o "$T/z.ply"
printf '0 0 0\n1 0 0\n0 1 0\n' >"$T/tiny.xyz"
expect 1 "noise without normals" -- "$BSURF" noise "$T/tiny.xyz" -o "$T/z.ply"
stderr_has "no normals" "noise without normals"
expect 1 "fewer points than K" -- "$BSURF" error "$T/tiny.xyz" -k 50 -o "$T/z.ply"
stderr_has "fewer than K" "fewer points than K"
printf '0 0 0\nnan 1 0\n0 1 0\n' >"$T/nan.xyz"
expect 1 "NaN coordinate" -- "$BSURF" info "$T/nan.xyz"
stderr_has "point 1" "NaN names the point"
ls -A "$T" | grep -q '\.tmp\.' && fail "temporary files left behind" || ok
finish
