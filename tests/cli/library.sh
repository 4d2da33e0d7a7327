#!/usr/bin/env bash
# The installed library (issue 18; docs/architecture.md "Installed library"):
# the shared library exports exactly the BSURF_API functions of bootsurf.h
# and has its SONAME; neither library defines an unprefixed global symbol;
# `cmake --install` into a temporary prefix gives a package that examples/
# build against through pkg-config (shared and --static) and find_package,
# and the programs so built run, agree with each other and with the command
# line (the files they write and the numbers they print).
. "$(dirname "$0")/common.inc"
SRC=$(cd "$(dirname "$0")/../.." && pwd)
B=$(cd "$(dirname "$BSURF")" && pwd) # the build tree
HDR=$SRC/include/bootsurf.h
VER=$(sed -n 's/^#define BSURF_VERSION_STRING "\(.*\)"$/\1/p' "$HDR")
MAJOR=${VER%%.*}
SO=$B/libbootsurf.so.$MAJOR

# ---- symbols ----
[ -f "$SO" ] && [ -f "$B/libbootsurf.a" ] && ok || fail "$SO or libbootsurf.a missing"
readelf -d "$SO" | grep -q "Library soname: \[libbootsurf.so.$MAJOR\]" && ok || fail "SONAME is not libbootsurf.so.$MAJOR"
[ -f "$B/libbootsurf.so.$VER" ] && ok || fail "no libbootsurf.so.$VER (VERSION)"
nm -D --defined-only "$SO" | awk '{print $NF}' | sort >"$T/exported"
bad=$(grep -v '^bsurf_' "$T/exported")
[ -z "$bad" ] && ok || fail "the shared library exports symbols without bsurf_: $bad"
# every function the header declares carries BSURF_API, and is exported; nothing else is
grep -E '^[a-z][a-z0-9_ ]*[ *]bsurf_[a-z0-9_]+\(' "$HDR" | grep -v '^typedef' >"$T/unmarked"
[ ! -s "$T/unmarked" ] && ok || fail "declarations without BSURF_API in bootsurf.h: $(cat "$T/unmarked")"
grep -oE '^BSURF_API [^;(]*[ *]bsurf_[a-z0-9_]+\(' "$HDR" | grep -oE 'bsurf_[a-z0-9_]+\($' | tr -d '(' | sort >"$T/declared"
[ -s "$T/declared" ] && cmp -s "$T/declared" "$T/exported" && ok ||
  fail "exported != declared: $(diff "$T/declared" "$T/exported" | grep '^[<>]' | tr '\n' ' ')"
# the static archive: defined global symbols (T, D, B, R, W, i, ...) all prefixed
# (an ASan build adds __odr_asan.NAME beside each global NAME: those of ours count as NAME)
bad=$(nm -g --defined-only "$B/libbootsurf.a" | awk 'NF == 3 {s = $3; sub(/^__odr_asan\./, "", s); if (s !~ /^bsurf_/) print $3}' | sort -u)
[ -z "$bad" ] && ok || fail "libbootsurf.a defines unprefixed globals: $bad"

# ---- install into a temporary prefix ----
P=$T/prefix
expect 0 "cmake --install" -- cmake --install "$B" --prefix "$P"
LIBDIR=$(dirname "$(find "$P" -name libbootsurf.so -print -quit)")
for f in include/bootsurf.h bin/bootsurf share/man/man1/bootsurf.1; do
  [ -e "$P/$f" ] && ok || fail "install lacks $f"
done
for f in libbootsurf.a "libbootsurf.so.$MAJOR" pkgconfig/bootsurf.pc cmake/bootsurf/bootsurfConfig.cmake \
  cmake/bootsurf/bootsurfConfigVersion.cmake; do
  [ -e "$LIBDIR/$f" ] && ok || fail "install lacks $LIBDIR/$f"
done
grep -q '^\.SS smooth' "$P/share/man/man1/bootsurf.1" && grep -q -- '--neighbors' "$P/share/man/man1/bootsurf.1" && ok ||
  fail "the man page lacks the commands' help"
expect 0 "installed CLI runs" -- "$P/bin/bootsurf" generate sphere -n 2000 -o "$T/s.ply" -q
expect 0 "installed CLI noise" -- "$P/bin/bootsurf" noise "$T/s.ply" --level 0.5 -o "$T/n.ply" -q
# the noisy points alone (noise keeps the exact normals as true_nx ..., which
# eval would score against instead of the command line's normals)
expect 0 "installed CLI convert" -- "$P/bin/bootsurf" convert "$T/n.ply" "$T/n.xyz" -q

# Programs built against a sanitized library must be sanitized too.
SANFLAGS=""
if readelf -d "$SO" | grep -q 'libasan'; then SANFLAGS="-fsanitize=address,undefined -fno-omit-frame-pointer"; fi
export PKG_CONFIG_PATH=$LIBDIR/pkgconfig
expect 0 "pkg-config --modversion" -- pkg-config --modversion bootsurf
[ "$(cat "$T/out")" = "$VER" ] && ok || fail "pkg-config version $(cat "$T/out") != $VER"
EX="error_array normals_confidence denoise estimate_error"
mkdir -p "$T/pc" "$T/pcs"
for e in $EX; do
  # shellcheck disable=SC2046,SC2086
  expect 0 "cc $e (pkg-config)" -- cc -std=c11 -Wall -Wextra -Werror $SANFLAGS -o "$T/pc/$e" "$SRC/examples/$e.c" \
    $(pkg-config --cflags --libs bootsurf) -Wl,-rpath,"$LIBDIR" -lm
  # the static library by path, and the dependencies pkg-config --static names
  # shellcheck disable=SC2046,SC2086
  expect 0 "cc $e (pkg-config --static)" -- cc -std=c11 -Wall -Wextra -Werror $SANFLAGS -o "$T/pcs/$e" "$SRC/examples/$e.c" \
    $(pkg-config --cflags bootsurf) "$LIBDIR/libbootsurf.a" $(pkg-config --libs --static bootsurf | sed 's/-lbootsurf//')
done
ldd "$T/pc/denoise" | grep -q "libbootsurf.so.$MAJOR => $LIBDIR" && ok || fail "pkg-config build does not use the installed shared library"
ldd "$T/pcs/denoise" | grep -q "libbootsurf" && fail "--static build links libbootsurf.so" || ok

expect 0 "find_package configure" -- cmake -S "$SRC/examples" -B "$T/fp" -DCMAKE_PREFIX_PATH="$P" \
  -DCMAKE_BUILD_TYPE=Release "-DCMAKE_C_FLAGS=$SANFLAGS" "-DCMAKE_EXE_LINKER_FLAGS=$SANFLAGS"
expect 0 "find_package build" -- cmake --build "$T/fp"
ldd "$T/fp/denoise" | grep -q "libbootsurf.so.$MAJOR => $LIBDIR" && ok || fail "find_package build does not use the installed shared library"

# ---- the programs run, and the three builds give the same bytes ----
for d in pc pcs fp; do
  expect 0 "$d/error_array" -- "$T/$d/error_array" 3000 0.01
  cp "$T/out" "$T/$d.error_array.txt"
  expect 0 "$d/normals_confidence" -- "$T/$d/normals_confidence" "$T/n.xyz" "$T/$d.normals.ply"
  expect 0 "$d/denoise" -- "$T/$d/denoise" "$T/n.ply" "$T/$d.denoised.ply"
  cp "$T/out" "$T/$d.denoise.txt"
  expect 0 "$d/estimate_error" -- "$T/$d/estimate_error" "$T/n.ply" "$T/$d.error.ply"
  cp "$T/out" "$T/$d.estimate_error.txt"
done
grep -q "3000 points, sigma = 0.01: mean err_train" "$T/pc.error_array.txt" && ok || fail "error_array output: $(cat "$T/pc.error_array.txt")"
for f in error_array.txt normals.ply denoised.ply error.ply; do
  cmp -s "$T/pc.$f" "$T/pcs.$f" && cmp -s "$T/pc.$f" "$T/fp.$f" && ok || fail "$f differs between the builds"
done
# the examples' results are the command line's
expect 0 "CLI normals" -- "$P/bin/bootsurf" normals "$T/n.xyz" -o "$T/cli_normals.ply" -q
# points and normals as text with 17 digits: equal files, equal bits
expect 0 "example normals as xyz" -- "$P/bin/bootsurf" convert "$T/pc.normals.ply" "$T/pc.normals.xyz" -q
expect 0 "CLI normals as xyz" -- "$P/bin/bootsurf" convert "$T/cli_normals.ply" "$T/cli_normals.xyz" -q
cmp -s "$T/pc.normals.xyz" "$T/cli_normals.xyz" && ok || fail "normals_confidence differs from bootsurf normals"
expect 0 "CLI smooth" -- "$P/bin/bootsurf" smooth "$T/n.ply" -o "$T/cli_smooth.ply" -q
for f in pc.denoised cli_smooth; do
  expect 0 "eval $f" -- "$P/bin/bootsurf" eval "$T/$f.ply" --truth "$T/s.ply" --json
  grep -o '"position":{[^}]*}' "$T/out" >"$T/$f.position"
done
[ -s "$T/pc.denoised.position" ] && cmp -s "$T/pc.denoised.position" "$T/cli_smooth.position" && ok ||
  fail "denoise and bootsurf smooth moved the points differently: $(cat "$T/pc.denoised.position" "$T/cli_smooth.position")"

# the numbers the examples print are the command line's (JSON values, printed
# as the examples print them: %g)
json_num() { grep -o "\"$1\":[-0-9.e+]*" "$2" | head -1 | cut -d: -f2; }
expect 0 "CLI smooth --json" -- "$P/bin/bootsurf" smooth "$T/n.ply" -o "$T/cli_smooth2.ply" --json
cp "$T/out" "$T/cli_smooth.json"
want=$(printf '%s points, h = %g: %s moved, by %g h on average' "$(json_num points "$T/cli_smooth.json")" \
  "$(json_num h "$T/cli_smooth.json")" "$(json_num moved_points "$T/cli_smooth.json")" \
  "$(json_num moved_mean_h "$T/cli_smooth.json")")
grep -qF "$want" "$T/pc.denoise.txt" && ok || fail "denoise printed '$(cat "$T/pc.denoise.txt")', bootsurf smooth: '$want'"
expect 0 "CLI error --json" -- "$P/bin/bootsurf" error "$T/n.ply" -o "$T/cli_error.ply" --json
cp "$T/out" "$T/cli_error.json"
want=$(printf '%s points, h = %g, %s replicate fits skipped' "$(json_num points "$T/cli_error.json")" \
  "$(json_num h "$T/cli_error.json")" "$(json_num replicates_skipped "$T/cli_error.json")")
grep -qF "$want" "$T/pc.estimate_error.txt" && ok ||
  fail "estimate_error printed '$(cat "$T/pc.estimate_error.txt")', bootsurf error: '$want'"
# and the values it writes are bootsurf error's err_632plus, bit for bit (CSV: 17 digits)
column() { # column FILE.csv NAME: that column's values
  awk -F, -v name="$2" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == name) c = i; next } c { print $c }' "$1"
}
expect 0 "example error as csv" -- "$P/bin/bootsurf" convert "$T/pc.error.ply" "$T/pc.error.csv" -q
expect 0 "CLI error as csv" -- "$P/bin/bootsurf" convert "$T/cli_error.ply" "$T/cli_error.csv" -q
column "$T/pc.error.csv" err_632plus >"$T/pc.err_632plus"
column "$T/cli_error.csv" err_632plus >"$T/cli.err_632plus"
[ "$(wc -l <"$T/pc.err_632plus")" -eq 2000 ] && cmp -s "$T/pc.err_632plus" "$T/cli.err_632plus" && ok ||
  fail "estimate_error's err_632plus differs from bootsurf error's ($(wc -l <"$T/pc.err_632plus") values)"
finish
