"""The Python package against the command line (same input, same seed: the
same bits), input conversions, determinism, interrupts, threads, bad input.

Run through ctest (tests/python/run.sh): PYTHONPATH holds build/python,
BSURF_CLI the bootsurf binary, BSURF_PY_TMP a scratch directory."""
import json
import math
import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import bootsurf

CLI = os.environ.get("BSURF_CLI", "bootsurf")
TMP = os.environ.get("BSURF_PY_TMP") or "/tmp"


def tmp(name):
    return os.path.join(TMP, name)


def cli(*args):
    """Runs the CLI; returns its JSON summary when --json is among args."""
    r = subprocess.run([CLI] + [str(a) for a in args], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout) if "--json" in args else None


def true_normals(cloud):
    """The exact normals a CLI noise output carries as true_nx true_ny true_nz."""
    return np.stack([cloud["true_nx"], cloud["true_ny"], cloud["true_nz"]], axis=1)


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype, (a.shape, b.shape, a.dtype, b.dtype)
    assert a.tobytes() == b.tobytes()


@pytest.fixture(scope="module")
def cube():
    """A noisy cube written by the CLI (generate, then noise) and read back."""
    cli("generate", "cube", "-n", 3000, "-o", tmp("cube.ply"), "-q")
    cli("noise", tmp("cube.ply"), "--level", 0.5, "--seed", 3, "-o", tmp("noisy.ply"), "-q")
    return bootsurf.read(tmp("noisy.ply"))


# ------------------------------------------------------------ the CLI's bits


def test_generate_and_noise_equal_cli(cube):
    c = bootsurf.generate("cube", points=3000)
    ref = bootsurf.read(tmp("cube.ply"))
    same_bits(c["points"], ref["points"])
    same_bits(c["feature"], ref["feature"])
    assert c.shape_name == ref.shape_name == "cube"
    noisy = bootsurf.noise(c, level=0.5, seed=3)
    same_bits(noisy, cube["points"])
    assert bootsurf.noise.last_report["h"] == pytest.approx(bootsurf.spacing(c["points"]),
                                                            abs=0)


def test_noise_sigma_diag_equals_cli():
    cli("noise", tmp("cube.ply"), "--sigma-diag", 0.006, "--seed", 5, "-o", tmp("pcp.ply"), "-q")
    c = bootsurf.read(tmp("cube.ply"))
    same_bits(bootsurf.noise(c, sigma_diag=0.006, seed=5), bootsurf.read(tmp("pcp.ply"))["points"])


def test_error_equals_cli(cube):
    summ = cli("error", tmp("noisy.ply"), "-k", 20, "-B", 10, "--seed", 7, "-o", tmp("err.ply"),
               "--json")
    ref = bootsurf.read(tmp("err.ply"))
    fields, s = bootsurf.error(cube["points"], neighbors=20, bootstrap=10, seed=7)
    assert set(fields) == set(s["means"])
    for name, values in fields.items():
        # the CLI writes the fields as float32: the same doubles rounded
        same_bits(values.astype(np.float32), ref[name])
        # the CLI prints %.10g of the library's numbers
        assert float("%.10g" % s["means"][name]) == summ["mean"][name]
    assert float("%.10g" % s["h"]) == summ["h"]
    assert s["points"] == summ["points"]
    for key in ("replicates_total", "replicates_skipped", "degree_reduced",
                "center_unestimated"):
        assert s["report"][key] == summ[key]


def test_normals_equal_cli(cube):
    cli("normals", tmp("noisy.ply"), "-k", 20, "-B", 8, "--test-error", "-o", tmp("nrm.ply"),
        "-q")
    ref = bootsurf.read(tmp("nrm.ply"))
    fields, s = bootsurf.normals(tmp("noisy.ply"), neighbors=20, bootstrap=8, test_error=True)
    same_bits(fields["normals"].astype(np.float32), ref["normals"].astype(np.float32))
    same_bits(fields["normal_var"].astype(np.float32), ref["normal_var"])
    same_bits(fields["normal_err"].astype(np.float32), ref["normal_err"])


def test_select_mse_equals_cli(cube):
    """K selection by the mse rule at its defaults (noise_k as the CLI's), with two_sheet."""
    cli("normals", tmp("noisy.ply"), "--select-k", "15:40:5", "--select-rule", "mse", "-B", 0,
        "-o", tmp("mse.ply"), "-q")
    ref = bootsurf.read(tmp("mse.ply"))
    fields, s = bootsurf.normals(cube, select_k="15:40:5", select_rule="mse", bootstrap=0)
    same_bits(fields["normals"].astype(np.float32), ref["normals"].astype(np.float32))
    for name in ("normal_err", "k_selected", "two_sheet"):
        same_bits(fields[name].astype(ref[name].dtype), ref[name])
    cli("normals", tmp("noisy.ply"), "--select-k", "15:40:5", "--select-rule", "mse", "-B", 0,
        "--noise-pool", "local", "-o", tmp("mse_local.ply"), "-q")
    ref = bootsurf.read(tmp("mse_local.ply"))
    fields, s = bootsurf.normals(cube, select_k="15:40:5", select_rule="mse", bootstrap=0,
                                 noise_pool="local")
    same_bits(fields["normals"].astype(np.float32), ref["normals"].astype(np.float32))
    same_bits(fields["k_selected"].astype(ref["k_selected"].dtype), ref["k_selected"])


def test_smooth_equals_cli(cube):
    for method, extra in (("bilateral", []), ("naive", ["--threshold", "0.5h"]),
                          ("multipass", ["--iterations", 3, "--h2", "1W"]),
                          ("bilateral", ["--degree-test", "off"])):
        cli("smooth", tmp("noisy.ply"), "--method", method, "-k", 20, "-B", 8, *extra, "-o",
            tmp("sm.ply"), "-q")
        ref = bootsurf.read(tmp("sm.ply"))
        kw = {"threshold": "0.5h"} if method == "naive" else {}
        if method == "multipass":
            kw = {"iterations": 3, "h2": "1W"}
        if "--degree-test" in extra:
            kw = {"degree_test": "off"}
        pts, fields, s = bootsurf.smooth(cube, method=method, neighbors=20, bootstrap=8, **kw)
        same_bits(pts, ref["points"])
        for name in fields:
            same_bits(fields[name].astype(np.float32), ref[name])


def test_smooth_noise_readings_equal_cli(cube):
    # the guard's two readings of the noise and the level it takes
    # (docs/smoothing.md, "Two readings"): the same numbers from both front ends
    j = cli("smooth", tmp("noisy.ply"), "-k", 20, "-B", 8, "--json", "-o", tmp("sm.ply"), "-q")
    pts, fields, s = bootsurf.smooth(cube, neighbors=20, bootstrap=8)
    r = s["report"]
    for key in ("noise", "noise_fits", "noise_select", "section_share", "misfit_fits"):
        # the CLI's JSON prints 10 significant digits, and NaN as null
        if j[key] is None:
            assert math.isnan(r[key]), (key, r[key])
        else:
            assert abs(r[key] - j[key]) <= 1e-9 * abs(j[key]), (key, r[key], j[key])
    # a cube has no cross-sections: the selection's passes are not needed
    assert math.isnan(r["noise_select"]) and 0 <= r["section_share"] <= 0.05


def test_features_equal_cli(cube):
    for method, rule, score in (("distance", "null", "feature_dist"),
                                ("variance", "null", "variance_z"),
                                ("variance", "otsu", "normal_var")):
        cli("features", tmp("noisy.ply"), "--method", method, "--tail-rule", rule, "-B", 8,
            "-o", tmp("ft.ply"), "-q")
        ref = bootsurf.read(tmp("ft.ply"))
        fields, s = bootsurf.features(cube, method=method, tail_rule=rule, bootstrap=8)
        same_bits(fields["feature"], ref["feature"])
        same_bits(fields[score].astype(np.float32), ref[score])
        assert s["report"]["feature_points"] == int(ref["feature"].sum())


def test_features_defaults_equal_cli(cube):
    """At defaults both front ends run the variance test with its chosen K."""
    summ = cli("features", tmp("noisy.ply"), "-B", 8, "-o", tmp("ftd.ply"), "--json")
    ref = bootsurf.read(tmp("ftd.ply"))
    fields, s = bootsurf.features(cube, bootstrap=8)
    same_bits(fields["feature"], ref["feature"])
    same_bits(fields["variance_z"].astype(np.float32), ref["variance_z"])
    assert s["report"]["k"] == summ["parameters"]["k"]
    assert float("%.10g" % s["report"]["edge_power"]) == summ["parameters"]["edge_power"]
    fields, s = bootsurf.features(cube, bootstrap=8, feature_angle=0)
    assert s["report"]["k"] == 30


def test_features_quadric_check_equal_cli():
    """The quadric check (docs/features.md) runs on a torus at light noise and
    clears points; both front ends give the same bits and report."""
    cli("generate", "torus", "-n", 12000, "--sampling", "random", "-o", tmp("qt.ply"), "-q")
    cli("noise", tmp("qt.ply"), "--level", 0.25, "-o", tmp("qtn.ply"), "-q")
    summ = cli("features", tmp("qtn.ply"), "-k", 15, "-B", 5, "-o", tmp("qf.ply"), "--json")
    ref = bootsurf.read(tmp("qf.ply"))
    pts = bootsurf.read(tmp("qtn.ply"))["points"]
    fields, s = bootsurf.features(pts, neighbors=15, bootstrap=5)
    same_bits(fields["feature"], ref["feature"])
    r, p = s["report"], summ["parameters"]
    assert r["quadric_k"] == p["quadric_k"] > 0
    assert r["quadric_cleared"] == p["quadric_cleared"] > 0
    assert r["border_points"] == p["border_points"] <= r["feature_points"]
    assert float("%.10g" % r["quadric_noise"]) == p["quadric_noise"]
    off, s0 = bootsurf.features(pts, neighbors=15, bootstrap=5, quadric_angle=0)
    assert s0["report"]["quadric_k"] == 0 and s0["report"]["quadric_cleared"] == 0
    assert 0 < int(off["feature"].sum()) - int(fields["feature"].sum()) <= r["quadric_cleared"]
    with pytest.raises(ValueError, match="quadric_angle"):
        bootsurf.features(pts, neighbors=15, bootstrap=5, quadric_angle=200)
    # tiled with tiles smaller than twice K_q (the stage at K_q widens them): the same bytes
    _, st = bootsurf.features(tmp("qtn.ply"), neighbors=15, bootstrap=5, output=tmp("qft.ply"),
                              tile_points=100)
    assert st["report"]["quadric_k"] == r["quadric_k"]
    assert st["report"]["quadric_cleared"] == r["quadric_cleared"]
    assert st["report"]["border_points"] == r["border_points"]
    with open(tmp("qf.ply"), "rb") as a, open(tmp("qft.ply"), "rb") as b:
        assert a.read() == b.read()


def test_render_equals_cli(cube):
    cli("render", tmp("noisy.ply"), "--size", "160x120", "-o", tmp("cli.png"), "-q")
    bootsurf.render(tmp("noisy.ply"), size=(160, 120), output=tmp("py.png"))
    with open(tmp("cli.png"), "rb") as a, open(tmp("py.png"), "rb") as b:
        assert a.read() == b.read()
    img = bootsurf.render(cube, size=(160, 120))
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    assert bootsurf.render.last_info["covered_pixels"] > 0
    # a field, four views
    cli("render", tmp("err.ply"), "--field", "err_632", "--views", 4, "--size", "200x160", "-o",
        tmp("cli4.png"), "-q")
    bootsurf.render(tmp("err.ply"), field="err_632", views=4, size=(200, 160),
                    output=tmp("py4.png"))
    with open(tmp("cli4.png"), "rb") as a, open(tmp("py4.png"), "rb") as b:
        assert a.read() == b.read()


def test_sample_equals_cli():
    # a tetrahedron: four sharp edges at every vertex
    mesh = {"points": np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float),
            "faces": np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.uint32)}
    bootsurf.write(tmp("tet.off"), mesh)
    cli("sample", tmp("tet.off"), "-n", 800, "--seed", 2, "-o", tmp("tet.ply"), "-q")
    ref = bootsurf.read(tmp("tet.ply"))
    s = bootsurf.sample(tmp("tet.off"), points=800, seed=2)
    for key in ref:
        same_bits(s[key].astype(ref[key].dtype), ref[key])
    assert bootsurf.sample.last_report["sharp_edges"] == 6


def test_tiled_runs_equal_cli_bytes(cube):
    """error, normals, smooth and features with tile_points= write the same
    bytes as the command's --tile-points, and the same values as in memory."""
    src = tmp("noisy.ply")
    runs = [("error", bootsurf.error, ["-k", 20, "-B", 5], dict(neighbors=20, bootstrap=5)),
            ("normals", bootsurf.normals, ["-k", 20, "-B", 5, "--test-error"],
             dict(neighbors=20, bootstrap=5, test_error=True)),
            ("smooth", bootsurf.smooth, ["-k", 20, "-B", 5], dict(neighbors=20, bootstrap=5)),
            ("features", bootsurf.features, ["--method", "variance", "-B", 5],
             dict(method="variance", bootstrap=5))]
    for name, fn, args, kw in runs:
        cli(name, src, *args, "--tile-points", 700, "-o", tmp("t_cli.ply"), "-q")
        r = fn(src, output=tmp("t_py.ply"), tile_points=700, **kw)
        summary = r[-1]
        assert all(x is None for x in r[:-1])
        assert summary["tiles"] > 1 and summary["points"] == len(cube["points"]), summary
        with open(tmp("t_cli.ply"), "rb") as a, open(tmp("t_py.ply"), "rb") as b:
            assert a.read() == b.read(), name
        if name == "normals":  # the tiles' values are those of the run in memory
            mem, _ = fn(src, **kw)
            got = bootsurf.read(tmp("t_py.ply"))
            same_bits(got["normal_var"], mem["normal_var"].astype(np.float32))
    with pytest.raises(TypeError, match="path"):
        bootsurf.normals(cube["points"], output=tmp("x.ply"), tile_points=500)
    with pytest.raises(ValueError, match="output"):
        bootsurf.normals(src, tile_points=500)
    with pytest.raises(ValueError, match="output"):
        bootsurf.normals(src, output=tmp("x.ply"))
    with pytest.raises(OSError, match="missing.ply"):
        bootsurf.normals(tmp("missing.ply"), output=tmp("x.ply"), tile_points=500)
    assert not os.path.exists(tmp("x.ply"))


def test_read_write_round_trip(cube):
    for ext in ("ply", "pcd", "csv", "las"):
        d = bootsurf.Cloud(cube)
        d["score"] = np.arange(len(d["points"]), dtype=np.float32)
        d["label"] = (np.arange(len(d["points"])) % 3).astype(np.uint8)
        bootsurf.write(tmp("rt." + ext), d)
        r = bootsurf.read(tmp("rt." + ext))
        assert np.array_equal(r["label"], d["label"]), ext
        assert np.array_equal(r["score"], d["score"]), ext
        if ext != "las":  # LAS stores scaled integer coordinates
            same_bits(r["points"], d["points"])
    bootsurf.write(tmp("rt.xyz"), cube["points"])
    assert np.allclose(bootsurf.read(tmp("rt.xyz"))["points"], cube["points"])


def test_evaluate_uses_eval_numbers(cube):
    fields, _ = bootsurf.normals(cube, neighbors=20, bootstrap=8)
    truth = bootsurf.read(tmp("cube.ply"))
    bootsurf.write(tmp("res.ply"), {"points": cube["points"], "normals": fields["normals"],
                                    "normal_var": fields["normal_var"]})
    bootsurf.write(tmp("truth.ply"), truth)
    summ = cli("eval", tmp("res.ply"), "--truth", tmp("truth.ply"), "--split", "normal_var:0.85", "--json")
    # float64 arrays are written as float64: the CLI reads the same numbers
    e = bootsurf.evaluate(fields["normals"], truth["normals"], split=fields["normal_var"],
                          feature=truth["feature"], true_feature=truth["feature"])
    assert float("%.10g" % e["normals"]["all"]["mean_deg"]) == summ["normals"]["mean_deg"]
    assert float("%.10g" % e["split"]["threshold"]) == summ["split"]["threshold"]
    high = summ["split"]["high"]
    assert e["normals"]["high"]["count"] == high["points"]
    assert float("%.10g" % e["normals"]["high"]["mean_rad"]) == high["normals"]["mean_rad"]
    assert e["features"]["f1"] == 1.0



def test_evaluate_features_nonzero_is_a_feature():
    """A label counts as a feature where it is not 0, as `eval` reads it
    (cli/cmd_eval.c): 0.5, 256 and -1 are features, not only 1 (a cast to
    uint8 made 0.5 and 256 into 0)."""
    res = np.array([0.5, 256.0, -1.0, 1.0, 0.0, 0.0, 0.25])
    tru = np.array([1.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0])
    e = bootsurf.evaluate(feature=res, true_feature=tru)["features"]
    assert (e["true_pos"], e["false_pos"], e["false_neg"], e["true_neg"]) == (3, 2, 1, 1)
    assert e["f1"] == 2 * 3 / (2 * 3 + 2 + 1)
    assert bootsurf.evaluate(feature=res.astype(bool), true_feature=tru)["features"] == \
        bootsurf.evaluate(feature=res != 0, true_feature=tru != 0)["features"]

def _same_json(py, js, path="position"):
    """Every number of the CLI's JSON object js equals py's, as the CLI prints
    it (%.10g: all the digits the JSON has)."""
    for key, want in js.items():
        if key == "source":
            continue
        assert key in py, (path, key)
        got = py[key]
        if isinstance(want, dict):
            _same_json(got, want, path + "." + key)
        elif isinstance(want, str) or isinstance(got, int):
            assert got == want, (path, key, got, want)
        else:
            assert float("%.10g" % got) == want, (path, key, got, want)


def test_evaluate_position_equals_cli(cube):
    """The position section: the generated cube as the surface (index
    correspondence, feature parts, split), a mesh given as surface=, and the
    tangent planes of a truth with fewer points (nearest correspondence)."""
    moved, fields, _ = bootsurf.smooth(cube, neighbors=20, bootstrap=8)
    res = {"points": moved, "err_632": fields["err_632"]}
    bootsurf.write(tmp("pos.ply"), res)
    summ = cli("eval", tmp("pos.ply"), "--truth", tmp("noisy.ply"), "--split", "err_632:0.8",
               "--json")
    e = bootsurf.evaluate(points=moved, truth=tmp("noisy.ply"), split=fields["err_632"],
                          split_q=0.8)
    assert e["position"]["surface"] == "shape" and e["position"]["correspondence"] == "index"
    assert "feature" in e["position"]["all"]
    _same_json(e["position"], {k: v for k, v in summ["position"].items()
                               if k in ("surface", "correspondence", "h")})
    _same_json(e["position"]["all"], {k: v for k, v in summ["position"].items()
                                      if k not in ("surface", "correspondence", "h", "source")})
    for g in ("high", "low"):
        _same_json(e["position"][g], summ["split"][g]["position"])
    assert e["distances"].shape == (len(moved),)
    assert e["position"]["all"]["max"] == e["distances"].max()
    # a triangle mesh as the true surface (--surface)
    mesh = {"points": np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                                [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float),
            "faces": np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                               [2, 3, 7], [2, 7, 6], [1, 2, 6], [1, 6, 5], [0, 4, 7], [0, 7, 3]],
                              np.uint32)}
    bootsurf.write(tmp("box.off"), mesh)
    summ = cli("eval", tmp("pos.ply"), "--truth", tmp("noisy.ply"), "--surface", tmp("box.off"),
               "--json")
    e = bootsurf.evaluate(points=tmp("pos.ply"), truth=tmp("noisy.ply"), surface=mesh)
    assert e["position"]["surface"] == "mesh"
    _same_json(e["position"], {k: v for k, v in summ["position"].items() if k == "surface"})
    _same_json(e["position"]["all"], {k: v for k, v in summ["position"].items()
                                      if k not in ("surface", "correspondence", "h", "source")})
    # tangent planes of a truth of other points: the nearest truth point
    truth = bootsurf.read(tmp("cube.ply"))
    sub = {"points": truth["points"][::2], "normals": truth["normals"][::2]}
    bootsurf.write(tmp("half.ply"), sub)
    summ = cli("eval", tmp("pos.ply"), "--truth", tmp("half.ply"), "--json")
    e = bootsurf.evaluate(points=moved, truth=sub, threads=1)
    assert e["position"]["surface"] == "tangent_plane"
    assert e["position"]["correspondence"] == "nearest"
    _same_json(e["position"], {k: v for k, v in summ["position"].items()
                               if k in ("surface", "correspondence", "h")})
    _same_json(e["position"]["all"], {k: v for k, v in summ["position"].items()
                                      if k not in ("surface", "correspondence", "h", "source")})
    with pytest.raises(ValueError, match="truth"):
        bootsurf.evaluate(points=moved)
    with pytest.raises(ValueError, match="no true surface"):
        bootsurf.evaluate(points=moved, truth={"points": truth["points"]})


def _find(obj, key):
    if isinstance(obj, dict):
        if key in obj:
            return obj[key]
        for v in obj.values():
            r = _find(v, key)
            if r is not None:
                return r
    return None


# ------------------------------------------------------------ conversions


def test_float32_and_non_contiguous(cube):
    p = cube["points"]
    ref, _ = bootsurf.error(p, neighbors=15, bootstrap=5)
    f32 = p.astype(np.float32)
    a, _ = bootsurf.error(f32, neighbors=15, bootstrap=5)
    b, _ = bootsurf.error(f32.astype(np.float64), neighbors=15, bootstrap=5)
    same_bits(a["err_632"], b["err_632"])
    big = np.zeros((len(p), 5))
    big[:, 1:4] = p
    strided = big[:, 1:4]
    assert not strided.flags.c_contiguous
    c, _ = bootsurf.error(strided, neighbors=15, bootstrap=5)
    same_bits(c["err_632"], ref["err_632"])
    d, _ = bootsurf.error(np.asfortranarray(p), neighbors=15, bootstrap=5)
    same_bits(d["err_632"], ref["err_632"])
    e, _ = bootsurf.error(p.tolist(), neighbors=15, bootstrap=5)
    same_bits(e["err_632"], ref["err_632"])


def test_threads_do_not_change_results(cube):
    a, sa = bootsurf.error(cube, neighbors=20, bootstrap=10, threads=1)
    b, sb = bootsurf.error(cube, neighbors=20, bootstrap=10, threads=2)
    for k in a:
        same_bits(a[k], b[k])
    assert sa == sb
    na, _ = bootsurf.normals(cube, bootstrap=10, threads=1)
    nb, _ = bootsurf.normals(cube, bootstrap=10, threads=2)
    for k in na:
        same_bits(na[k], nb[k])
    pa, fa, _ = bootsurf.smooth(cube, neighbors=20, bootstrap=8, threads=1)
    pb, fb, _ = bootsurf.smooth(cube, neighbors=20, bootstrap=8, threads=2)
    same_bits(pa, pb)
    ga, _ = bootsurf.features(cube, method="variance", bootstrap=8, threads=1)
    gb, _ = bootsurf.features(cube, method="variance", bootstrap=8, threads=2)
    same_bits(ga["variance_z"], gb["variance_z"])
    ia, da = bootsurf.knn(cube["points"], 8, threads=1)
    ib, db = bootsurf.knn(cube["points"], 8, threads=2)
    same_bits(ia, ib)
    same_bits(da, db)


def test_two_python_threads_at_once(cube):
    p = cube["points"]
    q = bootsurf.noise(p, true_normals(cube), seed=9)
    want = [bootsurf.error(x, neighbors=20, bootstrap=10)[0]["err_632plus"] for x in (p, q)]
    got = [None, None]

    def run(i, x):
        for _ in range(3):
            got[i] = bootsurf.error(x, neighbors=20, bootstrap=10)[0]["err_632plus"]

    ts = [threading.Thread(target=run, args=(i, x)) for i, x in enumerate((p, q))]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    for w, g in zip(want, got):
        same_bits(w, g)


# ------------------------------------------------------------ interrupts, progress


def test_keyboard_interrupt_on_a_million_points():
    """SIGINT from a timer thread while error runs on 1M points: the library
    is cancelled at its next progress callback (every 4096 points) and
    KeyboardInterrupt comes within a second -- on a machine shared by many
    jobs, within the time the library takes between two callbacks (the
    longest gap seen), which is what the mechanism can promise. The k-d tree
    build reports no progress, so the signal is sent once the estimation has
    begun (the callbacks' count restarts after the neighbour search)."""
    pts = bootsurf.generate("sphere", points=1000000, sampling="random", seed=4)["points"]
    calls = []
    sent = []

    def progress(done, total):
        now = time.monotonic()
        if calls and done < calls[-1][1] and not sent:
            # the second phase (estimation) has started: interrupt after its first chunk
            threading.Timer(0.05, lambda: (sent.append(time.monotonic()),
                                           os.kill(os.getpid(), signal.SIGINT))).start()
        calls.append((now, done))

    with pytest.raises(KeyboardInterrupt):
        bootsurf.error(pts, progress=progress)
    latency = time.monotonic() - sent[0]
    gaps = [b[0] - a[0] for a, b in zip(calls, calls[1:])]
    print("KeyboardInterrupt %.3f s after SIGINT; longest gap between callbacks %.3f s"
          % (latency, max(gaps)))
    assert latency < max(1.0, 1.5 * max(gaps)), (latency, max(gaps))
    assert calls[-1][1] < len(pts)  # stopped early
    # the interpreter is usable and the library too
    f, s = bootsurf.error(pts[:2000], neighbors=20, bootstrap=5)
    assert s["points"] == 2000 and np.isfinite(f["err_632"]).all()


def ring_cylinder(gap):
    """A cylinder sampled on rings `gap` spacings apart with gaussian noise of
    0.3 spacings along its normals (tests/test_util.h's shape, another draw)."""
    per, rings = 60, 60
    s = 2 * math.pi / per
    j, r = np.meshgrid(np.arange(per), np.arange(rings))
    t = ((j + 0.5 * (r % 2)) * s).ravel()
    nrm = np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=1)
    pts = nrm + np.stack([0 * t, 0 * t, (r * gap * s).ravel()], axis=1)
    return pts + nrm * np.random.default_rng(41).normal(0, 0.3 * s, len(t))[:, None]


def test_progress_reaches_the_noise_passes():
    """The K selection's noise passes call progress too (in smooth held where
    stage 1 ended; in normals with select_k in the first half of the
    selection's range), so an exception from progress (or Ctrl-C's
    KeyboardInterrupt) stops them: smooth on a ring-sampled cloud, where the
    guard's second reading runs, and normals with select_k."""
    pts = ring_cylinder(8)
    seen = []
    _, _, s = bootsurf.smooth(pts, neighbors=50, bootstrap=10,
                              progress=lambda d, t: seen.append((d, t)))
    assert s["report"]["section_share"] > 0.05 and math.isfinite(s["report"]["noise_select"])
    # the neighbour search, then multipass's three stages (1000 each): stage
    # 1 ends, then the passes' table and four passes hold there
    stages = [d for d, t in seen if t == 3000]
    assert stages.count(1000) >= 6 and stages[-1] == 3000
    assert all(a <= b for a, b in zip(stages, stages[1:]))

    class Stop(Exception):
        pass

    def stop_at(n, in_stage):
        calls = []

        def progress(done, total):
            calls.append((done, total))
            if sum(in_stage(d, t) for d, t in calls) == n:
                raise Stop()
        return calls, progress

    # stage 1 makes one call at its end; a third call there comes from the
    # passes' table or the passes, so Stop is raised within them or not at all
    calls, progress = stop_at(3, lambda d, t: 3 * d == t)
    with pytest.raises(Stop):
        bootsurf.smooth(pts, neighbors=50, bootstrap=10, progress=progress)
    # normals: the neighbour search reports over the rows, the selection over
    # twice the rows, the noise fits' pass in the first half (the pooling
    # after it holds there); the second call there stops it within them
    n = len(pts)
    calls, progress = stop_at(2, lambda d, t: t == 2 * n and d <= n)
    with pytest.raises(Stop):
        bootsurf.normals(pts, select_k="10:80:5", progress=progress)
    assert all(t == n for d, t in calls[:-2])  # the search's calls came first
    assert calls[-2:] == [(n, 2 * n), (n, 2 * n)]


def test_progress_callable_and_its_exception(cube):
    seen = []
    bootsurf.error(cube, neighbors=20, bootstrap=5, progress=lambda d, t: seen.append((d, t)))
    assert seen and seen[-1][0] == seen[-1][1]

    class Stop(Exception):
        pass

    def stop(done, total):
        raise Stop()

    with pytest.raises(Stop):
        bootsurf.normals(cube, progress=stop)


# ------------------------------------------------------------ bad input


def test_bad_numbers_in_the_cli_words(cube):
    """Numbers outside their range: Python's ValueError is the command line's
    usage error, the option spelled as each front end spells it (one copy of
    the range and the words: the library's checks)."""
    p = cube["points"]
    src = tmp("bad_in.ply")
    bootsurf.write(src, cube)
    cases = [
        (lambda: bootsurf.features(p, threshold=-1), ["features", src, "--threshold", "-1"]),
        (lambda: bootsurf.features(p, method="distance", threshold=1.5),
         ["features", src, "--method", "distance", "--threshold", "1.5"]),
        (lambda: bootsurf.render(p, azimuth=1000), ["render", src, "--azimuth", "1000"]),
        (lambda: bootsurf.render(p, azimuth=-361), ["render", src, "--azimuth", "-361"]),
        (lambda: bootsurf.render(p, elevation=91), ["render", src, "--elevation", "91"]),
        (lambda: bootsurf.render(p, point_size=100), ["render", src, "--point-size", "100"]),
    ]
    for call, args in cases:
        with pytest.raises(ValueError) as e:
            call()
        r = subprocess.run([CLI] + args + ["-o", tmp("bad_out.png" if args[0] == "render" else "bad_out.ply")],
                           capture_output=True, text=True)
        assert r.returncode == 2, (args, r.stderr)
        want = "bootsurf %s: --%s" % (args[0], str(e.value).replace("point_size", "point-size"))
        assert r.stderr.splitlines()[0] == want, (r.stderr, want)
    # in range: accepted by both
    img = bootsurf.render(p, azimuth=-360, elevation=90, point_size=0.05, size=(64, 64))
    assert img.shape == (64, 64, 3)


def test_bad_input(cube):
    p = cube["points"]
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        bootsurf.error(np.zeros((10, 2)))
    with pytest.raises(TypeError, match="float32 or float64"):
        bootsurf.error(np.array([["a", "b", "c"]]))
    with pytest.raises(TypeError):
        bootsurf.error(np.zeros((10, 3), dtype=complex))
    q = p.copy()
    q[7, 1] = np.nan
    # the library's message, with its subject (the CLI names the file there)
    with pytest.raises(ValueError, match=r"^points: point 7 has a NaN"):
        bootsurf.error(q)
    with pytest.raises(ValueError, match=r"^points: point 7 has a NaN"):
        bootsurf.knn(q, 4)
    with pytest.raises(ValueError, match=r"^points: has 20 points, fewer than K = 50"):
        bootsurf.error(p[:20])
    with pytest.raises(ValueError, match=r"^points: has 5 points, fewer than K = 30"):
        bootsurf.normals(p[:5])
    with pytest.raises(ValueError, match=r"^points: has 1 point"):
        bootsurf.spacing(p[:1])
    with pytest.raises(ValueError, match=r"k = 9"):
        bootsurf.knn(p[:8], 9)
    with pytest.raises(ValueError, match="gamma"):
        bootsurf.error(p, gamma="median")
    with pytest.raises(ValueError, match="too small for degree"):
        bootsurf.error(p, neighbors=5)
    with pytest.raises(ValueError):
        bootsurf.error(p, bootstrap=0)
    with pytest.raises(ValueError, match="normals"):
        bootsurf.noise(p)
    with pytest.raises(ValueError, match="shape"):
        bootsurf.generate("dodecahedron")
    with pytest.raises(ValueError, match="h1"):
        bootsurf.smooth(p, h1="2W")
    with pytest.raises(ValueError, match="method"):
        bootsurf.features(p, method="curvature")
    with pytest.raises(ValueError, match="select_k"):
        bootsurf.normals(p, select_k="30:10:1")
    # integer options: as strict as the command line's (no silent truncation,
    # its ranges), naming the option
    with pytest.raises(ValueError, match=r"^neighbors needs a whole number \(2 to 65535\), not -5$"):
        bootsurf.error(p, neighbors=-5)
    with pytest.raises(TypeError, match=r"^neighbors needs a whole number, not 5.5$"):
        bootsurf.error(p, neighbors=5.5)
    with pytest.raises(TypeError, match=r"^neighbors needs a whole number, not 'abc'$"):
        bootsurf.error(p, neighbors="abc")
    with pytest.raises(ValueError, match=r"^seed needs a whole number \(0 to 18446744073709551615\)"):
        bootsurf.normals(p, seed=-1)
    with pytest.raises(ValueError, match=r"^threads needs a whole number \(0 to 4096\), not -1$"):
        bootsurf.features(p, threads=-1)
    with pytest.raises(TypeError, match=r"^select_k needs a whole number, not 20.5$"):
        bootsurf.normals(p, select_k=[10, 20.5])
    with pytest.raises(TypeError, match=r"^iterations needs a whole number, not 2.5$"):
        bootsurf.smooth(p, iterations=2.5)
    with pytest.raises(TypeError, match=r"^points needs a whole number"):
        bootsurf.generate("cube", points="many")
    # numbers outside their meaning, refused as the command line refuses them
    # (no value taken silently for 'auto': the library's NaN and -1)
    with pytest.raises(ValueError, match=r"^threshold -1: method variance takes a normal_var value, at least 0, or auto$"):
        bootsurf.features(p, threshold=-1)
    with pytest.raises(ValueError, match=r"^threshold 1.5: method distance takes a fraction of max\(feature_dist\), 0 to 1, or auto$"):
        bootsurf.features(p, method="distance", threshold=1.5)
    with pytest.raises(ValueError, match=r"^threshold must be a number or 'auto', not nan$"):
        bootsurf.features(p, threshold=float("nan"))
    with pytest.raises(ValueError, match=r"^a must be a positive number or 'auto', not -1$"):
        bootsurf.smooth(p, a=-1)
    with pytest.raises(ValueError, match=r"^a must be a positive number or 'auto', not 0$"):
        bootsurf.smooth(p, a=0)
    with pytest.raises(ValueError, match=r"^iterations must be 0..1000000 or 'auto', not -1$"):
        bootsurf.smooth(p, iterations=-1)
    with pytest.raises(ValueError, match=r"^bootstrap needs a whole number \(1 to 100000\), not 0$"):
        bootsurf.smooth(p, bootstrap=0)
    # k_min: the command line's range (--k-min 3 to 65535), in its words
    with pytest.raises(ValueError, match=r"^k_min needs a whole number \(3 to 65535\), not 1$"):
        bootsurf.smooth(p, k_min=1)
    with pytest.raises(ValueError, match=r"^k_min needs a whole number \(3 to 65535\), not 2$"):
        bootsurf.features(p, method="distance", k_min=2)
    with pytest.raises(ValueError, match=r"^k_min 60 is larger than K = 50$"):
        bootsurf.smooth(p, k_min=60)
    with pytest.raises(ValueError, match=r"^k_max 10 is smaller than K = 50$"):
        bootsurf.smooth(p, k_max=10)
    # render: PNG bytes only under a .png name (the command's words)
    with pytest.raises(ValueError, match=r"^output .*x.jpg: the output is a PNG image: name it .png$"):
        bootsurf.render(p, output=tmp("x.jpg"))
    assert not os.path.exists(tmp("x.jpg"))
    with pytest.raises(ValueError, match=r"^size needs \(width, height\) with each in 64..8192"):
        bootsurf.render(p, size="100x100")
    with pytest.raises(ValueError, match=r"^h2 must be a positive length"):
        bootsurf.smooth(p, h2="0W")
    with pytest.raises(ValueError, match=r"^k_error must be a positive length"):
        bootsurf.smooth(p, k_error="0h")
    with pytest.raises(ValueError, match=r"^ply_names must be plain, cloudcompare or meshlab, not 'gray'$"):
        bootsurf.write(tmp("x.ply"), p, ply_names="gray")
    with pytest.raises(OSError, match=r": is a directory$"):  # not 'unknown file extension'
        bootsurf.write(TMP, p)
    with pytest.raises(TypeError, match=r"^shape must be sphere, cube, torus or plane, not 5$"):
        bootsurf.generate(5)
    with pytest.raises(ValueError, match=r"^points: the cloud has no 'points'"):
        bootsurf.error({"a": np.zeros(3)})
    with pytest.raises(TypeError, match=r"^progress must be None or a callable"):
        bootsurf.spacing(p, progress=5)
    # a tiled run never replaces its input (the command line refuses it too)
    bootsurf.write(tmp("in.ply"), cube)
    with open(tmp("in.ply"), "rb") as f:
        before_bytes = f.read()
    with pytest.raises(ValueError, match=r"in.ply: the output is the input file; refusing"):
        bootsurf.error(tmp("in.ply"), tile_points=1000, output=tmp("in.ply"), bootstrap=2)
    with open(tmp("in.ply"), "rb") as f:
        assert f.read() == before_bytes
    assert bootsurf.knn(p[:50], np.int64(4))[0].shape == (50, 4)  # numpy integers are whole
    assert bootsurf.generate("plane", points=100.0)["points"].shape[0] > 0  # so are 100.0
    with pytest.raises(OSError, match="nonexistent.ply"):
        bootsurf.read(tmp("nonexistent.ply"))
    open(tmp("empty.ply"), "w").close()
    with pytest.raises(OSError, match=r"empty.ply: the file is empty$"):  # the CLI's words
        bootsurf.read(tmp("empty.ply"))
    with open(tmp("bad.ply"), "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                "property float z\nend_header\n1 2 3\n1 2\n")
    with pytest.raises(OSError, match=r"bad.ply:9:"):
        bootsurf.read(tmp("bad.ply"))
    with pytest.raises(OSError, match="no-such-dir"):
        bootsurf.write(os.path.join(TMP, "no-such-dir", "x.ply"), p)
    # the input is never modified
    before = p.copy()
    bootsurf.noise(p, true_normals(cube))
    same_bits(p, before)


def test_help_reads_like_the_cli():
    doc = bootsurf.error.__doc__
    for word in ("neighbors", "degree", "bootstrap", "gamma", "pca_center", "seed", "threads",
                 "(4.3)", "4.11", "err_632plus"):
        assert word in doc
    assert "Eq. 5.5" in bootsurf.normals.__doc__
