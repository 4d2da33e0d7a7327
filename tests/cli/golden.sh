#!/usr/bin/env bash
# Golden outputs (tests/golden, scripts/golden.sh): every command on small
# fixed-seed inputs writes the files and JSON summaries pinned there.
# $1 = bootsurf binary, $2 = scratch directory.
set -u
HERE=$(cd "$(dirname "$0")/../.." && pwd)
exec bash "$HERE/scripts/golden.sh" "$1" "$2"
