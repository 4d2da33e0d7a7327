# Sourced by the benchmark scripts (run.sh, scaling.sh, normals_compare.sh,
# smooth_compare.sh): what they do alike.

# bench_usage SCRIPT: prints the script's header comment (the lines after the
# #! line up to the first that is not a comment) on stderr and exits 2.
bench_usage() {
  awk 'NR == 1 { next } /^#/ { print; next } { exit }' "$1" >&2
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
