"""bootsurf: statistics for 3D point clouds, on numpy arrays.

The Python front end of libbootsurf (include/bootsurf.h), which implements
the thesis "Bootstrap Based Surface Reconstruction": bootstrap test-error
estimates of local polynomial fits (chapter 4), normals with a confidence
value (chapter 5), denoising (chapter 6) and feature detection (chapter 7).

Every function mirrors a command of the ``bootsurf`` command line: the same
option names (``--pca-center`` is ``pca_center=``), the same defaults, the
same results to the last bit for the same input and seed. Points are any
(N, 3) array-like of float32 or float64 (converted to C-contiguous float64
with one copy only when they are not already). Clouds (``read``,
``generate``, ``sample``) are dicts of numpy arrays: ``points`` (N, 3),
optionally ``normals`` (N, 3) and ``faces`` (F, 3), and one (N,) array per
named field.

The library computes with the GIL released; Ctrl-C raises
KeyboardInterrupt within a chunk of points (4096, fewer for heavy
settings), and ``progress=`` takes
a callable ``progress(done, total)`` (raise in it to stop). Bad arguments
raise ValueError or TypeError with the library's message; file errors raise
OSError naming the file and the line.

Example::

    import bootsurf
    cloud = bootsurf.generate("cube", points=20000)
    noisy = bootsurf.noise(cloud["points"], cloud["normals"], level=0.5)
    fields, summary = bootsurf.error(noisy, bootstrap=20)
    print(summary["means"]["err_632plus"] / summary["h"])
"""

import math as _math

from . import _core

__version__ = _core.version()

__all__ = [
    "Cloud", "read", "write", "knn", "spacing", "error", "normals", "smooth", "features", "generate", "noise", "sample",
    "evaluate", "render", "__version__",
]

_GAMMAS = ("fit", "mean", "max")
_CENTERS = ("centroid", "point")
_SAMPLINGS = ("regular", "random")
_MODELS = ("gaussian", "uniform")
_PLY_NAMES = ("plain", "cloudcompare", "meshlab")


class Cloud(dict):
    """A point cloud or mesh: a dict of numpy arrays ('points' (N, 3), optional
    'normals' (N, 3), 'faces' (F, 3) and one (N,) array per field).

    ``shape_name`` is the generated shape the points sample ('' if none): PLY
    keeps it as the header comment "bootsurf shape NAME", and ``render(up=
    'auto')`` draws such clouds z-up."""

    def __init__(self, *args, shape_name="", **kwargs):
        super().__init__(*args, **kwargs)
        self.shape_name = shape_name


def _choice(value, names, option):
    if value not in names:  # the command line's words: "a, b or c"
        listed = ", ".join(names[:-1]) + " or " + names[-1] if len(names) > 1 else names[0]
        raise ValueError("%s must be %s, not %r" % (option, listed, value))
    return names.index(value)


# Ranges of the integer options as the command line checks them (cli/); the
# library checks the rest (degree, K against the point count, ...).
_INT_RANGES = {"neighbors": (2, 65535), "seed": (0, 2**64 - 1), "threads": (0, 4096),
               "bootstrap": (0, None), "tile_points": (0, None),
               "k_min": (3, 65535)}  # smooth and features: a plane fit's points


def _int(value, name):
    """An integer option: a whole number (int, numpy integer, or a float with
    no fraction); TypeError for anything else (5.5, '50', True), ValueError
    outside the command line's range, both naming the option."""
    import operator
    if isinstance(value, bool) or isinstance(value, str):
        raise TypeError("%s needs a whole number, not %r" % (name, value))
    try:
        v = operator.index(value)
    except TypeError:
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise TypeError("%s needs a whole number, not %r" % (name, value)) from None
        if not f.is_integer():
            raise TypeError("%s needs a whole number, not %r" % (name, value)) from None
        v = int(f)
    lo, hi = _INT_RANGES.get(name, (None, None))
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise ValueError("%s needs a whole number (%s), not %d"
                         % (name, "%d to %d" % (lo, hi) if hi is not None else "at least %d" % lo, v))
    return v


def _progress(progress):
    """progress= is None or a callable(done, total)."""
    if progress is not None and not callable(progress):
        raise TypeError("progress must be None or a callable(done, total), not %s"
                        % type(progress).__name__)
    return progress


def _real(value):
    """A finite number given as a number or its text ('0.5'), else NaN (which
    the library would take for 'auto'): the caller names the option."""
    if isinstance(value, bool):
        return _math.nan
    try:
        v = float(value)
    except (TypeError, ValueError):
        return _math.nan
    return v if _math.isfinite(v) else _math.nan


def _cloud(d, shape_name):
    return Cloud(d, shape_name=shape_name)


def _maybe_read(x):
    """A path (str or os.PathLike) is read; anything else is returned."""
    if isinstance(x, str) or hasattr(x, "__fspath__"):
        import os
        return read(os.fspath(x))
    return x


def _points(x):
    """(points, cloud or None) of an array-like or a cloud dict."""
    x = _maybe_read(x)
    if isinstance(x, dict):
        if "points" not in x:
            raise ValueError("points: the cloud has no 'points' (a Cloud, an (N, 3) array or a "
                             "path)")
        return x["points"], x
    return x, None


def _job_input(points, output, tile_points):
    """(points, tiled) of a job: in memory (points, None), or a tiled run from
    a binary PLY file to another (None, (input, output, tile_points))."""
    import os
    if tile_points is None:
        if output is not None:
            raise ValueError("output: only tiled runs (tile_points=) write their results; write() "
                             "saves results held in memory")
        return _points(points)[0], None
    if not (isinstance(points, str) or hasattr(points, "__fspath__")):
        raise TypeError("points: a tiled run reads a binary PLY file: give its path, not %s"
                        % type(points).__name__)
    if output is None or not os.fspath(output).lower().endswith(".ply"):
        raise ValueError("output: a tiled run writes binary PLY: give output='FILE.ply', not %r"
                         % (output,))
    if not os.fspath(points).lower().endswith(".ply"):
        raise ValueError("%s: tiled runs read binary PLY files (write one with write())"
                         % os.fspath(points))
    try:  # the input is never replaced (the command line's check; it has --force)
        same = os.path.samefile(points, output)
    except OSError:
        same = False  # no output yet, or no input: the library names what is wrong
    if same:
        raise ValueError("%s: the output is the input file; refusing to overwrite it"
                         % os.fspath(output))
    return None, (os.fspath(points), os.fspath(output), _int(tile_points, "tile_points"))


_TILED_DOC = """
    Tiled (out-of-core) run, as the command's --tile-points N -o OUT.ply:
    with tile_points=N, points is the path of a binary PLY file and output
    the .ply file to write; the cloud is processed N points at a time with
    exact halos (the same bytes as the command line writes, the same results
    as in memory) and the returned fields (and points) are None: the
    results are in output. summary then also has tile_points and tiles."""


# ---------------------------------------------------------------- files


def read(path):
    """read(path) -> Cloud

    Read a cloud or mesh, like every command's INPUT: .ply (ascii or binary),
    .pcd (PCL v0.7), .las (1.0-1.4, point formats 0-10), .csv/.asc (a header
    line naming the columns), .xyz/.txt/.pts, .off, .obj. The format comes
    from the content when it declares one, else from the extension.

    Returns a Cloud (a dict of numpy arrays): 'points' (N, 3) as stored
    (float32 or float64), 'normals' (N, 3) if present, 'faces' (F, 3) uint32
    for meshes (polygons fan-triangulated), and every other per-point
    property under its name in the type it is stored with (uint8 'feature',
    float32 'normal_var', ...). The arrays are the library's, not copies.

    Raises OSError "PATH:LINE: message" for a missing, unreadable or
    malformed file.
    """
    import os
    import stat
    path = os.fspath(path)
    try:  # the command line's first check (cli/util.c), with its words
        st = os.stat(path)
    except OSError:
        st = None  # the library names what is wrong
    if st is not None and stat.S_ISREG(st.st_mode) and st.st_size == 0:
        raise OSError("%s: the file is empty" % path)
    d, shape = _core.read(path)
    return _cloud(d, shape)


def write(path, cloud, *, ascii=False, format=None, float32=False, ply_names="plain",
          las_version="1.4"):
    """write(path, cloud, *, ascii=False, format=None, float32=False,
    ply_names='plain', las_version='1.4')

    Write a cloud (a dict with 'points' and optional 'normals', 'faces' and
    per-point fields, or an (N, 3) array) atomically: a temporary file in the
    same directory renamed into place, so a failed write leaves no partial
    file. Each field is stored in its array's dtype (uint8, int32, float32,
    float64, ...); float32 'points' are written as float.

    Options (as the command line's):
      ascii        write ascii PLY (default: binary little-endian)
      format       ply pcd las csv asc xyz off obj, whatever the extension
      float32      write double coordinates, normals and fields as float
      ply_names    PLY field names: plain, cloudcompare (scalar_ prefix) or
                   meshlab (+ quality)
      las_version  LAS output: 1.4 (point formats 6-8) or 1.2 (formats 1, 3)

    Formats that cannot carry every field (OFF, OBJ, XYZ) write what they
    can. Raises OSError naming the file when it cannot be written.
    """
    import os
    if not isinstance(cloud, dict):
        cloud = {"points": cloud}
    if las_version not in ("1.2", "1.4"):
        raise ValueError("las_version must be 1.2 or 1.4, not %r" % (las_version,))
    _core.write(os.fspath(path), cloud, getattr(cloud, "shape_name", ""), format, bool(ascii),
                _choice(ply_names, _PLY_NAMES, "ply_names"), bool(float32),
                las_version == "1.2")


# ---------------------------------------------------------------- neighbourhoods


def knn(points, k, *, threads=0, progress=None):
    """knn(points, k, *, threads=0, progress=None) -> (idx, dist2)

    The K nearest neighbours of every point among the points themselves
    (exact k-d tree). Row i lists point i first, then the k-1 nearest other
    points sorted by (squared distance, index), so duplicates of a point
    never displace the point itself.

    Returns idx (N, k) uint32 and dist2 (N, k) float64 (squared distances).
    The same for any thread count. k must be in [1, N].
    """
    return _core.knn(points, _int(k, "k"), _int(threads, "threads"), _progress(progress))


def spacing(points, *, threads=0, progress=None):
    """spacing(points, *, threads=0, progress=None) -> float

    h, the mean distance from each point to its nearest other point: the
    thesis's unit of noise levels and errors (4.2). Needs at least 2 points.
    """
    return _core.spacing(_points(points)[0], _int(threads, "threads"), _progress(progress))


# ---------------------------------------------------------------- chapter 4


def error(points, *, neighbors=50, degree=3, bootstrap=50, gamma="fit", pca_center="centroid",
          seed=1, threads=0, test_sample=None, output=None, tile_points=None, progress=None):
    """error(points, *, neighbors=50, degree=3, bootstrap=50, gamma='fit',
    pca_center='centroid', seed=1, threads=0, test_sample=None,
    output=None, tile_points=None, progress=None) -> (fields, summary)

    Bootstrap test-error estimates of local polynomial fits (thesis ch. 4);
    ``bootsurf error``.

    For every point: PCA frame of its K nearest neighbours (Eq. 3.4),
    least-squares fit of a height polynomial of degree d, B bootstrap refits
    (Algorithm 1), and the estimators err_train (Eq. 4.6), err_boot (4.3),
    err_loo (4.4), err_loo_center (4.11), err_632 (4.5), err_632plus
    (4.7-4.10), gamma (the no-information rate, 4.10) and overfit_rate (R,
    4.9). All per point in model units; the summary gives their means.

    Options:
      neighbors    neighbourhood size K, the point included (default: 50)
      degree       degree of the height polynomial, 1..4 (default: 3)
      bootstrap    bootstrap replicates per point, at least 1 (default: 50)
      gamma        no-information rate: fit (Eq. 4.10), mean or max over
                   replicates (4.2.1) (default: fit)
      pca_center   PCA about the centroid or the point (default: centroid)
      seed         random seed (default: 1)
      threads      threads, 0 = all cores (default: 0); results do not
                   depend on it
      test_sample  the same points with independent noise ((N, 3) or a
                   path): also err_test and err_test_center (validation)
      progress     callable(done, total), or None

    points: an (N, 3) array-like, a Cloud, or a path to read.

    Returns (fields, summary): fields maps each estimator's name to an (N,)
    float64 array; summary is {'points', 'h' (mean spacing), 'duplicates',
    'report': {'replicates_total', 'replicates_skipped', 'degree_reduced',
    'center_unestimated'}, 'means': {field: mean}}.
    """
    if _int(bootstrap, "bootstrap") < 1:
        raise ValueError("bootstrap = %d: the bootstrap estimators need at least one replicate"
                         % _int(bootstrap, "bootstrap"))
    pts, tiled = _job_input(points, output, tile_points)
    test = _maybe_read(test_sample)
    if isinstance(test, dict):
        test = test["points"]
    if tiled and test is not None:
        raise ValueError("test_sample: err_test needs the cloud in memory, not a tiled run")
    return _core.error(pts, tiled, test, _int(neighbors, "neighbors"), _int(degree, "degree"), _int(bootstrap, "bootstrap"),
                       _int(seed, "seed"), _choice(gamma, _GAMMAS, "gamma"),
                       _choice(pca_center, _CENTERS, "pca_center"), _int(threads, "threads"), _progress(progress))


# ---------------------------------------------------------------- chapter 5

_FITS = ("pca", "poly")
_RULES = ("test-error", "mse", "auto")  # BSURF_KSELECT_TEST_ERROR, _MSE, _AUTO
_NOISE_POOLS = ("global", "local")
_ORIENTS = ("none", "mst")


def _ks(select_k):
    """select_k as a list: 'A:B:STEP' (the command line's) or a sequence."""
    if select_k is None:
        return None
    if isinstance(select_k, str):
        try:
            a, b, step = (int(x) for x in select_k.split(":"))
        except ValueError:
            raise ValueError("select_k needs A:B:STEP, not %r" % select_k) from None
        if not (3 <= a <= b and step >= 1):
            raise ValueError("select_k needs A:B:STEP with 3 <= A <= B and STEP >= 1, not %r"
                             % select_k)
        return list(_builtin_range(a, b + 1, step))
    return [_int(k, "select_k") for k in select_k]


_builtin_range = range


def normals(points, *, neighbors=30, fit="pca", degree=2, pca_center="centroid", bootstrap=50,
            seed=1, threads=0, test_error=False, k_ref=0, select_k=None, select_rule="auto",
            noise_k=12, noise_pool="global", select_degree=None, curve=False, truth=None,
            smooth_iterations=0,
            alpha=0.1, sigma_d=0.0, sigma_nu="auto", orient="none", output=None,
            tile_points=None, progress=None):
    """normals(points, *, neighbors=30, fit='pca', degree=2,
    pca_center='centroid', bootstrap=50, seed=1, threads=0, test_error=False,
    k_ref=0, select_k=None, select_rule='auto', noise_k=12,
    noise_pool='global', select_degree=None, curve=False, truth=None, smooth_iterations=0,
    alpha=0.1, sigma_d=0.0, sigma_nu='auto', orient='none', output=None,
    tile_points=None, progress=None)
    -> (fields, summary)

    Normals with bootstrap confidence and test error (thesis ch. 5);
    ``bootsurf normals`` (bsurf_normals_job).

    For every point: the normal of its K nearest neighbours (PCA plane, 2.2
    and 5.2, or the gradient of a height polynomial, Eq. 5.9), B bootstrap
    refits, the normalised mean of the bootstrap normals (Eq. 5.4) and
    normal_var, the variance of their angles (Eq. 5.5): a per-point
    confidence. normal_err is the bootstrap test error of the normal (Eq.
    5.10, Algorithm 3) against reference PCA normals of k_ref neighbours.

    Options:
      neighbors          neighbourhood size K, the point included (30)
      fit                pca (plane) or poly (height polynomial, Eq. 5.9)
      degree             degree of the polynomial for fit='poly', 1..4 (2)
      pca_center         PCA about the centroid or the point (Eq. 2.1)
      bootstrap          bootstrap replicates; 0 = a single fit (50)
      seed, threads      random seed (1); threads, 0 = all cores
      test_error         also normal_err, the bootstrap test error (Eq. 5.10)
      k_ref              neighbourhood of the reference normals (0 = K)
      select_k           per point, the K chosen by select_rule: 'A:B:STEP'
                         or a list of K (5.5, Algorithm 3)
      select_rule        mse (estimated variance + bias^2 of the normal: the
                         PCA plane's, or with fit='poly' the fit's over K and
                         select_degree; also writes two_sheet, 1 where the
                         neighbourhood mixes two sheets, where the degree is
                         not selected), test-error (Eq. 5.10) or auto (mse
                         where it applies: no curve, K >= 7; else test-error)
      noise_k            with select_rule='mse': the noise fits' K (12)
      noise_pool         with select_rule='mse': one noise level for the cloud
                         ('global') or each point's own ('local')
      select_degree      with fit='poly': also choose the degree, e.g. [1, 2, 3]
      curve              with select_k: return each candidate's mean errors
                         (figs. 5.6-5.11) in summary['curve']
      truth              (N, 3) ground-truth normals for the curve's
                         mean_angle_err
      smooth_iterations  bilateral normal smoothing passes (Eqs. 5.6-5.8)
      alpha              strength of one smoothing pass (0.1)
      sigma_d            spatial sigma of the smoothing (0 = h)
      sigma_nu           variance sigma: a value, 'auto' (85th percentile of
                         normal_var) or 'inf' (single Gaussian)
      orient             none or mst (consistent orientation, Hoppe 1992)
      progress           callable(done, total), or None

    Returns (fields, summary): fields has 'normals' (N, 3) and, as
    computed, 'normal_var', 'normal_err' (float64), 'k_selected' (uint16),
    'degree_selected' (uint8); summary has points, h, duplicates, report,
    means (per field), sigma_d, sigma_nu and curve (a list of rows).
    """
    if sigma_nu == "auto":
        snu = _math.nan
    elif sigma_nu == "inf":
        snu = _math.inf
    else:
        snu = float(sigma_nu)
        if not snu > 0:
            raise ValueError("sigma_nu must be a positive number, 'auto' or 'inf'")
    ks = _ks(select_k)
    if curve and not ks:
        raise ValueError("curve needs select_k")
    ds = None if select_degree is None else [_int(d, "select_degree") for d in select_degree]
    pts, tiled = _job_input(points, output, tile_points)
    if truth is not None:
        truth = _maybe_read(truth)
        if isinstance(truth, dict):
            truth = truth["normals"]
    return _core.normals(pts, tiled, _int(neighbors, "neighbors"), _choice(fit, _FITS, "fit"), _int(degree, "degree"),
                         _choice(pca_center, _CENTERS, "pca_center"), _int(bootstrap, "bootstrap"), _int(seed, "seed"),
                         _int(threads, "threads"), bool(test_error), _int(k_ref, "k_ref"), ks,
                         _choice(select_rule, _RULES, "select_rule"), _int(noise_k, "noise_k"),
                         _choice(noise_pool, _NOISE_POOLS, "noise_pool"), ds,
                         _int(smooth_iterations, "smooth_iterations"), float(alpha), float(sigma_d), snu,
                         _choice(orient, _ORIENTS, "orient"), bool(curve), truth, _progress(progress))


# ---------------------------------------------------------------- chapter 6

_METHODS = ("naive", "bilateral", "multipass", "auto")
_ORDERS = ("parallel", "sequential")
_ESTIMATORS = ("auto", "632", "632plus")


def _length(value, option, allow_w=False):
    """A length as the command line takes it: a number (model units), 'Xh'
    (X times the mean spacing h, which the library knows) or, with allow_w,
    'XW' (X times the mean error |W|). Returns (value, in_h, fraction)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if not (_math.isfinite(value) and value >= 0):
            raise ValueError("%s must be a finite length >= 0, not %r" % (option, value))
        return float(value), False, _math.nan
    text = str(value)
    unit = text[-1:] if text[-1:] in ("h", "W") else ""
    if unit == "W" and not allow_w:
        unit = "?"
    try:
        x = float(text[:-1] or "1") if unit else float(text)
    except ValueError:
        x = _math.nan
    if unit == "?" or not (_math.isfinite(x) and x >= 0):
        raise ValueError("%s must be a length (e.g. 0.01 or 0.5h%s), not %r"
                         % (option, ", or 1W" if allow_w else "", value))
    if unit == "W":
        return 0.0, False, x
    return x, unit == "h", _math.nan


_DEGREE_TESTS = ("auto", "off", "on")  # degree_test -1, 0, 1


def smooth(points, *, method="auto", neighbors=50, degree=3, bootstrap=50, gamma="fit",
           pca_center="centroid", estimator="auto", threshold="auto", h1="auto", h2="auto",
           order="parallel", a="auto", iterations="auto", k_min=10, k_error="none", guard="on",
           degree_test="auto", k_max=0, seed=1, threads=0, output=None, tile_points=None,
           progress=None):
    """smooth(points, *, method='auto', neighbors=50, degree=3,
    bootstrap=50, gamma='fit', pca_center='centroid', estimator='auto',
    threshold='auto', h1='auto', h2='auto', order='parallel', a='auto',
    iterations='auto', k_min=10, k_error='none', guard='on', degree_test='auto',
    k_max=0, seed=1, threads=0, output=None, tile_points=None, progress=None)
    -> (points, fields, summary)

    Denoise: move points towards the bootstrap fits (thesis ch. 6);
    ``bootsurf smooth`` (bsurf_smooth_job).

    naive (6.2, Eq. 6.1): project a point onto the mean of its bootstrap fits
    where its error W_i is below threshold. bilateral (6.3, Algorithm 4, Eq.
    6.2): every neighbourhood's fit moves its points, weighted by distance
    (h1) and error (h2). multipass (6.4, Algorithm 5, Eqs. 6.3-6.5): per point
    a neighbourhood K_i (shrinking with the error with k_error), fits made once,
    then passes until one moves points by less than the fits' own error.

    Options (lengths: a number in model units, 'Xh' in units of the mean
    spacing h, and for h2 and k_error 'XW', X times the mean error |W|):
      method       naive, bilateral, multipass or auto (multipass in memory,
                   bilateral in tiled runs; summary['method'] says which ran)
      neighbors, degree, bootstrap, gamma, pca_center, seed: as error()
      estimator    the error W_i: 632, 632plus or auto (.632+ for naive,
                   .632 otherwise)
      threshold    naive: a length, 'auto' (the mean W_i) or 'none' (every point)
      h1           bilateral: distance sigma of Eq. 6.2 ('auto' = sqrt(h^2 +
                   2 sigma^2), sigma the guard's noise estimate; h without it)
      h2           bilateral, multipass: error sigma of Eq. 6.2 ('auto' = 2W;
                   multipass 2 W_n, W_n the median W_i)
      order        parallel (order-independent) or sequential (the thesis's
                   in-place sweep, one thread)
      a            multipass: h1 = a x d_L (Eq. 6.5); 'auto': 1.5 sqrt(pi / K_i),
                   the local spacing, widened by the guard's noise estimate
                   sigma to sqrt((a d_L)^2 + 2 sigma^2) (the thesis: a = 0.1)
      iterations   multipass: passes; 'auto': until a pass's mean squared move
                   is below the fits' prediction variance (at most 300; the
                   thesis: 300)
      k_min        multipass: the smallest neighbourhood (Eq. 6.3), at least 3
                   (the points of a plane fit)
      k_error      multipass: the error at which K_i reaches k_min (Eq. 6.4;
                   the thesis: '1W'); 'none': K_i = K
      guard        on (a fit biased at its centre by a second sheet or an
                   edge is made again from fewer points, or moves nothing;
                   a fit with more misfit than noise -- residual variance
                   above twice the cloud's noise variance, the lower decile
                   over the fits (each scaled by the share of the noise its
                   interval keeps), or the larger of that and the level
                   normals(select_k=...) reads where the fits are blind to
                   the noise (more than 5% of the points' 80 nearest
                   cross-sections of the surface), at the 5% level -- moves
                   nothing; the report's noise, noise_fits,
                   noise_select, section_share and misfit_fits) or off (the
                   thesis's methods as written)
      degree_test  the guard's sheet fits choose their degree, -d down to a
                   plane, by Mallows' C_p: on, off or auto (on for bilateral
                   and multipass);
                   docs/smoothing.md, "The degree test"
      k_max        multipass with the guard: the largest K the noise may widen
                   the neighbourhood to (0 = 8 x neighbors; neighbors keeps K):
                   where the noise is heavy against the K-ball, K grows to the
                   smallest size whose ball drops no more of the noise variance
                   than its fit's prediction variance holds (report['k'] is the
                   K used); docs/smoothing.md, "The neighbourhood's scale".
                   Its neighbourhoods cost about 12 bytes a point per unit of
                   k_max (5.5 kB a point at 400): the command line lowers the
                   default to what --memory-limit holds, Python does not
                   (docs/smoothing.md, "Memory")

    Returns (points, fields, summary): the moved points (N, 3) (the input is
    not modified), fields err_632, err_632plus, moved (and k_hat, d_local
    for multipass), and the summary (h, method, estimator, means, report).
    """
    thr, thr_h = _math.nan, False
    if threshold == "none":
        thr = _math.inf
    elif threshold != "auto":
        thr, thr_h, _ = _length(threshold, "threshold")
    v1, h1_h = (0.0, False) if h1 == "auto" else _length(h1, "h1")[:2]
    if not (v1 > 0 or h1 == "auto"):
        raise ValueError("h1 must be a positive length (e.g. 0.01 or 1.5h) or 'auto', not %r"
                         % (h1,))
    v2, h2_h, f2 = (_math.nan, False, _math.nan) if h2 == "auto" else _length(h2, "h2", True)
    if h2 != "auto" and not (v2 > 0 or f2 > 0):  # as the command line: G(W, 0) means nothing
        raise ValueError("h2 must be a positive length, a multiple of |W| (e.g. '1W') or "
                         "'auto', not %r" % (h2,))
    ke, ke_h, fk = ((_math.nan, False, _math.nan) if k_error in ("auto", "none")
                    else _length(k_error, "k_error", True))
    if k_error not in ("auto", "none") and not (ke > 0 or fk > 0):
        raise ValueError("k_error must be a positive length, a multiple of |W| or 'none', not %r"
                         % (k_error,))
    # 'auto' is -1 for the library: a number must be positive (A = 0: h1 = 0)
    if a != "auto" and not _real(a) > 0:
        raise ValueError("a must be a positive number or 'auto', not %r" % (a,))
    if iterations != "auto" and not 0 <= _int(iterations, "iterations") <= 1000000:
        raise ValueError("iterations must be 0..1000000 or 'auto', not %r" % (iterations,))
    # the command line's checks of K's bounds, in its words
    if _int(k_min, "k_min") > _int(neighbors, "neighbors"):
        raise ValueError("k_min %d is larger than K = %d" % (k_min, neighbors))
    if _int(k_max, "k_max") and k_max < neighbors:
        raise ValueError("k_max %d is smaller than K = %d" % (k_max, neighbors))
    if _int(bootstrap, "bootstrap") < 1:  # W_i is a bootstrap error
        raise ValueError("bootstrap needs a whole number (1 to 100000), not %d"
                         % _int(bootstrap, "bootstrap"))
    pts, tiled = _job_input(points, output, tile_points)
    return _core.smooth(pts, tiled, _choice(method, _METHODS, "method"), _int(neighbors, "neighbors"), _int(degree, "degree"),
                        _int(bootstrap, "bootstrap"), _int(seed, "seed"), _choice(gamma, _GAMMAS, "gamma"),
                        _choice(pca_center, _CENTERS, "pca_center"),
                        _choice(estimator, _ESTIMATORS, "estimator"), thr, thr_h, v1, h1_h, v2,
                        h2_h, f2, _choice(order, _ORDERS, "order"), -1.0 if a == "auto" else float(a),
                        -1 if iterations == "auto" else _int(iterations, "iterations"),
                        _int(k_min, "k_min"), ke, ke_h, fk, bool(_choice(guard, ("off", "on"), "guard")),
                        _choice(degree_test, _DEGREE_TESTS, "degree_test") - 1, _int(k_max, "k_max"),
                        _int(threads, "threads"), _progress(progress))


# ---------------------------------------------------------------- chapter 7

_FEATURE_METHODS = ("distance", "variance")
_TAIL_RULES = ("otsu", "mad", "null")  # BSURF_TAIL_OTSU, _MAD, _NULL


def features(points, *, method="variance", neighbors=30, bootstrap=50, k_min=15, k_max=60,
             k_step=2, ratio_threshold=0.1, noise_factor=1.75, derivative=0.0, alpha=0.5,
             iterations=5, filter_k=0, sigma_range=0.05, threshold="auto", tail_rule="null",
             false_positive_rate=0.01, variance_filter_k=0, feature_angle=90.0, variance_k_max=0,
             quadric_angle=45.0, seed=1, threads=0, output=None, tile_points=None, progress=None):
    """features(points, *, method='variance', neighbors=30, bootstrap=50,
    k_min=15, k_max=60, k_step=2, ratio_threshold=0.1, noise_factor=1.75,
    derivative=0.0, alpha=0.5, iterations=5, filter_k=0, sigma_range=0.05,
    threshold='auto', tail_rule='null', false_positive_rate=0.01,
    variance_filter_k=0, feature_angle=90.0, variance_k_max=0,
    quadric_angle=45.0, seed=1, threads=0, output=None,
    tile_points=None, progress=None)
    -> (fields, summary)

    Feature detection (thesis ch. 7); ``bootsurf features``
    (bsurf_features_job).

    distance (7.1): for each point the radius of the first neighbourhood size
    whose PCA ratio lambda0/lambda2 exceeds T_{a/c}, smoothed by a bilateral
    filter (Eq. 7.1): feature_dist; feature = 1 near the features. variance
    (7.2, Eq. 7.2): the bootstrap normal variance (Eq. 5.5) above a
    threshold. The default automatic rule (tail_rule='null') tests the
    normalised, median-filtered variance z = median(nu d / s^2) against the
    same score on a simulated flat patch at the cloud's measured noise, at
    false_positive_rate, and splits by Otsu on log z above that; a point is
    also a feature where the border test (the centroid's offset in the
    tangent plane, median-filtered, against the same patch at the same rate)
    says it lies on a border, e.g. a thin part's rim (docs/features.md); a
    point the variance test flags stays a feature only where a quadric does
    not explain its neighbourhood at the measured noise (the quadric check:
    a smooth bend is cleared, a crease is not); the
    score field is then 'variance_z'. 'otsu' and
    'mad' split log normal_var (the score field 'normal_var').

    Options:
      method           distance or variance
      neighbors        variance: neighbourhood of the normals (30)
      bootstrap        variance: bootstrap replicates, >= 2 (50)
      k_min, k_max, k_step   distance: neighbourhood sizes (15, 60, 2)
      ratio_threshold  distance: T_{a/c} on lambda0/lambda2 (0.1)
      noise_factor     distance: T_{a/c} of size K = max(T, C x median
                       f(K)) (0 = T alone) (1.75)
      derivative       distance: threshold f + D f' instead of f (0 = off)
      alpha            distance: bilateral filter strength (Eq. 7.1) (0.5)
      iterations       distance: bilateral filter passes (5)
      filter_k         distance: neighbours of the filter (0 = k_min)
      sigma_range      distance: range sigma of the filter, fraction of max
                       radius (0.05)
      threshold        distance: fraction of max(feature_dist), 0 to 1;
                       variance: normal_var value, at least 0; or 'auto'
      tail_rule        variance auto threshold: null (test against a flat
                       patch at the measured noise), otsu or mad (on log
                       normal_var) (null)
      false_positive_rate  variance, rule null: share of a flat area
                       flagged by each of the two tests, variance and
                       border (0.01)
      variance_filter_k    variance, rule null: neighbours of the median
                       filter (0 = K/2, 1 = none) (0)
      feature_angle    variance, rule null: K doubles from neighbors until a
                       simulated edge of this angle (degrees) at the measured
                       noise is detected at half its points; 0 = neighbors
                       always, the thesis (90)
      variance_k_max   variance: the largest K tried (0 = 8 x neighbors)
      quadric_angle    variance, rule null: the quadric check's crease
                       (degrees): its K_q is the first of K, 2K, 4K at which
                       a crease of this angle at the measured noise keeps 9
                       in 10 of its points; none (heavy noise): no check;
                       0 = off (45)
      seed, threads, progress

    Returns (fields, summary): fields 'feature' (uint8 0/1) and the score
    ('feature_dist', 'variance_z' or 'normal_var', float64); summary with
    points, h, duplicates and report (threshold, feature_points, max_radius,
    immediate, ratio_threshold_kmin, noise_level, k: the variance test's
    neighbourhood, edge_power: the simulated edge's detected share at k,
    border_threshold: the border test's threshold, quadric_k: the quadric
    check's K_q or 0, quadric_threshold, quadric_power: the simulated
    crease's share kept, quadric_noise: the noise sigma it reads,
    quadric_cleared: flagged points it cleared, border_points: feature points
    the border test alone flags -- an open scan's rims, and on a mesh's own
    vertices also the vertex density's gradient).
    """
    thr = _math.nan
    if threshold != "auto":  # NaN is the library's auto: a number must be finite
        thr = _real(threshold)
        if not _math.isfinite(thr):
            raise ValueError("threshold must be a number or 'auto', not %r" % (threshold,))
    pts, tiled = _job_input(points, output, tile_points)
    return _core.features(pts, tiled, _choice(method, _FEATURE_METHODS, "method"), _int(neighbors, "neighbors"),
                          _int(bootstrap, "bootstrap"), _int(k_min, "k_min"), _int(k_max, "k_max"), _int(k_step, "k_step"),
                          float(ratio_threshold), float(noise_factor), float(derivative),
                          float(alpha), _int(iterations, "iterations"), _int(filter_k, "filter_k"), float(sigma_range), thr,
                          _choice(tail_rule, _TAIL_RULES, "tail_rule"),
                          float(false_positive_rate), _int(variance_filter_k, "variance_filter_k"),
                          float(feature_angle), float(quadric_angle), _int(variance_k_max, "variance_k_max"),
                          _int(seed, "seed"), _int(threads, "threads"),
                          _progress(progress))


for _f in (error, normals, smooth, features):
    if _f.__doc__:  # None under python -OO
        _f.__doc__ += _TILED_DOC


# ---------------------------------------------------------------- data


def generate(shape, *, points=10000, sampling="regular", seed=1, feature_width=2.0):
    """generate(shape, *, points=10000, sampling='regular', seed=1,
    feature_width=2.0) -> Cloud

    Points on a shape with exact normals and feature labels; ``bootsurf
    generate``. shape: sphere (radius 1), cube (edge 2, sharp edges), torus
    (radii 1 and 0.35), plane ([-1, 1]^2 at z = 0).

    Options:
      points         number of points (regular sampling rounds it)
      sampling       regular (even, deterministic) or random (uniform by area)
      seed           random seed (random sampling)
      feature_width  cube: feature = within W nominal spacings of an edge

    Returns a Cloud with 'points', exact 'normals' and, for the cube,
    'feature_dist' and 'feature'.
    """
    if not isinstance(shape, str):
        raise TypeError("shape must be sphere, cube, torus or plane, not %r" % (shape,))
    d, name = _core.generate(shape, _int(points, "points"), _choice(sampling, _SAMPLINGS, "sampling"),
                             _int(seed, "seed"), float(feature_width))
    return _cloud(d, name)


def noise(points, normals=None, *, level=0.5, sigma_diag=None, model="gaussian", seed=1,
          threads=0, progress=None):
    """noise(points, normals=None, *, level=0.5, sigma_diag=None,
    model='gaussian', seed=1, threads=0, progress=None) -> points

    Displace points along their normals by t*h (thesis 4.2); ``bootsurf
    noise``. t ~ N(0, level^2) (gaussian, default) or U[-level, level]
    (uniform, the thesis text's model); h is the input's mean
    nearest-neighbour distance. Or, with sigma_diag=s, gaussian noise of
    sigma = s x bounding-box diagonal (PCPNet's protocol: 0.00125, 0.006,
    0.012). The draw of point i depends only on (seed, i).

    points: (N, 3), or a Cloud (then its normals, or the true_nx true_ny
    true_nz of an earlier noise output, are used); normals: (N, 3).
    Returns the displaced points, a new (N, 3) float64 array (the input is
    not modified). noise.last_report holds h, diagonal, level and scale.
    """
    pts, cloud = _points(points)
    if normals is None and cloud is not None:
        normals = cloud.get("normals")
        if normals is None:  # an earlier noise output's exact normals (true_nx ...)
            normals = _truth(cloud).get("normals")
    if normals is None:
        raise ValueError("noise moves points along their normals: give normals")
    if sigma_diag is not None and level != 0.5:
        raise ValueError("level and sigma_diag are exclusive (noise in units of h or of the "
                         "diagonal)")
    m = _choice(model, _MODELS, "model")
    if sigma_diag is not None and m != 0:
        raise ValueError("sigma_diag is gaussian noise; it cannot be used with model %r" % model)
    lvl = float(level)
    sd = 0.0
    if sigma_diag is not None:
        sd = float(sigma_diag)
        if sd == 0:
            lvl = 0.0  # sigma_diag=0: no noise, as the command line
    out, report = _core.noise(pts, normals, m, lvl, sd, _int(seed, "seed"), _int(threads, "threads"), _progress(progress))
    noise.last_report = report
    return out


noise.last_report = None


def sample(mesh, *, points=0, sharp_angle=30.0, feature_width=2.0, seed=1, threads=0):
    """sample(mesh, *, points=0, sharp_angle=30.0, feature_width=2.0, seed=1,
    threads=0) -> Cloud

    Points from a triangle mesh with ground-truth normals and feature labels
    (thesis 5.2.2: vertex normals from the mesh connectivity; 7.1.2: feature
    areas around the sharp edges); ``bootsurf sample``.

    mesh: a Cloud with 'points' and 'faces' (e.g. read('fandisk.off')) or a
    path. points=0: the mesh's vertices with area-weighted normals; points=n:
    n points uniform by area with face normals (from seed). Both get
    'feature_dist' (exact distance to the nearest sharp edge: faces' normals
    differing by more than sharp_angle degrees) and 'feature' (within
    feature_width nominal spacings sqrt(area / points) of one).
    sample.last_report holds the mesh statistics.
    """
    mesh = _maybe_read(mesh)
    d, report = _core.sample(mesh, _int(points, "points"), _int(seed, "seed"), float(sharp_angle),
                             float(feature_width), _int(threads, "threads"))
    sample.last_report = report
    return _cloud(d, "")


sample.last_report = None


# ---------------------------------------------------------------- evaluation


def _truth(cloud):
    """A truth cloud as ``bootsurf eval --truth`` reads it: the true_nx true_ny
    true_nz, true_feature and true_feature_dist fields that ``noise`` keeps
    are its normals, feature and feature_dist."""
    if not any(k.startswith("true_") for k in cloud):
        return cloud
    import numpy as np
    t = Cloud(cloud, shape_name=getattr(cloud, "shape_name", ""))
    if all(k in t for k in ("true_nx", "true_ny", "true_nz")):
        t["normals"] = np.stack([t["true_nx"], t["true_ny"], t["true_nz"]], axis=1)
    for named in ("true_feature", "true_feature_dist"):
        if named in t:
            t[named[5:]] = t.pop(named)
    return t


def evaluate(normals=None, true_normals=None, *, feature=None, true_feature=None, split=None,
             split_q=0.85, points=None, truth=None, surface=None, threads=0, progress=None):
    """evaluate(normals=None, true_normals=None, *, feature=None,
    true_feature=None, split=None, split_q=0.85, points=None, truth=None,
    surface=None, threads=0, progress=None) -> dict

    Compare results with ground truth; ``bootsurf eval`` (the same numbers as
    its --json, from the same library calls).

    normals: unoriented angle errors atan2(|a x b|, |a . b|) against
    true_normals of the same points (thesis 5.2.2, Tables 5.1, 5.3-5.9):
    'angles' (N,) in radians and 'normals': {'all': stats} with count,
    mean_rad, median_rad, rms_rad, mean_deg, under5deg, under10deg (PCPNet's
    PGP5/PGP10). With split (a per-point value such as normal_var), also
    'high' and 'low': the points above the split_q quantile and the others
    (5.2.3, Table 5.2: split_q = 0.85 is "the highest 15%").

    feature / true_feature (0/1 per point): precision, recall and F1 (thesis
    ch. 7) under 'features'.

    points with truth: the position error (smoothing, ch. 6): 'distances'
    (N,), each point's distance to the true surface, and 'position' with
    surface (mesh, shape or tangent_plane), correspondence (index, nearest
    or none), h (the truth's mean spacing) and per group ('all', and with
    split 'high' and 'low') points, mean, rms, max and the same over h, also
    for the 'feature' and 'non_feature' points when the truth has 'feature'.
    The true surface, in order: surface (a mesh Cloud or path, --surface),
    the truth's faces, its generated shape (shape_name), its normals
    (tangent planes). A point corresponds to truth point i when the counts
    agree, else to the nearest truth point.

    truth: a Cloud or path (``--truth``); its normals and feature stand in for
    true_normals and true_feature (a noise output's true_nx ... too). A
    points Cloud or path gives its normals and feature as the results, as
    ``eval RESULT`` does.
    """
    out = {}
    res = None
    pts = None
    if points is not None:
        pts, res = _points(points)
    if truth is not None:
        truth = _truth(_maybe_read(truth))
        if res is not None:  # a result cloud: its normals and labels, as eval RESULT
            if normals is None and "normals" in res and "normals" in truth:
                normals = res["normals"]
            if feature is None and "feature" in res and "feature" in truth:
                feature = res["feature"]
        if normals is not None and true_normals is None:
            true_normals = truth.get("normals")
        if feature is not None and true_feature is None:
            true_feature = truth.get("feature")
    elif pts is not None:
        raise ValueError("points: the position error needs truth= (a Cloud or path)")
    mask = None
    if split is not None:
        mask, threshold, count = _core.quantile_split(split, float(split_q))
        out["split"] = {"q": float(split_q), "threshold": threshold, "high_points": count}
    if normals is not None or true_normals is not None:
        if normals is None or true_normals is None:
            raise ValueError("normals and true_normals go together")
        angles, stats = _core.eval_normals(normals, true_normals, mask)
        out["angles"] = angles
        out["normals"] = stats
    if feature is not None or true_feature is not None:
        if feature is None or true_feature is None:
            raise ValueError("feature and true_feature go together")
        out["features"] = _core.eval_features(feature, true_feature)
    if pts is not None:
        if surface is not None:
            surface = _maybe_read(surface)
        out["distances"], out["position"] = _core.eval_position(
            pts, truth, getattr(truth, "shape_name", ""), surface, mask, _int(threads, "threads"), _progress(progress))
    if not out or list(out) == ["split"]:
        raise ValueError("nothing to evaluate: give normals and true_normals, feature and "
                         "true_feature, or points and truth")
    return out


# ---------------------------------------------------------------- pictures


def render(points, *, output=None, normals=None, field=None, colormap="viridis", range=None,
           view=None, azimuth=None, elevation=None, up="auto", views=1, size=(1024, 768),
           point_size=2.0, title=None, flat=False, square=False, threads=0, progress=None):
    """render(points, *, output=None, normals=None, field=None,
    colormap='viridis', range=None, view=None, azimuth=None, elevation=None,
    up='auto', views=1, size=(1024, 768), point_size=2.0, title=None,
    flat=False, square=False, threads=0, progress=None) -> image or None

    Render a cloud, shaded by its normals or coloured by a field (the
    thesis's figures); ``bootsurf render``. Orthographic, z-buffered splats
    of point_size x h (larger in sparse regions); the same picture for any
    thread count.

    points: (N, 3), a Cloud or a path. field: the name of a field of the
    cloud, or an (N,) array of values. Options as the command line's:
      output      a PNG file to write (then None is returned; a name with
                  another extension, x.jpg, is refused); without it the
                  (height, width, 3) uint8 image is returned
      colormap    viridis, magma, gray or coolwarm
      range       (lo, hi) at the colormap's ends (default: 1st-99th
                  percentile)
      view        front, back, left, right, top, bottom or iso (default iso)
      azimuth, elevation   the view direction in degrees instead (azimuth
                  -360 to 360, elevation -90 to 90)
      up          x, y, z or auto (z for generated shapes, else y)
      views       1, or 4 for front, right, top and iso in a 2x2 grid
      size        (width, height) in pixels
      point_size  splat diameter in units of h, 0.05 to 50
      title, flat (no shading of field colours), square (square splats)
    render.last_info holds the value range used, h and the covered pixels.
    """
    pts, cloud = _points(points)
    shape_name = getattr(cloud, "shape_name", "") if cloud is not None else ""
    if normals is None and cloud is not None:
        normals = cloud.get("normals")
    label = None
    values = None
    if field is not None:
        if isinstance(field, str):
            if cloud is None or field not in cloud:
                have = ", ".join(k for k in (cloud or {}) if k not in ("points", "normals",
                                                                       "faces")) or "none"
                raise ValueError("no field '%s'; available fields: %s" % (field, have))
            label, values = field, cloud[field]
        else:
            values = field
    if view is not None and (azimuth is not None or elevation is not None):
        raise ValueError("give view or azimuth/elevation, not both")
    if views not in (1, 4):
        raise ValueError("views must be 1 or 4, not %r" % (views,))
    try:
        w, h = (_int(v, "size") for v in size)
    except (TypeError, ValueError):
        w = h = 0
    if not (64 <= w <= 8192 and 64 <= h <= 8192):
        raise ValueError("size needs (width, height) with each in 64..8192, not %r" % (size,))
    lo = hi = _math.nan
    if range is not None:
        lo, hi = float(range[0]), float(range[1])
        if not (_math.isfinite(lo) and _math.isfinite(hi) and hi > lo):
            raise ValueError("range needs (lo, hi) with lo < hi, not %r" % (range,))
    import os
    if output is not None:  # the command's check (cli_png_name): PNG bytes only under .png
        base = os.path.basename(os.fspath(output))
        dot = base.rfind(".")
        if dot > 0 and dot + 1 < len(base) and base[dot:].lower() != ".png":
            raise ValueError("output %s: the output is a PNG image: name it .png"
                             % os.fspath(output))
    img, info = _core.render(pts, normals, values, None if output is None else os.fspath(output),
                             colormap, view,
                             _math.nan if azimuth is None else float(azimuth),
                             _math.nan if elevation is None else float(elevation), up,
                             shape_name, _int(views, "views"), int(w), int(h), float(point_size), lo, hi,
                             title, label, bool(flat), bool(square), _int(threads, "threads"), _progress(progress))
    render.last_info = info
    return img


render.last_info = None
