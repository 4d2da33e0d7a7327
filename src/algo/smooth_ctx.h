/* The shared state of the smoothing methods (src/algo/smooth*.c): the fit
 * records, the weights, the context every stage reads, and the functions the
 * files share (internal: bsurf_i_-prefixed link names). */
#ifndef BSURF_SMOOTH_CTX_H
#define BSURF_SMOOTH_CTX_H

#include "algo/algo.h"
#include "algo/smooth_stages.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#define GAUSS_CUT 37.42995136401172 /* 54 ln 2: exp(-GAUSS_CUT) = 2^-54 */

/* The exponent a^2 / b^2 of G(a, b) = exp(-a^2 / b^2) (Eq. 5.7); G(0, 0) = 1. */
static inline double gauss_exponent(double a, double b) {
  if (a == 0) return 0.0;
  if (!(b > 0)) return INFINITY;
  return (a / b) * (a / b);
}

/* A weight exp(-e), cut to 0 below 2^-54. */
static inline double weight_of(double e) {
  return e > GAUSS_CUT ? 0.0 : (e == 0 ? 1.0 : exp(-e));
}

/* e^x for the multipass weights (-GAUSS_CUT <= x <= 0), written once for
 * scalars and once for vector lanes with the same operations in the same
 * order, so both give the same bits: x = n ln2 + r (Cody-Waite: ln2 split in
 * a high part with 11 trailing zero bits, so n ln2_hi is exact, and a low
 * part; |r| <= ln2 / 2), e^r by its Taylor polynomial to degree 13 (the
 * remainder, below |r|^14 / 14! < 2^-57, is under the last bit), times 2^n
 * set in the exponent bits. n is rounded to nearest by adding and
 * subtracting 1.5 x 2^52, whose low bits then hold n. Within a few units in
 * the last place of glibc's exp: at most 4.3e-16 relative over 2e7 points
 * of [-GAUSS_CUT, 0] (Horner's order gave 2.2e-16, but its chain of
 * thirteen dependent steps cost the pair kernel about a tenth of its time;
 * tests/test_smooth.c checks 1e-15 relative). */
#define MPX_LOG2E 1.4426950408889634
#define MPX_LN2_HI 6.93147180369123816490e-01 /* 0x3fe62e42fee00000 */
#define MPX_LN2_LO 1.90821492927058770002e-10 /* 0x3dea39ef35793c76 */
#define MPX_MAGIC 6755399441055744.0          /* 1.5 x 2^52 */
/* p = e^r to degree 13 by Estrin's scheme: pairs c_2i + c_2i+1 r combined
 * with r^2, r^4 and r^8, so the longest chain is four multiply-adds deep
 * (about 24 cycles) where Horner's thirteen took about 78, the latency that
 * bounded the multipass pair kernel. p and r of type T: double or vector
 * lanes. */
#define MPX_POLY(T, p, r)                                                                          \
  do {                                                                                             \
    const T r2_ = (r) * (r);                                                                       \
    const T r4_ = r2_ * r2_;                                                                       \
    const T r8_ = r4_ * r4_;                                                                       \
    const T q0_ = 1.0 + (r);                                                                       \
    const T q1_ = 0.5 + (r) * (1.0 / 6.0);                                                         \
    const T q2_ = (1.0 / 24.0) + (r) * (1.0 / 120.0);                                              \
    const T q3_ = (1.0 / 720.0) + (r) * (1.0 / 5040.0);                                            \
    const T q4_ = (1.0 / 40320.0) + (r) * (1.0 / 362880.0);                                        \
    const T q5_ = (1.0 / 3628800.0) + (r) * (1.0 / 39916800.0);                                    \
    const T q6_ = (1.0 / 479001600.0) + (r) * (1.0 / 6227020800.0);                                \
    const T s0_ = q0_ + q1_ * r2_, s1_ = q2_ + q3_ * r2_;                                          \
    const T s2_ = q4_ + q5_ * r2_;                                                                 \
    const T t0_ = s0_ + s1_ * r4_, t1_ = s2_ + q6_ * r4_;                                          \
    (p) = t0_ + t1_ * r8_;                                                                         \
  } while (0)

static inline double mp_exp1(double x) {
  const double t = x * MPX_LOG2E + MPX_MAGIC;
  const double n = t - MPX_MAGIC;
  const double r = (x - n * MPX_LN2_HI) - n * MPX_LN2_LO;
  double p;
  MPX_POLY(double, p, r);
  int64_t tb, mb;
  memcpy(&tb, &t, sizeof tb);
  const double magic = MPX_MAGIC;
  memcpy(&mb, &magic, sizeof mb);
  const int64_t bits = (tb - mb + 1023) * ((int64_t)1 << 52);
  double scale;
  memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

/* ---- a fit kept for later passes: frame, scale, coefficients ----------- */
/* Layout of one stored fit: origin[3], rot[9] (row-major), inv_scale, the
 * largest |residual| of a point the fit moves (the guard's prediction bound;
 * INFINITY without the guard), coef[m]. */
#define FIT_HEAD 14
#define MP_EXTRA 3 /* multipass: e2, inv_h1sq, w2 after the coefficients */

static inline void fit_store(double *F, const bsurf_frame *fr, double inv_scale, const double *coef,
                             int m) {
  for (int t = 0; t < 3; t++)
    F[t] = fr->origin[t];
  for (int r = 0; r < 3; r++)
    for (int t = 0; t < 3; t++)
      F[3 + 3 * r + t] = fr->rot[r][t];
  F[12] = inv_scale;
  F[13] = INFINITY;
  for (int a = 0; a < m; a++)
    F[FIT_HEAD + a] = coef[a];
}

/* delta = f(x', y') - z' for p in the stored frame: p's projection onto the
 * fitted surface along the frame normal is p + delta n. A fit holds only over
 * the disc its points span (scaled radius 1): outside it, where a polynomial
 * extrapolates, NAN (no move); and only for points within its prediction
 * bound F[13] (the guard: a point farther from the fit is on another sheet),
 * NAN beyond. */
static inline __attribute__((always_inline)) double
fit_delta_any(const double *F, int degree, int m, const double p[3], int held) {
  double q[3] = {p[0] - F[0], p[1] - F[1], p[2] - F[2]};
  double x = F[3] * q[0] + F[4] * q[1] + F[5] * q[2];
  double y = F[6] * q[0] + F[7] * q[1] + F[8] * q[2];
  double z = F[9] * q[0] + F[10] * q[1] + F[11] * q[2];
  double u = x * F[12], v = y * F[12];
  if (held && u * u + v * v > 1.0) return NAN;
  const double *a = &F[FIT_HEAD];
  double f;
  if (m <= 10) {
    /* the graded basis up to degree 3 (zero-padded coefficients), summed in
     * basis order as bsurf_poly_basis would */
    double uu = u * u, uv = u * v, vv = v * v;
    f = a[0];
    if (m > 1) f += a[1] * u + a[2] * v;
    if (m > 3) f += a[3] * uu + a[4] * uv + a[5] * vv;
    if (m > 6) f += a[6] * (uu * u) + a[7] * (uu * v) + a[8] * (u * vv) + a[9] * (vv * v);
  } else {
    /* the fit's own degree: a multipass fit of lower degree has only its
     * terms' values in phi (the coefficients beyond are zero) */
    double phi[BSURF_TERMS_MAX];
    bsurf_poly_basis(degree, u, v, phi);
    f = 0;
    for (int t = 0; t < bsurf_poly_terms(degree); t++)
      f += phi[t] * a[t];
  }
  const double delta = f - z;
  return !held || fabs(delta) <= F[13] ? delta : NAN;
}

static inline __attribute__((always_inline)) double fit_delta(const double *F, int degree, int m,
                                                              const double p[3]) {
  return fit_delta_any(F, degree, m, p, 1);
}

/* ---- progress over several stages ------------------------------------- */
typedef struct staged_progress {
  bsurf_progress_fn fn;
  void *user;
  int stage, stages;
} staged_progress;
/* ---- the shared state -------------------------------------------------- */
typedef struct smooth_ctx {
  const double *xyz;
  const bsurf_neighbors *nb;
  bsurf_smooth_options o;
  size_t n;
  int k, degree, m, stride;
  bsurf_error_scratch *scr; /* per thread */
  double *err_632, *err_632plus, *W;
  double *fits;    /* n x stride (bilateral parallel, multipass) */
  int *fit_degree; /* n */
  double *out;     /* n x 3 */
  /* multipass */
  int *khat;        /* n */
  double *dl;       /* n */
  double *e2;       /* n: theta_2(W_i) = exp(-e2[i]) */
  double *w2;       /* n: theta_2(W_i) itself (the weight at distance 0) */
  double *inv_h1sq; /* n: 1 / h1_i^2 (0 when h1_i = 0) */
  double h1, h2, k_error;
  double noise;      /* the guard's noise variance of the cloud (bsurf_smooth_noise_level of the
                        two below; NAN: not tested) */
  double noise_fits; /* its reading from the sheet fits (guard_noise) */
  double noise_select[2]; /* its reading by the K selection's noise passes (NAN: none)
                             and the share of section-sampled points they found */
  double inv_h1sq_global; /* bilateral: 1 / h1^2 */
  /* reverse neighbourhoods: the i whose neighbourhood contains p */
  const size_t *rev_off; /* n + 1 */
  const uint32_t *rev;   /* rev_off[n] */
  const uint32_t *self;  /* tiled stage 2: point p's row in cur (NULL: p) */
  const double *cur;     /* positions a pass reads */
  double *next;          /* positions a pass writes */
  /* multipass: the pairs that can have a weight, rebuilt as points move */
  uint32_t *act;   /* rev_off[n]: per p, a prefix of its slot range */
  uint32_t *act_n; /* n */
  double *reach2;  /* n: (cut distance of theta_1 + 2 margin)^2 */
  double *tmax;    /* threads x 8: largest move of a pass, per thread */
  /* multipass passes in blocks (gather_multipass_block): per thread, room
   * for the pairs of any block (mp_cap = the largest block's slot count) */
  size_t mp_cap;
  uint32_t *mp_point; /* threads x mp_cap: the pairs' p */
  size_t *act_off;    /* n + 1: the active lists compacted, point p's at act[act_off[p]] */
  double *mp_val;     /* threads x 4 mp_cap: w, target (3) */
  /* multipass time blocks (mp_tblock_task): a region's rows and pairs,
   * rebuilt with the active lists, for blocks of up to tb_S passes */
  struct mp_region *reg; /* nreg */
  size_t nreg;
  int tb_S, tb_s;   /* passes the regions are built for; passes of the running block */
  int tb_max;       /* passes per block that the current lists' halos allow (1: none) */
  uint32_t *lmap;   /* threads x n: rank -> local row while a region is built (UINT32_MAX: none) */
  size_t tb_cap;    /* rows of the largest region */
  double *tb_pos;   /* threads x 2 tb_cap x 3: a block's local positions, two passes */
  double *tb_step;  /* threads x MP_TSTRIDE: the largest squared move of each pass of a block */
  uint32_t *gcount; /* threads x k: the guard's sheet (guard_fit) */
  double *svar;     /* n x BSURF_SMOOTH_SV: the guard's sheet fit's record for the misfit test
                      (residual variance, degrees of freedom, share kept; smooth_stages.h) */
  bsurf_smooth_tuning tune; /* how the multipass passes run (same bits either way) */
} smooth_ctx;
#define GCOUNT(c, thread) (&(c)->gcount[(size_t)(thread) * (size_t)(c)->k])

#define MP_BLOCK 32 /* points per block */
#if defined(__GNUC__)
#define MP_LANES 1 /* the multipass pairs in vector lanes (smooth_lanes.c) */
#endif
/* multipass time blocks (smooth_lanes.c) */
#define MP_REGION 1024 /* ranks per region */
#define MP_SMAX 16     /* passes per block, at most */
#define MP_TSTRIDE 32  /* doubles per thread in tb_step (>= MP_SMAX, its own cache lines) */
typedef struct mp_region {
  uint32_t
      *row; /* local row -> rank: the region's own ranks, then each level of halo (in rank order) */
  size_t *off;   /* len[1] + 1: the pairs of the rows a block computes */
  uint32_t *ctr; /* per pair: its centre's local row */
  uint32_t *fit; /* per pair: its centre's rank (fit record) */
  size_t len[MP_SMAX +
             1]; /* pass j of a block of S passes computes rows 0..len[j]-1 (len[S]: own rows) */
  size_t row_cap, off_cap, ctr_cap, fit_cap; /* each array's own capacity */
  size_t sub_max;                            /* the most pairs of MP_BLOCK consecutive rows */
  int failed;                                /* out of memory */
} mp_region;

/* The combined move of one point from its gathered sums: o = P x + (1 - P)
 * T / S (x where no weight reached it). Returns |o - x|^2. */
static inline double update_finish(const double *x, double P, double S, const double T[3],
                                   double *o) {
  if (S > 0) {
    for (int t = 0; t < 3; t++)
      o[t] = P * x[t] + (1.0 - P) * (T[t] / S);
  } else {
    for (int t = 0; t < 3; t++)
      o[t] = x[t];
  }
  return (o[0] - x[0]) * (o[0] - x[0]) + (o[1] - x[1]) * (o[1] - x[1]) +
         (o[2] - x[2]) * (o[2] - x[2]);
}

#define solve_with_fallback bsurf_i_smooth_solve_with_fallback
#define staged_cb bsurf_i_smooth_staged_cb
#define boot_task bsurf_i_smooth_boot_task
#define set_theta2 bsurf_i_smooth_set_theta2
#define naive_select bsurf_i_smooth_naive_select
#define moved_of bsurf_i_smooth_moved_of
#define gather_update bsurf_i_smooth_gather_update
#define gather_bilateral_task bsurf_i_smooth_gather_bilateral_task
#define build_reverse bsurf_i_smooth_build_reverse
#define permute_rows bsurf_i_smooth_permute_rows
#define ctx_init bsurf_i_smooth_ctx_init
#define ctx_free bsurf_i_smooth_ctx_free
#define guard_fit bsurf_i_smooth_guard_fit
#define guard_noise bsurf_i_smooth_guard_noise
#define guard_misfit bsurf_i_smooth_guard_misfit
#define guard_ball_share bsurf_ball_share /* ball_scale.c */
#define gather_multipass_block bsurf_i_smooth_gather_multipass_block
#define mp_tblock_task bsurf_i_smooth_mp_tblock_task
#define mp_regions_build bsurf_i_smooth_mp_regions_build
#define smooth_multipass_run bsurf_i_smooth_multipass_run

/* smooth.c */
int solve_with_fallback(const bsurf_localfit *lf, int degree, int m, double *coef);
int staged_cb(void *u, size_t done, size_t total);
void boot_task(void *vc, int thread, size_t i);
void set_theta2(smooth_ctx *c, size_t i, double W, const double *sv);
int naive_select(double W, double threshold, const double *x, double *out);
double moved_of(const double *a, const double *b);
double gather_update(const smooth_ctx *c, size_t p, int multipass);
void gather_bilateral_task(void *vc, int thread, size_t p);
bsurf_status build_reverse(smooth_ctx *c, const int *size, const uint32_t *perm,
                           const uint32_t *rank);
bsurf_status permute_rows(void **array, size_t n, size_t row_bytes, const uint32_t *perm);
void ctx_init(smooth_ctx *c, const double *xyz, const bsurf_neighbors *nb,
              const bsurf_smooth_options *o);
void ctx_free(smooth_ctx *c, int T);
/* smooth_guard.c */
double guard_noise(const double *sv, size_t n, size_t stride, double *scratch);
int guard_misfit(const double *sv, double noise);
int guard_fit(const smooth_ctx *c, bsurf_error_scratch *s, uint32_t *act, const double *xyz,
              const uint32_t *idx, int k, double *F, int *degree, double *svar);
/* smooth_lanes.c */
void gather_multipass_block(void *vc, int thread, size_t blk);
void mp_tblock_task(void *vc, int thread, size_t r);
bsurf_status mp_regions_build(smooth_ctx *c, int T);
/* smooth_multipass.c */
bsurf_status smooth_multipass_run(smooth_ctx *c, const bsurf_smooth_options *o,
                                  const uint32_t *visit, int T, staged_progress *sp, double meanW,
                                  bsurf_smooth_fields *fields, bsurf_smooth_report *report);

#endif /* BSURF_SMOOTH_CTX_H */
