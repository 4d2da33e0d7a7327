#!/usr/bin/env bash
# Golden outputs: what every command writes, pinned.
#
#   scripts/golden.sh BOOTSURF [SCRATCH]            check (exit 1 and a list of what differs)
#   scripts/golden.sh --update BOOTSURF [SCRATCH]   regenerate tests/golden/{SHA256SUMS,json/}
#
# BOOTSURF is the binary or a build directory holding it. The cases are
# tests/golden/cases.sh: every command on small fixed-seed inputs. For each case
# the JSON summary (`--json`) is kept as tests/golden/json/NAME.json, less the
# keys that change from run to run or machine to machine (seconds and *_seconds,
# threads, version), and every file the cases write is pinned by its sha256 in
# tests/golden/SHA256SUMS.
#
# Regenerate only when a change is meant to change results, and say in the
# commit message which outputs changed and why: `git diff tests/golden` shows
# the JSON summaries line by line.
set -euo pipefail
HERE=$(cd "$(dirname "$0")/.." && pwd)
GOLD=$HERE/tests/golden
update=0
if [ "${1:-}" = "--update" ]; then
  update=1
  shift
fi
if [ $# -lt 1 ]; then
  echo "usage: scripts/golden.sh [--update] BOOTSURF|BUILD_DIR [SCRATCH]" >&2
  exit 2
fi
B=$1
[ -d "$B" ] && B=$B/bootsurf
[ -x "$B" ] || { echo "golden: no bootsurf binary at $B" >&2; exit 2; }
B=$(cd "$(dirname "$B")" && pwd)/$(basename "$B")
W=${2:-$(mktemp -d "${TMPDIR:-/tmp}/bsurf-golden.XXXXXX")}
rm -rf "$W"
mkdir -p "$W/json"
cp "$GOLD/box.off" "$W/"
cd "$W"

# The summary without what differs between identical runs.
strip_json() {
  sed -E -e 's/"(seconds|[a-z_]+_seconds|threads|version)":("[^"]*"|[^,}]*)//g' \
    -e 's/,,+/,/g' -e 's/\{,/{/g' -e 's/,\}/}/g'
}

failed_cases=0
run() {
  local name=$1
  shift 2 # NAME --
  # -j 2 everywhere a command takes it is not needed: outputs are the same for
  # any thread count (tests check that separately)
  if ! "$B" "$@" --json >"json/$name.raw" 2>"json/$name.err"; then
    echo "golden: case $name failed: bootsurf $*" >&2
    sed 's/^/    /' "json/$name.err" | head -5 >&2
    failed_cases=$((failed_cases + 1))
  fi
  strip_json <"json/$name.raw" >"json/$name.json"
  rm -f "json/$name.raw" "json/$name.err"
}
# shellcheck source=/dev/null
. "$GOLD/cases.sh"
rm -f box.off
if [ "$failed_cases" -ne 0 ]; then
  echo "golden: $failed_cases case(s) failed to run" >&2
  exit 1
fi

# every output file, in a stable order
find . -path ./json -prune -o -type f -print | LC_ALL=C sort | sed 's|^\./||' |
  while read -r f; do sha256sum "$f"; done >json/SHA256SUMS.new

if [ "$update" -eq 1 ]; then
  rm -rf "$GOLD/json"
  mkdir -p "$GOLD/json"
  cp json/*.json "$GOLD/json/"
  mv json/SHA256SUMS.new "$GOLD/SHA256SUMS"
  echo "golden: regenerated $(wc -l <"$GOLD/SHA256SUMS") files and $(ls json | wc -l) summaries in tests/golden"
  exit 0
fi

differ=0
if ! diff -u "$GOLD/SHA256SUMS" json/SHA256SUMS.new >json/sums.diff; then
  echo "golden: output files differ (- expected, + now):"
  grep -E "^[-+][0-9a-f]" json/sums.diff | sed 's/^/  /'
  differ=1
fi
for f in "$GOLD"/json/*.json; do
  n=$(basename "$f")
  if [ ! -f "json/$n" ]; then
    echo "golden: summary $n no longer written"
    differ=1
  elif ! cmp -s "$f" "json/$n"; then
    echo "golden: summary $n differs:"
    echo "  expected: $(cat "$f")"
    echo "  now:      $(cat "json/$n")"
    differ=1
  fi
done
for f in json/*.json; do
  [ -f "$GOLD/$f" ] || { echo "golden: new summary $(basename "$f") (run --update)"; differ=1; }
done
if [ "$differ" -ne 0 ]; then
  echo "golden: results changed. If that is intended, regenerate with"
  echo "  scripts/golden.sh --update BUILD_DIR"
  echo "and say in the commit message which outputs changed and why."
  echo "0 passed, 1 failed"
  exit 1
fi
echo "golden: $(wc -l <"$GOLD/SHA256SUMS") files and $(ls json/*.json | wc -l) summaries as pinned"
echo "1 passed, 0 failed"
[ -n "${2:-}" ] || rm -rf "$W"
