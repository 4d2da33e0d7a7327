#!/usr/bin/env bash
# Issue 18, item 3: "a failure record and the test-error estimator should not
# both be called bsurf_error*". The failure record (where a reader, writer or
# tiled run failed: line, byte, message) becomes bsurf_failure; every
# remaining bsurf_error* name is then the test-error estimator (Algorithm 1):
# bsurf_error_options, bsurf_error_fields, bsurf_error_report,
# bsurf_error_job, ... are left as they are.
#
# Run ONCE on main after every branch of the session is merged (the branches
# still use the old name), from the repository's root:
#   scripts/rename_api.sh && cmake --build build && ctest --test-dir build
# The substitution is word-bounded (\b...\b: bsurf_error_options is not
# touched) and covers every tracked C source, header, Python, shell, CMake and
# Markdown file except CHANGELOG.md's released history (a line is added to
# its Unreleased section instead). It changes no output: the golden test
# must pass unchanged.
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"
mapfile -t files < <(git grep -lwE 'bsurf_error' -- '*.c' '*.h' '*.py' '*.pyx' '*.sh' '*.md' '*.txt' '*.cmake' '*.in' \
  ':!CHANGELOG.md' ':!scripts/rename_api.sh')
[ ${#files[@]} -eq 0 ] && { echo "rename_api.sh: nothing to rename (already done?)"; exit 0; }
sed -i -E 's/\bbsurf_error\b/bsurf_failure/g' "${files[@]}"
# the record's own comment in bootsurf.h keeps reading naturally
echo "rename_api.sh: bsurf_error -> bsurf_failure in ${#files[@]} files"
if ! grep -q 'bsurf_failure' CHANGELOG.md; then
  sed -i '0,/^## Unreleased$/s//## Unreleased\n\n### Changed (API)\n- The failure record `bsurf_error` (line, byte, message of a failed read, write or\n  tiled run) is now `bsurf_failure`, so that every `bsurf_error*` name belongs to the\n  test-error estimator (issue 18; `scripts\/rename_api.sh`)./' CHANGELOG.md
fi
left=$(git grep -nwE 'bsurf_error' -- ':!CHANGELOG.md' ':!scripts/rename_api.sh' || true)
if [ -n "$left" ]; then
  echo "rename_api.sh: still named bsurf_error:" >&2
  echo "$left" >&2
  exit 1
fi
