#!/usr/bin/env bash
# Bytes written by a tiled run (docs/scaling.md, "Now the output is written once"):
# wall, peak RSS and the kernel's count of bytes sent to storage (ru_oublock x 512 =
# write_bytes of /proc/PID/io) for `bootsurf normals -k 10 -B 0` on a random-order
# sphere, in memory and tiled, without and with a helper that fdatasyncs every file
# the run has open for writing every second (the kernel's writeback made frequent,
# as in a run whose output exceeds the dirty-page limits). A benchmark, not a test.
#
# usage: bench/tile_writes.sh BUILD_DIR [OTHER_BUILD_DIR ...]
#   env: N=4000000 TILE_POINTS=200000 WORK=DIR (default a fresh mktemp -d beside the
#        repository, removed at exit: the scratch files go beside the output)
set -euo pipefail
[ $# -ge 1 ] || { sed -n 2,12p "$0"; exit 2; }
N=${N:-4000000} TP=${TILE_POINTS:-200000}
HERE=$(cd "$(dirname "$0")/.." && pwd)
WORK=${WORK:-$(mktemp -d "$HERE/.tile_writes.XXXXXX")}
trap 'rm -rf "$WORK"' EXIT
FLUSH='import os, sys, time
pid = sys.argv[1]
while os.path.exists("/proc/" + pid):
    try:
        fds = os.listdir("/proc/%s/fd" % pid)
    except OSError:
        break
    for fd in fds:
        try:
            info = open("/proc/%s/fdinfo/%s" % (pid, fd)).read()
            if int(info.split("flags:")[1].split()[0], 8) & 3 == 0:
                continue
            f = os.open("/proc/%s/fd/%s" % (pid, fd), os.O_RDONLY)
            if os.path.isfile("/proc/self/fd/%d" % f):
                os.fdatasync(f)
            os.close(f)
        except (OSError, IndexError, ValueError):
            pass
    time.sleep(1)'
run() { # label flush(0/1) bootsurf args...
  local label=$1 flush=$2; shift 2
  /usr/bin/time -v -o "$WORK/time" "$@" >/dev/null 2>"$WORK/err" &
  local tp=$! fp=
  if [ "$flush" = 1 ]; then
    sleep 0.2
    python3 -c "$FLUSH" "$(pgrep -P $tp | head -1)" &
    fp=$!
  fi
  wait $tp || { cat "$WORK/err" >&2; exit 1; }
  [ -z "$fp" ] || wait $fp
  cmp -s "$WORK/ref.ply" "$WORK/out.ply" || { echo "$label: output differs from the in-memory run" >&2; exit 1; }
  printf '| %s | %s | %s MiB | %s MB |\n' "$label" \
    "$(awk -F': ' '/Elapsed/ {print $2}' "$WORK/time")" \
    "$(awk -F': ' '/Maximum resident/ {printf "%d", $2 / 1024}' "$WORK/time")" \
    "$(awk -F': ' '/File system outputs/ {printf "%d", $2 * 512 / 1e6}' "$WORK/time")"
  rm -f "$WORK/out.ply"
}
B0=$1/bootsurf
"$B0" generate sphere --sampling random -n "$N" -o "$WORK/in.ply" -q
"$B0" normals "$WORK/in.ply" -k 10 -B 0 -o "$WORK/ref.ply" --memory-limit none -q
echo "| run ($N points, --tile-points $TP) | wall | peak RSS | written |"
echo "|---|---:|---:|---:|"
run "in memory" 0 "$B0" normals "$WORK/in.ply" -k 10 -B 0 -o "$WORK/out.ply" --memory-limit none -q
for b in "$@"; do
  run "tiled, $b" 0 "$b/bootsurf" normals "$WORK/in.ply" -k 10 -B 0 -o "$WORK/out.ply" --tile-points "$TP" -q
  run "tiled, $b, flushed every 1 s" 1 "$b/bootsurf" normals "$WORK/in.ply" -k 10 -B 0 -o "$WORK/out.ply" --tile-points "$TP" -q
done
