#!/usr/bin/env bash
# The README's demo: a noisy cube, its bootstrap error estimates, the summary.
set -euo pipefail
BSURF=${BSURF:-build/bootsurf}
OUT=${BSURF_DEMO_DIR:-demo-out}
mkdir -p "$OUT"
set -x
"$BSURF" generate cube -n 60000 -o "$OUT/cube.ply"
"$BSURF" noise "$OUT/cube.ply" --level 0.5 --seed 1 -o "$OUT/cube_noisy.ply"
"$BSURF" error "$OUT/cube_noisy.ply" -k 50 -d 3 -B 50 -o "$OUT/cube_error.ply"
"$BSURF" info "$OUT/cube_error.ply"
"$BSURF" render "$OUT/cube_error.ply" --field err_632plus -o "$OUT/cube_err632plus.png"
