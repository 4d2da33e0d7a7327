#!/usr/bin/env bash
# The C sources in .clang-format's style (clang-format 14, Debian 12's).
#   scripts/format.sh          check: list the files that differ, exit 1 if any
#   scripts/format.sh --fix    reformat them in place
# Generated files (generated/ldl_unrolled.h: scripts/gen_ldl_unrolled.py) are
# left as their generator writes them.
set -euo pipefail
cd "$(dirname "$0")/.."
CF=${CLANG_FORMAT:-clang-format}
command -v "$CF" >/dev/null 2>&1 || { echo "format: $CF not found (apt-get install clang-format)" >&2; exit 2; }
mapfile -t files < <(git ls-files '*.c' '*.h' '*.cpp' '*.hpp' | grep -v '^generated/ldl_unrolled\.h$')
if [ "${1:-}" = "--fix" ]; then
  "$CF" -i "${files[@]}"
  exit 0
fi
bad=0
for f in "${files[@]}"; do
  if ! "$CF" --dry-run -Werror "$f" >/dev/null 2>&1; then
    echo "format: $f differs from .clang-format (scripts/format.sh --fix)"
    bad=1
  fi
done
[ "$bad" -eq 0 ] && echo "format: ${#files[@]} files as .clang-format says"
exit "$bad"
