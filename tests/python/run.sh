#!/usr/bin/env bash
# The Python package's tests through ctest: run.sh PYTHON PACKAGE_DIR CLI TMP
set -u
PY=$1 PKG=$2 CLI=$3 TMP=$4
if ! "$PY" -c 'import numpy, pytest' >/dev/null 2>&1; then
  echo "SKIP: $PY lacks numpy or pytest (apt-get install python3-numpy python3-pytest)"
  exit 77
fi
rm -rf "$TMP" && mkdir -p "$TMP"
export PYTHONPATH="$PKG${PYTHONPATH:+:$PYTHONPATH}" BSURF_CLI="$CLI" BSURF_PY_TMP="$TMP"
cd "$(dirname "$0")" && exec "$PY" -m pytest -q -p no:cacheprovider .
