#!/usr/bin/env bash
# LAS 1.4 read by an independent reader: the npm package `copc` (its Las
# module reads uncompressed LAS 1.2 and 1.4, point formats 0-3 and 6-8, and
# extra bytes), run by node. bootsurf's default LAS output (1.4, point format
# 6, 7 or 8, every other field as extra bytes) must give copc the same
# coordinates (within the scale), standard attributes and extra-bytes fields
# as bootsurf reads back. @loaders.gl/las, the reader of tests/cli/formats.sh,
# stops at LAS 1.3. Skipped (exit 77) when node, npm or the package is absent.
. "$(dirname "$0")/common.inc"

NPM_DIR=${BSURF_NPM_CACHE:-$(dirname "$T")}/npm-copc
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  echo "SKIP: copc (LAS 1.4 reader): node or npm not installed (apt-get install nodejs npm)"
  exit 77
fi
if [ ! -d "$NPM_DIR/node_modules/copc" ]; then
  mkdir -p "$NPM_DIR"
  timeout 300 npm install --no-audit --no-fund --prefix "$NPM_DIR" copc@0.0.8 >"$NPM_DIR/npm.log" 2>&1 || true
fi
if [ ! -d "$NPM_DIR/node_modules/copc" ]; then
  echo "SKIP: copc (LAS 1.4 reader): npm install failed (no registry access?): $(tail -1 "$NPM_DIR/npm.log")"
  exit 77
fi

# copc's view of a LAS file: the header's version and point format, then one
# JSON object a point with every dimension it finds (standard ones under
# copc's names, extra bytes under their own)
cat >"$T/copc.js" <<'JS'
const fs = require('fs');
const {Las} = require(process.argv[2] + '/copc');
(async () => {
  const path = process.argv[3];
  const buf = new Uint8Array(fs.readFileSync(path));
  const header = Las.Header.parse(buf);
  const vlrs = await Las.Vlr.walk(path, header);
  const ebVlr = Las.Vlr.find(vlrs, 'LASF_Spec', 4);
  const eb = ebVlr ? Las.ExtraBytes.parse(await Las.Vlr.fetch(path, ebVlr)) : [];
  const n = Number(header.pointCount);
  const start = header.pointDataOffset, len = n * header.pointDataRecordLength;
  const view = Las.View.create(buf.slice(start, start + len), header, eb);
  const names = Object.keys(view.dimensions);
  const get = Object.fromEntries(names.map((d) => [d, view.getter(d)]));
  console.log(JSON.stringify({version: `${header.majorVersion}.${header.minorVersion}`,
                              format: header.pointDataRecordFormat, count: n,
                              scale: header.scale, extra: eb.map((e) => e.name)}));
  for (let i = 0; i < view.pointCount; i++) {
    const row = {};
    for (const d of names) row[d] = get[d](i);
    console.log(JSON.stringify(row));
  }
})().catch((e) => { console.error(String(e)); process.exit(1); });
JS

# 1) every standard attribute of format 8 plus extra bytes of several types
cat >"$T/attrs.csv" <<'CSV'
x,y,z,intensity,return_number,number_of_returns,classification,scan_angle,user_data,point_source_id,gps_time,red,green,blue,nir,err,label,hits,w
10.25,-3.5,100.125,7,1,2,2,-1500,9,17,301234.5678901234,65535,0,1024,300,0.1234567890123,-5,40000,0.5
11.5,-2.75,99.875,900,2,2,6,2500,0,18,301234.6,12,34,56,78,1e-300,3,0,-0.25
10.75,-3.25,101.5,0,1,1,31,0,255,0,301235,0,1,2,3,-2.5,-128,65535,1.75
CSV
# 2) a generated cube with normals (extra bytes nx ny nz) and bootsurf's fields
expect 0 "generate" -- "$BSURF" generate cube -n 300 --seed 4 -o "$T/cube.ply" -q
for f in attrs cube; do
  in="$T/$f.csv"
  [ "$f" = cube ] && in="$T/cube.ply"
  expect 0 "$f to las" -- "$BSURF" convert "$in" "$T/$f.las" -q
  expect 0 "$f las back" -- "$BSURF" convert "$T/$f.las" "$T/$f.back.csv" -q
  expect 0 "$f reference" -- "$BSURF" convert "$in" "$T/$f.ref.csv" -q
  if node "$T/copc.js" "$NPM_DIR/node_modules" "$T/$f.las" >"$T/$f.copc" 2>"$T/$f.copc.err"; then
    ok
  else
    fail "copc could not read $f.las: $(head -3 "$T/$f.copc.err")"
  fi
done

/usr/bin/python3 - "$T" <<'PY' >"$T/check.log" 2>&1 && ok || { fail "copc reads our LAS 1.4 with other values"; cat "$T/check.log"; }
import csv, json, sys
T = sys.argv[1]
# bootsurf's field -> copc's dimension (LAS 1.4 R15 names)
STD = {"intensity": "Intensity", "return_number": "ReturnNumber",
       "number_of_returns": "NumberOfReturns", "classification": "Classification",
       "user_data": "UserData", "point_source_id": "PointSourceId", "gps_time": "GpsTime",
       "red": "Red", "green": "Green", "blue": "Blue", "nir": "Infrared"}
def table(p):
    with open(p) as f:
        rows = list(csv.reader(f))
    return rows[0], [[float(v) for v in r] for r in rows[1:]]
for name, want_format, want_extra in (("attrs", 8, ["err", "label", "hits", "w"]),
                                      ("cube", 6, None)):
    lines = open(f"{T}/{name}.copc").read().split("\n")
    head, pts = json.loads(lines[0]), [json.loads(l) for l in lines[1:] if l]
    assert head["version"] == "1.4", head
    assert head["format"] == want_format, head
    cols, ref = table(f"{T}/{name}.ref.csv")
    bcols, back = table(f"{T}/{name}.back.csv")
    assert sorted(cols) == sorted(bcols), (cols, bcols)  # LAS reads in its own order
    back = [[row[bcols.index(c)] for c in cols] for row in back]
    assert len(pts) == len(ref) == head["count"], (len(pts), len(ref))
    if want_extra is not None:
        assert head["extra"] == want_extra, head["extra"]
    half = head["scale"][0] / 2 * 1.000001
    checked = set()
    for p, r, b in zip(pts, ref, back):
        for k, axis in enumerate("XYZ"):
            # copc: X * scale + offset; bootsurf's own reading is the fma of it
            assert abs(p[axis] - r[k]) <= half, (axis, p[axis], r[k])
            assert abs(p[axis] - b[k]) <= 1e-9 * max(1.0, abs(b[k])), (axis, p[axis], b[k])
        for c, name_ in enumerate(cols[3:], 3):
            dim = STD.get(name_, name_)
            if name_ == "scan_angle":  # copc gives degrees (units of 0.006)
                assert abs(p["ScanAngle"] - r[c] * 0.006) < 1e-9, (p["ScanAngle"], r[c]); continue
            assert dim in p, (name_, sorted(p))
            assert p[dim] == r[c] == b[c], (name_, p[dim], r[c], b[c])
            checked.add(name_)
    print(name, "format", head["format"], "checked:", " ".join(sorted(checked)))
PY
cat "$T/check.log"
finish
