/* bsurf_smooth (thesis chapter 6): exact cases (a plane and a quadric do not
 * move), a noisy plane gets flatter, the naive threshold's semantics, the
 * multipass neighbourhood sizes, determinism for any thread count, and
 * argument checks. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "algo/algo.h"          /* bsurf_smooth_tuned */
#include "algo/smooth_stages.h" /* bsurf_smooth_noise_level */
#include "test_util.h"

static const bsurf_smooth_method methods[3] = {BSURF_SMOOTH_NAIVE, BSURF_SMOOTH_BILATERAL,
                                               BSURF_SMOOTH_MULTIPASS};

static bsurf_smooth_options options(bsurf_smooth_method m, int k, int degree, int B) {
  bsurf_smooth_options o = bsurf_smooth_options_default();
  o.method = m;
  o.error.k = k;
  o.error.degree = degree;
  o.error.bootstrap = B;
  o.error.threads = 2;
  o.iterations = 20;
  if (m == BSURF_SMOOTH_MULTIPASS) {
    /* the thesis's multipass settings (6.4.1), as these tests had them
     * before the defaults changed: h1 = 0.1 d_L, fewer active pairs,
     * shorter runs; the defaults are exercised by test_two_sheets,
     * test_cube_distance and test_multipass_defaults */
    o.h2_fraction = 0.3;
    o.k_error_fraction = 1.0;
    o.a = 0.1;
  }
  return o;
}

/* A random sample of [-1,1]^2 lifted by z = f(x, y), then tilted about x. */
static void surface(bsurf_cloud *c, size_t n, double qa, double qb, double qc, double tilt) {
  assert_int_equal(bsurf_generate(c, BSURF_SHAPE_PLANE, n, BSURF_SAMPLING_RANDOM, 5, 0), BSURF_OK);
  for (size_t i = 0; i < c->point_count; i++) {
    double *p = &c->xyz[3 * i];
    double x = p[0], y = p[1];
    double z = 0.1 * x - 0.2 * y + qa * x * x + qb * x * y + qc * y * y;
    p[1] = cos(tilt) * y - sin(tilt) * z + 3;
    p[2] = sin(tilt) * y + cos(tilt) * z - 1;
  }
}

/* Points on a generated shape (`sampling`) with gaussian noise of `level` h
 * along the normals; returns h, the clean sample's mean spacing. */
static double noisy_sample(bsurf_cloud *c, bsurf_shape shape, size_t n, bsurf_sampling sampling,
                           uint64_t seed, double feature_width, double level, uint64_t noise_seed) {
  assert_int_equal(bsurf_generate(c, shape, n, sampling, seed, feature_width), BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c->xyz, c->point_count, 2, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c->xyz, c->normals, c->point_count, BSURF_NOISE_GAUSSIAN, level,
                                   h, noise_seed),
                   BSURF_OK);
  return h;
}

/* noisy_sample with random sampling. */
static double noisy_shape(bsurf_cloud *c, bsurf_shape shape, size_t n, uint64_t seed,
                          double feature_width, double level, uint64_t noise_seed) {
  return noisy_sample(c, shape, n, BSURF_SAMPLING_RANDOM, seed, feature_width, level, noise_seed);
}

static double max_move(const double *a, const double *b, size_t n) {
  double mx = 0;
  for (size_t i = 0; i < 3 * n; i += 3) {
    double d = sqrt((a[i] - b[i]) * (a[i] - b[i]) + (a[i + 1] - b[i + 1]) * (a[i + 1] - b[i + 1]) +
                    (a[i + 2] - b[i + 2]) * (a[i + 2] - b[i + 2]));
    if (d > mx) mx = d;
  }
  return mx;
}

/* Points on a plane are fitted exactly: no method, no order moves them. */
static void test_plane_does_not_move(void **state) {
  (void)state;
  bsurf_cloud c;
  surface(&c, 3000, 0, 0, 0, 0.6);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 30, 2, NULL, NULL), BSURF_OK);
  double *out = malloc(c.point_count * 3 * sizeof(double));
  for (int m = 0; m < 4; m++)
    for (int order = 0; order < 2; order++) {
      bsurf_smooth_options o = options(methods[m < 3 ? m : 2], 30, m < 3 ? 3 : 4, 20);
      o.order = (bsurf_smooth_order)order;
      o.threshold = INFINITY;
      bsurf_smooth_report r;
      assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, &r), BSURF_OK);
      assert_true(max_move(c.xyz, out, c.point_count) <= 1e-9 * nb.h);
      assert_true(r.moved_max <= 1e-9 * nb.h);
    }
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* On a quadric the local height function in a tilted PCA frame is not a
 * polynomial, but a cubic fit follows it far below the point spacing: the
 * points stay put (moves < 1e-3 h), and the quadric's own axis-aligned
 * neighbourhoods are reproduced. */
static void test_quadric_does_not_move(void **state) {
  (void)state;
  bsurf_cloud c;
  surface(&c, 4000, 0.3, -0.2, 0.25, 0.0);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 40, 2, NULL, NULL), BSURF_OK);
  double *out = malloc(c.point_count * 3 * sizeof(double));
  for (int m = 0; m < 3; m++)
    for (int guard = 0; guard < 2; guard++) {
      bsurf_smooth_options o = options(methods[m], 40, 3, 20);
      o.threshold = INFINITY;
      o.guard = guard;
      bsurf_smooth_report r;
      assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, &r), BSURF_OK);
      print_message("quadric, method %d guard %d: max move %.3g h\n", m, guard, r.moved_max / nb.h);
      /* the guard's sheet is grown from the 12 nearest points by their
       * prediction interval; a tilted quadric is not a polynomial height in
       * the frame, so the farthest points' extrapolation residuals exceed
       * that interval and the fit is of fewer points */
      assert_true(r.moved_max < (guard ? 0.05 : 1e-3) * nb.h);
    }
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Gaussian noise of 0.5 h on a plane: every method leaves it flatter. */
static void test_noisy_plane_gets_flatter(void **state) {
  (void)state;
  bsurf_cloud c;
  double h = noisy_shape(&c, BSURF_SHAPE_PLANE, 6000, 7, 0, 0.5, 11);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 50, 2, NULL, NULL), BSURF_OK);
  double *out = malloc(c.point_count * 3 * sizeof(double));
  double rms0 = 0;
  size_t inner = 0;
  for (size_t i = 0; i < c.point_count; i++)
    rms0 += c.xyz[3 * i + 2] * c.xyz[3 * i + 2];
  rms0 = sqrt(rms0 / c.point_count);
  for (int m = 0; m < 3; m++)
    for (int order = 0; order < 2; order++) {
      bsurf_smooth_options o = options(methods[m], 50, 2, 30);
      o.order = (bsurf_smooth_order)order;
      o.threshold = INFINITY;
      o.h2_fraction = 2.0; /* a wide error weight: smooth everywhere */
      o.iterations = 300;
      o.guard = 0; /* the thesis's methods (the guard: test_two_sheets) */
      bsurf_smooth_report r;
      assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, &r), BSURF_OK);
      double rms = 0;
      inner = 0;
      for (size_t i = 0; i < c.point_count; i++) {
        /* away from the border, where fits extrapolate */
        if (fabs(c.xyz[3 * i]) > 0.8 || fabs(c.xyz[3 * i + 1]) > 0.8) continue;
        rms += out[3 * i + 2] * out[3 * i + 2];
        inner++;
      }
      rms = sqrt(rms / inner);
      print_message("noisy plane, method %d order %d: rms %.3f h -> %.3f h\n", m, order, rms0 / h,
                    rms / h);
      /* multipass shrinks K_i to k_min (a plane fit of 10 points) wherever
       * W_i exceeds the mean error (Eq. 6.4): on pure noise that is half the
       * points, so it smooths less */
      assert_true(rms < (methods[m] == BSURF_SMOOTH_MULTIPASS ? 0.75 : 0.35) * rms0);
    }
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Two parallel sheets gap_h spacings h apart (the plane's mean spacing h):
 * even points on z = +gap/2, odd ones on z = -gap/2, uniform noise of
 * noise_h h along z; nb their 50-neighbourhoods. */
static void sheets_make(bsurf_cloud *c, bsurf_neighbors *nb, double gap_h, double noise_h,
                        unsigned seed, double *h, double *gap) {
  assert_int_equal(bsurf_generate(c, BSURF_SHAPE_PLANE, 8000, BSURF_SAMPLING_RANDOM, 3, 0),
                   BSURF_OK);
  assert_int_equal(bsurf_mean_spacing(c->xyz, c->point_count, 2, h), BSURF_OK);
  const size_t n = c->point_count;
  *gap = gap_h * *h;
  for (size_t i = 0; i < n; i++)
    c->xyz[3 * i + 2] = (i % 2 ? -0.5 : 0.5) * *gap;
  assert_int_equal(bsurf_add_noise(c->xyz, c->normals, n, BSURF_NOISE_UNIFORM, noise_h, *h, seed),
                   BSURF_OK);
  assert_int_equal(bsurf_neighbors_build(nb, c->xyz, n, 50, 2, NULL, NULL), BSURF_OK);
}

/* Mean distance of the points P (rows of c's points) away from the border
 * to the point's own sheet, or (nearer) to the nearer sheet, as `bootsurf
 * eval --surface` measures it. */
static double sheets_err(const bsurf_cloud *c, const double *P, double gap, int nearer) {
  double s = 0;
  size_t m = 0;
  for (size_t i = 0; i < c->point_count; i++) {
    if (fabs(c->xyz[3 * i]) > 0.8 || fabs(c->xyz[3 * i + 1]) > 0.8) continue;
    const double z = P[3 * i + 2];
    s += nearer ? fmin(fabs(z - 0.5 * gap), fabs(z + 0.5 * gap))
                : fabs(z - (i % 2 ? -0.5 : 0.5) * gap);
    m++;
  }
  return s / (double)m;
}

/* Two parallel sheets 6 spacings h apart (a thin plate: the other sheet
 * lies inside most 50-neighbourhoods; each sheet's own mean spacing is about
 * 1.4 h, and where the gap is below the radius of a sheet's 12 nearest
 * points -- 4 h here -- those mix the sheets and the guard cannot separate
 * them, docs/smoothing.md), uniform noise of 0.5 h: with the
 * guard, at the defaults, no method and no order ends farther from the
 * nearest sheet than the noisy input, and multipass smooths to within
 * sqrt(2 m / K_min) of the noise (a least-squares fit of m terms predicts its
 * centre from K points with about m / K of the noise variance; K_i = K at
 * the defaults, down to K / 2 where the guard halves it). Without the guard the
 * bilateral method averages across the sheets. */
static void test_two_sheets(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_neighbors nb;
  double h, gap;
  sheets_make(&c, &nb, 6, 0.5, 13, &h, &gap);
  const size_t n = c.point_count;
  double *out = malloc(n * 3 * sizeof(double));
  const double e0 = sheets_err(&c, c.xyz, gap, 0);
  for (int m = 0; m < 3; m++)
    for (int order = 0; order < 2; order++) {
      bsurf_smooth_options o = bsurf_smooth_options_default();
      o.method = methods[m];
      o.order = (bsurf_smooth_order)order;
      o.error.bootstrap = 20;
      o.error.threads = 2;
      if (methods[m] == BSURF_SMOOTH_MULTIPASS && order) o.iterations = 30;
      assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_OK);
      const double e = sheets_err(&c, out, gap, 0);
      print_message("two sheets, method %d order %d: %.3f h -> %.3f h\n", m, order, e0 / h, e / h);
      assert_true(e < e0);
      if (methods[m] == BSURF_SMOOTH_MULTIPASS && !order) assert_true(e < sqrt(2.0 * 10 / 25) * e0);
    }
  bsurf_smooth_options o = bsurf_smooth_options_default();
  o.error.bootstrap = 20;
  o.error.threads = 2;
  o.guard = 0;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_OK);
  const double e = sheets_err(&c, out, gap, 0);
  print_message("two sheets, bilateral without the guard: %.3f h -> %.3f h\n", e0 / h, e / h);
  assert_true(e > e0);
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Two sheets gap_h spacings apart with uniform noise noise_h (sheets_make,
 * seed): every method at its defaults ends no farther from the nearest sheet
 * than the noisy input. */
static void thin_sheets_from(double gap_h, double noise_h, unsigned seed, int first, int last) {
  bsurf_cloud c;
  bsurf_neighbors nb;
  double h, gap;
  sheets_make(&c, &nb, gap_h, noise_h, seed, &h, &gap);
  const size_t n = c.point_count;
  double *out = malloc(n * 3 * sizeof(double));
  const double e0 = sheets_err(&c, c.xyz, gap, 1);
  for (int m = first; m < last; m++) {
    bsurf_smooth_options o = bsurf_smooth_options_default();
    o.method = methods[m];
    o.error.bootstrap = 20;
    o.error.threads = 2;
    assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_OK);
    const double e = sheets_err(&c, out, gap, 1);
    print_message("thin sheets, noise %.2f, method %d: %.3f h -> %.3f h\n", noise_h, m, e0 / h,
                  e / h);
    assert_true(e <= e0);
  }
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

static void thin_sheets_check(double gap_h, double noise_h, unsigned seed) {
  thin_sheets_from(gap_h, noise_h, seed, 0, 3);
}

/* Two sheets closer than their own spacing (the development set's thin
 * plate: faces 0.6 of a face's spacing apart, so about half of every
 * neighbourhood is the other face), uniform noise of 0.12 of that spacing:
 * the faces' residuals about a plane through both leave a gap, the guard
 * splits there (guard_gap, on all K points even where the fit is of fewer,
 * as multipass's K_i), and at the defaults no method ends farther from the
 * nearest sheet than the noisy input. Before the gap test the default
 * (bilateral) moved points from 0.125 h to 0.38 h (devset plate_thin_u0.25,
 * docs/smoothing.md). */
static void test_thin_sheets(void **state) {
  (void)state;
  thin_sheets_check(0.6, 0.12, 17);
}

/* The thin plate again, with noise that overlaps the faces' residuals more
 * (0.17 of the spacing): the gap between the faces' residuals about a plane
 * through both is then too narrow for guard_gap in many neighbourhoods, and
 * the second test (guard_bimodal: the best two-group split leaves less than
 * the quarter of the variance that any unimodal noise leaves) splits them.
 * At the defaults no method ends farther from the nearest sheet than the
 * noisy input (issue 22). Measured: 0.086 h noisy; naive 0.084 h, bilateral
 * (the default) 0.071 h, multipass 0.070 h; without the two-group test naive
 * 0.097 h and bilateral 0.096 h (the test failed). At noise 0.2 the default
 * ended farther (0.101 h -> 0.108 h; 0.132 h without the two-group test)
 * until the misfit test (test_thin_sheets_mixed). */
static void test_thin_sheets_overlap(void **state) {
  (void)state;
  thin_sheets_check(0.6, 0.17, 19);
}

/* The thin plate with still more noise, where the faces' residuals overlap
 * (noise 0.2 and 0.3 of the spacing; the development set's plate at
 * uniform 0.5 h is of this kind): in many neighbourhoods neither of the
 * guard's two-sheet tests fires, and before the misfit test the default
 * ended farther from the nearest sheet than the noisy input (noise 0.2:
 * 0.101 h -> 0.108 h). The misfit test (smooth_guard.c: a fit through both
 * faces leaves a residual variance far above the cloud's noise estimate)
 * keeps those fits from moving points: no method ends farther at 0.2. At
 * 0.25: test_thin_sheets_heavy. */
static void test_thin_sheets_mixed(void **state) {
  (void)state;
  thin_sheets_check(0.6, 0.2, 23);
}

/* The thin plate at noise 0.25 of the spacing (the development set's plate
 * at uniform 0.5 h is of this kind: the faces' residuals overlap so far that
 * most fits are of both faces): bilateral (the default) ends no farther
 * from the nearest sheet than the noisy input (measured 0.124 h -> 0.118 h).
 * Before the noise estimate took the lower decile of the fits' variances (it
 * took the lower quartile, itself a mixture's there) it went 0.124 h ->
 * 0.196 h. Not checked: naive still ends farther (0.124 h -> 0.130 h, was
 * 0.151 h: each point moves onto its own fit alone, and the mixed fits that
 * pass the misfit test are not averaged away), multipass at parity (0.124 h
 * -> 0.124 h). */
static void test_thin_sheets_heavy(void **state) {
  (void)state;
  thin_sheets_from(0.6, 0.25, 29, 1, 2);
}

/* The default smoothing (B = 20, two threads) of the n points xyz with K = 50
 * neighbourhoods: out (n x 3) and its report. */
/* The default smoothing at K = 50, B = 20, two threads, with a progress
 * callback (may be NULL): its status */
static bsurf_status smooth_k50(const double *xyz, size_t n, double *out, bsurf_smooth_report *rep,
                               bsurf_progress_fn progress, void *user) {
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 50, 2, NULL, NULL), BSURF_OK);
  bsurf_smooth_options o = bsurf_smooth_options_default();
  o.error.bootstrap = 20;
  o.error.threads = 2;
  o.error.progress = progress;
  o.error.progress_user = user;
  const bsurf_status st = bsurf_smooth(xyz, &nb, &o, out, NULL, rep);
  bsurf_neighbors_free(&nb);
  return st;
}

static void smooth_default_k50(const double *xyz, size_t n, double *out, bsurf_smooth_report *rep) {
  assert_int_equal(smooth_k50(xyz, n, out, rep, NULL, NULL), BSURF_OK);
}

/* The guard's noise estimate (bsurf_smooth_report.noise, guard_noise): on a
 * plane with gaussian noise sigma it is sigma to within a fifth (measured
 * 0.279 h for 0.3 h), and it stays so when a third of the plane is replaced
 * by a surface the fits cannot follow (a ridge every 3 spacings, 6 sigma
 * high: a fit flattens it, leaving a misfit of variance A^2 / 12 = 3
 * sigma^2): the lower decile of the fits' variances comes from the rest
 * (0.290 h). There the misfit test rejects most fits in the ridged part
 * (report.misfit_fits: 3494 of 12000), and the ridged part ends within
 * 3% of its noisy points' distance (measured 0.247 h -> 0.252 h: the few
 * fits that pass by chance), where flattening the ridge would leave A / 4 =
 * 0.45 h. */
static double ridge_z(double x, double h) {
  const double t = x / (3 * h) - floor(x / (3 * h)); /* a triangle wave of period 3h */
  return (t < 0.5 ? t : 1 - t) * 2.0;
}
static void test_noise_estimate(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 12000, BSURF_SAMPLING_RANDOM, 7, 0),
                   BSURF_OK);
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, c.point_count, 2, &h), BSURF_OK);
  const size_t n = c.point_count;
  const double sigma = 0.3 * h, A = 6 * sigma;
  double *z0 = malloc(n * sizeof(double)), *out = malloc(n * 3 * sizeof(double)), sig0 = 0;
  for (int ridged = 0; ridged < 2; ridged++) {
    for (size_t i = 0; i < n; i++) {
      const double x = c.xyz[3 * i];
      z0[i] = ridged && x > 1.0 / 3 ? A * ridge_z(x, h) : 0.0;
      c.xyz[3 * i + 2] = z0[i];
    }
    assert_int_equal(bsurf_add_noise(c.xyz, c.normals, n, BSURF_NOISE_GAUSSIAN, 0.3, h, 31),
                     BSURF_OK);
    bsurf_smooth_report rep;
    smooth_default_k50(c.xyz, n, out, &rep);
    double e0 = 0, e = 0;
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
      const double x = c.xyz[3 * i], y = c.xyz[3 * i + 1];
      if (x < 0.5 || x > 0.8 || fabs(y) > 0.8) continue; /* inside the ridged part */
      /* vertical distance: the ridge's slope is 4 A / (3 h) = 0.8 */
      e0 += fabs(c.xyz[3 * i + 2] - z0[i]);
      e += fabs(out[3 * i + 2] - A * (ridged ? ridge_z(out[3 * i], h) : 0.0));
      m++;
    }
    print_message("noise estimate, ridged %d: sigma %.3f h (true %.3f h), %zu misfit fits; "
                  "ridged part %.3f h -> %.3f h\n",
                  ridged, rep.noise / h, sigma / h, rep.misfit_fits, e0 / (double)m / h,
                  e / (double)m / h);
    if (!ridged) sig0 = rep.noise;
    assert_true(fabs(rep.noise - sigma) < 0.2 * sigma);
    assert_true(fabs(rep.noise - sig0) < 0.1 * sig0);
    if (ridged) {
      assert_true(rep.misfit_fits > n / 5);
      assert_true(e <= 1.03 * e0);
    } else {
      assert_true(e < 0.6 * e0);
    }
  }
  free(z0);
  free(out);
  bsurf_cloud_free(&c);
}

/* The noisy cube of issue 22 (gaussian noise 0.5 h along the normals,
 * 20,000 evenly spaced points, K = 50, B = 50): the mean distance to the
 * exact cube after the default smoothing (bilateral with the guard and
 * the degree test), after multipass at its defaults (the default method in
 * memory), and after bilateral without the degree test. The issue asks for
 * 0.12 h for both: bilateral measures 0.111 h here, multipass 0.1055 h
 * (0.171 h with its former defaults: h1 = 0.1 d_L, 300 passes, k_error
 * 3 |W|), bilateral without the degree test 0.147 h (docs/smoothing.md).
 * The bounds are the 0.12 h for bilateral and multipass and a
 * regression bound for the last; all keep at most 0.45 of the noisy
 * input's distance, and the degree test must lower bilateral's distance by
 * at least a tenth. Multipass must also end no farther than bilateral on
 * the feature points (within 2 spacings of an edge), as the issue asks. */
#define BOUND_DEFAULT 0.120
#define BOUND_MULTIPASS 0.120
#define BOUND_NO_TEST 0.155
/* The guard's two readings of the noise (bsurf_smooth_noise_level,
 * docs/smoothing.md, "Two readings of the noise"), exactly: the sheet fits'
 * reading stands unless the selection's is larger and more than 5% of the
 * points' neighbourhoods are cross-sections; exact data (the fits' reading
 * at most 1e-12 of the selection's) stay exact. */
static void test_noise_readings(void **state) {
  (void)state;
  assert_true(bsurf_smooth_noise_level(0.8, 2.0, 0.0) == 0.8);     /* no sections */
  assert_true(bsurf_smooth_noise_level(0.8, 2.0, 0.06) == 2.0);    /* sections */
  assert_true(bsurf_smooth_noise_level(0.8, 2.0, 0.05) == 0.8);    /* not above 5% */
  assert_true(bsurf_smooth_noise_level(0.8, 0.5, 1.0) == 0.8);     /* the larger */
  assert_true(bsurf_smooth_noise_level(0.0, 2.0, 1.0) == 0.0);     /* exact data */
  assert_true(bsurf_smooth_noise_level(2e-12, 2.0, 1.0) == 2e-12); /* to rounding */
  assert_true(bsurf_smooth_noise_level(2.1e-12, 2.0, 1.0) == 2.0);
  assert_true(isnan(bsurf_smooth_noise_level(NAN, 2.0, 1.0))); /* no fits */
  assert_true(bsurf_smooth_noise_level(0.8, NAN, 1.0) == 0.8); /* no selection */
  /* the selection's count of section-sampled points: those with a
   * cross-section level (the second of each point's two pooled values) */
  const double pooled[8] = {1, NAN, 1, 0.5, NAN, 0.7, 2, NAN};
  assert_int_equal(bsurf_ksel_sections(pooled, 4), 2);
  assert_int_equal(bsurf_ksel_sections(pooled, 1), 0);
}

/* The cylinder sampled on rings of test_util.h (ring_cylinder). Rings 8 s
 * apart: a point's nearest are an arc of its ring, and the sheet fits'
 * reading collapses (measured 0.0008 sigma); the selection finds 52% of the
 * points section-sampled and reads 1.05 sigma, and the guard takes that.
 * The fits there are the arcs themselves, so the points hardly move (0.2358
 * s -> 0.2347 s), but they do not move away. Rings 4 s apart (the nearest
 * reach the next ring): the fits' reading stands (0.80 sigma; 0.2358 s ->
 * 0.0795 s). */
static double ring_distance(const double *xyz, size_t n) {
  double e = 0;
  for (size_t i = 0; i < n; i++)
    e += fabs(hypot(xyz[3 * i], xyz[3 * i + 1]) - 1.0);
  return e / (double)n;
}
/* Progress through the guard's second reading: while the selection's table
 * is built and its passes run, the progress stays where stage 1 ended
 * (multipass: 1000 of 3000) and is reported after every chunk, so a caller
 * can cancel them (Python's KeyboardInterrupt, docs/python.md); the
 * callback changes no result. */
typedef struct stage_log {
  size_t calls, at_end, last;
  int back, cancel_at;
} stage_log;

static int stage_cb(void *u, size_t done, size_t total) {
  stage_log *l = u;
  if (done < l->last) l->back = 1;
  l->last = done;
  l->at_end += done * 3 == total;
  return l->at_end == (size_t)l->cancel_at;
}

static void rings_progress(const double *xyz, size_t n, const double *expect) {
  double *out = malloc(n * 3 * sizeof(double));
  assert_non_null(out);
  stage_log l = {0};
  assert_int_equal(smooth_k50(xyz, n, out, NULL, stage_cb, &l), BSURF_OK);
  print_message("progress at stage 1's end: %zu calls, back %d, last %zu\n", l.at_end, l.back,
                l.last);
  /* stage 1's last chunk, then the build and four passes at least */
  assert_true(l.at_end >= 6 && !l.back && l.last == 3000);
  assert_memory_equal(out, expect, n * 3 * sizeof(double));
  /* cancelled within the passes: no call after it (at_end stays 3, last
   * stays at stage 1's end) */
  stage_log c = {.cancel_at = 3};
  assert_int_equal(smooth_k50(xyz, n, out, NULL, stage_cb, &c), BSURF_ERR_CANCELLED);
  assert_true(c.at_end == 3 && c.last * 3 == 3000);
  free(out);
}

static void test_noise_rings(void **state) {
  (void)state;
  const size_t N = 3600;
  const double s = 2 * RING_PI / 60, sigma = 0.3 * s;
  double *xyz = malloc(N * 3 * sizeof(double)), *nrm = malloc(N * 3 * sizeof(double));
  double *out = malloc(N * 3 * sizeof(double));
  assert_non_null(xyz);
  assert_non_null(nrm);
  assert_non_null(out);
  for (int gap = 8; gap >= 4; gap -= 4) {
    const size_t n = ring_cylinder(gap, xyz, nrm);
    assert_true(n == N);
    bsurf_smooth_report rep;
    smooth_default_k50(xyz, n, out, &rep);
    const double e0 = ring_distance(xyz, n), e = ring_distance(out, n);
    print_message("rings %d s apart: noise %.3f sigma (fits %.4f, selection %.3f, sections "
                  "%.3f), %zu misfit fits; %.4f s -> %.4f s\n",
                  gap, rep.noise / sigma, rep.noise_fits / sigma, rep.noise_select / sigma,
                  rep.section_share, rep.misfit_fits, e0 / s, e / s);
    if (gap == 8) {
      assert_true(fabs(rep.noise_select - sigma) < 0.25 * sigma);
      assert_true(rep.section_share > 0.3);
      assert_true(rep.noise_fits < 0.05 * sigma);
      assert_true(rep.noise == rep.noise_select);
      assert_true(e <= e0);
      /* the section test alone bounds the passes' count from above
       * (bsurf_ksel_section_bound: the superset that lets bsurf_smooth skip
       * the passes where it is at most 5%) */
      bsurf_neighbors nb;
      assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 80, 2, NULL, NULL), BSURF_OK);
      bsurf_kselect_options ko;
      bsurf_smooth_select_options(2, &ko); /* the guard's: 10:80:5, GLOBAL */
      size_t bound = 0, sections = 0;
      double level;
      assert_int_equal(bsurf_ksel_section_bound(xyz, &nb, &ko, &bound), BSURF_OK);
      assert_int_equal(bsurf_ksel_cloud_noise(xyz, &nb, &ko, &level, &sections), BSURF_OK);
      print_message("sections %zu, their bound %zu of %zu\n", sections, bound, n);
      assert_true(sections > 0 && bound >= sections);
      assert_true((double)sections / (double)n == rep.section_share);
      assert_true(sqrt(level) == rep.noise_select);
      bsurf_neighbors_free(&nb);
      rings_progress(xyz, n, out);
    } else {
      /* not read: the section test alone finds at most 5% */
      assert_true(isnan(rep.noise_select) && rep.section_share <= 0.05);
      assert_true(rep.noise == rep.noise_fits);
      assert_true(fabs(rep.noise_fits - sigma) < 0.25 * sigma);
      assert_true(e < 0.5 * e0);
    }
  }
  free(xyz);
  free(nrm);
  free(out);
}

static void test_cube_distance(void **state) {
  (void)state;
  bsurf_cloud c;
  const double h = noisy_sample(&c, BSURF_SHAPE_CUBE, 20000, BSURF_SAMPLING_REGULAR, 1, 2, 0.5, 1);
  const size_t n = c.point_count;
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 50, 2, NULL, NULL), BSURF_OK);
  double *out = malloc(n * 3 * sizeof(double)), *dist = malloc(2 * n * sizeof(double));
  double e0 = 0;
  for (size_t i = 0; i < n; i++)
    e0 += bsurf_shape_distance(BSURF_SHAPE_CUBE, &c.xyz[3 * i]);
  e0 /= (double)n * h;
  /* bilateral (its degree test on), multipass (the default in memory), and
   * bilateral without the degree test (docs/smoothing.md, "The degree
   * test"), which must end farther than with it */
  const bsurf_smooth_method ms[3] = {BSURF_SMOOTH_BILATERAL, BSURF_SMOOTH_MULTIPASS,
                                     BSURF_SMOOTH_BILATERAL};
  const int dtest[3] = {-1, -1, 0};
  const double bound[3] = {BOUND_DEFAULT, BOUND_MULTIPASS, BOUND_NO_TEST};
  const bsurf_field *feat = bsurf_cloud_field(&c, "feature");
  assert_non_null(feat);
  double e_of[3], ef_of[3];
  for (int m = 0; m < 3; m++) {
    bsurf_smooth_options o = bsurf_smooth_options_default();
    o.method = ms[m];
    o.degree_test = dtest[m];
    o.error.threads = 2;
    assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_OK);
    double e = 0, ef = 0;
    size_t nf = 0;
    for (size_t i = 0; i < n; i++) {
      const double d = bsurf_shape_distance(BSURF_SHAPE_CUBE, &out[3 * i]);
      if (m < 2) dist[m * n + i] = d;
      e += d;
      if (feat->values[i] > 0) ef += d, nf++;
    }
    e /= (double)n * h;
    ef /= (double)(nf ? nf : 1) * h;
    print_message("cube, gaussian 0.5 h, method %d, degree test %d: %.4f h -> %.4f h "
                  "(%zu feature points: %.4f h)\n",
                  (int)ms[m], dtest[m], e0, e, nf, ef);
    assert_true(e <= bound[m]);
    assert_true(e <= 0.45 * e0);
    e_of[m] = e;
    ef_of[m] = ef;
  }
  assert_true(e_of[0] < 0.9 * e_of[2]);
  /* issue 22 asks multipass to be no worse than bilateral on feature points.
   * With multipass's h1 = sqrt((a d_L)^2 + 2 sigma^2) (bilateral's noise
   * correction, smooth_multipass.c) it is nearer: 0.2107 h against 0.2124 h
   * here (paired difference -0.00167 h, standard error 0.00107 h), 0.2136 h
   * against 0.2154 h on the development set's cube at gaussian 0.5 h
   * (docs/smoothing.md; before, with h1 = a d_L, 0.3% worse: 0.2130 h
   * against 0.2124 h here). What is checked: the paired difference over the
   * feature points is not above zero, and the point means agree with ef_of */
  double sd = 0, sd2 = 0;
  size_t nf = 0;
  const bsurf_field *lab = bsurf_cloud_field(&c, "feature");
  for (size_t i = 0; i < n; i++) {
    if (!(lab->values[i] > 0)) continue;
    const double d = (dist[n + i] - dist[i]) / h;
    sd += d, sd2 += d * d, nf++;
  }
  const double md = sd / (double)nf, se = sqrt((sd2 / (double)nf - md * md) / (double)(nf - 1));
  print_message("multipass - bilateral on %zu feature points: %.5f h (standard error %.5f h)\n", nf,
                md, se);
  assert_true(fabs(md - (ef_of[1] - ef_of[0])) < 1e-9);
  assert_true(md <= 0);
  free(dist);
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Noise-free input (docs/smoothing.md, "Noise-free input"): a cube sampled
 * on its faces, with sharp edges. The fits within a face leave no residual,
 * so the guard's noise estimate is 0, and at 0 its misfit test still runs:
 * no move helps where there is no noise to remove, and every fit that runs
 * across an edge (it leaves a residual) moves nothing. Before, a noise of 0
 * switched the test off and those fits moved the points near the edges off
 * the surface (the development set's CAD meshes without noise: up to
 * 0.047 h). Every method at its defaults, in both orders: the points stay on
 * the cube to 1e-9 h. */
static void test_clean_cube_stays(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 6000, BSURF_SAMPLING_REGULAR, 1, 2),
                   BSURF_OK);
  const size_t n = c.point_count;
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 50, 2, NULL, NULL), BSURF_OK);
  double *out = malloc(n * 3 * sizeof(double));
  for (int m = 0; m < 3; m++)
    for (int order = 0; order < 2; order++) {
      bsurf_smooth_options o = bsurf_smooth_options_default();
      o.method = methods[m];
      o.order = (bsurf_smooth_order)order;
      o.error.threads = 2;
      bsurf_smooth_report r;
      assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, &r), BSURF_OK);
      double mx = 0;
      for (size_t i = 0; i < n; i++)
        mx = fmax(mx, bsurf_shape_distance(BSURF_SHAPE_CUBE, &out[3 * i]));
      print_message("noise-free cube, method %d order %d: noise %.3g h, %zu misfit fits, "
                    "farthest from the cube %.3g h\n",
                    m, order, r.noise / nb.h, r.misfit_fits, mx / nb.h);
      assert_true(r.noise == 0);
      assert_true(mx <= 1e-9 * nb.h);
    }
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* The naive threshold: 0 moves nothing, none (INFINITY) projects every
 * point, auto projects exactly the points whose .632+ error is below the
 * mean, and those move along their frame normal only. */
static void test_naive_threshold(void **state) {
  (void)state;
  bsurf_cloud c;
  (void)noisy_shape(&c, BSURF_SHAPE_CUBE, 3000, 2, 2, 0.3, 1);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 30, 2, NULL, NULL), BSURF_OK);
  const size_t n = c.point_count;
  double *out = malloc(n * 3 * sizeof(double)), *e632p = malloc(n * sizeof(double)),
         *moved = malloc(n * sizeof(double));
  bsurf_smooth_fields f;
  memset(&f, 0, sizeof f);
  f.err_632plus = e632p;
  f.moved = moved;
  bsurf_smooth_options o = options(BSURF_SMOOTH_NAIVE, 30, 3, 25);
  bsurf_smooth_report r;

  o.threshold = 0;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, &f, &r), BSURF_OK);
  assert_int_equal(r.projected, 0);
  assert_int_equal(r.moved_points, 0);
  assert_memory_equal(out, c.xyz, n * 3 * sizeof(double));

  o.threshold = INFINITY;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, &f, &r), BSURF_OK);
  assert_int_equal(r.projected, n);

  o.threshold = NAN;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, &f, &r), BSURF_OK);
  double mean = 0;
  for (size_t i = 0; i < n; i++)
    mean += e632p[i];
  mean /= n;
  assert_true(fabs((r.threshold) - (mean)) <= 1e-12 * mean);
  assert_true(fabs((r.mean_error) - (mean)) <= 1e-12 * mean);
  size_t below = 0;
  for (size_t i = 0; i < n; i++) {
    if (e632p[i] < r.threshold) {
      below++;
    } else {
      assert_true(moved[i] == 0);
    }
  }
  assert_int_equal(r.projected, below);
  assert_true(below > n / 5 && below < n);
  free(out);
  free(e632p);
  free(moved);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* Multipass: K_i within [k_min, K], K where the error is smallest, k_min
 * where it reaches k_error; d_L positive; the report's passes. */
static void test_multipass_neighbourhoods(void **state) {
  (void)state;
  bsurf_cloud c;
  (void)noisy_shape(&c, BSURF_SHAPE_CUBE, 3000, 4, 2, 0.5, 3);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 40, 2, NULL, NULL), BSURF_OK);
  const size_t n = c.point_count;
  double *out = malloc(n * 3 * sizeof(double)), *e632 = malloc(n * sizeof(double)),
         *khat = malloc(n * sizeof(double)), *dl = malloc(n * sizeof(double));
  bsurf_smooth_fields f;
  memset(&f, 0, sizeof f);
  f.err_632 = e632;
  f.k_hat = khat;
  f.d_local = dl;
  bsurf_smooth_options o = options(BSURF_SMOOTH_MULTIPASS, 40, 3, 20);
  o.iterations = 7;
  bsurf_smooth_report r;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, &f, &r), BSURF_OK);
  assert_int_equal(r.iterations, 7);
  assert_true(fabs((r.k_error) - (r.mean_error)) <= 0);
  for (size_t i = 0; i < n; i++) {
    assert_true(khat[i] >= 10 && khat[i] <= 40);
    double y = (10.0 - 40.0) / r.k_error * e632[i] + 40.0;
    double expect = y <= 10 ? 10 : floor(y + 0.5);
    assert_true(khat[i] == expect);
    assert_true(dl[i] > 0);
  }
  free(out);
  free(e632);
  free(khat);
  free(dl);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* A noisy shape, its K = 30 neighbourhoods and two outputs, for tests that
 * compare two runs bit for bit. */
typedef struct twin_runs {
  bsurf_cloud c;
  bsurf_neighbors nb;
  size_t n;
  double *a, *b;
} twin_runs;

/* t->c's K-neighbourhoods and the two outputs. */
static void twins_finish(twin_runs *t, int K) {
  assert_int_equal(bsurf_neighbors_build(&t->nb, t->c.xyz, t->c.point_count, K, 2, NULL, NULL),
                   BSURF_OK);
  t->n = t->c.point_count;
  t->a = malloc(t->n * 3 * sizeof(double));
  t->b = malloc(t->n * 3 * sizeof(double));
}

static void twins_open(twin_runs *t, bsurf_shape shape, size_t n, uint64_t seed,
                       double feature_width, uint64_t noise_seed) {
  (void)noisy_shape(&t->c, shape, n, seed, feature_width, 0.5, noise_seed);
  twins_finish(t, 30);
}

/* Both outputs equal, and the points moved. */
static void twins_check(const twin_runs *t) {
  assert_memory_equal(t->a, t->b, t->n * 3 * sizeof(double));
  assert_true(max_move(t->c.xyz, t->a, t->n) > 0);
}

static void twins_close(twin_runs *t) {
  free(t->a);
  free(t->b);
  bsurf_neighbors_free(&t->nb);
  bsurf_cloud_free(&t->c);
}

/* 1 thread == 2 threads, bit for bit, for every method and order; and the
 * multipass at degree 4, where the points of small K_i get fits of lower
 * degree (a past bug evaluated those with the degree-4 basis's unset
 * values: no point moved on one thread, and two runs differed). */
static void test_thread_determinism(void **state) {
  (void)state;
  twin_runs t;
  twins_open(&t, BSURF_SHAPE_TORUS, 4000, 9, 0, 5);
  for (int m = 0; m < 4; m++)
    for (int order = 0; order < 2; order++) {
      bsurf_smooth_options o = options(methods[m < 3 ? m : 2], 30, m < 3 ? 3 : 4, 20);
      o.order = (bsurf_smooth_order)order;
      o.h2_fraction = 1.0;
      o.error.threads = 1;
      assert_int_equal(bsurf_smooth(t.c.xyz, &t.nb, &o, t.a, NULL, NULL), BSURF_OK);
      o.error.threads = 2;
      assert_int_equal(bsurf_smooth(t.c.xyz, &t.nb, &o, t.b, NULL, NULL), BSURF_OK);
      twins_check(&t);
    }
  twins_close(&t);
}

/* Multipass at its defaults (h1 the local spacing, h2 = 2 W_n, K_i = K,
 * passes until the stop rule): 1 thread == 2 threads bit for bit, in both
 * orders; the stop rule ends well before 300 passes; and on a noisy sphere
 * (6,000 points, gaussian 0.5 h, fixed seeds) the points end nearer than
 * 0.45 of the noisy input's distance, as test_cube_distance asks (0.35 of it
 * measured, in 2 passes: a fit of p terms from K points keeps about p / K of
 * the noise variance, sqrt(3 / 50) = 0.25 of its scale, plus the bias of
 * fits of the sphere's curvature at this density). */
static void test_multipass_defaults(void **state) {
  (void)state;
  twin_runs t;
  (void)noisy_shape(&t.c, BSURF_SHAPE_SPHERE, 6000, 3, 0, 0.5, 11);
  twins_finish(&t, 50);
  double e0 = 0;
  for (size_t i = 0; i < t.n; i++)
    e0 += bsurf_shape_distance(BSURF_SHAPE_SPHERE, &t.c.xyz[3 * i]);
  for (int order = 0; order < 2; order++) {
    bsurf_smooth_options o = bsurf_smooth_options_default();
    o.method = BSURF_SMOOTH_MULTIPASS;
    o.order = (bsurf_smooth_order)order;
    bsurf_smooth_report r1, r2;
    memset(&r1, 0, sizeof r1);
    memset(&r2, 0, sizeof r2);
    o.error.threads = 1;
    assert_int_equal(bsurf_smooth(t.c.xyz, &t.nb, &o, t.a, NULL, &r1), BSURF_OK);
    o.error.threads = 2;
    assert_int_equal(bsurf_smooth(t.c.xyz, &t.nb, &o, t.b, NULL, &r2), BSURF_OK);
    twins_check(&t);
    assert_int_equal(r1.iterations, r2.iterations);
    assert_true(r1.iterations >= 1 && r1.iterations < 20);
    double e = 0;
    for (size_t i = 0; i < t.n; i++)
      e += bsurf_shape_distance(BSURF_SHAPE_SPHERE, &t.a[3 * i]);
    print_message("sphere, gaussian 0.5 h, multipass defaults, order %d: %d passes, %.4g -> %.4g\n",
                  order, r1.iterations, e0 / (double)t.n, e / (double)t.n);
    assert_true(e < 0.45 * e0);
  }
  twins_close(&t);
}

/* The multipass passes in blocks, pairs in vector lanes, give the bits of
 * the point-by-point passes: degrees 1-3, a noisy cube (edges, where fits
 * leave their discs) and a wide h1 (--a, more pairs within the cut), on
 * one and two threads. */
static void test_multipass_block_passes(void **state) {
  (void)state;
  twin_runs t;
  twins_open(&t, BSURF_SHAPE_CUBE, 5000, 4, 2, 8);
  for (int degree = 1; degree <= 3; degree++)
    for (int wide = 0; wide < 2; wide++) {
      bsurf_smooth_options o = options(BSURF_SMOOTH_MULTIPASS, 30, degree, 20);
      o.iterations = 25;
      o.a = wide ? 0.6 : 0.1;
      o.error.threads = 1 + wide;
      bsurf_smooth_tuning tu = bsurf_smooth_tuning_defaults();
      tu.lanes = 0;
      assert_int_equal(bsurf_smooth_tuned(t.c.xyz, &t.nb, &o, &tu, t.a, NULL, NULL), BSURF_OK);
      assert_int_equal(bsurf_smooth(t.c.xyz, &t.nb, &o, t.b, NULL, NULL), BSURF_OK);
      twins_check(&t);
    }
  twins_close(&t);
}

/* The multipass passes in time blocks (several passes per region of 1024
 * points, the halo rows computed again) give the bits of the passes one by
 * one: 5000 points (five regions, so halos cross them), blocks of 8 and of
 * 3 passes (37 passes: a shorter last block), more pairs per point (h2 =
 * 1W, a wide h1; blocks allowed however wide their halos) and few,
 * degrees 1-3, one and two threads. A halo one level short, or a block run
 * on lists that miss a pair, would differ. */
static void test_multipass_time_blocks(void **state) {
  (void)state;
  twin_runs t;
  twins_open(&t, BSURF_SHAPE_CUBE, 5000, 6, 2, 3);
  for (int degree = 1; degree <= 3; degree++)
    for (int variant = 0; variant < 4; variant++) {
      bsurf_smooth_options o = options(BSURF_SMOOTH_MULTIPASS, 30, degree, 20);
      o.iterations = 37;
      o.a = variant & 1 ? 0.6 : 0.1;
      o.h2_fraction = variant & 2 ? 1.0 : 0.3;
      o.error.threads = 1;
      bsurf_smooth_tuning tu = bsurf_smooth_tuning_defaults();
      tu.tblock_passes = 1;
      assert_int_equal(bsurf_smooth_tuned(t.c.xyz, &t.nb, &o, &tu, t.a, NULL, NULL), BSURF_OK);
      for (int threads = 1; threads <= 2; threads++)
        for (int passes = 3; passes <= 8; passes += 5) {
          o.error.threads = threads;
          tu.tblock_passes = passes;
          tu.any_halo = 1;
          assert_int_equal(bsurf_smooth_tuned(t.c.xyz, &t.nb, &o, &tu, t.b, NULL, NULL), BSURF_OK);
          twins_check(&t);
        }
    }
  twins_close(&t);
}

/* The default 300 passes with h2 = 1W on a noisy cube: the active lists are
 * rebuilt many times and each region's pair arrays are refilled with
 * growing and shrinking sizes. A first version kept one capacity for two
 * arrays and wrote past one of them (`smooth --method multipass --h2 1W`
 * aborted in malloc; ASan: heap-buffer-overflow in mp_region_task). Same
 * bits as the passes one by one, on two threads. */
static void test_multipass_time_blocks_long(void **state) {
  (void)state;
  twin_runs
      t; /* as `generate cube -n 3000`, `noise --level 0.5` and the command's K = 50, B = 50 */
  (void)noisy_sample(&t.c, BSURF_SHAPE_CUBE, 3000, BSURF_SAMPLING_REGULAR, 1, 2, 0.5, 1);
  twins_finish(&t, 50);
  bsurf_smooth_options o = options(BSURF_SMOOTH_MULTIPASS, 50, 3, 50);
  o.iterations = 300;
  o.h2_fraction = 1.0;
  bsurf_smooth_tuning tu = bsurf_smooth_tuning_defaults();
  tu.tblock_passes = 1;
  assert_int_equal(bsurf_smooth_tuned(t.c.xyz, &t.nb, &o, &tu, t.a, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_smooth(t.c.xyz, &t.nb, &o, t.b, NULL, NULL), BSURF_OK);
  twins_check(&t);
  twins_close(&t);
}

/* The multipass weights' exponential: within 1e-15 relative of libm's exp
 * over its whole range [-GAUSS_CUT, 0] (37.43), exact at 0, and monotone. */
static void test_multipass_exp(void **state) {
  (void)state;
  double worst = 0, prev = 0;
  assert_true(bsurf_smooth_exp(0.0) == 1.0);
  for (int i = 0; i <= 400000; i++) {
    const double x = -37.43 + 37.43 * (double)i / 400000.0;
    const double e = bsurf_smooth_exp(x), ref = exp(x);
    const double rel = fabs(e - ref) / ref;
    if (rel > worst) worst = rel;
    assert_true(e >= prev);
    prev = e;
  }
  print_message("multipass exp: largest relative difference from exp %.3g\n", worst);
  assert_true(worst < 1e-15);
}

static void test_arguments(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 500, BSURF_SAMPLING_REGULAR, 1, 0),
                   BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 20, 2, NULL, NULL), BSURF_OK);
  double *out = malloc(c.point_count * 3 * sizeof(double));
  bsurf_smooth_options o = options(BSURF_SMOOTH_MULTIPASS, 20, 2, 10);
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, c.xyz, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, NULL, NULL, NULL), BSURF_ERR_INVALID_ARG);
  o.k_min = 21;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_ERR_INVALID_ARG);
  /* K_i = k_min points must carry a plane fit: 3 at least */
  o.k_min = 2;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_non_null(strstr(bsurf_last_message(), "k_min = 2: must be in [3"));
  o.k_min = 3;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_OK);
  o.k_min = 10;
  o = options(BSURF_SMOOTH_BILATERAL, 30, 2, 10); /* more than the neighbourhoods hold */
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_ERR_INVALID_ARG);
  o = options(BSURF_SMOOTH_BILATERAL, 5, 2, 10); /* fewer points than terms */
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_ERR_TOO_FEW_POINTS);
  o = options(BSURF_SMOOTH_BILATERAL, 20, 2, 10);
  o.h1 = NAN;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_ERR_INVALID_ARG);
  o = options(BSURF_SMOOTH_BILATERAL, 20, 2, 10);
  o.degree_test = 2; /* -1, 0 or 1 */
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &o, out, NULL, NULL), BSURF_ERR_INVALID_ARG);
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_does_not_move),
      cmocka_unit_test(test_quadric_does_not_move),
      cmocka_unit_test(test_noisy_plane_gets_flatter),
      cmocka_unit_test(test_two_sheets),
      cmocka_unit_test(test_thin_sheets),
      cmocka_unit_test(test_thin_sheets_overlap),
      cmocka_unit_test(test_thin_sheets_heavy),
      cmocka_unit_test(test_thin_sheets_mixed),
      cmocka_unit_test(test_noise_estimate),
      cmocka_unit_test(test_noise_readings),
      cmocka_unit_test(test_noise_rings),
      cmocka_unit_test(test_cube_distance),
      cmocka_unit_test(test_clean_cube_stays),
      cmocka_unit_test(test_naive_threshold),
      cmocka_unit_test(test_multipass_neighbourhoods),
      cmocka_unit_test(test_thread_determinism),
      cmocka_unit_test(test_multipass_defaults),
      cmocka_unit_test(test_multipass_block_passes),
      cmocka_unit_test(test_multipass_time_blocks),
      cmocka_unit_test(test_multipass_time_blocks_long),
      cmocka_unit_test(test_multipass_exp),
      cmocka_unit_test(test_arguments),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
