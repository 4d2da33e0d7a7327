#!/usr/bin/env bash
# Formats with other programs (docs/formats.md): PCD written by bootsurf read
# by PCL (pcl_pcd2ply) and Open3D with the right values, PCL's PCD (binary
# and binary_compressed) read by bootsurf, LAS read by the independent npm
# reader @loaders.gl/las, pipes through - and formats found from the content.
# Each outside tool is skipped with a message when it is absent.
. "$(dirname "$0")/common.inc"

expect 0 "generate" -- "$BSURF" generate cube -n 400 --seed 5 -o "$T/a.ply" -q
# the reference values: csv of every field
expect 0 "reference csv" -- "$BSURF" convert "$T/a.ply" "$T/ref.csv" -q

# ---- pipes and detection by content ----
"$BSURF" convert "$T/a.ply" - --format pcd -q <"$T/a.ply" | "$BSURF" convert - --format csv - -q >"$T/pipe.csv" 2>"$T/err"
cmp -s "$T/pipe.csv" "$T/ref.csv" && ok || fail "ply -> pcd -> csv through pipes differs"
"$BSURF" convert - "$T/stdin.csv" -q <"$T/a.ply" 2>"$T/err"
cmp -s "$T/stdin.csv" "$T/ref.csv" && ok || fail "standard input (ply by content) differs"
cp "$T/a.ply" "$T/really_ply.xyz"
expect 0 "ply called .xyz" -- "$BSURF" convert "$T/really_ply.xyz" "$T/det.csv" -q
cmp -s "$T/det.csv" "$T/ref.csv" && ok || fail "ply called .xyz: not read as ply"
expect 2 "stdout without --format" -- "$BSURF" convert "$T/a.ply" - -q
stderr_has "needs --format" "stdout without --format"
# -o - : the cloud on stdout, the summary on stderr
"$BSURF" noise "$T/a.ply" --level 0.1 -o - --format ply >"$T/noise_out.ply" 2>"$T/err"
head -c 3 "$T/noise_out.ply" | grep -q ply && ok || fail "noise -o -: stdout is not a ply"
grep -q "noise gaussian" "$T/err" && ok || fail "noise -o -: the summary is not on stderr"

# ---- every format back to the same csv ----
for f in pcd las csv asc; do
  expect 0 "to $f" -- "$BSURF" convert "$T/a.ply" "$T/a.$f" -q
  expect 0 "from $f" -- "$BSURF" convert "$T/a.$f" "$T/back_$f.csv" -q
done
cmp -s "$T/back_pcd.csv" "$T/ref.csv" && ok || fail "pcd round trip differs"
cmp -s "$T/back_csv.csv" "$T/ref.csv" && ok || fail "csv round trip differs"
cmp -s "$T/back_asc.csv" "$T/ref.csv" && ok || fail "asc round trip differs"
# LAS: the fields exactly, the coordinates within the scale (1e-9 here)
/usr/bin/python3 - "$T/ref.csv" "$T/back_las.csv" <<'PY' && ok || fail "las round trip"
import sys
a = [l.rstrip("\n").split(",") for l in open(sys.argv[1])]
b = [l.rstrip("\n").split(",") for l in open(sys.argv[2])]
assert a[0] == b[0] and len(a) == len(b), (a[0], b[0])
for ra, rb in zip(a[1:], b[1:]):
    for j, (x, y) in enumerate(zip(ra, rb)):
        if j < 3:
            assert abs(float(x) - float(y)) <= 0.5e-9 * 1.000001, (x, y)
        else:
            assert x == y, (a[0][j], x, y)
PY

# ---- the LAS header's creation date: 0 0 (same bytes on every run), or
# SOURCE_DATE_EPOCH's UTC date when it is set (docs/formats.md) ----
las_date() { od -An -tu2 -j90 -N4 "$1" | tr -s ' ' | sed 's/^ //; s/ $//'; }
(unset SOURCE_DATE_EPOCH; "$BSURF" convert "$T/a.ply" "$T/d0.las" -q && "$BSURF" convert "$T/a.ply" "$T/d0b.las" -q) &&
  ok || fail "las without SOURCE_DATE_EPOCH"
[ "$(las_date "$T/d0.las")" = "0 0" ] && ok || fail "las date without SOURCE_DATE_EPOCH: $(las_date "$T/d0.las")"
cmp -s "$T/d0.las" "$T/d0b.las" && ok || fail "two las runs differ"
SOURCE_DATE_EPOCH=1700000000 "$BSURF" convert "$T/a.ply" "$T/d1.las" -q && ok || fail "las with SOURCE_DATE_EPOCH"
[ "$(las_date "$T/d1.las")" = "318 2023" ] && ok || fail "las date of 1700000000 (2023-11-14): $(las_date "$T/d1.las")"
[ "$(cmp -l "$T/d0.las" "$T/d1.las" | awk '$1 < 91 || $1 > 94' | wc -l)" -eq 0 ] && ok || fail "SOURCE_DATE_EPOCH changed more than the date"
SOURCE_DATE_EPOCH=1700000000 "$BSURF" convert "$T/a.ply" "$T/d12.las" --las-version 1.2 -q && [ "$(las_date "$T/d12.las")" = "318 2023" ] &&
  ok || fail "las 1.2 date: $(las_date "$T/d12.las")"
SOURCE_DATE_EPOCH=soon "$BSURF" convert "$T/a.ply" "$T/dbad.las" -q 2>"$T/err"
[ $? -eq 1 ] && [ ! -e "$T/dbad.las" ] && ok || fail "a malformed SOURCE_DATE_EPOCH: not refused, or a file written"
stderr_has "dbad.las: SOURCE_DATE_EPOCH='soon' is not a number of seconds since 1970" "malformed SOURCE_DATE_EPOCH"

# ---- PCL ----
if command -v pcl_pcd2ply >/dev/null 2>&1 && command -v pcl_ply2pcd >/dev/null 2>&1; then
  for mode in "" --ascii; do
    expect 0 "pcd for pcl $mode" -- "$BSURF" convert "$T/a.ply" "$T/pcl_in.pcd" --float32 $mode -q
    expect 0 "pcl_pcd2ply $mode" -- pcl_pcd2ply "$T/pcl_in.pcd" "$T/pcl_out.ply"
    expect 0 "read pcl's ply" -- "$BSURF" convert "$T/pcl_out.ply" "$T/pcl_out.csv" -q
    expect 0 "float32 reference" -- "$BSURF" convert "$T/a.ply" "$T/ref32.csv" --float32 -q
    expect 0 "float32 reference csv" -- "$BSURF" convert "$T/ref32.csv" "$T/ref32b.csv" -q
    cmp -s "$T/pcl_out.csv" "$T/ref32b.csv" && ok || fail "pcl_pcd2ply of our pcd $mode: values differ"
  done
  expect 0 "pcl_ply2pcd" -- pcl_ply2pcd "$T/a.ply" "$T/pcl.pcd"
  expect 0 "read pcl's pcd" -- "$BSURF" convert "$T/pcl.pcd" "$T/pcl_pcd.csv" -q
  cmp -s "$T/pcl_pcd.csv" "$T/ref.csv" && ok || fail "pcl's pcd read back differs"
  if command -v pcl_convert_pcd_ascii_binary >/dev/null 2>&1; then
    expect 0 "pcl binary_compressed" -- pcl_convert_pcd_ascii_binary "$T/pcl.pcd" "$T/pcl_c.pcd" 2
    grep -a -q "DATA binary_compressed" "$T/pcl_c.pcd" && ok || fail "pcl did not compress"
    expect 0 "read binary_compressed" -- "$BSURF" convert "$T/pcl_c.pcd" "$T/pcl_c.csv" -q
    cmp -s "$T/pcl_c.csv" "$T/ref.csv" && ok || fail "pcl's binary_compressed pcd read back differs"
  fi
  # packed colour: red green blue through PCL
  printf 'x,y,z,red,green,blue\n0,0,0,255,0,10\n1,0.5,0.25,3,200,0\n' >"$T/rgb.csv"
  expect 0 "rgb pcd" -- "$BSURF" convert "$T/rgb.csv" "$T/rgb.pcd" -q
  expect 0 "pcl rgb" -- pcl_pcd2ply "$T/rgb.pcd" "$T/rgb.ply"
  expect 0 "rgb back" -- "$BSURF" convert "$T/rgb.ply" "$T/rgb_back.csv" -q
  cmp -s "$T/rgb_back.csv" "$T/rgb.csv" && ok || fail "packed rgb through PCL differs"
else
  echo "SKIP: PCL: pcl_pcd2ply / pcl_ply2pcd not installed (apt-get install pcl-tools)"
fi

# ---- PLY -> PCD keeps every type: float32 normals and fields stay 4 bytes
# beside double coordinates (nothing lost, nothing inflated) ----
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float curv\nproperty ushort i\nproperty uchar f\nend_header\n0.1 0.2 0.3 0 0 1 0.5 7 1\n1.1 0.2 0.3 0.6 0.8 0 0.1 65535 0\n0.1 1.2 0.3 1 0 0 -2.75 0 255\n' >"$T/mixed.ply"
expect 0 "mixed types, csv" -- "$BSURF" convert "$T/mixed.ply" "$T/mixed.csv" -q
for mode in "" --ascii; do
  expect 0 "mixed types to pcd $mode" -- "$BSURF" convert "$T/mixed.ply" "$T/mixed.pcd" $mode -q
  grep -aqx "SIZE 8 8 8 4 4 4 4 2 1" "$T/mixed.pcd" && grep -aqx "TYPE F F F F F F F U U" "$T/mixed.pcd" && ok ||
    fail "ply -> pcd $mode: types not kept: $(grep -a -e ^SIZE -e ^TYPE "$T/mixed.pcd" | tr '\n' ' ')"
  expect 0 "mixed pcd back $mode" -- "$BSURF" convert "$T/mixed.pcd" "$T/mixed_back.ply" -q
  grep -a "^property" "$T/mixed_back.ply" | tr '\n' ' ' | grep -q "^property double x property double y property double z property float nx property float ny property float nz property float curv property ushort i property uchar f $" && ok ||
    fail "pcd -> ply $mode: types: $(grep -a ^property "$T/mixed_back.ply" | tr '\n' ' ')"
  if command -v pcl_pcd2ply >/dev/null 2>&1; then # PCL's own reader: the types and the values
    expect 0 "pcl_pcd2ply of mixed types $mode" -- pcl_pcd2ply "$T/mixed.pcd" "$T/mixed_pcl.ply"
    grep -a "^property" "$T/mixed_pcl.ply" | head -9 | tr '\n' ' ' | grep -q "^property double x property double y property double z property float nx property float ny property float nz property float curv property ushort i property uchar f $" && ok ||
      fail "pcl_pcd2ply $mode: types: $(grep -a ^property "$T/mixed_pcl.ply" | head -9 | tr '\n' ' ')"
    expect 0 "pcl's ply of mixed types $mode" -- "$BSURF" convert "$T/mixed_pcl.ply" "$T/mixed_pcl.csv" -q
    cmp -s "$T/mixed_pcl.csv" "$T/mixed.csv" && ok || fail "pcl_pcd2ply $mode: values differ"
  fi
done

# ---- Open3D ----
O3D_PY=${BSURF_OPEN3D_PYTHON:-/usr/bin/python3}
if "$O3D_PY" -c 'import open3d' >/dev/null 2>&1; then
  # Debian's Open3D (0.16) reads binary PCD doubles as zeros: binary with
  # --float32 (compared with the float values), ascii as they are
  expect 0 "float32 csv" -- "$BSURF" convert "$T/a.ply" "$T/o3d32.csv" --float32 -q
  expect 0 "float32 csv again" -- "$BSURF" convert "$T/o3d32.csv" "$T/o3d32b.csv" -q
  for mode in --float32 --ascii; do
    expect 0 "pcd for open3d $mode" -- "$BSURF" convert "$T/a.ply" "$T/o3d.pcd" $mode -q
    ref=$T/ref.csv
    [ "$mode" = --float32 ] && ref=$T/o3d32b.csv
    "$O3D_PY" - "$T/o3d.pcd" "$ref" <<'PY' >"$T/o3d.log" 2>&1 && ok || { fail "open3d reads our pcd $mode"; head -5 "$T/o3d.log"; }
import sys, numpy as np, open3d as o3d
pc = o3d.io.read_point_cloud(sys.argv[1])
ref = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1)
p, n = np.asarray(pc.points), np.asarray(pc.normals)
assert p.shape == (len(ref), 3), p.shape
assert np.array_equal(p, ref[:, :3]), "points"
assert np.array_equal(n, ref[:, 3:6]), "normals"
PY
  done
  # the tensor API: every field with its type (float32 curv, uint16 i, uint8
  # f beside double positions). Its normals take the positions' type: when
  # the file's differ (float beside double) Open3D 0.16 reads them wrongly
  # (docs/formats.md), so they are checked only where the types agree.
  for mode in --ascii --float32; do
    expect 0 "mixed pcd for open3d $mode" -- "$BSURF" convert "$T/mixed.ply" "$T/mixed_o3d.pcd" $mode -q
    "$O3D_PY" - "$T/mixed_o3d.pcd" "$T/mixed.csv" "$mode" <<'PY' >"$T/o3d.log" 2>&1 && ok || { fail "open3d tensor reads our mixed pcd $mode"; head -5 "$T/o3d.log"; }
import sys, numpy as np, open3d as o3d
pc = o3d.t.io.read_point_cloud(sys.argv[1])
ref = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1)
f32 = sys.argv[3] == "--float32"
want = {"positions": o3d.core.float32 if f32 else o3d.core.float64, "curv": o3d.core.float32,
        "i": o3d.core.uint16, "f": o3d.core.uint8}
for k, t in want.items():
    assert pc.point[k].dtype == t, (k, pc.point[k].dtype)
p = pc.point.positions.numpy()
assert np.array_equal(p, ref[:, :3].astype(p.dtype)), "positions"
assert np.array_equal(pc.point.curv.numpy()[:, 0], ref[:, 6].astype(np.float32)), "curv"
assert np.array_equal(pc.point.i.numpy()[:, 0], ref[:, 7]), "i"
assert np.array_equal(pc.point.f.numpy()[:, 0], ref[:, 8]), "f"
if f32:
    assert np.array_equal(pc.point.normals.numpy(), ref[:, 3:6].astype(np.float32)), "normals"
PY
  done
else
  echo "SKIP: Open3D: '$O3D_PY -c \"import open3d\"' failed (apt-get install python3-open3d)"
fi

# ---- an independent LAS reader: @loaders.gl/las (npm) ----
NPM_DIR=${BSURF_NPM_CACHE:-$(dirname "$T")/npm-las}
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  echo "SKIP: @loaders.gl/las: node or npm not installed"
else
  if [ ! -d "$NPM_DIR/node_modules/@loaders.gl/las" ]; then
    mkdir -p "$NPM_DIR"
    timeout 300 npm install --no-audit --no-fund --prefix "$NPM_DIR" @loaders.gl/las @loaders.gl/core >"$NPM_DIR/npm.log" 2>&1 || true
  fi
  if [ ! -d "$NPM_DIR/node_modules/@loaders.gl/las" ]; then
    echo "SKIP: @loaders.gl/las: npm install failed (no registry access?): $(tail -1 "$NPM_DIR/npm.log")"
  else
    # @loaders.gl/las (4.x) reads LAS up to 1.3: bootsurf's LAS 1.2 output
    # (--las-version 1.2, point format 1 or 3) with standard attributes
    printf 'x,y,z,intensity,classification,red,green,blue,w\n0,0,0,7,2,255,0,10,0.5\n1,0.5,0.25,9,6,3,200,0,0.25\n0,1,0,4,31,1,2,3,-1\n' >"$T/las_in.csv"
    expect 0 "las 1.2" -- "$BSURF" convert "$T/las_in.csv" "$T/l12.las" --las-version 1.2 -q
    expect 0 "las 1.2 of the cube" -- "$BSURF" convert "$T/a.ply" "$T/a12.las" --las-version 1.2 -q
    cat >"$T/las.mjs" <<'JS'
import {readFileSync} from 'fs';
import {createRequire} from 'module';
const require = createRequire(process.argv[2] + '/');
const {LASLoader} = require('@loaders.gl/las');
const {parse} = require('@loaders.gl/core');
const d = readFileSync(process.argv[3]);
const out = await parse(d.buffer.slice(d.byteOffset, d.byteOffset + d.byteLength), LASLoader,
                        {las: {fp64: true}, worker: false});
const a = out.attributes, n = out.header.vertexCount;
console.log(n);
for (let i = 0; i < n; i++) {
  const row = [a.POSITION.value[3 * i], a.POSITION.value[3 * i + 1], a.POSITION.value[3 * i + 2],
               a.intensity.value[i], a.classification.value[i]];
  if (a.COLOR_0) for (let k = 0; k < 3; k++) row.push(a.COLOR_0.value[a.COLOR_0.size * i + k]);
  console.log(row.join(' '));
}
JS
    for f in l12 a12; do
      node "$T/las.mjs" "$NPM_DIR/node_modules" "$T/$f.las" >"$T/$f.out" 2>&1 || { fail "@loaders.gl/las on $f.las"; head -3 "$T/$f.out"; }
    done
    /usr/bin/python3 - "$T/l12.out" "$T/las_in.csv" "$T/a12.out" "$T/ref.csv" <<'PY' >"$T/las_check.log" 2>&1 && ok || { fail "@loaders.gl/las reads our las"; cat "$T/las_check.log"; }
import sys
def rows(p, sep):
    return [[float(v) for v in l.split(sep)] for l in open(p).read().split("\n") if l and l[0] not in "xX"]
got, want = rows(sys.argv[1], " "), rows(sys.argv[2], ",")
assert int(got[0][0]) == len(want), got[0]
for g, w in zip(got[1:], want):
    assert all(abs(g[k] - w[k]) <= 0.5e-9 * 1.000001 for k in range(3)), (g, w)
    assert g[3:] == w[3:8], (g, w)  # intensity, classification, red green blue
got, want = rows(sys.argv[3], " "), rows(sys.argv[4], ",")
assert int(got[0][0]) == len(want)
for g, w in zip(got[1:], want):
    assert all(abs(g[k] - w[k]) <= 0.5e-9 * 1.000001 for k in range(3)), (g, w)
PY
    # and bootsurf reads its LAS 1.2 back with every field
    expect 0 "las 1.2 back" -- "$BSURF" convert "$T/l12.las" "$T/l12.csv" -q
    head -1 "$T/l12.csv" | grep -q '^x,y,z,intensity,classification,red,green,blue,w$' && ok || fail "las 1.2 fields: $(head -1 "$T/l12.csv")"
  fi
fi

# ---- --ply-names read back (docs/formats.md): the names bootsurf wrote for a
# viewer come back as they were, in memory and in tiled runs ----
expect 0 "cube" -- "$BSURF" generate cube -n 3000 --seed 2 -o "$T/s.ply" -q
expect 0 "plain error" -- "$BSURF" error "$T/s.ply" -o "$T/e_plain.ply" -q
for n in cloudcompare meshlab; do
  expect 0 "--ply-names $n" -- "$BSURF" convert "$T/s.ply" "$T/s_$n.ply" --ply-names "$n" -q
  grep -aq "^comment bootsurf ply-names $n\$" "$T/s_$n.ply" && ok || fail "--ply-names $n: no header comment"
  expect 0 "$n back to csv" -- "$BSURF" convert "$T/s_$n.ply" "$T/s_$n.csv" -q
  expect 0 "plain to csv" -- "$BSURF" convert "$T/s.ply" "$T/s_plain.csv" -q
  cmp -s "$T/s_$n.csv" "$T/s_plain.csv" && ok || fail "--ply-names $n: read back with other names or values"
  expect 0 "tiled error of $n names" -- "$BSURF" error "$T/s_$n.ply" -o "$T/e_$n.ply" --tile-points 1000 -q
  cmp -s "$T/e_$n.ply" "$T/e_plain.ply" && ok || fail "tiled error of a $n-named file differs from the plain file's"
done

finish
