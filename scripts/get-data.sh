#!/usr/bin/env bash
# Fetches the thesis's test meshes (Fandisk and Bunny, chapters 4-7) from
# Debian's CGAL data (package libcgal-demo) into DIR (default: data/, which
# git ignores). Only these two files are extracted; never commit them.
# With --all, the meshes of the development set too (scripts/devset.py:
# elephant, dino, couplingdown, joint, femur, camel).
#   scripts/get-data.sh [--all] [DIR]
set -euo pipefail
FILES=(data/meshes/fandisk_large.off data/meshes/bunny00.off)
if [ "${1:-}" = "--all" ]; then
  shift
  for m in elephant dino couplingdown joint femur camel; do FILES+=("data/meshes/$m.off"); done
fi
DIR=${1:-"$(cd "$(dirname "$0")/.." && pwd)/data"}
ARCHIVE=/usr/share/doc/libcgal-dev/data.tar.gz

if [ ! -f "$ARCHIVE" ]; then
  if [ "$(id -u)" -ne 0 ]; then
    echo "get-data: $ARCHIVE is missing; run as root (or: sudo apt-get install libcgal-demo)" >&2
    exit 1
  fi
  echo "get-data: installing libcgal-demo (Debian) for $ARCHIVE" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends libcgal-demo >&2
fi

mkdir -p "$DIR"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/bsurf-data.XXXXXX")
chmod 755 "$TMP" # apt-get download runs as _apt
trap 'rm -rf "$TMP"' EXIT
if [ ! -f "$ARCHIVE" ]; then
  # images that exclude /usr/share/doc from installs (dpkg path-exclude):
  # take the file from the package itself
  echo "get-data: $ARCHIVE not installed; unpacking it from the libcgal-demo package" >&2
  (cd "$TMP" && apt-get download libcgal-demo >&2)
  dpkg-deb -x "$TMP"/libcgal-demo_*.deb "$TMP/deb"
  ARCHIVE="$TMP/deb$ARCHIVE"
  if [ ! -f "$ARCHIVE" ]; then
    echo "get-data: the libcgal-demo package has no ${ARCHIVE#"$TMP/deb"}" >&2
    exit 1
  fi
fi
tar -xzf "$ARCHIVE" -C "$TMP" "${FILES[@]}"
for f in "${FILES[@]}"; do
  mv -f "$TMP/$f" "$DIR/$(basename "$f")"
  echo "$DIR/$(basename "$f")"
done
