/* Internal to src/algo (and src/tile/features_tiled.c): the per-point
 * bootstrap fit of chapter 4, shared by the error estimates (error.c) and
 * the smoothing of chapter 6 (smooth.c), so both run the very same fits;
 * the stages of features --method distance. */
#ifndef BSURF_ALGO_H
#define BSURF_ALGO_H

#include "bootstrap/bootstrap.h"
#include "common/common.h"
#include "local/local.h"

/* A parallel loop over the points of a neighbourhood graph, each thread with
 * its own scratch (point_loop.c): bsurf_point_loop_run makes one scratch of
 * scratch_size bytes per thread by alloc(scratch, arg) (zero-filled before;
 * release is called on every one, also after a failed alloc), calls point(ctx, that thread's
 * scratch, i) for every point in k-d tree order (bsurf_visit_order: cache locality, no result
 * depends on it), then, if all went well, tally(ctx, scratch) for every thread (NULL: none), and
 * release(scratch) for every thread. `work`: one point's work in the unit of
 * bsurf_progress_chunk (it sets how many points run between progress calls). */
typedef struct bsurf_point_loop {
  size_t scratch_size;
  bsurf_status (*alloc)(void *scratch, const void *arg);
  void (*release)(void *scratch);
  void (*point)(void *ctx, void *scratch, size_t i);
  void (*tally)(void *ctx, const void *scratch);
} bsurf_point_loop;
bsurf_status bsurf_point_loop_run(const bsurf_point_loop *loop, const void *arg, void *ctx,
                                  const bsurf_neighbors *nb, const double *xyz, double work,
                                  int threads, bsurf_progress_fn progress, void *progress_user);

/* One thread's scratch for bsurf_error_point. */
typedef struct bsurf_error_scratch {
  bsurf_localfit lf;
  double *pred_full;    /* k */
  double *pred_boot;    /* B x k */
  uint16_t *counts;     /* B x k: the replicates' multiplicities */
  double *missing;      /* B x k: 1 where the point is not in the replicate */
  uint16_t *draws;      /* B x k: each replicate's indices in the order drawn */
  double *rows;         /* R x ncols, R = B + 1 rounded up to 4: normal
                           equations (bsurf_gemm_lanes layout), row B the full fit */
  double *coefs;        /* B x terms */
  unsigned char *valid; /* B */
  double *est_scratch;  /* 6k + 1 */
  bsurf_blocks mem;     /* the arrays above */
  size_t skipped, reduced, center_unestimated;
} bsurf_error_scratch;

/* How the multipass passes run (src/algo/smooth_lanes.c); every setting
 * gives the same bits, so tests compare them: lanes = 0 runs the passes
 * point by point (gather_update) instead of in blocks with the pairs in
 * vector lanes; tblock_passes (1 to 16) passes per time block, 1 pass by
 * pass; any_halo = 1 runs time blocks however wide their halos (by default a
 * block's halo rows are at most a tenth of its rows). */
typedef struct bsurf_smooth_tuning {
  int lanes;         /* 1 */
  int tblock_passes; /* 8 */
  int any_halo;      /* 0 */
} bsurf_smooth_tuning;
static inline bsurf_smooth_tuning bsurf_smooth_tuning_defaults(void) {
  bsurf_smooth_tuning t = {1, 8, 0};
  return t;
}
/* bsurf_smooth with the passes run as `tune` says (NULL: the defaults). */
bsurf_status bsurf_smooth_tuned(const double *xyz, const bsurf_neighbors *nb,
                                const bsurf_smooth_options *opts, const bsurf_smooth_tuning *tune,
                                double *out_xyz, bsurf_smooth_fields *fields,
                                bsurf_smooth_report *report);
/* The multipass weights' e^x (-37.5 <= x <= 0), exposed for its test. */
double bsurf_smooth_exp(double x);

bsurf_status bsurf_error_scratch_alloc(bsurf_error_scratch *s, int k, int B, int degree);
void bsurf_error_scratch_free(bsurf_error_scratch *s);

/* What a point's fits leave beyond the estimators. */
typedef struct bsurf_error_fit {
  bsurf_frame frame;            /* PCA frame; origin = the point itself */
  double inv_scale;             /* u = x' * inv_scale, v = y' * inv_scale */
  int degree;                   /* degree of the full fit (may be reduced) */
  double coef[BSURF_TERMS_MAX]; /* full fit, zero-padded to the asked degree */
  double boot_center;           /* (1/B) sum_b f*b(x_0) over valid replicates:
                                   the height of Eq. 6.1 (the full fit's when
                                   no replicate is valid) */
  bsurf_boot_result r;          /* the estimators */
} bsurf_error_fit;

/* Algorithm 1 at point i with neighbourhood idx[0..o->k-1] (idx[0] = i):
 * writes the point's entries of `out` (whose pointers may be NULL) and, when
 * `fit` is not NULL, fills it. test_xyz may be NULL. */
void bsurf_error_point(const double *xyz, const uint32_t *idx, const double *test_xyz,
                       const bsurf_error_options *o, size_t i, bsurf_error_scratch *s,
                       bsurf_error_fields *out, bsurf_error_fit *fit);

/* Validates error options against the neighbourhoods (as bsurf_estimate_error). */
bsurf_status bsurf_error_check(const bsurf_error_options *o, const bsurf_neighbors *nb);

/* ---- nested neighbourhoods (nested.c) ----
 * For a point with its sorted neighbour list idx[0..kmax) (idx[0] = the
 * point d_i), candidate neighbourhoods P_K are the first K neighbours for K
 * in a strictly increasing list ks[0..nk) with ks[nk - 1] <= kmax. One pass
 * over the kmax neighbours with running moment sums gives every candidate's
 * (weighted) moments, for R weight rows (bootstrap replicates) at once.
 * Typical use, per point:
 *   bsurf_nested_terms(xyz, idx, kmax, terms);                 once
 *   bsurf_nested_sums(terms, kmax, R, Wt, ks, nk, sums, nz);   once per weights
 *   for c, r: bsurf_nested_cov(&sums[c * 10 R + r], R, center, mu, cov);
 *             bsurf_eigen_sym3_smallest(cov, n);               the normal */
#define BSURF_NESTED_COLS 10 /* q q^T (xx xy xz yy yz zz), q, 1; q = p - d_i */

/* The per-neighbour terms (kmax x BSURF_NESTED_COLS, row-major), relative
 * to d_i (accurate far from the origin). */
void bsurf_nested_terms(const double *xyz, const uint32_t *idx, int kmax, double *terms);
/* The moment sums of every candidate for R weight rows: Wt (kmax x R,
 * Wt[j R + r] = weight of neighbour j in row r; NULL = a single row of ones,
 * then R must be 1). sums out: nk blocks of BSURF_NESTED_COLS x R, column-major
 * within a block (sums[(c COLS + col) R + r]). distinct out (nk x R, may be
 * NULL): the number of nonzero weights among candidate c's points. Each sum
 * runs over j = 0, 1, ... in order: candidate c's sums are exactly those of
 * a separate sum over its own K points. */
void bsurf_nested_sums(const double *terms, int kmax, int R, const double *Wt, const int *ks,
                       int nk, double *sums, int *distinct);
/* From one (candidate, row) of the sums (sums points at its column 0, stride
 * R between columns): mu the weighted centroid relative to d_i, cov (xx xy xz
 * yy yz zz) the weighted second moments about the centroid, or about d_i
 * (BSURF_PCA_POINT, Eq. 2.1), each divided by the total weight. Returns 0,
 * or -1 when the total weight is 0. */
int bsurf_nested_cov(const double *sums, size_t stride, bsurf_pca_center center, double mu[3],
                     double cov[6]);
/* bsurf_nested_cov for the R rows of one candidate's block (block: its
 * column 0), in vector lanes: cov out 6 x R (cov[t R + r]), ok[r] = 1 when
 * the row's weight is positive (else its cov is not defined). Same values
 * as row by row. */
void bsurf_nested_cov_lanes(const double *block, int R, bsurf_pca_center center, double *cov,
                            int *ok);
/* sum_j theta(g, r_j), j < k: the unoriented angles (atan2(|g x r|, |g . r|),
 * within 2 ulp of the C library's, tests/test_nested.c) between unit g and
 * the unit vectors (rx, ry, rz)[j], summed in a fixed order (four running
 * sums by j mod 4 from +0, combined as (s0 + s1) + (s2 + s3)). The inner
 * sum of Eq. 5.10. */
double bsurf_nested_angle_sum(const double g[3], const double *rx, const double *ry,
                              const double *rz, int k);
/* bsurf_nested_angle_sum for P pairs at once, in vector lanes: pair p's
 * unit vector g[3 p ..] and count kl[p] (non-decreasing in p, as a nested
 * selection's candidates with their replicates), sums[p] with the bits of
 * bsurf_nested_angle_sum(&g[3 p], rx, ry, rz, kl[p]) whatever the other
 * pairs; pairs with valid[p] == 0 (valid may be NULL: all) are not read and
 * their sums are meaningless. */
void bsurf_nested_angle_sums(size_t P, const double *g, const unsigned char *valid, const int *kl,
                             const double *rx, const double *ry, const double *rz, double *sums);

/* The candidate list of a nested selection: ks[0..nk) strictly increasing,
 * ks[0] >= kmin, ks[nk - 1] <= nb->k, 65535 and the point count; messages
 * name `who` (the public function). */
bsurf_status bsurf_nested_check_ks(const char *who, const int *ks, int nk, int kmin,
                                   const bsurf_neighbors *nb);
/* The angle between unit a and b, accurate near 0 (atan2 of |a x b| and
 * a . b); unoriented: the smaller of the angles with b and -b. */
double bsurf_angle_between(const double a[3], const double b[3], int unoriented);
/* One candidate's B replicate normals bn (B x 3, unit; valid[b] = 0 skips
 * one) oriented to its whole-neighbourhood normal nP (5.2.1, in place), the
 * estimate nrm = sum / |sum| (Eq. 5.4; nP when no replicate is valid) and
 * the variance *var of the angles between the first valid replicate and
 * each (Eq. 5.5, 0 below two; the angles by Cephes' atan in vector lanes,
 * within 2 ulp of libm's atan2). ang: B doubles of scratch. Returns the
 * number of valid replicates. */
int bsurf_nested_summary(int B, const double nP[3], double *bn, const unsigned char *valid,
                         double nrm[3], double *var, double *ang);
/* Eq. 5.10's inner double sum for one polynomial candidate: sum over the
 * replicates b < nrep with valid[b] (valid NULL: all) of sum_{j<k}
 * theta(g_b(p_j), r_j), where g_b(p_j) = (-f_u / s, -f_v / s, 1) is the
 * normal (Eq. 5.9, unnormalised) at neighbour j of replicate b's height
 * polynomial f = sum_t coefs[b m + t] phi_t (degree `degree`, m its terms;
 * 0: g = (0, 0, 1)), inv_scale = 1 / s, and r_j the reference normals in
 * the same frame. phif: the graded basis at the neighbours in float,
 * term-major, row stride kq (a multiple of 16, >= k), at least
 * terms(degree - 1) rows (the gradient is a polynomial of one degree less),
 * zero past k; rf: rx, ry, rz, each kq floats, (0, 0, 1) past k. The angles
 * are evaluated in single precision (unoriented, atan2 reduced to Cephes'
 * atanf; within 1e-6 rad of libm's atan2 of the double field,
 * tests/test_nested.c), in vector lanes over j < k rounded up to a multiple
 * of 8 (the padding evaluated, not summed), summed over at most 64
 * replicates in float, then in double in a fixed order. accf, accd: kq
 * floats and doubles of scratch. */
double bsurf_nested_field_angle_total(int degree, int nrep, const double *coefs,
                                      const unsigned char *valid, double inv_scale,
                                      const float *phif, size_t kq, const float *rf, int k,
                                      float *accf, double *accd);

/* bsurf_estimate_normals with each point's own K: point i's fields are
 * those of bsurf_estimate_normals with opts->k = k_at[i] (the same bits;
 * opts->k is the largest, 3 <= k_at[i] <= opts->k), in one pass instead of
 * one pass per K (the MSE rule's chosen K with B replicates). No reference
 * normals: out->normal_err must be NULL. */
bsurf_status bsurf_estimate_normals_at(const double *xyz, const bsurf_neighbors *nb,
                                       const bsurf_normal_options *opts, const int *k_at,
                                       bsurf_normal_fields *out, bsurf_normal_report *report);
/* The same with the POLY fit at each point's own degree too (d_at: NULL,
 * or 1 <= d_at[i] <= opts->degree, k_at[i] >= its terms): point i's
 * estimate is bsurf_estimate_normals's with opts->k = k_at[i] and
 * opts->degree = d_at[i] (the chosen (K, degree) of the MSE rule). */
bsurf_status bsurf_estimate_normals_at_kd(const double *xyz, const bsurf_neighbors *nb,
                                          const bsurf_normal_options *opts, const int *k_at,
                                          const int *d_at, bsurf_normal_fields *out,
                                          bsurf_normal_report *report);

/* bsurf_estimate_normals without the neighbour lists: the cloud's
 * neighbourhoods searched (bsurf_neighbors_stream, nb_k neighbours, of which
 * opts->k are used) and each point's normal estimated from its row while it
 * is in cache, so the point_count x nb_k array is never built. The same
 * fields as bsurf_estimate_normals on bsurf_neighbors_build's lists (the
 * same rows, the same per-point code: the same bits), without reference
 * normals (out->normal_err must be NULL) and with opts->point_index NULL;
 * h and duplicates as bsurf_neighbors_build's h and the jobs' count. */
bsurf_status bsurf_estimate_normals_streamed(const double *xyz, size_t point_count, int nb_k,
                                             const bsurf_normal_options *opts,
                                             bsurf_normal_fields *out, bsurf_normal_report *report,
                                             double *h, size_t *duplicates);

/* The MSE rule's passes (bsurf_select_k, kselect_run.c) on the rows of any
 * neighbourhood table, for the tiled job (src/jobs/normals_mse_tiled.c,
 * docs/scaling.md): a row's point is nb->idx[r k] (r on the whole cloud, a
 * local index in a tile); the values a pass reads at the neighbours are
 * indexed like nb->idx, its own values by row. A run holds the options, the
 * threads' scratch and (two_sheet) the two-sheet test's critical ratios, for
 * any number of tables, one at a time. bsurf_ksel_noise: pass 1, each row's
 * residual variance and cross-section estimate (NAN: none), s2[2 r] and
 * s2[2 r + 1] (kselect_noise.c); bsurf_ksel_pool: pass 2, each row's two
 * pooled noise variances from the neighbours' s2 (the quadric's, and the
 * cross-section's where the neighbourhood is section-sampled, else NAN:
 * noise[2 r], noise[2 r + 1]); bsurf_ksel_level: the pooled values of every
 * point of the cloud (2 n, in index order) made the noise the passes below
 * read, noise[0 .. n) (GLOBAL: their median, of the cloud's majority
 * population; LOCAL: bsurf_ksel_point_level); bsurf_ksel_first: pass 3's first
 * choices' normals (row x 3) and criteria M (row); bsurf_ksel_choose: passes
 * 3 and 4 into out (fref, fmref: the neighbours' first choices and their M,
 * indexed like nb->idx, given for the points that are not rows of nb; pass
 * 3 writes the rows' own into them before pass 4 reads them; NULL: this
 * table's own, when its rows are every point). bref, bmref: the
 * neighbours' first choices of a pass 3 without them, the references of the
 * empirical bias where the quadric does not fit (kselect_lof.c; NULL: none),
 * when bsurf_ksel_empirical: bsurf_select_k makes the choices of
 * bsurf_ksel_first followed by bsurf_ksel_choose with the first's as bref
 * (in memory it runs pass 3 again only where the lack-of-fit gate fires:
 * kselect_run.c, ksel_select with defer). The same bits as bsurf_select_k for the
 * same rows. */
typedef struct bsurf_ksel_run bsurf_ksel_run;
bsurf_status bsurf_ksel_open(const bsurf_kselect_options *opts, int nb_k, int two_sheet,
                             bsurf_ksel_run **run);
void bsurf_ksel_close(bsurf_ksel_run *run);
bsurf_status bsurf_ksel_noise(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                              double *s2);
bsurf_status bsurf_ksel_pool(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                             const double *s2, double *noise);
bsurf_status bsurf_ksel_level(const bsurf_ksel_run *r, double *noise, size_t n);
/* The cloud's noise variance as the MSE rule reads it (passes 1, 2 and 2b
 * on every row of nb, a whole cloud's table with nb->k >= the candidates'
 * largest K; opts->noise_pool GLOBAL): *level (NAN on failure), and
 * *sections, the points whose neighbourhoods pass 2 found section-sampled
 * (bsurf_ksel_sections). The smoothing guard's second reading of the noise
 * (smooth.c). */
bsurf_status bsurf_ksel_cloud_noise(const double *xyz, const bsurf_neighbors *nb,
                                    const bsurf_kselect_options *opts, double *level,
                                    size_t *sections);
/* An upper bound on bsurf_ksel_sections at a fraction of the passes' cost
 * (kselect_noise.c, section_point): bsurf_ksel_section_tests, each row's
 * cross-section test alone (s2 as bsurf_ksel_noise's, 2 per row, only the
 * second value set); bsurf_ksel_section_flags, the rows whose K_max
 * neighbours (s2 read by neighbour) passed it as often as pass 2 asks of a
 * section-sampled neighbourhood, counted in *flagged; bsurf_ksel_section_bound
 * both on a whole cloud's table. Every point bsurf_ksel_sections counts is
 * among them. */
bsurf_status bsurf_ksel_section_tests(bsurf_ksel_run *r, const double *xyz,
                                      const bsurf_neighbors *nb, double *s2);
bsurf_status bsurf_ksel_section_flags(bsurf_ksel_run *r, const double *xyz,
                                      const bsurf_neighbors *nb, const double *s2, size_t *flagged);
bsurf_status bsurf_ksel_section_bound(const double *xyz, const bsurf_neighbors *nb,
                                      const bsurf_kselect_options *opts, size_t *bound);
/* Of n points' pooled values (bsurf_ksel_pool's, 2 n), those with a
 * cross-section level: their K_max neighbours are section-sampled beyond
 * chance (kselect_noise.c, pool_point). */
size_t bsurf_ksel_sections(const double *pooled, size_t n);
/* A point's LOCAL level from its two pooled values (kselect_noise.c): the
 * cross-section's where there is one, else the quadric's. */
double bsurf_ksel_point_level(const double pooled[2]);
bsurf_status bsurf_ksel_first(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                              const double *noise, const double *bref, const double *bmref,
                              double *fnrm, double *fmse);
bsurf_status bsurf_ksel_choose(bsurf_ksel_run *r, const double *xyz, const bsurf_neighbors *nb,
                               const double *noise, const double *bref, const double *bmref,
                               double *fref, double *fmref, bsurf_kselect_fields *out,
                               bsurf_kselect_report *report);
int bsurf_ksel_empirical(const bsurf_ksel_run *r);

/* Per-point K and degree selection of polynomial normals (5.5, Algorithm 3;
 * select_degree.c): every candidate (ks[a], ds[d]) as bsurf_select_normals_k
 * does for PCA (Poisson(1) counts over the kmax = ks[nk - 1] neighbours,
 * drawn once per point and shared by every K and degree), each K's fits in
 * the PCA frame of its own K points (Eq. 3.4) with one product of the
 * weights and the monomials at the largest degree serving every degree.
 * opts->fit must be BSURF_NORMAL_POLY (opts->k and opts->degree ignored);
 * ds: nd degrees in [1, BSURF_DEGREE_MAX], each needing ks[0] >= its
 * terms. Candidate c = a nd + d; out->cand_*: point_count x nk nd;
 * degree_selected (may be NULL): the chosen degree. Ties: the smaller K,
 * then the earlier degree. */
bsurf_status bsurf_select_normals_kd(const double *xyz, const bsurf_neighbors *nb,
                                     const double *ref_normals, const bsurf_normal_options *opts,
                                     const int *ks, int nk, const int *ds, int nd,
                                     bsurf_normal_select_fields *out, int *degree_selected,
                                     bsurf_normal_report *report);

/* ---- the neighbourhood's ball against the noise (ball_scale.c) ----
 * t = R / sigma, R the ball's radius, sigma the noise along the normal.
 * kappa: the share of the noise variance the ball's points keep about its
 * fit; count: its points per sigma^2 of area at unit areal density. */
double bsurf_ball_share(double t);
double bsurf_ball_count(double t);
/* The noise variance whose ball of radius R keeps the variance v, sigma^2
 * with kappa(R / sigma) sigma^2 = v: the smallest such, reached from below
 * (sigma^2 = v / kappa(R / sigma) from sigma^2 = v; each step at least the
 * one before, bounded as kappa is at least its value at t = 1), stopping when
 * it changes by less than 1e-12 of itself (at most 200 steps). v where v or
 * R is not > 0. */
double bsurf_ball_noise(double v, double R);
/* The scale rule: the smallest K >= k0 (steps of 2^(1/4), at most k_cap)
 * whose ball drops no more of the noise than its fit's mean prediction
 * variance holds, 1 - kappa(t_K) <= p / K, from t0 = R_k0 / sigma measured at
 * k0; *t_k (may be NULL) its t. k0 when t0 is not > 0. */
int bsurf_scale_k(double t0, int k0, int p, int k_cap, double *t_k);
/* The median over the rows of nb of the distance to the k-th point of the
 * row (the point itself first): the K-ball's radius. */
bsurf_status bsurf_ball_radius(const double *xyz, const bsurf_neighbors *nb, int k, double *R);

/* ---- features --method distance (7.1) in stages (features.c), run on the
 * whole cloud by bsurf_detect_features and tile by tile by
 * bsurf_features_distance_tiled (src/tile/features_tiled.c): the same functions on
 * the same values, hence the same bits. Rows of nb: row r's point is
 * nb->idx[r k] (r itself on the whole cloud, a local index in a tile). ---- */

/* Options against neighbourhoods of k points in a cloud of n. */
bsurf_status bsurf_fdist_check(const bsurf_feature_options *o, int k, size_t n);
/* The neighbourhood sizes k_min, k_min + k_step, ... <= k_max. */
int bsurf_fdist_sizes(const bsurf_feature_options *o);
/* The sample of the noise_factor medians: every stride-th point (global
 * index), m of them, at most ~4M values in all. */
void bsurf_fdist_sample(const bsurf_feature_options *o, size_t n, size_t *stride, size_t *m);
/* f(K) = lambda0 / lambda2 at every size of the sampled rows:
 * vals[j m + g / stride] for the point of global index g. point_index NULL:
 * the whole cloud (the m samples); else the tile's rows, each with its
 * global index, of which the multiples of stride are written. */
bsurf_status bsurf_fdist_sample_ratios(const double *xyz, const bsurf_neighbors *nb,
                                       const bsurf_feature_options *o, const uint64_t *point_index,
                                       size_t stride, size_t m, double *vals);
/* T_{a/c} per size: max(ratio_threshold, noise_factor x the median of the
 * sample's f(K)); vals (sizes x m) is sorted in place. */
void bsurf_fdist_thresholds(const bsurf_feature_options *o, size_t m, double *vals, double *T);
/* The raw map of every row (the radius where the growth stops) and its
 * state (0 reached k_max, 1 exceeded T_{a/c} later, 2 at k_min); ksel may
 * be NULL. */
bsurf_status bsurf_fdist_raw(const double *xyz, const bsurf_neighbors *nb,
                             const bsurf_feature_options *o, const double *T, double *dist,
                             int *ksel, uint8_t *state);
/* *R = max(*R, dist[0..n)), in index order. */
void bsurf_fdist_max_radius(const double *dist, size_t n, double *R);
/* The map after the points that stopped at once get -max(radius). */
static inline double bsurf_fdist_fixed(double dist, int state, double R) {
  return state == 2 ? -R : dist;
}
/* The filter's neighbours (filter_k, 0 = k_min) and passes (0 when off). */
int bsurf_fdist_filter_k(const bsurf_feature_options *o);
int bsurf_fdist_filter_passes(const bsurf_feature_options *o, double R);
/* One Jacobi pass of Eq. 7.1 over the rows of nb: out[r] from the values
 * `in` of the points of xyz (sigma_a = h, or R when h is 0; sigma_b =
 * sigma_range x R). */
bsurf_status bsurf_fdist_filter(const double *xyz, const bsurf_neighbors *nb,
                                const bsurf_feature_options *o, double h, double R,
                                const double *in, double *out);
/* Otsu's split of the m positive values of the map (sorted in place); 0
 * when m < 2. */
double bsurf_fdist_otsu_positive(double *pos, size_t m);
/* The automatic T_h of the map of n points: Otsu's split of its positive
 * values (features_distance.c). */
bsurf_status bsurf_fdist_auto_threshold(const double *map, size_t n, double *t);
/* The map of the whole cloud (bsurf_detect_features): the raw map, T_{a/c}
 * from the cloud's medians, the points that stopped at once set to
 * -max(radius); state (may be NULL) as bsurf_fdist_raw's, *t_kmin T_{a/c}
 * at k_min. */
bsurf_status bsurf_fdist_distance_raw(const double *xyz, const bsurf_neighbors *nb,
                                      const bsurf_feature_options *opts, double *dist, int *ksel,
                                      double *max_radius, size_t *immediate, double *t_kmin,
                                      uint8_t *state);
/* Otsu's two-class split of count >= 1 sorted values (features.c): the
 * upper edge of the lower class's last bin of a 256-bin histogram. */
double bsurf_otsu_sorted(const double *l, size_t count);
/* feature of a point of map value v and state, with the absolute T_h thr;
 * threshold: the option (NAN = auto). */
int bsurf_fdist_feature(double v, int state, double thr, double threshold);

/* lambda0 (>= 0) and the trace of the covariance (about the centroid) of
 * the first k points xyz[idx[0..k-1]]; design (may be NULL): 4 / (1 /
 * lambda1 + 1 / lambda2), the tangential spread that sets a fitted plane's
 * tilt variance (the trace less lambda0 when lambda1 = lambda2). With resid (2 k doubles of
 * scratch, may be NULL: returns 0) it returns 1 when they hold two parallel sheets: the heights
 * about the common normal of a pair of parallel planes fitted to them fall in two groups apart
 * (bsurf_split_bimodal); then *mu0 is the pair's residual variance (the smallest eigenvalue of the
 * covariance pooled within the two groups). */
int bsurf_pca_l0_trace(const double *xyz, const uint32_t *idx, int k, double *l0, double *tr,
                       double *design, double *resid, double *mu0, double *border);

/* ---- features --method variance, rule NULL (features_variance.c): the
 * stages of bsurf_detect_features, also run tile by tile. Rows of nb as
 * above; nu and the outputs by row, u of bsurf_fvar_filter by point. ---- */
typedef struct bsurf_fvar_result {
  double threshold;         /* t = max(null_threshold, split) on the filtered z */
  double null_threshold;    /* t_alpha: the null patch's (1 - alpha) quantile */
  double split;             /* Otsu's split of log z (NAN without noise) */
  double noise_level;       /* s = sqrt(median lambda0) */
  double sigma0;            /* the null patch's noise (unit density); 0 if none */
  double border_threshold;  /* t_b: the null patch's (1 - alpha) quantile of zb */
  int quadric_k;            /* the quadric check's K_q; 0: no check */
  double quadric_threshold; /* t_q on q (NAN: no check) */
  double quadric_power;     /* the simulated crease's share kept (NAN) */
  double quadric_noise;     /* sqrt of the cloud's noise variance it reads (NAN) */
  size_t quadric_cleared;   /* points with z > t and q <= t_q */
  size_t border_points;     /* points the border test alone flags */
} bsurf_fvar_result;
/* The expected lambda0 of a smooth patch at a neighbourhood of tangential
 * spread g = (lambda1 + lambda2)^2: E(g) = sigma2 + c g (noise plus the plane
 * fit's bias on a curved patch), fitted to the medians of lambda0 in
 * FVAR_FIT_BINS equal-count bins of g (features_variance.c). Use: prepare
 * on a copy of g (sorted in place), put every (g, lambda0) into an array of
 * n, solve on that array. */
enum { FVAR_FIT_BINS = 16 };
typedef struct bsurf_fvar_fit {
  int bins;
  double edge[FVAR_FIT_BINS]; /* upper g edge of bins 0 .. bins - 2 */
  double g[FVAR_FIT_BINS];    /* the median g of each bin */
  size_t first[FVAR_FIT_BINS + 1], fill[FVAR_FIT_BINS];
  double sigma2, c; /* E(g) = sigma2 + c clamp(g, g[0], g[bins - 1]) */
} bsurf_fvar_fit;
void bsurf_fvar_fit_prepare(bsurf_fvar_fit *f, double *g, size_t n);
void bsurf_fvar_fit_put(bsurf_fvar_fit *f, double *dst, double g, double l0);
/* s2: the median lambda0 (sigma2 when lambda0 does not grow with g) */
void bsurf_fvar_fit_solve(bsurf_fvar_fit *f, double *dst, double s2);
/* u and w (may be NULL; w >= 0 only) of n points scaled by s2 / E(g): the
 * filter's Z = u / s2 becomes nu d / E(g) */
void bsurf_fvar_fit_scale(const bsurf_fvar_fit *f, double s2, size_t n, const double *g, double *u,
                          double *w);
/* The residual variance RSS / (K - 6) of the least-squares quadric of the
 * K points idx (xyz rows) in their PCA frame, as the K selection's noise fit
 * reads it (kselect_noise.c); work: 3 K doubles. -1 when rank-deficient. */
int bsurf_ksel_quad_variance(const double *xyz, const uint32_t *idx, int K, double *work,
                             double *var);
/* A point is a feature: z > threshold (unless the quadric check ran,
 * quadric_k > 0, and q <= quadric_threshold) or zb > border_threshold. */
int bsurf_fvar_feature(const bsurf_fvar_result *res, double z, double zb, double q);
/* A report before any method has run: zeros, and NAN in the fields that
 * stay NAN where their method or rule does not apply (ratio_threshold_kmin,
 * noise_level, edge_power, border_threshold, quadric_threshold,
 * quadric_power, quadric_noise: bootsurf.h) -- in memory, tiled and in the
 * jobs alike, also when a call fails. */
void bsurf_feature_report_clear(bsurf_feature_report *rep);
/* The null rule's numbers into a report: threshold, noise_level,
 * border_threshold and the quadric check's fields (in memory and tiled). */
void bsurf_fvar_report(const bsurf_fvar_result *res, bsurf_feature_report *rep);
/* Adds point (z, zb, q)'s flag (bsurf_fvar_feature) to *features (may be NULL) and its
 * share in res's counts (quadric_cleared, border_points): one copy for the
 * in-memory run and the tiled one. Returns the flag. */
int bsurf_fvar_count(bsurf_fvar_result *res, double z, double zb, double q, size_t *features);
/* The quadric check's statistic before its filter: per row, the residual
 * variance of the quadric of its first kq neighbours (rank-deficient:
 * HUGE_VAL, no quadric explains it), into v by row; progress may be NULL. */
bsurf_status bsurf_fvar_quadric_rss(const double *xyz, const bsurf_neighbors *nb, int kq,
                                    int threads, double *v, bsurf_progress_fn progress,
                                    void *progress_user);
/* The quadric check's neighbourhood and threshold (quadric_angle > 0,
 * sigma > 0, the patch's noise: bsurf_fvar_quadric_sigma): for K_q =
 * normals.k, 2 normals.k, 4 normals.k (<= k_cap) a patch folded by quadric_angle at
 * sigma: its filtered residual variance over sigma^2, t_q the (1 -
 * false_positive_rate) quantile over its flat parts, the power the share
 * of its points within a spacing of the fold above t_q; the first K_q with
 * power >= 0.9. *kq = 0 (and *tq NAN) when none reaches it or the check is
 * off; *power the last tried's (NAN when none). */
bsurf_status bsurf_fvar_quadric_k(const bsurf_feature_options *o, double sigma, int k_cap, int *kq,
                                  double *tq, double *power);
/* The quadric check's patch noise: the null patch's sigma_0 (res, from
 * bsurf_fvar_null) times the noise the check reads over the median
 * lambda0's, sqrt(level / s2). */
double bsurf_fvar_quadric_sigma(const bsurf_fvar_result *res, double level, double s2);
/* The smallest neighbourhood table the quadric check needs beside normals.k
 * (the K selection's noise passes: 80; K_q at most 4 normals.k and k_cap);
 * normals.k when the check is off or the rule is not NULL. */
int bsurf_fvar_neighbors_k(const bsurf_feature_options *o, int k_cap);
/* The filter's neighbours k_f (variance_filter_k, 0 = normals.k / 2). */
int bsurf_fvar_filter_k(const bsurf_feature_options *o);
/* Per row of the k-neighbourhoods: u = nu d (the design of
 * bsurf_pca_l0_trace), lambda0 and lambda0 / tr;
 * w (may be NULL): where the neighbourhood holds two parallel sheets
 * (bsurf_pca_l0_trace's test) their pair's residual variance mu0, else -1;
 * b (may be NULL): the border statistic; g (may be NULL): (lambda1 + lambda2)^2. */
bsurf_status bsurf_fvar_local(const double *xyz, const bsurf_neighbors *nb, int k, int threads,
                              const double *nu, double *u, double *l0, double *ratio, double *w,
                              double *b, double *g);
/* z[r] = median of Z over the first kf neighbours of row r, Z_j = u_j / s2
 * (s2 <= 0: u_j), or 0 where w_j (w may be NULL; k-neighbourhoods) says two
 * parallel sheets whose residual variance is within the noise s2's 99%
 * quantile: flat, however far apart the sheets (their gap raises nu). */
bsurf_status bsurf_fvar_filter(const bsurf_neighbors *nb, int kf, int threads, double s2, int k,
                               const double *u, const double *w, double *z);
/* t: the (1 - false_positive_rate) quantile of z on the flat null patch
 * whose median lambda0 / tr is eta; sigma0 out may be NULL. */
bsurf_status bsurf_fvar_null_threshold(const bsurf_feature_options *o, double eta, double *t,
                                       double *tb, double *sigma0);
/* The neighbourhood size of the variance test (feature_angle > 0): the
 * first of normals.k, 2 normals.k, 4 normals.k ... <= k_cap at which a
 * simulated edge of feature_angle at the cloud's noise (eta = median
 * lambda0 / tr at normals.k) is detected at >= half its points; else the
 * most powerful. normals.k when feature_angle is 0. power out may be NULL
 * (NAN when not simulated). */
bsurf_status bsurf_fvar_choose_k(const bsurf_feature_options *o, double eta, int k_cap, int *k,
                                 double *power);
/* The largest K of the choice: variance_k_max (0 = 8 normals.k), at most
 * 65535 and n, at least normals.k. */
int bsurf_fvar_k_cap(const bsurf_feature_options *o, size_t n);
/* eta = the median over the rows of lambda0 / tr of the first k neighbours. */
bsurf_status bsurf_fvar_eta(const double *xyz, const bsurf_neighbors *nb, int k, int threads,
                            double *eta);
/* The null rule's null from s2 = median lambda0 and eta = median lambda0 /
 * tr of the cloud: res's noise_level, t_alpha, t_b and sigma_0 (NAN and 0
 * without noise), its counts and quadric fields reset. */
bsurf_status bsurf_fvar_null(const bsurf_feature_options *o, double s2, double eta,
                             bsurf_fvar_result *res);
/* Then the threshold t over the filtered scores z: max(t_alpha, Otsu's
 * split of log z); without noise 1e-12 max z. */
bsurf_status bsurf_fvar_split(const double *z, size_t n, bsurf_fvar_result *res);
/* In memory: score in nu, out z; feature out z > t. */
bsurf_status bsurf_fvar_detect(const double *xyz, const bsurf_neighbors *nb,
                               const bsurf_feature_options *o, double *score, uint8_t *feature,
                               bsurf_fvar_result *res);

#include "algo/smooth_stages.h"

#endif
