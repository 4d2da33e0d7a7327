#!/usr/bin/env bash
# smooth's memory plan (bsurf_smooth_job_memory, docs/smoothing.md "Memory"):
# the scale rule may widen K up to --k-max (8 K by default), and the plan
# counts those neighbourhoods. Under a --memory-limit that holds the cloud
# at K but not at 8 K, the default cap is lowered to the widest K that fits
# (a warning, JSON k_max), an explicit --k-max is refused naming --k-max and
# --memory-limit; the cap is the same run as that --k-max given by hand.
. "$(dirname "$0")/common.inc"

IN="$T/in"
mkdir -p "$IN"
OUT="$T/out.ply"
expect 0 "generate" -- "$BSURF" generate sphere -n 20000 -o "$IN/s.ply" -q
S=(-k 20 -d 2 -B 2 -j 2)

# no limit: the cap is 8 K
expect 0 "no limit" -- "$BSURF" smooth "$IN/s.ply" "${S[@]}" --memory-limit none --json -o "$T/a.ply"
grep -q '"k_max":160' "$T/out" && ok || fail "no limit: k_max $(grep -o '"k_max":[0-9]*' "$T/out")"

# 40 MB holds 20,000 points at K = 20, not at 160: the default cap is lowered
expect 0 "40M" -- "$BSURF" smooth "$IN/s.ply" "${S[@]}" --memory-limit 40M --json -o "$T/b.ply"
stderr_has "the scale rule's K is capped at" "40M"
stderr_has "--k-max or --memory-limit change it" "40M"
cap=$(grep -o '"k_max":[0-9]*' "$T/out" | cut -d: -f2)
[ -n "$cap" ] && [ "$cap" -gt 20 ] && [ "$cap" -lt 160 ] && ok || fail "40M: k_max '$cap'"
grep -q '"method":"multipass"' "$T/out" && ok || fail "40M: not multipass in memory"

# the same cap given by hand: accepted at that limit, the same bytes
expect 0 "--k-max cap" -- "$BSURF" smooth "$IN/s.ply" "${S[@]}" --memory-limit 40M --k-max "$cap" -o "$T/c.ply" -q
[ -s "$T/err" ] && fail "--k-max $cap: $(head -1 "$T/err")" || ok
cmp -s "$T/b.ply" "$T/c.ply" && ok || fail "the capped run differs from --k-max $cap"

# one more: refused, naming both options and the widest K that fits
bad 1 "--k-max cap+1" "smooth --k-max $((cap + 1)) needs about" "--memory-limit" "give --k-max $cap or less" -- \
  "$BSURF" smooth "$IN/s.ply" "${S[@]}" --memory-limit 40M --k-max $((cap + 1)) -o "$OUT"

# K fixed (--k-max = K) or bilateral: nothing to cap
expect 0 "--k-max K" -- "$BSURF" smooth "$IN/s.ply" "${S[@]}" --memory-limit 40M --k-max 20 -o "$T/d.ply" -q
[ -s "$T/err" ] && fail "--k-max 20: $(head -1 "$T/err")" || ok

finish
