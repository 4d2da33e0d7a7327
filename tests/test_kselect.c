/* K selection by the estimated mean squared error of the PCA normal
 * (src/algo/kselect.c): the nested moments against direct sums, the noise
 * estimate, statistical checks at a fixed seed on generated shapes,
 * determinism across thread counts, bad options. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <stdint.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "algo/algo.h"
#include "local/local.h"

static const int KS[] = {15, 20, 25, 30, 40, 50, 60, 70, 80};
#define NKS ((int)(sizeof KS / sizeof KS[0]))

static double angle_u(const double *a, const double *b) {
  double d = fabs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
  double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), d);
}

/* A generated shape with noise along its normals (level in units of the
 * clean cloud's spacing h), its neighbourhoods (K_max = 80) and h. */
typedef struct noisy_shape {
  bsurf_cloud c;
  double *clean_normals;
  bsurf_neighbors nb;
  double h;
} noisy_shape;

static void shape_make(noisy_shape *s, bsurf_shape shape, size_t n, bsurf_noise_model model,
                       double level) {
  assert_int_equal(bsurf_generate(&s->c, shape, n, BSURF_SAMPLING_RANDOM, 3, 2), BSURF_OK);
  bsurf_neighbors nb0;
  assert_int_equal(bsurf_neighbors_build(&nb0, s->c.xyz, s->c.point_count, 2, 2, NULL, NULL),
                   BSURF_OK);
  s->h = nb0.h;
  bsurf_neighbors_free(&nb0);
  s->clean_normals = malloc(3 * s->c.point_count * sizeof(double));
  memcpy(s->clean_normals, s->c.normals, 3 * s->c.point_count * sizeof(double));
  assert_int_equal(bsurf_add_noise(s->c.xyz, s->c.normals, s->c.point_count, model, level, s->h, 7),
                   BSURF_OK);
  assert_int_equal(bsurf_neighbors_build(&s->nb, s->c.xyz, s->c.point_count, 80, 2, NULL, NULL),
                   BSURF_OK);
}

static void shape_free(noisy_shape *s) {
  bsurf_neighbors_free(&s->nb);
  bsurf_cloud_free(&s->c);
  free(s->clean_normals);
}

typedef struct sel_out {
  double *normals, *rmse, *noise;
  int *k;
} sel_out;

/* The selection over KS on n points with their neighbourhoods nb: every
 * field of r allocated and filled, rep (may be NULL) the report. */
static void select_nb(const double *xyz, const bsurf_neighbors *nb, int threads,
                      bsurf_noise_pool pool, sel_out *r, bsurf_kselect_report *rep) {
  const size_t n = nb->point_count;
  r->normals = malloc(3 * n * sizeof(double));
  r->rmse = malloc(n * sizeof(double));
  r->noise = malloc(n * sizeof(double));
  r->k = malloc(n * sizeof(int));
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.threads = threads;
  o.noise_pool = pool;
  bsurf_kselect_fields f = {r->normals, r->k, r->rmse, r->noise, NULL, NULL};
  assert_int_equal(bsurf_select_k(xyz, nb, &o, &f, rep), BSURF_OK);
}

static void select_run_pool(const noisy_shape *s, int threads, bsurf_noise_pool pool, sel_out *r) {
  select_nb(s->c.xyz, &s->nb, threads, pool, r, NULL);
}

/* The same on bare points: their K_max neighbourhoods first; two threads. */
static void select_xyz(const double *xyz, size_t n, sel_out *r, bsurf_kselect_report *rep) {
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  select_nb(xyz, &nb, 2, BSURF_NOISE_POOL_GLOBAL, r, rep);
  bsurf_neighbors_free(&nb);
}

static void select_run(const noisy_shape *s, int threads, sel_out *r) {
  select_run_pool(s, threads, BSURF_NOISE_POOL_GLOBAL, r);
}

static void sel_free(sel_out *r) {
  free(r->normals);
  free(r->rmse);
  free(r->noise);
  free(r->k);
}

static double mean_k(const sel_out *r, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++)
    s += r->k[i];
  return s / n;
}

/* One pass of running sums gives each prefix's centroid and covariance as
 * a direct two-pass computation does. */
static void test_nested_moments(void **state) {
  (void)state;
  noisy_shape s;
  shape_make(&s, BSURF_SHAPE_TORUS, 3000, BSURF_NOISE_GAUSSIAN, 0.5);
  const int ks[] = {12, 20, 33, 80};
  double mu[4 * 3], cov[4 * 6], terms[80 * BSURF_NESTED_COLS], sums[4 * BSURF_NESTED_COLS];
  for (size_t i = 0; i < s.c.point_count; i += 97) {
    const uint32_t *idx = &s.nb.idx[i * (size_t)s.nb.k];
    bsurf_nested_terms(s.c.xyz, idx, 80, terms);
    bsurf_nested_sums(terms, 80, 1, NULL, ks, 4, sums, NULL);
    for (int a = 0; a < 4; a++)
      assert_int_equal(bsurf_nested_cov(&sums[a * BSURF_NESTED_COLS], 1, BSURF_PCA_CENTROID,
                                        &mu[3 * a], &cov[6 * a]),
                       0);
    for (int a = 0; a < 4; a++) {
      const double *d = &s.c.xyz[3 * (size_t)idx[0]];
      double m[3] = {0, 0, 0}, C[6] = {0};
      for (int j = 0; j < ks[a]; j++)
        for (int t = 0; t < 3; t++)
          m[t] += (s.c.xyz[3 * (size_t)idx[j] + t] - d[t]) / ks[a];
      for (int j = 0; j < ks[a]; j++) {
        double q[3];
        for (int t = 0; t < 3; t++)
          q[t] = s.c.xyz[3 * (size_t)idx[j] + t] - d[t] - m[t];
        C[0] += q[0] * q[0] / ks[a], C[1] += q[0] * q[1] / ks[a], C[2] += q[0] * q[2] / ks[a];
        C[3] += q[1] * q[1] / ks[a], C[4] += q[1] * q[2] / ks[a], C[5] += q[2] * q[2] / ks[a];
      }
      for (int t = 0; t < 3; t++)
        assert_true(fabs(mu[3 * a + t] - m[t]) < 1e-12);
      for (int t = 0; t < 6; t++)
        assert_true(fabs(cov[6 * a + t] - C[t]) < 1e-12);
    }
  }
  shape_free(&s);
}

/* The pooled noise estimate against the noise put in, on a plane: small
 * noise (sigma = 0.3 h, the quadric on 20 neighbours) and large (sigma =
 * 2 h, where 20 neighbours are a truncated sample and the fit moves to
 * larger K). */
static void test_noise_estimate(void **state) {
  (void)state;
  /* at 2 h the K_max-th neighbour lies within 5 sigma, the residuals are
   * truncated and the lower-quartile pooling reads them low (docs/normals.md:
   * the noise is resolved while R >= 5 sigma): 0.919 of sigma (0.957 at
   * 0.3 h), the same before and after session 17's reading of the truncated
   * scales (the pool's lower quartile falls on points with an untruncated
   * scale); about 20% low when the pooling was introduced */
  const double levels[] = {0.3, 2.0}, tol[] = {0.1, 0.25};
  for (int l = 0; l < 2; l++) {
    noisy_shape s;
    shape_make(&s, BSURF_SHAPE_PLANE, 20000, BSURF_NOISE_GAUSSIAN, levels[l]);
    sel_out r;
    select_run(&s, 2, &r);
    double m = 0;
    for (size_t i = 0; i < s.c.point_count; i++)
      m += r.noise[i];
    m /= s.c.point_count;
    const double sigma = levels[l] * s.h;
    print_message("plane, sigma = %.1f h: pooled noise / sigma %.3f\n", levels[l], m / sigma);
    assert_true(fabs(m / sigma - 1) < tol[l]);
    sel_free(&r);
    shape_free(&s);
  }
}

/* On a sphere the chosen K grows with the noise (the variance term) and
 * stays below K_max at low noise (the curvature's bias). */
static void test_k_grows_with_noise(void **state) {
  (void)state;
  const double levels[] = {0.05, 0.3, 1.0};
  double prev = 0;
  for (int l = 0; l < 3; l++) {
    noisy_shape s;
    shape_make(&s, BSURF_SHAPE_SPHERE, 4000, BSURF_NOISE_GAUSSIAN, levels[l]);
    sel_out r;
    select_run(&s, 2, &r);
    const double mk = mean_k(&r, s.c.point_count);
    if (l == 0) assert_true(mk < 60);
    assert_true(mk > prev);
    prev = mk;
    sel_free(&r);
    shape_free(&s);
  }
}

/* The mean angle error of the fixed-K PCA normals of s (single fits); with
 * fe, also their mean over the points it flags (> 0.5) into *ef. */
static double fixed_k_error(const noisy_shape *s, int k, const bsurf_field *fe, double *ef) {
  const size_t n = s->c.point_count;
  double *fixed = malloc(3 * n * sizeof(double));
  bsurf_normal_options o = bsurf_normal_options_default();
  o.k = k;
  o.bootstrap = 0;
  bsurf_normal_fields out = {fixed, NULL, NULL};
  assert_int_equal(bsurf_estimate_normals(s->c.xyz, &s->nb, NULL, &o, &out, NULL), BSURF_OK);
  double e = 0, sf = 0, nf = 0;
  for (size_t i = 0; i < n; i++) {
    const double d = angle_u(&fixed[3 * i], &s->clean_normals[3 * i]);
    e += d;
    if (fe && fe->values[i] > 0.5) sf += d, nf++;
  }
  if (fe) *ef = sf / nf;
  free(fixed);
  return e / n;
}

/* A cube of 20,000 points with Gaussian noise of level h (seed fixed), the
 * selection on it and its feature flag (points near an edge). */
static const bsurf_field *cube_selected(noisy_shape *s, double level, sel_out *r) {
  shape_make(s, BSURF_SHAPE_CUBE, 20000, BSURF_NOISE_GAUSSIAN, level);
  select_run(s, 2, r);
  const bsurf_field *fe = bsurf_cloud_field(&s->c, "feature");
  assert_non_null(fe);
  return fe;
}

/* On a noisy cube, points near the edges get smaller neighbourhoods than
 * the faces' interiors, and the selection's mean angle error is no worse
 * than the best single candidate K's (chosen in hindsight), over the whole
 * cloud and over the points near an edge alone (the generator's feature
 * flag): there the bias changes within a few spacings, which each point's
 * own drift estimates must see (averaged over 12 neighbours, the former
 * rule's, they were diluted by the neighbours farther from the edge). */
static void test_cube_edges(void **state) {
  (void)state;
  noisy_shape s;
  sel_out r;
  const bsurf_field *fe = cube_selected(&s, 0.3, &r);
  double kf = 0, kn = 0, nf = 0, nn = 0, err = 0, errf = 0;
  const size_t n = s.c.point_count;
  for (size_t i = 0; i < n; i++) {
    const double e = angle_u(&r.normals[3 * i], &s.clean_normals[3 * i]);
    if (fe->values[i] > 0.5)
      kf += r.k[i], nf++, errf += e;
    else
      kn += r.k[i], nn++;
    err += e;
  }
  assert_true(nf > 100 && nn > 100);
  assert_true(kf / nf < 0.8 * (kn / nn));
  err /= n;
  errf /= nf;
  double best = INFINITY, bestf = INFINITY;
  for (int a = 0; a < NKS; a++) {
    double ef;
    const double e = fixed_k_error(&s, KS[a], fe, &ef);
    if (e < best) best = e;
    if (ef < bestf) bestf = ef;
  }
  print_message("cube: selection %.5f (edges %.5f, K %.1f; faces K %.1f), best fixed K %.5f "
                "(edges %.5f)\n",
                err, errf, kf / nf, kn / nn, best, bestf);
  assert_true(err <= best);
  assert_true(errf <= bestf);
  sel_free(&r);
  shape_free(&s);
}

/* The tie-break weighs each neighbour's reference normal by its
 * precision, 1 / M of its first choice (docs/normals.md, "Choosing K"):
 * on a cube with Gaussian noise of 0.6 h (seed fixed), where the edges'
 * references are several times less precise than the faces', the
 * selection beats the best single candidate K over the cloud and, at the
 * edges (the generator's feature flag), that K's error there: it does not
 * buy the faces' gain with the edges (measured: 0.08356, edges 0.44366,
 * against the best fixed K's 0.10695 and 0.50383; the best K at the edges
 * alone, 0.43691, is not reached; with equal weights 0.08490 and
 * 0.44799). */
static void test_tie_weights(void **state) {
  (void)state;
  noisy_shape s;
  sel_out r;
  const bsurf_field *fe = cube_selected(&s, 0.6, &r);
  const size_t n = s.c.point_count;
  double err = 0, errf = 0, nf = 0, best = INFINITY, bestf = INFINITY;
  for (size_t i = 0; i < n; i++) {
    const double e = angle_u(&r.normals[3 * i], &s.clean_normals[3 * i]);
    err += e;
    if (fe->values[i] > 0.5) errf += e, nf++;
  }
  assert_true(nf > 100);
  for (int a = 0; a < NKS; a++) {
    double ef;
    const double e = fixed_k_error(&s, KS[a], fe, &ef);
    if (e < best) best = e, bestf = ef;
  }
  print_message("tie weights: cube g0.6 selection %.5f (edges %.5f, K %.1f), best fixed K %.5f "
                "(its edges %.5f)\n",
                err / n, errf / nf, mean_k(&r, n), best, bestf);
  assert_true(err / n <= best);
  assert_true(errf / nf <= bestf);
  sel_free(&r);
  shape_free(&s);
}

/* On a smooth sphere with noise (seed fixed), where larger K is better up to
 * K_max, the selection beats the smallest candidate K by far and comes
 * within 30% of the best candidate (K = 80; measured: 0.01046 against
 * 0.00993, K = 15 0.0510, mean K 72.8; with equal tie-break weights
 * 0.01029, mean K 73.0; with the drifts averaged over 12 neighbours, the
 * former rule: 0.0124, mean K 72.6): the drift term must
 * not mistake the small candidates' noise for bias (hence its Bonferroni
 * allowance; the first version of the rule, one draw at c = 2, was 2.6x the
 * best K on the development set's anisotropic sphere). */
static void test_sphere_smooth(void **state) {
  (void)state;
  noisy_shape s;
  shape_make(&s, BSURF_SHAPE_SPHERE, 20000, BSURF_NOISE_UNIFORM, 0.5);
  sel_out r;
  select_run(&s, 2, &r);
  const size_t n = s.c.point_count;
  double err = 0;
  for (size_t i = 0; i < n; i++)
    err += angle_u(&r.normals[3 * i], &s.clean_normals[3 * i]);
  err /= n;
  const double e15 = fixed_k_error(&s, 15, NULL, NULL), e80 = fixed_k_error(&s, 80, NULL, NULL);
  print_message("sphere: selection %.5f (K %.1f), K = 15 %.5f, K = 80 %.5f\n", err, mean_k(&r, n),
                e15, e80);
  assert_true(e80 < e15);
  assert_true(err < 0.5 * e15);
  assert_true(err <= 1.3 * e80);
  sel_free(&r);
  shape_free(&s);
}

static double sel_error(const noisy_shape *s, const sel_out *r) {
  double e = 0;
  for (size_t i = 0; i < s->c.point_count; i++)
    e += angle_u(&r->normals[3 * i], &s->clean_normals[3 * i]);
  return e / s->c.point_count;
}

/* The noise's pooling (docs/normals.md, "Choosing K"): with one level for
 * the cloud (the default) every point's estimate is the same number, and
 * on a torus with Gaussian noise (seed fixed), whose best fixed K is the
 * largest, the selection comes closer to it than with each point's own
 * level (measured: 0.02595, mean K 70.7, against 0.02711, mean K 70.0; the
 * best fixed K, 80: 0.02402; the global sigma 0.570 h for 0.6 h). The bound
 * against the best fixed K is 1.2: each point's own drift estimates at the
 * Bonferroni level charge about 5% of a smooth surface's points a bias that
 * is noise (1.145x here; 1.05x when the drifts were averaged over 12
 * neighbours, which missed sharp edges: test_cube_edges). */
static void test_noise_pool(void **state) {
  (void)state;
  noisy_shape s;
  shape_make(&s, BSURF_SHAPE_TORUS, 20000, BSURF_NOISE_GAUSSIAN, 0.6);
  sel_out g, l;
  select_run_pool(&s, 2, BSURF_NOISE_POOL_GLOBAL, &g);
  select_run_pool(&s, 2, BSURF_NOISE_POOL_LOCAL, &l);
  const size_t n = s.c.point_count;
  for (size_t i = 1; i < n; i++)
    assert_true(g.noise[i] == g.noise[0]);
  double best = INFINITY;
  for (int a = 0; a < NKS; a++) {
    const double e = fixed_k_error(&s, KS[a], NULL, NULL);
    if (e < best) best = e;
  }
  const double eg = sel_error(&s, &g), el = sel_error(&s, &l);
  print_message(
      "noise pool: global %.5f (K %.1f) local %.5f (K %.1f) best fixed %.5f, sigma %.5f h "
      "global\n",
      eg, mean_k(&g, n), el, mean_k(&l, n), best, g.noise[0] / s.h);
  assert_true(fabs(g.noise[0] / (0.6 * s.h) - 1) < 0.1);
  assert_true(eg < el);
  assert_true(eg <= 1.2 * best);
  sel_free(&g);
  sel_free(&l);
  shape_free(&s);
}

/* The selection on one thread (*a) and on two (*b): the same bits in every
 * output. */
static void select_both_threads(const noisy_shape *s, sel_out *a, sel_out *b) {
  select_run(s, 1, a);
  select_run(s, 2, b);
  const size_t n = s->c.point_count;
  assert_memory_equal(a->normals, b->normals, 3 * n * sizeof(double));
  assert_memory_equal(a->k, b->k, n * sizeof(int));
  assert_memory_equal(a->rmse, b->rmse, n * sizeof(double));
  assert_memory_equal(a->noise, b->noise, n * sizeof(double));
}

/* Same bits with one thread and with two. */
static void test_determinism(void **state) {
  (void)state;
  noisy_shape s;
  shape_make(&s, BSURF_SHAPE_TORUS, 5000, BSURF_NOISE_UNIFORM, 0.5);
  sel_out a, b;
  select_both_threads(&s, &a, &b);
  sel_free(&a);
  sel_free(&b);
  shape_free(&s);
}

/* The tie-break's compact store (kselect.c, tie_store / tie_load) hands
 * back the chosen candidate's own normal: every output normal has the bits
 * of the PCA normal of the chosen K as select_point computes it (nested
 * sums, bsurf_eigen_sym3), on a cube (edges and faces: several K
 * chosen); -j1 and -j2 agree. */
static void test_tie_store_exact(void **state) {
  (void)state;
  noisy_shape s;
  shape_make(&s, BSURF_SHAPE_CUBE, 6000, BSURF_NOISE_UNIFORM, 0.5);
  sel_out a, b;
  select_both_threads(&s, &a, &b);
  const size_t n = s.c.point_count;
  double terms[80 * BSURF_NESTED_COLS], sums[NKS * BSURF_NESTED_COLS];
  int chosen[NKS] = {0};
  for (size_t i = 0; i < n; i++) {
    const uint32_t *idx = &s.nb.idx[i * (size_t)s.nb.k];
    bsurf_nested_terms(s.c.xyz, idx, 80, terms);
    bsurf_nested_sums(terms, 80, 1, NULL, KS, NKS, sums, NULL);
    int c = 0;
    while (c < NKS && KS[c] != a.k[i])
      c++;
    assert_true(c < NKS);
    chosen[c] = 1;
    double mu[3], cv[6];
    bsurf_nested_cov(&sums[(size_t)c * BSURF_NESTED_COLS], 1, BSURF_PCA_CENTROID, mu, cv);
    double C[3][3] = {{cv[0], cv[1], cv[2]}, {cv[1], cv[3], cv[4]}, {cv[2], cv[4], cv[5]}};
    double ev[3], V[3][3];
    bsurf_eigen_sym3(C, ev, V);
    assert_memory_equal(&a.normals[3 * i], V[0], 3 * sizeof(double));
  }
  int distinct = 0; /* the store's candidate indices exercised */
  for (int c = 0; c < NKS; c++)
    distinct += chosen[c];
  assert_true(distinct >= 3);
  sel_free(&a);
  sel_free(&b);
  shape_free(&s);
}

/* Progress and cancellation: bsurf_select_k reports over twice the rows,
 * the noise fits' pass in the first range and the selection's in the
 * second; the pooling between them holds at the first range's end and the
 * passes after the selection at the total, after every chunk, so a caller
 * can cancel any of them (Python's KeyboardInterrupt) and its progress
 * never goes back; the callback changes no result. */
typedef struct progress_log {
  size_t n, calls, first, held, second, last, total;
  int back, cancel_at;
} progress_log;

static int log_cb(void *u, size_t done, size_t total) {
  progress_log *l = u;
  if (done < l->last || (l->calls && total != l->total)) l->back = 1;
  l->first += done > 0 && done < l->n;
  l->held += done == l->n && l->last == l->n;
  l->second += done > l->n && done < 2 * l->n;
  l->last = done, l->total = total;
  return ++l->calls == (size_t)l->cancel_at;
}

static void test_progress(void **state) {
  (void)state;
  noisy_shape s;
  shape_make(&s, BSURF_SHAPE_SPHERE, 9000, BSURF_NOISE_GAUSSIAN, 0.3);
  const size_t n = s.c.point_count;
  sel_out a;
  select_run(&s, 2, &a);
  double *nrm = malloc(3 * n * sizeof(double));
  int *k = malloc(n * sizeof(int));
  bsurf_kselect_fields f = {nrm, k, NULL, NULL, NULL, NULL};
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.threads = 2;
  progress_log l = {.n = n};
  o.progress = log_cb;
  o.progress_user = &l;
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_OK);
  print_message("progress: %zu calls, %zu within the noise fits, %zu held between, %zu within "
                "the selection, last %zu of %zu\n",
                l.calls, l.first, l.held, l.second, l.last, l.total);
  /* 9,000 rows: 3 chunks a pass (the last of each at its range's end) */
  assert_true(l.first >= 2 && l.held >= 2 && l.second >= 2);
  assert_true(!l.back && l.last == 2 * n && l.total == 2 * n);
  assert_memory_equal(nrm, a.normals, 3 * n * sizeof(double));
  assert_memory_equal(k, a.k, n * sizeof(int));
  /* cancelled within the noise passes, and at the last call */
  const int at[] = {1, (int)l.calls};
  for (int j = 0; j < 2; j++) {
    progress_log c = {.n = n, .cancel_at = at[j]};
    o.progress_user = &c;
    assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_CANCELLED);
    assert_true(c.calls == (size_t)at[j]);
  }
  free(nrm);
  free(k);
  sel_free(&a);
  shape_free(&s);
}

static void test_bad_options(void **state) {
  (void)state;
  noisy_shape s;
  shape_make(&s, BSURF_SHAPE_SPHERE, 500, BSURF_NOISE_GAUSSIAN, 0.1);
  double nrm[3 * 500];
  int k[500];
  bsurf_kselect_fields f = {nrm, k, NULL, NULL, NULL, NULL};
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  assert_int_equal(bsurf_select_k(NULL, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, NULL, &f, NULL), BSURF_ERR_INVALID_ARG);
  const int small[] = {6, 20}, unsorted[] = {30, 20}, big[] = {20, 81};
  o.ks = small;
  o.nk = 2;
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.ks = unsorted;
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.ks = big; /* beyond the neighbourhoods' K_max */
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.ks = KS;
  o.nk = 0;
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.nk = NKS;
  o.noise_k = 11;
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.noise_k = 20;
  o.rule = BSURF_KSELECT_TEST_ERROR; /* the caller's loop, not this function */
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  o.rule = BSURF_KSELECT_MSE;
  o.noise_pool = (bsurf_noise_pool)2;
  assert_int_equal(bsurf_select_k(s.c.xyz, &s.nb, &o, &f, NULL), BSURF_ERR_INVALID_ARG);
  shape_free(&s);
}

/* The two_sheet flag of the chosen neighbourhood, as a share of the points. */
static double sheet_share(const double *xyz, const bsurf_neighbors *nb) {
  const size_t n = nb->point_count;
  int *k = malloc(n * sizeof(int)), *two = malloc(n * sizeof(int));
  bsurf_kselect_options o = bsurf_kselect_options_default();
  o.ks = KS;
  o.nk = NKS;
  o.threads = 2;
  bsurf_kselect_fields f = {NULL, k, NULL, NULL, two, NULL};
  assert_int_equal(bsurf_select_k(xyz, nb, &o, &f, NULL), BSURF_OK);
  size_t m = 0;
  for (size_t i = 0; i < n; i++) {
    assert_true(two[i] == 0 || two[i] == 1);
    m += (size_t)two[i];
  }
  free(k);
  free(two);
  return (double)m / (double)n;
}

/* A thin plate: two parallel sheets of the unit square 0.6 point spacings
 * apart (the development set's thin parts), Gaussian noise of 0.1 spacing
 * along z: most points are flagged (a neighbourhood split unevenly
 * between the sheets, or a small K, can stay below the test's power). One sheet with uniform noise
 * (the test's least favourable null) and a sphere with Gaussian noise: about the test's level,
 * 0.001, of the points. Fixed seeds. */
static void test_two_sheets(void **state) {
  (void)state;
  const size_t n = 20000;
  const double spacing = sqrt(2.0 / (double)n), gap = 0.6 * spacing;
  double *xyz = malloc(3 * n * sizeof(double));
  bsurf_rng rng;
  bsurf_rng_init(&rng, 11, 0, 0);
  for (size_t i = 0; i < n; i++) {
    xyz[3 * i] = bsurf_rng_uniform(&rng);
    xyz[3 * i + 1] = bsurf_rng_uniform(&rng);
    xyz[3 * i + 2] = (i % 2 ? 0.5 : -0.5) * gap + 0.1 * spacing * bsurf_rng_normal(&rng);
  }
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 80, 2, NULL, NULL), BSURF_OK);
  const double plate = sheet_share(xyz, &nb);
  bsurf_neighbors_free(&nb);
  free(xyz);
  noisy_shape one, sphere;
  shape_make(&one, BSURF_SHAPE_PLANE, n, BSURF_NOISE_UNIFORM, 0.5);
  shape_make(&sphere, BSURF_SHAPE_SPHERE, n, BSURF_NOISE_GAUSSIAN, 0.3);
  const double plane = sheet_share(one.c.xyz, &one.nb), sph = sheet_share(sphere.c.xyz, &sphere.nb);
  print_message("two_sheet: plate %.4f, plane (uniform noise) %.4f, sphere %.4f\n", plate, plane,
                sph);
  assert_true(plate > 0.5); /* most (0.70 at this seed) */
  assert_true(plane < 0.005);
  assert_true(sph < 0.005);
  shape_free(&one);
  shape_free(&sphere);
}

/* Curve-sampled neighbourhoods (src/algo/kselect.c, docs/normals.md): the
 * vertices of a cylinder on 30 rings of 300 points each, the rings 1.0
 * apart and their points 0.021 apart (joint's CAD rings, exaggerated), with
 * Gaussian noise of 0.2 in-ring spacings: each point's 80 nearest
 * neighbours lie on its own ring, a curve, whose PCA plane is the ring's
 * plane (perpendicular to the surface) while the rule's estimates read a
 * clean plane. Nearly all of them (measured: all) must be unassessed: the
 * largest candidate, normal_err pi / 2, counted in the report. The surface
 * controls, a sphere with uniform noise 0.5 h and a plane with Gaussian
 * noise 0.3 h (random sampling, a Poisson process): at the test's level,
 * 1e-5, of their points (none here). Fixed seeds. */
static int unassessed_count(const double *xyz, size_t n, int *kmax_share, size_t *reported) {
  sel_out r;
  bsurf_kselect_report rep;
  select_xyz(xyz, n, &r, &rep);
  int m = 0, mk = 0;
  for (size_t i = 0; i < n; i++)
    if (r.rmse[i] > 1.5707963) {
      m++;
      mk += r.k[i] == KS[NKS - 1];
    }
  *kmax_share = mk;
  *reported = rep.unassessed;
  sel_free(&r);
  return m;
}

static void test_curve_sampled(void **state) {
  (void)state;
  const int rings = 30, per = 300;
  const size_t n = (size_t)rings * per;
  const double step = 2 * 3.14159265358979323846 / per;
  double *xyz = malloc(3 * n * sizeof(double));
  bsurf_rng rng;
  bsurf_rng_init(&rng, 5, 0, 0);
  for (int r = 0; r < rings; r++)
    for (int j = 0; j < per; j++) {
      double *p = &xyz[3 * ((size_t)r * per + j)];
      p[0] = cos(j * step) + 0.2 * step * bsurf_rng_normal(&rng);
      p[1] = sin(j * step) + 0.2 * step * bsurf_rng_normal(&rng);
      p[2] = r * 1.0 + 0.2 * step * bsurf_rng_normal(&rng);
    }
  int mk;
  size_t rep;
  const int ring = unassessed_count(xyz, n, &mk, &rep);
  free(xyz);
  assert_int_equal(mk, ring);
  assert_int_equal(rep, (size_t)ring);
  noisy_shape sph, pl;
  shape_make(&sph, BSURF_SHAPE_SPHERE, 10000, BSURF_NOISE_UNIFORM, 0.5);
  shape_make(&pl, BSURF_SHAPE_PLANE, 10000, BSURF_NOISE_GAUSSIAN, 0.3);
  const int a = unassessed_count(sph.c.xyz, sph.c.point_count, &mk, &rep);
  const int b = unassessed_count(pl.c.xyz, pl.c.point_count, &mk, &rep);
  print_message("curve-sampled: rings %d of %zu unassessed, sphere %d, plane %d\n", ring, n, a, b);
  assert_true(ring >= 0.95 * n);
  assert_true(a <= 2 && b <= 2);
  shape_free(&sph);
  shape_free(&pl);
}

/* A clean surface patch in a noisy cloud (docs/normals.md, "Planes thinner
 * than the noise"): the unit square at z = 0 with no noise (4,000 random
 * points) beside a noisy one at z = 10 (6,000 points, Gaussian 0.3 h; fixed
 * seeds), so that the cloud's global noise level is the noisy square's. At
 * the clean square's points every candidate's plane is thinner than that
 * level allows, but it is the surface's own tangent plane (it agrees with the
 * K_max neighbours' plane, and they are a surface patch), not a
 * cross-section's: each candidate is assessed and the normal is exact.
 * Within 0.4 of the border the K_max neighbours are a half-disc, no patch by
 * the disc test, so the points counted are those of the inner square
 * |x|, |y| <= 0.6; of them at most the disc test's level (5%, asymptotic)
 * plus a margin, 10%, may be taken for a curve's run and stay unassessed.
 * Before the condition every candidate there was left out, and every point
 * was unassessed (the largest K, normal_err pi / 2). */
static void test_clean_patch(void **state) {
  (void)state;
  bsurf_cloud a, b;
  assert_int_equal(bsurf_generate(&a, BSURF_SHAPE_PLANE, 4000, BSURF_SAMPLING_RANDOM, 3, 2),
                   BSURF_OK);
  assert_int_equal(bsurf_generate(&b, BSURF_SHAPE_PLANE, 6000, BSURF_SAMPLING_RANDOM, 5, 2),
                   BSURF_OK);
  bsurf_neighbors nb0;
  assert_int_equal(bsurf_neighbors_build(&nb0, b.xyz, b.point_count, 2, 2, NULL, NULL), BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(b.xyz, b.normals, b.point_count, BSURF_NOISE_GAUSSIAN, 0.3, nb0.h, 7),
      BSURF_OK);
  bsurf_neighbors_free(&nb0);
  const size_t na = a.point_count, n = na + b.point_count;
  double *xyz = malloc(3 * n * sizeof(double));
  memcpy(xyz, a.xyz, 3 * na * sizeof(double));
  for (size_t i = 0; i < b.point_count; i++) {
    memcpy(&xyz[3 * (na + i)], &b.xyz[3 * i], 3 * sizeof(double));
    xyz[3 * (na + i) + 2] += 10.0;
  }
  sel_out r;
  select_xyz(xyz, n, &r, NULL);
  size_t unassessed = 0, inner = 0;
  double worst = 0;
  const double up[3] = {0, 0, 1};
  for (size_t i = 0; i < na; i++) {
    if (fabs(xyz[3 * i]) > 0.6 || fabs(xyz[3 * i + 1]) > 0.6) continue;
    inner++;
    unassessed += !(r.rmse[i] < 1.5707963);
    const double e = angle_u(&r.normals[3 * i], up);
    worst = e > worst ? e : worst;
  }
  print_message("clean patch: noise %.3g, %zu of %zu inner clean points unassessed, worst angle "
                "%.3g\n",
                r.noise[0], unassessed, inner, worst);
  assert_true(r.noise[0] > 0);
  assert_true(unassessed <= 0.1 * inner);
  assert_true(worst < 1e-9);
  sel_free(&r);
  bsurf_cloud_free(&a);
  bsurf_cloud_free(&b);
  free(xyz);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_nested_moments),     cmocka_unit_test(test_noise_estimate),
      cmocka_unit_test(test_k_grows_with_noise), cmocka_unit_test(test_cube_edges),
      cmocka_unit_test(test_sphere_smooth),      cmocka_unit_test(test_determinism),
      cmocka_unit_test(test_bad_options),        cmocka_unit_test(test_two_sheets),
      cmocka_unit_test(test_noise_pool),         cmocka_unit_test(test_tie_store_exact),
      cmocka_unit_test(test_curve_sampled),      cmocka_unit_test(test_tie_weights),
      cmocka_unit_test(test_clean_patch),        cmocka_unit_test(test_progress),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
