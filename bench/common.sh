# Sourced by the benchmark scripts (run.sh, scaling.sh, normals_compare.sh,
# smooth_compare.sh): what they do alike.

# bench_usage SCRIPT LAST_LINE: prints the script's header comment (lines 2 to
# LAST_LINE) on stderr and exits 2.
bench_usage() {
  sed -n "2,${2}p" "$1" >&2
  exit 2
}

# bench_work: WORK, the scratch directory, made absolute: the caller's WORK
# (created if needed, kept), or a fresh mktemp -d removed when the script exits.
bench_work() {
  if [ -n "${WORK:-}" ]; then
    mkdir -p "$WORK"
  else
    WORK=$(mktemp -d)
    trap 'rm -rf "$WORK"' EXIT
  fi
  WORK=$(cd "$WORK" && pwd)
}
