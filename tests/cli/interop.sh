#!/usr/bin/env bash
# Files other tools can read: our PLY output (double positions, float normals,
# float and uchar scalar fields; binary and ascii) loaded by Open3D and by PCL
# (pcl_ply2pcd), and what they write read back by bootsurf with every value
# intact. Each tool is skipped with a message when it is not installed
# (.ci/run installs python3-open3d and pcl-tools).
. "$(dirname "$0")/common.inc"

# Open3D is a Debian package for the system python; a python3 earlier on PATH
# (pyenv, venv) usually lacks it.
O3D_PY=${BSURF_OPEN3D_PYTHON:-/usr/bin/python3}
PY=""
for p in "$O3D_PY" python3; do
  if command -v "$p" >/dev/null 2>&1; then
    PY=$p
    break
  fi
done

# compare_ply A B [PROPERTY...]: the vertex properties (all those of A, or the
# ones named) have the same values in B, to float precision.
cat >"$T/compare_ply.py" <<'EOF'
import struct, sys

TYPES = {"char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
         "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
         "float": "f", "float32": "f", "double": "d", "float64": "d"}

def read_vertices(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt, elements = None, []
    for line in header:
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property":
            if w[1] == "list":
                elements[-1][2].append((w[4], None))
            else:
                elements[-1][2].append((w[2], TYPES[w[1]]))
    assert elements and elements[0][0] == "vertex", "the vertex element must come first"
    name, count, props = elements[0]
    names = [p[0] for p in props]
    if fmt == "ascii":
        rows = [l.split() for l in data[end:].decode("ascii").split("\n") if l.strip()][:count]
        cols = {n: [float(r[i]) for r in rows] for i, n in enumerate(names)}
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        rec = struct.Struct(order + "".join(p[1] for p in props))
        vals = [rec.unpack_from(data, end + i * rec.size) for i in range(count)]
        cols = {n: [float(v[i]) for v in vals] for i, n in enumerate(names)}
    return count, cols

na, a = read_vertices(sys.argv[1])
nb, b = read_vertices(sys.argv[2])
names = sys.argv[3:] or list(a)
bad = []
if na != nb:
    bad.append("%d points against %d" % (na, nb))
for n in names:
    if n not in a or n not in b:
        bad.append("property %s missing" % n)
        continue
    worst = max((abs(x - y) / max(1.0, abs(x)) for x, y in zip(a[n], b[n])), default=0.0)
    if worst > 1e-6:
        bad.append("%s differs by %g" % (n, worst))
if bad:
    print("; ".join(bad))
    sys.exit(1)
EOF
compare() { # compare DESCRIPTION A B [PROPERTY...]
  local what=$1
  shift
  if [ -z "$PY" ]; then
    echo "note: no python3, value comparison skipped ($what)"
    return
  fi
  if "$PY" "$T/compare_ply.py" "$@" >"$T/cmp" 2>&1; then ok; else fail "$what: $(head -3 "$T/cmp")"; fi
}
# info_has FILE DESCRIPTION KEY...: bootsurf reads FILE and its JSON info has every KEY
info_has() {
  local f=$1 what=$2
  shift 2
  expect 0 "bootsurf reads $what" -- "$BSURF" info "$f" --json
  for key in "$@"; do grep -qF -- "$key" "$T/out" && ok || fail "$what: info lacks $key: $(head -c 300 "$T/out")"; done
}

# our files: x y z double, nx ny nz float, feature_dist float, feature uchar, err_* float
expect 0 "generate" -- "$BSURF" generate cube -n 2000 --ascii -o "$T/c.ply" -q
sed 's/^property double n\([xyz]\)$/property float n\1/' "$T/c.ply" >"$T/cf.ply"
expect 0 "error (binary)" -- "$BSURF" error "$T/cf.ply" -k 20 -d 2 -B 5 -o "$T/ours.ply" -q
expect 0 "error (ascii)" -- "$BSURF" error "$T/cf.ply" -k 20 -d 2 -B 5 -o "$T/ours_ascii.ply" --ascii -q
for p in "double x" "float nx" "float feature_dist" "uchar feature" "float err_632plus"; do
  grep -a -q "^property $p\$" "$T/ours.ply" && ok || fail "our output lacks 'property $p'"
done
compare "binary and ascii outputs" "$T/ours.ply" "$T/ours_ascii.ply"
expect 0 "info" -- "$BSURF" info "$T/ours.ply" --json
N=$(sed 's/.*"points":\([0-9]*\).*/\1/' "$T/out")
ALL='"fields":["feature_dist","feature","err_train","err_boot","err_loo","err_loo_center","err_632","err_632plus","gamma","overfit_rate"]'

# ---- Open3D ---------------------------------------------------------------------
if command -v "$O3D_PY" >/dev/null 2>&1 && "$O3D_PY" -c 'import open3d' >/dev/null 2>&1; then
  cat >"$T/o3d.py" <<'EOF'
import sys
import numpy as np
import open3d as o3d

t, n = sys.argv[1], int(sys.argv[2])
for name in ("ours.ply", "ours_ascii.ply"):
    # the legacy API: positions and normals
    p = o3d.io.read_point_cloud(t + "/" + name)
    assert len(p.points) == n, (name, len(p.points))
    assert p.has_normals(), name
    # the tensor API: every vertex property with its type
    c = o3d.t.io.read_point_cloud(t + "/" + name)
    assert c.point.positions.shape[0] == n
    for key, dtype in (("feature", np.uint8), ("feature_dist", np.float32), ("err_632plus", np.float32)):
        v = c.point[key].numpy()
        assert v.dtype == dtype and v.shape[0] == n, (name, key, v.dtype, v.shape)
    assert set(np.unique(c.point["feature"].numpy())) <= {0, 1}
    assert np.isfinite(c.point["err_632plus"].numpy()).all()
p = o3d.io.read_point_cloud(t + "/ours.ply")
o3d.io.write_point_cloud(t + "/o3d_legacy.ply", p)
o3d.io.write_point_cloud(t + "/o3d_legacy_ascii.ply", p, write_ascii=True)
c = o3d.t.io.read_point_cloud(t + "/ours.ply")
o3d.t.io.write_point_cloud(t + "/o3d_tensor.ply", c)
o3d.t.io.write_point_cloud(t + "/o3d_tensor_ascii.ply", c, write_ascii=True)
print("open3d", o3d.__version__)
EOF
  expect 0 "Open3D reads and writes our files" -- "$O3D_PY" "$T/o3d.py" "$T" "$N"
  [ -s "$T/err" ] && sed 's/^/    /' "$T/err" | head -5
  echo "$(cat "$T/out"): read $N points (binary and ascii), wrote 4 files"
  for f in o3d_legacy o3d_legacy_ascii; do
    info_has "$T/$f.ply" "Open3D's $f.ply" "\"points\":$N" '"normals":true'
    compare "Open3D's $f.ply" "$T/ours.ply" "$T/$f.ply" x y z nx ny nz
  done
  for f in o3d_tensor o3d_tensor_ascii; do
    info_has "$T/$f.ply" "Open3D's $f.ply" "\"points\":$N" '"normals":true' '"feature"' '"err_632plus"' '"feature_dist"'
    compare "Open3D's $f.ply" "$T/ours.ply" "$T/$f.ply"
  done
  expect 0 "bootsurf computes on Open3D's file" -- "$BSURF" normals "$T/o3d_legacy.ply" -k 20 -B 4 -o "$T/o3d_n.ply" -q
else
  echo "SKIP: Open3D: '$O3D_PY -c \"import open3d\"' fails (apt-get install python3-open3d)"
fi

# ---- PCL ------------------------------------------------------------------------------
if command -v pcl_ply2pcd >/dev/null 2>&1 && command -v pcl_pcd2ply >/dev/null 2>&1; then
  expect 0 "pcl_ply2pcd (binary PLY)" -- pcl_ply2pcd "$T/ours.ply" "$T/pcl.pcd"
  grep -a -q "^POINTS $N\$" "$T/pcl.pcd" && ok || fail "PCL's PCD does not have $N points"
  grep -a "^FIELDS" "$T/pcl.pcd" | grep -q "x y z normal_x normal_y normal_z feature_dist feature err_train .* err_632plus gamma overfit_rate" &&
    ok || fail "PCL's PCD lacks fields: $(grep -a '^FIELDS' "$T/pcl.pcd")"
  grep -a "^TYPE" "$T/pcl.pcd" | grep -q "^TYPE F F F F F F F U F" && ok || fail "PCL's PCD types: $(grep -a '^TYPE' "$T/pcl.pcd")"
  expect 0 "pcl_ply2pcd (ascii PLY, ascii PCD)" -- pcl_ply2pcd -format 0 "$T/ours_ascii.ply" "$T/pcl_ascii.pcd"
  grep -a -q "^DATA ascii" "$T/pcl_ascii.pcd" && grep -a -q "^POINTS $N\$" "$T/pcl_ascii.pcd" && ok || fail "PCL's ascii PCD"
  for f in pcl pcl_ascii; do
    expect 0 "pcl_pcd2ply $f" -- pcl_pcd2ply "$T/$f.pcd" "$T/${f}_back.ply"
    info_has "$T/${f}_back.ply" "PCL's ${f}_back.ply" "\"points\":$N" '"normals":true' "$ALL"
    compare "PCL's ${f}_back.ply" "$T/ours.ply" "$T/${f}_back.ply"
  done
  echo "PCL: pcl_ply2pcd read $N points with every field; pcl_pcd2ply's PLY read back with the same values"
  # PCL's PCD -> PLY writes double normals as doubles under a 'float' header
  # (PCL 1.13): bootsurf must either read the file or reject it cleanly.
  expect 0 "pcl_ply2pcd (double normals)" -- pcl_ply2pcd "$T/c.ply" "$T/pcl_d.pcd"
  expect 0 "pcl_pcd2ply (double normals)" -- pcl_pcd2ply "$T/pcl_d.pcd" "$T/pcl_d_back.ply"
  "$BSURF" info "$T/pcl_d_back.ply" >"$T/out" 2>"$T/err"
  rc=$?
  case $rc in
  0) ok ;;
  1)
    stderr_has "the header does not describe the data" "PCL's double-normal PLY"
    echo "note: pcl_pcd2ply wrote double normals under a 'float' header; bootsurf rejects the file: $(cat "$T/err")"
    ;;
  *) fail "PCL's double-normal PLY: exit $rc" ;;
  esac
else
  echo "SKIP: PCL: pcl_ply2pcd / pcl_pcd2ply not found (apt-get install pcl-tools)"
fi

finish
