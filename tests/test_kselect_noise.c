/* The MSE rule's noise estimate where its misfit extrapolation degenerates,
 * at light noise on a sparse sampling and on a plane whose small balls
 * truncate the noise (src/algo/kselect_noise.c;
 * docs/normals.md, "Choosing K", *noise*): a cube whose edges make the
 * extrapolation degenerate at the points near them, and a sphere whose
 * density varies 10x across it with Gaussian noise about the sparse
 * part's spacing, a coarse wavy surface whose misfit must not be read as
 * noise (fixed seeds); and bsurf_select_k against its passes,
 * whose second pass 3 runs at the gated points only (kselect_run.c). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <stdint.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "algo/algo.h"
#include "bootsurf.h"

static double angle_u(const double *a, const double *b) {
  const double d = fabs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
  const double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                       a[0] * b[1] - a[1] * b[0]};
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), d);
}

#define SPHERE_SIGMA 1.0 /* the noise's deviation, in units of the thinned cloud's h */

static const int KS[] = {15, 20, 25, 30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80};
#define NKS ((int)(sizeof KS / sizeof KS[0]))

/* the selection's mean angle error, the pooled noise deviation (its median
 * over the points: global, the one value) and the share and mean error of
 * the points at K <= 30 */
typedef struct sel_result {
  double err, sigma, small_share, small_err;
} sel_result;

static sel_result select_pool(const double *xyz, const double *tn, size_t n,
                              const bsurf_neighbors *nb, bsurf_noise_pool pool) {
  double *nrm = malloc(3 * n * sizeof(double)), *noise = malloc(n * sizeof(double));
  int *k = malloc(n * sizeof(int));
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.threads = 2;
  o.noise_pool = pool;
  bsurf_kselect_fields f = {nrm, k, NULL, noise, NULL, NULL};
  assert_int_equal(bsurf_select_k(xyz, nb, &o, &f, NULL), BSURF_OK);
  sel_result r = {0, 0, 0, 0};
  size_t nsmall = 0;
  for (size_t i = 0; i < n; i++) {
    const double e = angle_u(&nrm[3 * i], &tn[3 * i]);
    r.err += e;
    if (k[i] <= 30) r.small_err += e, nsmall++;
  }
  r.err /= n;
  r.sigma = bsurf_median(noise, n);
  r.small_share = (double)nsmall / n;
  r.small_err = nsmall ? r.small_err / nsmall : 0;
  free(nrm);
  free(noise);
  free(k);
  return r;
}

static sel_result select_on(const double *xyz, const double *tn, size_t n,
                            const bsurf_neighbors *nb) {
  return select_pool(xyz, tn, n, nb, BSURF_NOISE_POOL_GLOBAL);
}

/* the mean angle error of the PCA normals at a fixed K */
static double fixed_k(const double *xyz, const double *tn, size_t n, const bsurf_neighbors *nb,
                      int K) {
  double *nrm = malloc(3 * n * sizeof(double));
  bsurf_normal_options no = bsurf_normal_options_default();
  no.k = K;
  no.bootstrap = 0;
  bsurf_normal_fields out = {nrm, NULL, NULL};
  assert_int_equal(bsurf_estimate_normals(xyz, nb, NULL, &no, &out, NULL), BSURF_OK);
  double e = 0;
  for (size_t i = 0; i < n; i++)
    e += angle_u(&nrm[3 * i], &tn[3 * i]);
  free(nrm);
  return e / n;
}

/* A sphere of 30,000 random points thinned with keep probability 0.1^t,
 * t = (x + 1) / 2 (the development set's anisotropic sampling: density
 * 10x across), Gaussian noise of one thinned-cloud spacing h along the
 * normals (fixed seeds): the development set's anisotropic sphere at g0.25
 * in miniature. Its best fixed K is the largest; where the noise reads low
 * the small candidates' variance reads low, a few sparse points take a
 * small K whose normal is far off, and the larger candidates' drifts from
 * it read as bias. Measured: with the degenerate extrapolations clamped to
 * 0 and the quartile of chi^2 at the first fit's degrees of freedom, sigma
 * 0.835 of the true one, 0.99% of the points at K <= 30 (mean error 0.326
 * rad), 1.126x the best fixed K (80); then sigma 0.873, 0.59% (0.309 rad),
 * 1.061x (the truncation rule's stop at the first scale whose own, low-drawn
 * estimate passed it); with the scale chosen by Lepski's method over the
 * nested scales (kselect_noise.c) sigma 0.918, 0.38% (0.212 rad), 1.016x
 * (0.950, 0.993x while a smaller scale tested a larger one only where it
 * resolved the larger's level, a condition since dropped). With the drift's
 * two witnesses (kselect.c: the second largest term, session 15) the same
 * sigma and 0.38% of the points at K <= 30 (0.190 rad), 1.031x: a larger K
 * is charged only where two smaller candidates disagree, and a little of
 * the sparse side's curvature bias goes uncharged (the development set's
 * anisotropic sphere at g0.25 1.003 -> 1.018; its 95 ordinary cases 72
 * -> 76 at most the best fixed K). The bounds sit between the
 * noise-estimate rules above: 1.04 keeps the two before Lepski's scale out. */
static void test_aniso_sphere(void **state) {
  (void)state;
  bsurf_cloud dense;
  assert_int_equal(bsurf_generate(&dense, BSURF_SHAPE_SPHERE, 30000, BSURF_SAMPLING_RANDOM, 7, 2),
                   BSURF_OK);
  const size_t nd = dense.point_count;
  double *xyz = malloc(3 * nd * sizeof(double)), *tn = malloc(3 * nd * sizeof(double));
  size_t n = 0;
  bsurf_rng rng;
  bsurf_rng_init(&rng, 20261125, 0, 0);
  for (size_t i = 0; i < nd; i++) {
    const double t = (dense.xyz[3 * i] + 1) / 2;
    if (!(bsurf_rng_uniform(&rng) < pow(0.1, t))) continue;
    memcpy(&xyz[3 * n], &dense.xyz[3 * i], 3 * sizeof(double));
    memcpy(&tn[3 * n], &dense.normals[3 * i], 3 * sizeof(double));
    n++;
  }
  bsurf_cloud_free(&dense);
  double h;
  assert_int_equal(bsurf_mean_spacing(xyz, n, 2, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(xyz, tn, n, BSURF_NOISE_GAUSSIAN, SPHERE_SIGMA, h, 11),
                   BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  const sel_result r = select_on(xyz, tn, n, &nb);
  double best = INFINITY;
  int kbest = 0;
  for (int a = 0; a < NKS; a++) {
    const double e = fixed_k(xyz, tn, n, &nb, KS[a]);
    if (e < best) best = e, kbest = KS[a];
  }
  print_message("aniso sphere (%zu points): sigma estimated / true %.3f; selection %.5f (%.4f of "
                "the points at K <= 30, mean error %.3f), best fixed K %d %.5f, ratio %.3f\n",
                n, r.sigma / (SPHERE_SIGMA * h), r.err, r.small_share, r.small_err, kbest, best,
                r.err / best);
  assert_true(r.sigma > 0.90 * SPHERE_SIGMA * h && r.sigma < 1.1 * SPHERE_SIGMA * h);
  assert_true(r.err < 1.04 * best);
  free(xyz);
  free(tn);
  bsurf_neighbors_free(&nb);
}

/* The noise level alone (the pooled global estimate of the selection's
 * noise field) on a plane of 20,000 random points with Gaussian noise of
 * deviation sigma along the normal (fixed seeds), the candidates 15:80:5.
 * At sigma = 0.25 h the 12-ball's radius is about 7 sigma, the truncation
 * small; at sigma = h about 2 sigma, so the residuals of a small ball are a
 * truncated sample, and the truncation rule's stop (kselect_noise.c) on the
 * point's own draw leaves the estimate low. Measured (sigma / h 0.25, 0.5,
 * 1.0, 1.5, 2.0): 1.014, 0.991, 0.892, 0.803, 0.843 of sigma; with the
 * stop's and the extrapolation's residual variances read through the
 * truncation model v = sigma^2 tau(R / sigma) (tried, not kept:
 * docs/normals.md, "The ball's truncation modelled") 1.016, 1.002, 0.928,
 * 0.843, 0.891. With the scale chosen per point by Lepski's method
 * (kselect_noise.c), which moves on past the first untruncated scale while
 * the estimate does not rise beyond its precision, 0.954 and 0.935 at 0.25
 * and 1.0 h: the heavy level's bound is above the former 0.892. At 3.0 h
 * every scale up to K_max = 80 is truncated at most points, and the
 * largest's residual variance read as the share kappa(R / sigma) of the
 * noise its ball keeps (bsurf_ball_noise, ball_scale.c) gives 1.005 of
 * sigma (0.894 as the bare residual variance, before). */
static double plane_sigma(double sigma, uint64_t seed) {
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 20000, BSURF_SAMPLING_RANDOM, seed, 2),
                   BSURF_OK);
  const size_t n = c.point_count;
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, n, 2, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, n, BSURF_NOISE_GAUSSIAN, sigma, h, seed + 1),
                   BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  double *tn = malloc(3 * n * sizeof(double));
  memcpy(tn, c.normals, 3 * n * sizeof(double));
  const sel_result r = select_on(c.xyz, tn, n, &nb);
  free(tn);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  return r.sigma / (sigma * h);
}

static void test_plane_noise(void **state) {
  (void)state;
  const double light = plane_sigma(0.25, 31), heavy = plane_sigma(1.0, 41);
  const double unresolved = plane_sigma(3.0, 51);
  print_message("plane: sigma estimated / true at 0.25 h %.3f, at 1.0 h %.3f, at 3.0 h %.3f\n",
                light, heavy, unresolved);
  assert_true(light > 0.9 && light < 1.1);
  assert_true(heavy > 0.91 && heavy < 1.1);
  assert_true(unresolved > 0.93 && unresolved < 1.1);
}

/* A coarse wavy surface: 3,000 random points of the square [-1, 1]^2
 * lifted to z = A sin(2 pi x / L) sin(2 pi y / L), L = 8 h and A = h (h the
 * mean spacing), Gaussian noise of 0.1 h along the true normals (fixed
 * seeds). A quadric resolves a wave of eight spacings only over the
 * smallest neighbourhoods: its residual variance holds the misfit, which
 * grows with K far beyond the noise and is no polynomial the quadric's
 * next degree would take up, as on the coarse vertex sets of the
 * development set. The per-point scale (kselect_noise.c) must stop where
 * the residual variance rises: a scale rule that follows the rise reads
 * the misfit as noise. Measured (sigma estimated / true): the truncation
 * rule's first untruncated scale 2.575, the per-point scale by Lepski's
 * test on the log scale 2.894; the fit at noise_k = 40 5.107, and Lepski's
 * test on the plain difference v_K - v_j against v_K sqrt(2 / nu_j - 2 /
 * nu_K) (the larger, inflated estimate setting its own allowance) 4.956.
 * The bound sits between. */
static void test_wavy_noise(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_PLANE, 3000, BSURF_SAMPLING_RANDOM, 13, 2),
                   BSURF_OK);
  const size_t n = c.point_count;
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, n, 2, &h), BSURF_OK);
  const double L = 8 * h, A = h, w = 2 * 3.14159265358979323846 / L;
  for (size_t i = 0; i < n; i++) {
    const double x = c.xyz[3 * i], y = c.xyz[3 * i + 1];
    c.xyz[3 * i + 2] = A * sin(w * x) * sin(w * y);
    const double gx = A * w * cos(w * x) * sin(w * y), gy = A * w * sin(w * x) * cos(w * y);
    const double nn = sqrt(1 + gx * gx + gy * gy);
    c.normals[3 * i] = -gx / nn, c.normals[3 * i + 1] = -gy / nn, c.normals[3 * i + 2] = 1 / nn;
  }
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, n, BSURF_NOISE_GAUSSIAN, 0.1, h, 17),
                   BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  const sel_result r = select_on(c.xyz, c.normals, n, &nb);
  print_message("wavy: sigma estimated / true %.3f, selection %.5f\n", r.sigma / (0.1 * h), r.err);
  assert_true(r.sigma > 0.8 * 0.1 * h && r.sigma < 3.8 * 0.1 * h);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* A ring-sampled cylinder, as a CAD mesh's vertices often are (joint's in
 * the development set): radius 1, rings of 60 points 0.8 apart along the
 * axis (7.6 in-ring spacings: a point's 12 nearest are one ring's arc), 20
 * rings, Gaussian noise of deviation 0.002 along the normal (fixed seed), so
 * within each ring's plane; the pooled noise, global and local. The
 * quadric's heights read no noise in a ring's plane, and across rings a
 * misfit (six deviations over the 80 nearest) its extrapolation takes away
 * with the noise; the cross-section estimate (kselect_noise.c, "The noise
 * within a cross-section's plane") reads it. Measured (sigma estimated /
 * true): the quadric's alone (main before it) 0.000, with it 1.013 (the
 * local pool's median 0.965). The control, the same number of points at
 * random on the same cylinder (no rings), reads 0.586 with either: its
 * level is the quadric's, the cross-section estimate not taken. (Rows of
 * straight lines, where the conic is poorly determined, are
 * tests/cli/tiles.sh's and docs/normals.md's.) */
static double cylinder_sigma(int rings, double *local_ratio) {
  const int M = 60, H = 20;
  const double sigma = 0.002, dz = 0.8;
  const size_t n = (size_t)M * H;
  double *xyz = malloc(3 * n * sizeof(double)), *tn = malloc(3 * n * sizeof(double));
  bsurf_rng rng;
  bsurf_rng_init(&rng, 20261127, 0, 0);
  for (size_t i = 0; i < n; i++) {
    const double t = rings ? 2 * 3.14159265358979323846 * (double)(i % M) / M
                           : 2 * 3.14159265358979323846 * bsurf_rng_uniform(&rng);
    const double z = rings ? dz * (double)(i / M) : dz * H * bsurf_rng_uniform(&rng);
    tn[3 * i] = cos(t), tn[3 * i + 1] = sin(t), tn[3 * i + 2] = 0;
    xyz[3 * i] = cos(t), xyz[3 * i + 1] = sin(t), xyz[3 * i + 2] = z;
  }
  assert_int_equal(bsurf_add_noise(xyz, tn, n, BSURF_NOISE_GAUSSIAN, sigma, 1.0, 5), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  const sel_result r = select_on(xyz, tn, n, &nb);
  *local_ratio = select_pool(xyz, tn, n, &nb, BSURF_NOISE_POOL_LOCAL).sigma / sigma;
  free(xyz);
  free(tn);
  bsurf_neighbors_free(&nb);
  return r.sigma / sigma;
}

static void test_ring_cylinder(void **state) {
  (void)state;
  double lr, lc;
  const double ring = cylinder_sigma(1, &lr), ctl = cylinder_sigma(0, &lc);
  print_message("ring-sampled cylinder: sigma estimated / true %.3f (local pool's median %.3f); "
                "randomly sampled %.3f (%.3f)\n",
                ring, lr, ctl, lc);
  assert_true(ring > 0.85 && ring < 1.15);
  assert_true(lr > 0.85 && lr < 1.15);
  assert_true(ctl > 0.5 && ctl < 0.7 && lc > 0.5 && lc < 0.7);
}

/* A cube of 3,000 random points with Gaussian noise of 0.1 h along the
 * normals (fixed seeds): sparse enough that many points' doubled
 * neighbourhoods (the misfit's extrapolation) cross an edge, where the
 * extrapolation degenerates. Clamping those to 0, which the lower-quartile
 * pool then picked, read sigma 0.766 of the true one; leaving them out
 * (and the extrapolated estimates' effective degrees of freedom) 1.105. */
static void test_cube_noise(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 3000, BSURF_SAMPLING_RANDOM, 3, 2),
                   BSURF_OK);
  const size_t n = c.point_count;
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, n, 2, &h), BSURF_OK);
  double *tn = malloc(3 * n * sizeof(double));
  memcpy(tn, c.normals, 3 * n * sizeof(double));
  assert_int_equal(bsurf_add_noise(c.xyz, tn, n, BSURF_NOISE_GAUSSIAN, 0.1, h, 7), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  const sel_result r = select_on(c.xyz, tn, n, &nb);
  print_message("cube: sigma estimated / true %.3f, selection %.5f, K = 30 %.5f\n",
                r.sigma / (0.1 * h), r.err, fixed_k(c.xyz, tn, n, &nb, 30));
  assert_true(r.sigma > 0.85 * 0.1 * h && r.sigma < 1.2 * 0.1 * h);
  free(tn);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

/* bsurf_select_k by its passes (algo.h): bsurf_ksel_first, then
 * bsurf_ksel_choose with the first choices as the empirical bias's
 * references. In memory bsurf_select_k runs pass 3 once for every point and
 * once more only where the lack-of-fit gate fires (kselect_run.c,
 * ksel_select with defer): the same bits, the same unassessed count. */
static void passes(const double *xyz, const bsurf_neighbors *nb, const bsurf_kselect_options *o,
                   bsurf_kselect_fields *f, bsurf_kselect_report *rep) {
  const size_t n = nb->point_count;
  bsurf_ksel_run *r;
  assert_int_equal(bsurf_ksel_open(o, nb->k, f->two_sheet != NULL, &r), BSURF_OK);
  assert_true(bsurf_ksel_empirical(r));
  double *s2 = malloc(2 * n * sizeof(double)), *noise = malloc(2 * n * sizeof(double));
  double *bref = malloc(3 * n * sizeof(double)), *bm = malloc(n * sizeof(double));
  assert_int_equal(bsurf_ksel_noise(r, xyz, nb, s2), BSURF_OK);
  assert_int_equal(bsurf_ksel_pool(r, xyz, nb, s2, noise), BSURF_OK);
  assert_int_equal(bsurf_ksel_level(r, noise, n), BSURF_OK);
  assert_int_equal(bsurf_ksel_first(r, xyz, nb, noise, NULL, NULL, bref, bm), BSURF_OK);
  memset(rep, 0, sizeof *rep);
  assert_int_equal(bsurf_ksel_choose(r, xyz, nb, noise, bref, bm, NULL, NULL, f, rep), BSURF_OK);
  free(s2);
  free(noise);
  free(bref);
  free(bm);
  bsurf_ksel_close(r);
}

/* A cube of 4,000 random points with Gaussian noise of 0.3 h (fixed seeds):
 * at its edges the quadric does not fit and the gate fires, so the second
 * pass 3 has points to choose again. Every field bit for bit, at 1 and 2
 * threads. */
static void test_second_pass(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 4000, BSURF_SAMPLING_RANDOM, 5, 2),
                   BSURF_OK);
  const size_t n = c.point_count;
  double h;
  assert_int_equal(bsurf_mean_spacing(c.xyz, n, 2, &h), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, n, BSURF_NOISE_GAUSSIAN, 0.3, h, 9), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  double *nrm[2], *err[2], *noise[2];
  int *k[2], *sheet[2];
  for (int v = 0; v < 2; v++) {
    nrm[v] = malloc(3 * n * sizeof(double));
    err[v] = malloc(n * sizeof(double));
    noise[v] = malloc(n * sizeof(double));
    k[v] = malloc(n * sizeof(int));
    sheet[v] = malloc(n * sizeof(int));
  }
  size_t moved = 0; /* points whose K the empirical bias moved */
  for (int threads = 1; threads <= 2; threads++) {
    bsurf_kselect_options o = bsurf_kselect_options_default();
    o.ks = KS;
    o.nk = NKS;
    o.threads = threads;
    bsurf_kselect_fields f0 = {nrm[0], k[0], err[0], noise[0], sheet[0], NULL};
    bsurf_kselect_fields f1 = {nrm[1], k[1], err[1], noise[1], sheet[1], NULL};
    bsurf_kselect_report r0, r1;
    assert_int_equal(bsurf_select_k(c.xyz, &nb, &o, &f0, &r0), BSURF_OK);
    passes(c.xyz, &nb, &o, &f1, &r1);
    assert_memory_equal(nrm[0], nrm[1], 3 * n * sizeof(double));
    assert_memory_equal(err[0], err[1], n * sizeof(double));
    assert_memory_equal(noise[0], noise[1], n * sizeof(double));
    assert_memory_equal(k[0], k[1], n * sizeof(int));
    assert_memory_equal(sheet[0], sheet[1], n * sizeof(int));
    assert_int_equal(r0.unassessed, r1.unassessed);
    if (threads == 1) { /* the bias moves some choices: the second pass is exercised */
      bsurf_ksel_run *r;
      assert_int_equal(bsurf_ksel_open(&o, nb.k, 0, &r), BSURF_OK);
      double *s2 = malloc(2 * n * sizeof(double)), *nz = malloc(2 * n * sizeof(double));
      double *fn = malloc(3 * n * sizeof(double));
      int *k2 = malloc(n * sizeof(int));
      assert_int_equal(bsurf_ksel_noise(r, c.xyz, &nb, s2), BSURF_OK);
      assert_int_equal(bsurf_ksel_pool(r, c.xyz, &nb, s2, nz), BSURF_OK);
      assert_int_equal(bsurf_ksel_level(r, nz, n), BSURF_OK);
      bsurf_kselect_fields f2 = {fn, k2, NULL, NULL, NULL, NULL};
      assert_int_equal(bsurf_ksel_choose(r, c.xyz, &nb, nz, NULL, NULL, NULL, NULL, &f2, NULL),
                       BSURF_OK);
      for (size_t i = 0; i < n; i++)
        moved += k2[i] != k[0][i];
      free(s2);
      free(nz);
      free(fn);
      free(k2);
      bsurf_ksel_close(r);
    }
  }
  print_message("cube: the empirical bias moved the K of %zu of %zu points\n", moved, n);
  assert_true(moved > 0);
  for (int v = 0; v < 2; v++) {
    free(nrm[v]);
    free(err[v]);
    free(noise[v]);
    free(k[v]);
    free(sheet[v]);
  }
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_aniso_sphere), cmocka_unit_test(test_cube_noise),
      cmocka_unit_test(test_plane_noise),  cmocka_unit_test(test_wavy_noise),
      cmocka_unit_test(test_second_pass),  cmocka_unit_test(test_ring_cylinder),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
