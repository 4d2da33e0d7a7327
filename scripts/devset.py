#!/usr/bin/python3
"""devset -- the development set of bootsurf's statistics (issues 22 and 24).

Builds, once, noisy point clouds with their ground truth from Debian CGAL's
meshes and from generated shapes, so that K selection, smoothing and feature
detection are measured on many models and noise levels, not on the two the
thesis tuned on. Nothing here computes a result: the cases are made and scored
by the bootsurf command itself (`sample`, `generate`, `noise`, `eval`).

usage:
  /usr/bin/python3 scripts/devset.py build --bootsurf BUILD/bootsurf \
      [--meshes DIR] [--out DIR] [--quick] [--only SUBSTR] [--noise LIST] [--models LIST]
      [--jobs N]
  /usr/bin/python3 scripts/devset.py list [--out DIR]

--meshes is the folder of Debian's CGAL meshes (data/meshes of
/usr/share/doc/libcgal-dev/data.tar.gz; `scripts/get-data.sh --all DIR`
extracts it). Every case is a folder DIR/<case>/ with
  truth.ply    the clean points: x y z nx ny nz feature feature_dist
               (and `comment bootsurf shape NAME` for generated shapes)
  noisy.ply    the same points displaced by the case's noise: x y z only, so no
               result can inherit the truth
  surface.off  the true surface for position errors (absent for generated shapes:
               `eval` then uses the exact shape named in truth.ply)
  case.json    name, model, sampling, noise, n, h (truth's mean spacing), diag
A case is rebuilt only when one of its files is missing. --models M1,M2 builds only
those meshes (both samplings) and no generated shape; with --noise, any level
(u0.35, g0.4 ...): the held-out set of scripts/heldout.py.

Cases (name = MODEL_SAMPLING_NOISE):
  models    fandisk_large bunny00 elephant dino couplingdown joint femur camel,
            sampled as `vertices` (the mesh's vertices, area-weighted mesh normals;
            several of these meshes are coarse or CAD-sampled: hard cases) and as
            `area50k` (50,000 points uniform by area, face normals);
  generated cube sphere torus as `aniso`: 100,000 random points thinned with keep
            probability 0.1^t, t = (x - xmin) / (xmax - xmin), so the density varies
            10x across the shape (about 39,000 points); cube and torus as `regular`
            (50,000 points, evenly spaced);
  thin      `plate` (a 2 x 2 slab) and `shell` (a hemispherical bowl of radius 1),
            50,000 points by area, whose two faces are 0.6 point spacings apart, so
            the opposite face lies inside most neighbourhoods;
  noise     u0.25 u0.5: uniform t ~ U[-xi, xi] times h along the normal (thesis 4.2);
            g0.25 g0.6 g1.2: gaussian, sigma = 0.25%, 0.6%, 1.2% of the bounding-box
            diagonal (PCPNet's protocol); gh0.5: gaussian, sigma = 0.5 h (the
            README's cube) -- built for the `regular` shapes only.

As a module (sys.path.insert(0, "scripts"); import devset):
  devset.load(DIR, only=None) -> [Case]   Case: name model sampling noise truth
                                           noisy surface h diag n (paths as str)
  devset.evaluate(bootsurf, result, case, split=None) -> dict of `bootsurf eval
      RESULT --truth TRUTH [--surface MESH] --json` (normals, features, position)
  devset.read_ply(path) -> (dict name -> numpy array, comments)
  devset.write_ply(path, fields, comments=()) binary little-endian
"""
import argparse
import json
import math
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

MODELS = ["fandisk_large", "bunny00", "elephant", "dino", "couplingdown", "joint", "femur",
          "camel"]
NOISES = ["u0.25", "u0.5", "g0.25", "g0.6", "g1.2"]
QUICK_MODELS = ["fandisk_large", "elephant"]
QUICK_NOISES = ["u0.5", "g0.6"]
AREA_POINTS = 50000
ANISO_POINTS = 100000
THIN_GAP = 0.6  # the thin shapes' wall, in point spacings sqrt(area / points)

PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
             "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
             "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
             "float64": "f8"}
NP_TO_PLY = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int",
             "u4": "uint", "f4": "float", "f8": "double"}


# --- PLY (vertex element only) ----------------------------------------------------
def read_ply(path):
    """A PLY file's vertex properties as {name: 1-d array} and its comment lines."""
    with open(path, "rb") as f:
        if f.readline().strip() != b"ply":
            raise ValueError("%s: not a PLY file" % path)
        fmt, comments, props, count, in_vertex, before = None, [], [], 0, False, 0
        while True:
            line = f.readline()
            if not line:
                raise ValueError("%s: header without end_header" % path)
            w = line.decode("ascii", "replace").split()
            if not w:
                continue
            if w[0] == "end_header":
                break
            if w[0] == "format":
                fmt = w[1]
            elif w[0] == "comment":
                comments.append(line.decode("ascii", "replace").strip()[len("comment "):])
            elif w[0] == "element":
                in_vertex = w[1] == "vertex"
                if in_vertex:
                    count = int(w[2])
                elif count == 0:
                    before += 1  # an element before vertex: not supported below
            elif w[0] == "property" and in_vertex:
                if w[1] == "list":
                    raise ValueError("%s: list property in vertex" % path)
                props.append((w[2], PLY_TYPES[w[1]]))
        if before:
            raise ValueError("%s: elements before vertex" % path)
        if fmt == "ascii":
            data = np.loadtxt(f, max_rows=count, ndmin=2)
            return {n: data[:, i].astype(t) for i, (n, t) in enumerate(props)}, comments
        order = "<" if fmt == "binary_little_endian" else ">"
        dt = np.dtype([(n, order + t) for n, t in props])
        rec = np.frombuffer(f.read(dt.itemsize * count), dtype=dt, count=count)
        return {n: rec[n].astype(rec[n].dtype.newbyteorder("=")) for n, _ in props}, comments


def write_ply(path, fields, comments=()):
    """Writes {name: array} (same lengths) as a binary little-endian PLY."""
    names = list(fields)
    n = len(fields[names[0]]) if names else 0
    dt = np.dtype([(k, "<" + np.asarray(fields[k]).dtype.str[1:]) for k in names])
    rec = np.empty(n, dtype=dt)
    for k in names:
        rec[k] = fields[k]
    head = ["ply", "format binary_little_endian 1.0"]
    head += ["comment " + c for c in comments]
    head.append("element vertex %d" % n)
    head += ["property %s %s" % (NP_TO_PLY[dt[k].str[1:]], k) for k in names]
    head.append("end_header")
    tmp = path + ".part"
    with open(tmp, "wb") as f:
        f.write(("\n".join(head) + "\n").encode("ascii"))
        f.write(rec.tobytes())
    os.replace(tmp, path)


def write_off(path, verts, faces):
    tmp = path + ".part"
    with open(tmp, "w") as f:
        f.write("OFF\n%d %d 0\n" % (len(verts), len(faces)))
        for v in verts:
            f.write("%.17g %.17g %.17g\n" % tuple(v))
        for t in faces:
            f.write("3 %d %d %d\n" % tuple(t))
    os.replace(tmp, path)


# --- thin shapes -----------------------------------------------------------------
def gap_for(area):
    """THIN_GAP point spacings of AREA_POINTS points over `area`."""
    return THIN_GAP * math.sqrt(area / AREA_POINTS)


def plate_mesh():
    """A 2 x 2 slab, its two faces `gap` apart (sides included in the area)."""
    gap = gap_for(8.0)
    for _ in range(3):  # the sides add a little area
        gap = gap_for(8.0 + 8.0 * gap)
    v = np.array([[x, y, z] for z in (0.0, gap) for y in (-1.0, 1.0) for x in (-1.0, 1.0)])
    # vertex index = 4 * top + 2 * (y > 0) + (x > 0); faces outward
    f = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6),  # bottom (-z), top (+z)
         (0, 1, 5), (0, 5, 4), (2, 6, 7), (2, 7, 3),  # y = -1, y = +1
         (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]  # x = -1, x = +1
    return v, np.array(f)


def shell_mesh(nlat=96, nlon=192):
    """A hemispherical bowl: outer radius 1, inner 1 - gap, joined by a flat rim at z = 0."""
    gap = gap_for(4.0 * math.pi)
    verts, faces = [], []

    def ring(r, k):  # vertices of latitude row k (0 = rim, nlat = pole) on radius r
        th = (math.pi / 2) * k / nlat
        return [(r * math.cos(th) * math.cos(p), r * math.cos(th) * math.sin(p), -r * math.sin(th))
                for p in np.linspace(0, 2 * math.pi, nlon, endpoint=False)]

    def sheet(r, outward):
        base = len(verts)
        for k in range(nlat):
            verts.extend(ring(r, k))
        pole = len(verts)
        verts.append((0.0, 0.0, -r))
        for k in range(nlat):
            for j in range(nlon):
                a = base + k * nlon + j
                b = base + k * nlon + (j + 1) % nlon
                if k + 1 < nlat:
                    c, d = a + nlon, b + nlon
                    tri = [(a, c, b), (b, c, d)]
                else:
                    tri = [(a, pole, b)]
                for t in tri:
                    faces.append(t if outward else (t[0], t[2], t[1]))
        return base

    outer = sheet(1.0, True)
    inner = sheet(1.0 - gap, False)
    for j in range(nlon):  # the rim: outer row 0 to inner row 0, facing +z
        a, b = outer + j, outer + (j + 1) % nlon
        c, d = inner + j, inner + (j + 1) % nlon
        faces.append((a, b, c))
        faces.append((b, d, c))
    return np.array(verts), np.array(faces)


# --- building ----------------------------------------------------------------------
class Case:
    def __init__(self, d):
        self.__dict__.update(d)

    def __repr__(self):
        return "Case(%s)" % self.name


def run(args, quiet=True):
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError("failed: %s\n%s" % (" ".join(map(str, args)), r.stderr))
    return r.stdout


def noise_args(noise):
    """bootsurf noise's options for a noise name (u0.5, g0.6, gh0.5)."""
    if noise.startswith("gh"):
        return ["--level", noise[2:], "--model", "gaussian"]
    if noise.startswith("u"):
        return ["--level", noise[1:], "--model", "uniform"]
    if noise.startswith("g"):
        return ["--sigma-diag", "%g" % (float(noise[1:]) / 100.0)]
    raise ValueError("unknown noise %s" % noise)


def shapes(meshes, quick, models=None):
    """(model, sampling, how) for every clean shape of the set; with `models` (a list of
    mesh names in `meshes`), those meshes' two samplings only (the held-out set)."""
    out = []
    if models:
        for m in models:
            path = os.path.join(meshes, m + ".off")
            out += [(m, "vertices", ("mesh", path, 0)), (m, "area50k", ("mesh", path, AREA_POINTS))]
        return out
    for m in (QUICK_MODELS if quick else MODELS):
        path = os.path.join(meshes, m + ".off")
        out.append((m, "vertices", ("mesh", path, 0)))
        if not quick:
            out.append((m, "area50k", ("mesh", path, AREA_POINTS)))
    for s in (["cube"] if quick else ["cube", "sphere", "torus"]):
        out.append((s, "aniso", ("aniso", s)))
    if not quick:
        for s in ["cube", "torus"]:
            out.append((s, "regular", ("regular", s)))
    out.append(("plate", "thin", ("thin", "plate")))
    if not quick:
        out.append(("shell", "thin", ("thin", "shell")))
    return out


def make_truth(bs, how, shape_dir):
    """Writes shape_dir/truth.ply (and surface.off); returns the surface path or None."""
    truth = os.path.join(shape_dir, "truth.ply")
    kind = how[0]
    if kind == "mesh":
        _, path, n = how
        args = [bs, "sample", path, "-q", "-o", truth]
        if n:
            args[3:3] = ["-n", str(n)]
        run(args)
        return path
    if kind == "regular":
        run([bs, "generate", how[1], "-n", str(AREA_POINTS), "-q", "-o", truth])
        return None
    if kind == "aniso":
        dense = os.path.join(shape_dir, "dense.ply")
        run([bs, "generate", how[1], "-n", str(ANISO_POINTS), "--sampling", "random", "--seed", "7",
             "-q", "-o", dense])
        f, comments = read_ply(dense)
        x = f["x"]
        t = (x - x.min()) / (x.max() - x.min())
        # fixed-seed uniform draws: the same thinning every build
        keep = np.random.default_rng(20261125).random(len(x)) < 0.1 ** t
        write_ply(truth, {k: v[keep] for k, v in f.items()}, comments)
        os.remove(dense)
        return None
    if kind == "thin":
        v, faces = plate_mesh() if how[1] == "plate" else shell_mesh()
        surface = os.path.join(shape_dir, "surface.off")
        write_off(surface, v, faces)
        run([bs, "sample", surface, "-n", str(AREA_POINTS), "-q", "-o", truth])
        return surface
    raise ValueError(kind)


def build_case(bs, out, model, sampling, how, noise, truth_src, surface_src):
    name = "%s_%s_%s" % (model, sampling, noise)
    d = os.path.join(out, name)
    files = ["truth.ply", "noisy.ply", "case.json"]
    if all(os.path.exists(os.path.join(d, f)) for f in files):
        return name, "kept"
    os.makedirs(d, exist_ok=True)
    truth = os.path.join(d, "truth.ply")
    if not os.path.exists(truth):
        try:
            os.link(truth_src, truth)
        except OSError:
            import shutil
            shutil.copyfile(truth_src, truth)
    tmp = os.path.join(d, "noisy_full.ply")
    info = json.loads(run([bs, "noise", truth, "--seed", "1", "--json", "-o", tmp] + noise_args(noise)))
    f, _ = read_ply(tmp)
    write_ply(os.path.join(d, "noisy.ply"), {k: f[k] for k in ("x", "y", "z")})
    os.remove(tmp)
    t, _ = read_ply(truth)
    p = np.stack([t["x"], t["y"], t["z"]], 1)
    diag = float(np.linalg.norm(p.max(0) - p.min(0)))
    surface = None
    if surface_src:
        surface = os.path.join(d, "surface.off")
        if not os.path.exists(surface):
            os.symlink(os.path.abspath(surface_src), surface)
    meta = {"name": name, "model": model, "sampling": sampling, "noise": noise, "n": len(p),
            "h": info["h"], "diag": diag, "noise_sigma": info.get("sigma"),
            "surface": "surface.off" if surface else None}
    with open(os.path.join(d, "case.json.part"), "w") as fh:
        json.dump(meta, fh, indent=1)
    os.replace(os.path.join(d, "case.json.part"), os.path.join(d, "case.json"))
    return name, "built"


def build(args):
    bs = os.path.abspath(args.bootsurf)
    if os.path.isdir(bs):
        bs = os.path.join(bs, "bootsurf")
    out = os.path.abspath(args.out)
    os.makedirs(os.path.join(out, ".shapes"), exist_ok=True)
    noises = args.noise.split(",") if args.noise else (QUICK_NOISES if args.quick else NOISES)
    jobs = []
    models = args.models.split(",") if args.models else None
    for model, sampling, how in shapes(args.meshes, args.quick, models):
        if how[0] == "mesh" and not os.path.exists(how[1]):
            sys.exit("devset: %s is missing (scripts/get-data.sh --all %s)" % (how[1], args.meshes))
        ns = list(noises) + (["gh0.5"] if sampling == "regular" and not args.noise else [])
        names = ["%s_%s_%s" % (model, sampling, n) for n in ns]
        if args.only and not any(args.only in n for n in names):
            continue
        jobs.append((model, sampling, how, ns))

    def one(job):
        model, sampling, how, ns = job
        sd = os.path.join(out, ".shapes", "%s_%s" % (model, sampling))
        os.makedirs(sd, exist_ok=True)
        truth = os.path.join(sd, "truth.ply")
        surface = os.path.join(sd, "surface.off") if how[0] == "thin" else (
            how[1] if how[0] == "mesh" else None)
        if not os.path.exists(truth):
            make_truth(bs, how, sd)
        done = []
        for n in ns:
            name = "%s_%s_%s" % (model, sampling, n)
            if args.only and args.only not in name:
                continue
            done.append(build_case(bs, out, model, sampling, how, n, truth, surface))
        return done

    with ThreadPoolExecutor(max_workers=args.jobs) as ex:
        for done in ex.map(one, jobs):
            for name, what in done:
                print("%-32s %s" % (name, what))


def load(out, only=None):
    """The cases under `out` (built by `devset.py build`), sorted by name."""
    cases = []
    for name in sorted(os.listdir(out)):
        d = os.path.join(out, name)
        meta = os.path.join(d, "case.json")
        if name.startswith(".") or not os.path.exists(meta):
            continue
        if only and only not in name:
            continue
        with open(meta) as fh:
            c = json.load(fh)
        c["truth"] = os.path.join(d, "truth.ply")
        c["noisy"] = os.path.join(d, "noisy.ply")
        c["surface"] = os.path.join(d, c["surface"]) if c.get("surface") else None
        c["dir"] = d
        cases.append(Case(c))
    return cases


def evaluate(bootsurf, result, case, split=None, threads=0):
    """`bootsurf eval RESULT --truth TRUTH [--surface MESH] --json` as a dict."""
    args = [bootsurf, "eval", result, "--truth", case.truth, "--json", "-j", str(threads)]
    if case.surface:
        args += ["--surface", case.surface]
    if split:
        args += ["--split", split]
    return json.loads(run(args))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build", help="make the cases (kept ones are not rebuilt)")
    b.add_argument("--bootsurf", required=True, help="the bootsurf binary or its build folder")
    b.add_argument("--meshes", default="data/meshes", help="Debian CGAL's data/meshes folder")
    b.add_argument("--out", default="devset", help="where the cases go (default: devset/)")
    b.add_argument("--quick", action="store_true",
                   help="a small subset: %s and cube aniso, plate; noise %s"
                   % (" ".join(QUICK_MODELS), " ".join(QUICK_NOISES)))
    b.add_argument("--only", help="only cases whose name contains this")
    b.add_argument("--noise", help="comma-separated noises instead of the default list")
    b.add_argument("--models", help="comma-separated meshes of --meshes (vertices and area50k) "
                   "instead of the set's models and generated shapes (scripts/heldout.py)")
    b.add_argument("--jobs", type=int, default=2, help="shapes built at once (default 2)")
    ls = sub.add_parser("list", help="list the built cases")
    ls.add_argument("--out", default="devset")
    a = ap.parse_args()
    if a.cmd == "build":
        build(a)
    else:
        for c in load(a.out):
            print("%-32s n=%-7d h=%.6g diag=%.6g surface=%s" % (c.name, c.n, c.h, c.diag,
                                                               c.surface or "(shape)"))


if __name__ == "__main__":
    main()
