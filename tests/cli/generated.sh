#!/usr/bin/env bash
# Generated code is what its generator writes today: generated/ldl_unrolled.h
# from scripts/gen_ldl_unrolled.py. $1 = bootsurf binary (unused), $2 = scratch.
set -u
HERE=$(cd "$(dirname "$0")/../.." && pwd)
PY=$(command -v python3 || true)
if [ -z "$PY" ]; then
  echo "SKIP: python3 not found; generated/ldl_unrolled.h is not checked against its generator"
  exit 77
fi
mkdir -p "$2"
"$PY" "$HERE/scripts/gen_ldl_unrolled.py" >"$2/ldl_unrolled.h" || { echo "0 passed, 1 failed"; exit 1; }
if cmp -s "$2/ldl_unrolled.h" "$HERE/generated/ldl_unrolled.h"; then
  echo "1 passed, 0 failed"
else
  echo "FAIL: generated/ldl_unrolled.h differs from scripts/gen_ldl_unrolled.py's output:"
  diff "$2/ldl_unrolled.h" "$HERE/generated/ldl_unrolled.h" | head -20
  echo "0 passed, 1 failed"
  exit 1
fi
