/* Smoothing driven by the bootstrap test error (thesis chapter 6).
 *
 * Every method starts with the bootstrap pass of chapter 4 (Algorithm 1,
 * the same per-point fits as bsurf_estimate_error, algo/algo.h), which gives
 * each point i its error W_i and its fits. Then:
 *
 * naive (6.2, Eq. 6.1): (x_i, y_i) -> (x_i, (1/B) sum_b f*b(x_i)) in point
 *   i's local frame, i.e. the point moves along the frame normal to the mean
 *   of the replicates' predictions at it, only where W_i (.632+ by default)
 *   is below the threshold.
 *
 * bilateral (6.3, Algorithm 4, Eq. 6.2): the fit f_i of neighbourhood i moves
 *   every neighbour z_ij towards its projection z*_ij onto the fitted surface
 *   (along the frame normal: z*_ij = z_ij + (f_i(x_j, y_j) - y_j) n_i):
 *       z_ij -> (1 - w_ij) z_ij + w_ij z*_ij,
 *       w_ij = theta_1(|z_ij - z_i0|) theta_2(W_i),  theta_k(x) = G(x, h_k),
 *   with G(a, b) = exp(-a^2/b^2) (Eq. 5.7).
 *   order sequential: the thesis's sweep i = 1..N in place; each fit (frame
 *     and polynomial) is made from the current positions, so earlier moves
 *     feed later fits (6.4's remark on Algorithm 4). One thread.
 *   order parallel: every fit from the input positions; a point p that lies
 *     in the neighbourhoods i_1 < i_2 < ... receives the moves of all of them
 *     at once as
 *         p' = P p + (1 - P) sum_i w_i z*_i / sum_i w_i,  P = prod_i (1 - w_i),
 *     which is what the sequential composition gives when the targets agree,
 *     and does not depend on the order (sums run in increasing i).
 *
 * multipass (6.4, Algorithm 5, Eqs. 6.3-6.5): per point, K_i = max{k_min, y}
 *   with y = (k_min - K) / k_error * W_i + K (Eq. 6.4, k_error = 3 mean W by
 *   default (the thesis: mean W), or a multiple of it, y rounded to the nearest integer); d_L, the
 * local average distance between points, taken as the mean distance from the point to the other K_i
 * - 1 (for a uniformly sampled disc the mean over all pairs is about 1.36 times this; it would cost
 * K_i^2 instead of K_i); the frame and polynomial of the K_i neighbourhood, computed once
 * (Algorithm 5's second loop), of the asked degree or lower so that there are at least two points
 *   per coefficient (K_i = 10 would otherwise make a cubic interpolate).
 *   A fit moves only points inside the disc its neighbourhood spans. Then `iterations` passes of
 * Eq. 6.2 with h1 = a d_L (Eq. 6.5): each pass projects the current positions onto the fixed fitted
 * surfaces, with weights from the current distances. The passes combine as the bilateral orders
 * above.
 *
 * Every method's fits pass the guard (guard_fit below, docs/smoothing.md "The
 * guard"): a fit of the centre's own sheet, moving only that sheet's points.
 *
 * Gaussian weights below 2^-54 are taken as 0: 1 - w rounds to 1 there, so
 * such a weight cannot move a point by itself; this cut (a^2/b^2 > 54 ln 2)
 * lets the passes skip far neighbours after one distance test.
 *
 * All of it is deterministic for a given seed, whatever the thread count:
 * every point is updated by gathering its contributions in a fixed order.
 * The multipass's parallel passes run over the points in Morton order (cache
 * locality; the order of a point's sums follows it), several passes at a
 * time per region of points (time blocks, mp_tblock_task: the same bits). */
#include "algo/algo.h"
#include "search/search.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define GAUSS_CUT 37.42995136401172 /* 54 ln 2: exp(-GAUSS_CUT) = 2^-54 */

bsurf_smooth_options bsurf_smooth_options_default(void) {
  bsurf_smooth_options o;
  memset(&o, 0, sizeof o);
  o.method = BSURF_SMOOTH_BILATERAL;
  o.error = bsurf_error_options_default();
  o.estimator = BSURF_SMOOTH_EST_DEFAULT;
  o.threshold = NAN;
  o.h1 = 0;
  o.h2 = 0;
  o.h2_fraction = 0;
  o.order = BSURF_ORDER_PARALLEL;
  o.a = 0.1;
  o.iterations = 300;
  o.k_min = 10;
  o.k_error = 0;
  o.k_error_fraction = 3.0;
  o.guard = 1;
  return o;
}

/* The exponent a^2 / b^2 of G(a, b) = exp(-a^2 / b^2) (Eq. 5.7); G(0, 0) = 1. */
static double gauss_exponent(double a, double b) {
  if (a == 0) return 0.0;
  if (!(b > 0)) return INFINITY;
  return (a / b) * (a / b);
}

/* A weight exp(-e), cut to 0 below 2^-54. */
static double weight_of(double e) {
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

double bsurf_smooth_exp(double x) {
  return mp_exp1(x);
}

/* ---- a fit kept for later passes: frame, scale, coefficients ----------- */
/* Layout of one stored fit: origin[3], rot[9] (row-major), inv_scale, the
 * largest |residual| of a point the fit moves (the guard's prediction bound;
 * INFINITY without the guard), coef[m]. */
#define FIT_HEAD 14
#define MP_EXTRA 3 /* multipass: e2, inv_h1sq, w2 after the coefficients */

static void fit_store(double *F, const bsurf_frame *fr, double inv_scale, const double *coef,
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

/* Full-rank fit of the highest degree <= `degree` (down to a constant), as
 * the error pass does for degenerate neighbourhoods; coef zero-padded to m. */
static int solve_with_fallback(const bsurf_localfit *lf, int degree, int m, double *coef) {
  int d = degree;
  while (d > 0 && bsurf_localfit_solve(lf, d, NULL, coef) != 0)
    d--;
  if (d == 0) bsurf_localfit_solve(lf, 0, NULL, coef);
  for (int a = bsurf_poly_terms(d); a < m; a++)
    coef[a] = 0.0;
  return d;
}

/* ---- progress over several stages ------------------------------------- */
typedef struct staged_progress {
  bsurf_progress_fn fn;
  void *user;
  int stage, stages;
} staged_progress;

static int staged_cb(void *u, size_t done, size_t total) {
  staged_progress *s = u;
  if (!s->fn) return 0;
  size_t per = 1000;
  size_t d = total ? (size_t)((double)done / (double)total * per) : per;
  return s->fn(s->user, (size_t)s->stage * per + d, (size_t)s->stages * per);
}

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
} smooth_ctx;
#define GCOUNT(c, thread) (&(c)->gcount[(size_t)(thread) * (size_t)(c)->k])

/* ---- the guard (docs/smoothing.md, "The guard") ------------------------
 * A least-squares fit to a neighbourhood that mixes two sheets (the
 * opposite face of a thin part, the other side of a sharp edge) runs
 * between them, and every point it moves goes off its own surface. The guard
 * makes each neighbourhood's fit a fit of its centre's sheet, and moves with
 * it only the points of that sheet:
 *  1. the centre's sheet: the n_s = max(K/4, 12) points nearest the centre,
 *     fitted first; their residuals give the sheet's offset m (median) and
 *     noise scale s (1.4826 x the median absolute deviation, robust to the
 *     few points of another sheet among them);
 *  2. a point belongs to the sheet when its residual lies in the prediction
 *     interval |r - m| <= t s sqrt(1 + 1/n_s) (t: Student's quantile at
 *     two-sided level 1%, n_s - 1 degrees of freedom); the fit is made again
 *     from these points only, and 1-2 repeat until the set stops changing
 *     (at most GUARD_ROUNDS times);
 *  3. the fit must be unbiased at the centre: Student's one-sample t test
 *     of "the mean residual of the centre's sheet's n_s nearest points is 0"
 *     (two-sided, same level). A fit that fails is made again from the
 *     nearest K/2 points (the degree drops so that there are two points per
 *     coefficient), down to k_min points; a neighbourhood whose smallest fit
 *     still fails moves no point.
 * The fit then moves only points within GUARD_MOVE prediction half-widths of
 * it (fit_delta's bound). The level is the tests' false-alarm rate on a single sheet: a false
 * alarm costs a fit from fewer points, or one point left to other fits. */
#define BSURF_GUARD_Z 2.5758293035489 /* the normal quantile of 1 - 0.01 / 2 */
#define GUARD_ROUNDS 6
/* A fit moves the points within GUARD_MOVE prediction half-widths of it:
 * with one, the noise's own tail (1% of a sheet at this level, more where
 * n_s points underestimate the scale) was never moved (cube, gaussian 0.5:
 * 0.156 h against 0.147 h with two); a second sheet lies farther out. */
#define GUARD_MOVE 2.0

/* Student's t quantile with nu degrees of freedom at the normal quantile z
 * (Cornish-Fisher expansion, Abramowitz & Stegun 26.7.5: within 1% of the
 * table for nu >= 5 at z = 2.58). */
static double student_t_quantile(double z, double nu) {
  const double z2 = z * z, z3 = z2 * z, z5 = z3 * z2, z7 = z5 * z2;
  return z + (z3 + z) / (4 * nu) + (5 * z5 + 16 * z3 + 3 * z) / (96 * nu * nu) +
         (3 * z7 + 19 * z5 + 17 * z3 - 15 * z) / (384 * nu * nu * nu);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static double median_of(double *v, int n) {
  qsort(v, (size_t)n, sizeof *v, cmp_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* n_s: a quarter of the neighbourhood, and at least 12 points (two per
 * coefficient of a quadric, the lowest degree that follows curvature: the
 * first fit of an exact surface is then exact) */
static int guard_near(int k) {
  return k / 4 > 12 ? k / 4 : (k < 12 ? k : 12);
}

/* Two sheets apart: the largest gap between the sorted residuals v[0..n-1]
 * of the first fit, as a scan test. On a single sheet the residuals near
 * any value c are locally uniform with density lambda (points per unit
 * residual), so the spacing after a point exceeds x / lambda with
 * probability e^-x, and the largest of n spacings exceeds ln(n / alpha) /
 * lambda with probability about alpha (the guard's level, 1%). lambda at a
 * gap: the q = max(3, n/4) points on each side over the width they span. A
 * gap with lambda g above that bound separates two sheets (the opposite face
 * of a thin part: on a 2 x 2 plate whose faces are 1.3 spacings apart, at
 * uniform noise 0.25 h, the faces' residuals leave a gap of 0.8 h); only
 * gaps with at least q points on each side count. Returns the gap's
 * midpoint, NAN when there is none. */
static double guard_gap(const double *v, int n) {
  const int q = n / 4 > 3 ? n / 4 : 3;
  double best = log((double)n / 0.01), cut = NAN;
  for (int i = q - 1; i + q < n; i++) {
    const double g = v[i + 1] - v[i];
    const double wl = v[i] - v[i - q + 1], wr = v[i + q] - v[i + 1];
    if (!(g > 0)) continue;
    const double lambda = (wl + wr > 0) ? 2.0 * (q - 1) / (wl + wr) : INFINITY;
    if (lambda * g > best) {
      best = lambda * g;
      cut = 0.5 * (v[i] + v[i + 1]);
    }
  }
  return cut;
}

/* The guard on the neighbourhood idx[0..k-1] (idx[0] its centre) of the
 * positions xyz: F (fit_store's record) and *degree out. Returns the
 * neighbourhood size whose fit passes (negative when the fit is of only part
 * of it, a sheet); 0 when none down to k_min does, F's scale is then NAN,
 * which fit_delta and the pair lanes read as "moves nothing". s: the
 * thread's scratch (its localfit and est_scratch); act: k entries.
 * Where the first fit's residuals fall in two groups apart (guard_gap), the
 * centre's group is its sheet: the offset and scale come from that sheet's
 * nearest points, and no point beyond the gap belongs to it or is moved. */
static int guard_fit(const smooth_ctx *c, bsurf_error_scratch *s, uint32_t *act, const double *xyz,
                     const uint32_t *idx, int k, double *F, int *degree) {
  const double tiny = 1e-9 * (c->nb ? c->nb->h : c->h1);
  const int kmin = c->o.k_min > 3 ? c->o.k_min : 3;
  bsurf_localfit *lf = &s->lf;
  double *r = s->est_scratch + k, *tmp = s->est_scratch + 2 * (size_t)k;
  double *srt = s->est_scratch + 3 * (size_t)k, *in = s->est_scratch + 4 * (size_t)k;
  for (int kc = k; kc >= kmin; kc /= 2) {
    const int ns = guard_near(kc);
    /* the first fit: the centre's ns nearest points (most of them on its
     * sheet, however many of the K are not), grown from there */
    int na = ns, deg = c->degree;
    for (int j = 0; j < ns; j++)
      act[j] = idx[j];
    double m = 0, bound = INFINITY;
    /* two sheets: the residuals about the fit of all kc points (through
     * both sheets) fall in two groups with a gap between them (guard_gap);
     * the centre's group is its sheet (side), and lim is half the distance
     * between the groups' medians: no point farther than that from the
     * sheet belongs to it or is moved by its fit */
    int side = 0;
    double lim = INFINITY;
    {
      bsurf_frame fr;
      bsurf_local_frame(xyz, idx, kc, c->o.error.pca_center, &fr);
      /* a plane: a fit of higher degree bends between the sheets and
       * fills the gap (a cubic of 50 points on the plate above hides it in
       * most neighbourhoods) */
      bsurf_localfit_setup(lf, xyz, idx, kc, &fr, 1);
      double coef[BSURF_TERMS_MAX];
      const int dd = solve_with_fallback(lf, 1, c->m, coef);
      fit_store(F, &fr, 1.0 / lf->scale, coef, c->m);
      int nv = 0;
      for (int j = 0; j < kc; j++) {
        r[j] = -fit_delta_any(F, dd, c->m, &xyz[3 * (size_t)idx[j]], 0);
        if (!isnan(r[j])) srt[nv++] = r[j];
      }
      qsort(srt, (size_t)nv, sizeof *srt, cmp_double);
      const double cut = nv >= 8 && !isnan(r[0]) ? guard_gap(srt, nv) : NAN;
      if (!isnan(cut)) {
        side = r[0] > cut ? 1 : -1;
        int lo = 0, hi = 0;
        for (int j = 0; j < nv; j++)
          if (srt[j] > cut)
            hi++;
          else
            lo++;
        /* the groups' medians: srt[0..lo) and srt[lo..nv) */
        const double m_lo = lo % 2 ? srt[lo / 2] : 0.5 * (srt[lo / 2 - 1] + srt[lo / 2]);
        const double m_hi =
            hi % 2 ? srt[lo + hi / 2] : 0.5 * (srt[lo + hi / 2 - 1] + srt[lo + hi / 2]);
        lim = 0.5 * (m_hi - m_lo);
        na = 0;
        for (int j = 0; j < kc; j++)
          if (!isnan(r[j]) && (r[j] > cut ? 1 : -1) == side) act[na++] = idx[j];
        if (na < 3) side = 0, na = ns, lim = INFINITY;
        if (!side)
          for (int j = 0; j < ns; j++)
            act[j] = idx[j];
      }
    }
    for (int round = 0;; round++) {
      /* the fit of the sheet's points: frame, degree with two points per
       * coefficient, least squares */
      bsurf_frame fr;
      bsurf_local_frame(xyz, act, na, c->o.error.pca_center, &fr);
      int d = c->degree;
      while (d > 1 && 2 * bsurf_poly_terms(d) > na)
        d--;
      bsurf_localfit_setup(lf, xyz, act, na, &fr, d);
      double coef[BSURF_TERMS_MAX];
      deg = solve_with_fallback(lf, d, c->m, coef);
      fit_store(F, &fr, 1.0 / lf->scale, coef, c->m);
      /* residuals of every point of the neighbourhood (beyond the fit's
       * disc too: the sheet grows from its nearest points) */
      int nn = 0;
      for (int j = 0; j < kc; j++)
        r[j] = -fit_delta_any(F, deg, c->m, &xyz[3 * (size_t)idx[j]], 0);
      if (side) { /* which of the neighbourhood's points are the sheet's now */
        for (int j = 0; j < kc; j++)
          in[j] = 0;
        for (int a = 0, j = 0; a < na && j < kc; j++)
          if (idx[j] == act[a]) in[j] = 1, a++;
      }
      /* 1: the centre's sheet: offset and noise scale from its nearest
       * points (of its side of a gap) */
      for (int j = 0; j < kc && nn < ns; j++)
        if (!isnan(r[j]) && (side ? in[j] != 0 : j < ns)) tmp[nn++] = r[j];
      if (nn < 3) break;
      m = median_of(tmp, nn);
      int t = 0;
      for (int j = 0; j < kc && t < nn; j++)
        if (!isnan(r[j]) && (side ? in[j] != 0 : j < ns)) tmp[t++] = fabs(r[j] - m);
      const double sc = 1.4826 * median_of(tmp, t);
      bound = fmax(student_t_quantile(BSURF_GUARD_Z, t - 1) * sc * sqrt(1.0 + 1.0 / t), tiny);
      const double bin = fmin(bound, lim);
      /* 2: the points of that sheet (the centre always) */
      int n_in = 1, changed = 0;
      for (int j = 1; j < kc; j++) {
        if (!(fabs(r[j] - m) <= bin)) continue;
        if (n_in >= na || act[n_in] != idx[j]) changed = 1;
        act[n_in++] = idx[j];
      }
      changed |= n_in != na;
      if (!changed || round == GUARD_ROUNDS || n_in < 3) break;
      na = n_in;
    }
    /* 3: unbiased at the centre: the t test on the sheet's nearest points */
    const double bin = fmin(bound, lim);
    double sum = 0, ss = 0;
    int n = 0;
    for (int j = 0; j < ns; j++)
      if (fabs(r[j] - m) <= bin) sum += r[j], n++;
    const double mean = n ? sum / n : 0;
    for (int j = 0; j < ns; j++)
      if (fabs(r[j] - m) <= bin) ss += (r[j] - mean) * (r[j] - mean);
    const double sd = n > 1 ? sqrt(ss / (n - 1)) : 0;
    if (n >= 3 && !(fabs(mean) > tiny &&
                    fabs(mean) * sqrt((double)n) > student_t_quantile(BSURF_GUARD_Z, n - 1) * sd)) {
      /* moves: delta = f - z = -r, so |delta| <= |m| + bound holds the sheet
       * (and no point beyond a gap) */
      F[13] = fabs(m) + fmin(GUARD_MOVE * bound, lim);
      *degree = deg;
      return na < kc ? -kc : kc;
    }
  }
  F[12] = NAN;
  return 0;
}

/* Stage 1: Algorithm 1 at every point (and the naive projection). */
static void boot_task(void *vc, int thread, size_t i) {
  smooth_ctx *c = vc;
  bsurf_error_fields ef;
  memset(&ef, 0, sizeof ef);
  ef.err_632 = c->err_632;
  ef.err_632plus = c->err_632plus;
  bsurf_error_fit fit;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  bsurf_error_point(c->xyz, idx, NULL, &c->o.error, i, &c->scr[thread], &ef, &fit);
  const double *p = &c->xyz[3 * (size_t)idx[0]]; /* row i's point (i itself in a whole cloud) */
  if (c->o.method == BSURF_SMOOTH_NAIVE) {
    /* Eq. 6.1: the centre has local coordinates (0, 0, 0) (the frame's
     * origin is the point), so it moves by boot_center along n. */
    double height = fit.boot_center, *n = fit.frame.rot[2];
    double F[FIT_HEAD + BSURF_TERMS_MAX]; /* n may point into it below */
    if (c->o.guard) {
      /* a biased fit: the height of the guard's smaller fit at the point
       * (no bootstrap mean there), or no move */
      int deg = fit.degree;
      fit_store(F, &fit.frame, fit.inv_scale, fit.coef, c->m);
      int kg = guard_fit(c, &c->scr[thread], GCOUNT(c, thread), c->xyz, idx, c->k, F, &deg);
      if (kg == 0)
        height = 0;
      else if (kg != c->k) {
        height = fit_delta(F, deg, c->m, p);
        if (isnan(height)) height = 0;
        n = &F[9];
      }
    }
    for (int t = 0; t < 3; t++)
      c->out[3 * i + t] = p[t] + height * n[t];
  } else if (c->fits) {
    double *F = &c->fits[i * (size_t)c->stride];
    fit_store(F, &fit.frame, fit.inv_scale, fit.coef, c->m);
    int deg = c->degree;
    if (c->o.guard) {
      deg = fit.degree;
      guard_fit(c, &c->scr[thread], GCOUNT(c, thread), c->xyz, idx, c->k, F, &deg);
    }
    if (c->fit_degree) c->fit_degree[i] = deg;
  }
}

/* theta_2(W_i) = G(W_i, h2) of Eq. 6.2: its exponent and its value. */
static void set_theta2(smooth_ctx *c, size_t i, double W) {
  c->e2[i] = gauss_exponent(W, c->h2);
  c->w2[i] = c->e2[i] == 0 ? 1.0 : exp(-c->e2[i]);
}

/* Naive (6.2): Eq. 6.1's projection stands where W_i < threshold; elsewhere
 * the point stays at x. 1 when projected. */
static int naive_select(double W, double threshold, const double *x, double *out) {
  if (W < threshold) return 1;
  for (int t = 0; t < 3; t++)
    out[t] = x[t];
  return 0;
}

static double moved_of(const double *a, const double *b) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

/* Multipass stage 2: K_i (Eqs. 6.3-6.4), d_L and the fit of the K_i points. */
static void multipass_fit_task(void *vc, int thread, size_t i) {
  smooth_ctx *c = vc;
  const int K = c->k, kmin = c->o.k_min;
  double y = (double)K;
  if (c->k_error > 0) y = (double)(kmin - K) / c->k_error * c->W[i] + (double)K;
  int kh = kmin;
  if (y > kmin) kh = y >= K ? K : (int)floor(y + 0.5);
  if (kh < kmin) kh = kmin;
  if (kh > K) kh = K;
  c->khat[i] = kh;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const double *p0 = &c->xyz[3 * i];
  double s = 0;
  for (int j = 1; j < kh; j++) {
    const double *q = &c->xyz[3 * (size_t)idx[j]];
    s += sqrt((q[0] - p0[0]) * (q[0] - p0[0]) + (q[1] - p0[1]) * (q[1] - p0[1]) +
              (q[2] - p0[2]) * (q[2] - p0[2]));
  }
  c->dl[i] = kh > 1 ? s / (kh - 1) : 0.0;

  bsurf_frame fr;
  bsurf_local_frame(c->xyz, idx, kh, c->o.error.pca_center, &fr);
  bsurf_localfit *lf = &c->scr[thread].lf;
  /* least squares with at least two points per term: a fit that (nearly)
   * interpolates K_i noisy points follows the noise and swings between them */
  int deg = c->degree;
  while (deg > 1 && 2 * bsurf_poly_terms(deg) > kh)
    deg--;
  bsurf_localfit_setup(lf, c->xyz, idx, kh, &fr, deg);
  double coef[BSURF_TERMS_MAX];
  c->fit_degree[i] = solve_with_fallback(lf, deg, c->m, coef);
  fit_store(&c->fits[i * (size_t)c->stride], &fr, 1.0 / lf->scale, coef, c->m);
  if (c->o.guard)
    guard_fit(c, &c->scr[thread], GCOUNT(c, thread), c->xyz, idx, kh,
              &c->fits[i * (size_t)c->stride], &c->fit_degree[i]);

  double h1 = c->o.a * c->dl[i];
  c->inv_h1sq[i] = h1 > 0 ? 1.0 / (h1 * h1) : 0.0;
  set_theta2(c, i, c->W[i]);
  double *rec = &c->fits[i * (size_t)c->stride + FIT_HEAD + (size_t)c->m];
  rec[0] = c->e2[i];
  rec[1] = c->inv_h1sq[i];
  rec[2] = c->w2[i];
}

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

/* One point's gathered update (parallel order): the moves of every
 * neighbourhood i that contains p, from the positions `cur`. */
static double gather_update(const smooth_ctx *c, size_t p, int multipass) {
  const double *x = &c->cur[3 * (c->self ? (size_t)c->self[p] : p)];
  double P = 1.0, S = 0.0, T[3] = {0, 0, 0};
  const uint32_t *list = multipass ? &c->act[c->rev_off[p]] : &c->rev[c->rev_off[p]];
  const size_t count = multipass ? c->act_n[p] : c->rev_off[p + 1] - c->rev_off[p];
  for (size_t e = 0; e < count; e++) {
    const uint32_t i = list[e];
    const double *ci = &c->cur[3 * (size_t)i];
    double d2 = (x[0] - ci[0]) * (x[0] - ci[0]) + (x[1] - ci[1]) * (x[1] - ci[1]) +
                (x[2] - ci[2]) * (x[2] - ci[2]);
    /* w = theta_1 theta_2 = exp(-(d^2/h1^2 + W_i^2/h2^2)) */
    double ex = c->e2[i], w;
    if (d2 > 0) {
      double inv = multipass ? c->inv_h1sq[i] : c->inv_h1sq_global;
      ex = inv > 0 ? ex + d2 * inv : INFINITY; /* h1 = 0: only the point itself */
      if (!(ex <= GAUSS_CUT)) continue;
      w = ex == 0 ? 1.0 : (multipass ? mp_exp1(-ex) : exp(-ex));
    } else { /* the point itself (or a duplicate): theta_1 = 1, precomputed */
      if (!(ex <= GAUSS_CUT)) continue;
      w = c->w2[i];
    }
    const double *F = &c->fits[(size_t)i * c->stride];
    double delta = fit_delta(F, c->fit_degree ? c->fit_degree[i] : c->degree, c->m, x);
    if (isnan(delta)) continue;
    P *= 1.0 - w;
    S += w;
    for (int t = 0; t < 3; t++)
      T[t] += w * (x[t] + delta * F[9 + t]);
  }
  return update_finish(x, P, S, T, &c->next[3 * p]);
}

static void gather_bilateral_task(void *vc, int thread, size_t p) {
  (void)thread;
  gather_update(vc, p, 0);
}

static void gather_multipass_task(void *vc, int thread, size_t p) {
  smooth_ctx *c = vc;
  double step2 = gather_update(c, p, 1);
  if (step2 > c->tmax[8 * thread]) c->tmax[8 * thread] = step2;
}

/* ---- multipass passes in blocks of points, pairs in vector lanes ------
 * The arithmetic of gather_update, operation for operation (no contraction),
 * arranged for throughput: a block's active pairs (p, i) are listed flat;
 * every pair's weight w and target x + delta n are computed four pairs at a
 * time in vector lanes (the exponential by glibc's exp per lane, as in
 * gather_update); then each point sums its pairs in its list's order. A
 * pair without a weight (theta beyond the cut, or p outside fit i's disc)
 * gets w = 0 and target 0: P (1 - 0), S + 0 and T + 0 x 0 leave the sums'
 * bits as they were (T starts at +0 and cannot become -0), so the output is
 * gather_update's, bit for bit. For the bases up to degree 3 (m <= 10) with
 * GCC/clang vector extensions; otherwise the passes use gather_update. */
#define MP_BLOCK 32 /* points per block */
static int mp_blocks_on = 1;
void bsurf_smooth_block_passes(int on) {
  mp_blocks_on = on;
}
#if defined(__GNUC__)
#define MP_LANES 1
typedef double mp_v4d __attribute__((vector_size(32)));
typedef long long mp_v4l __attribute__((vector_size(32)));
/* lanes of field k of the four records A[0..3] */
#define MP_GATHER(A, k) ((mp_v4d){(A)[0][k], (A)[1][k], (A)[2][k], (A)[3][k]})
/* mask ? a : b, lane by lane */
#define MP_SELECT(mask, a, b)                                                                      \
  ((mp_v4d)(((mp_v4l)(mask) & (mp_v4l)(a)) | (~(mp_v4l)(mask) & (mp_v4l)(b))))

/* out = mp_exp1(x) in four lanes (a statement: no vector-valued calls) */
#define MP_EXP4(out, x)                                                                            \
  do {                                                                                             \
    const mp_v4d magic_ = {MPX_MAGIC, MPX_MAGIC, MPX_MAGIC, MPX_MAGIC};                            \
    const mp_v4d t_ = (x)*MPX_LOG2E + magic_;                                                      \
    const mp_v4d n_ = t_ - magic_;                                                                 \
    const mp_v4d r_ = ((x)-n_ * MPX_LN2_HI) - n_ * MPX_LN2_LO;                                     \
    mp_v4d p_;                                                                                     \
    MPX_POLY(mp_v4d, p_, r_);                                                                      \
    const mp_v4l bits_ = ((mp_v4l)t_ - (mp_v4l)magic_ + 1023) * ((long long)1 << 52);              \
    (out) = p_ * (mp_v4d)bits_;                                                                    \
  } while (0)

/* w[e] and tg[3e..3e+2] of the pairs e0..e0+3 (lanes past np repeat pair e0
 * and are not stored): pair e is point pp[e] (its row in pos) with the
 * centre pi[e] (its row in pos) and that centre's fit record pf[e]; M = the
 * number of terms, a constant per call site. */
static inline __attribute__((always_inline)) void
mp_pairs4(const smooth_ctx *c, int M, const double *pos, const uint32_t *pi, const uint32_t *pf,
          const uint32_t *pp, size_t e0, size_t np, double *w, double *tg) {
  const double *X[4], *C[4], *F[4];
  const int L = np - e0 < 4 ? (int)(np - e0) : 4;
  for (int l = 0; l < 4; l++) {
    const size_t e = e0 + (size_t)(l < L ? l : 0);
    X[l] = &pos[3 * (size_t)pp[e]];
    C[l] = &pos[3 * (size_t)pi[e]];
    F[l] = &c->fits[(size_t)pf[e] * c->stride];
  }
  const mp_v4d x0 = MP_GATHER(X, 0), x1 = MP_GATHER(X, 1), x2 = MP_GATHER(X, 2);
  const mp_v4d c0 = MP_GATHER(C, 0), c1 = MP_GATHER(C, 1), c2 = MP_GATHER(C, 2);
  const mp_v4d d2 = (x0 - c0) * (x0 - c0) + (x1 - c1) * (x1 - c1) + (x2 - c2) * (x2 - c2);
  const mp_v4d e2 = MP_GATHER(F, FIT_HEAD + M), inv = MP_GATHER(F, FIT_HEAD + M + 1);
  const mp_v4d zero = {0, 0, 0, 0}, inf = {INFINITY, INFINITY, INFINITY, INFINITY};
  /* d > 0: e2 + d^2 / h1^2 (h1 = 0: infinite); d = 0: e2 */
  const mp_v4d ex = MP_SELECT(d2 > zero, MP_SELECT(inv > zero, e2 + d2 * inv, inf), e2);
  /* fit_delta */
  const mp_v4d q0 = x0 - MP_GATHER(F, 0), q1 = x1 - MP_GATHER(F, 1), q2 = x2 - MP_GATHER(F, 2);
  const mp_v4d lx = MP_GATHER(F, 3) * q0 + MP_GATHER(F, 4) * q1 + MP_GATHER(F, 5) * q2;
  const mp_v4d ly = MP_GATHER(F, 6) * q0 + MP_GATHER(F, 7) * q1 + MP_GATHER(F, 8) * q2;
  const mp_v4d n0 = MP_GATHER(F, 9), n1 = MP_GATHER(F, 10), n2 = MP_GATHER(F, 11);
  const mp_v4d lz = n0 * q0 + n1 * q1 + n2 * q2;
  const mp_v4d sc = MP_GATHER(F, 12);
  const mp_v4d u = lx * sc, v = ly * sc;
  const mp_v4d one = {1, 1, 1, 1};
  const mp_v4l outside = u * u + v * v > one;
  const mp_v4d uu = u * u, uv = u * v, vv = v * v;
  mp_v4d f = MP_GATHER(F, FIT_HEAD + 0);
  if (M > 1) f += MP_GATHER(F, FIT_HEAD + 1) * u + MP_GATHER(F, FIT_HEAD + 2) * v;
  if (M > 3)
    f += MP_GATHER(F, FIT_HEAD + 3) * uu + MP_GATHER(F, FIT_HEAD + 4) * uv +
         MP_GATHER(F, FIT_HEAD + 5) * vv;
  if (M > 6)
    f += MP_GATHER(F, FIT_HEAD + 6) * (uu * u) + MP_GATHER(F, FIT_HEAD + 7) * (uu * v) +
         MP_GATHER(F, FIT_HEAD + 8) * (u * vv) + MP_GATHER(F, FIT_HEAD + 9) * (vv * v);
  const mp_v4d delta = f - lz;
  const mp_v4d cut = {GAUSS_CUT, GAUSS_CUT, GAUSS_CUT, GAUSS_CUT};
  const mp_v4d bound = MP_GATHER(F, 13);
  const mp_v4l ok = (ex <= cut) & ~outside & (MP_SELECT(delta < zero, -delta, delta) <= bound);
  const mp_v4d t0 = MP_SELECT(ok, x0 + delta * n0, zero), t1 = MP_SELECT(ok, x1 + delta * n1, zero),
               t2 = MP_SELECT(ok, x2 + delta * n2, zero);
  /* d > 0: e^-ex (1 at ex = 0); d = 0: theta_2, kept in the record */
  const mp_v4d w2 = MP_GATHER(F, FIT_HEAD + M + 2);
  mp_v4d ee;
  MP_EXP4(ee, -ex);
  const mp_v4d we = MP_SELECT(ok, MP_SELECT(ex == zero, one, MP_SELECT(d2 == zero, w2, ee)), zero);
  for (int l = 0; l < L; l++) {
    w[e0 + (size_t)l] = we[l];
    tg[3 * (e0 + (size_t)l)] = t0[l];
    tg[3 * (e0 + (size_t)l) + 1] = t1[l];
    tg[3 * (e0 + (size_t)l) + 2] = t2[l];
  }
}

BSURF_CLONES
static void mp_pairs(const smooth_ctx *c, const double *pos, const uint32_t *pi, const uint32_t *pf,
                     const uint32_t *pp, size_t np, double *w, double *tg) {
#define MP_PAIRS(M)                                                                                \
  for (size_t e0 = 0; e0 < np; e0 += 4)                                                            \
  mp_pairs4(c, M, pos, pi, pf, pp, e0, np, w, tg)
  switch (c->m) {
  case 3: MP_PAIRS(3); break;
  case 6: MP_PAIRS(6); break;
  default: MP_PAIRS(10); break;
  }
#undef MP_PAIRS
}

/* The points of one pass as the blocks see them: the whole cloud (rows =
 * ranks, pairs = the compacted active lists) or a time block's local rows
 * (mp_tblock_task). */
typedef struct mp_view {
  const double *cur;   /* rows read */
  double *next;        /* rows written */
  size_t n;            /* rows computed */
  const size_t *off;   /* row p's pairs: off[p] .. off[p + 1] - 1 */
  const uint32_t *ctr; /* per pair: its centre's row in cur */
  const uint32_t *fit; /* per pair: its centre's fit record (the centre's rank) */
} mp_view;

/* Rows p0..p1-1 of a view, one block of a multipass pass; returns the
 * largest squared move, mx or above. */
static double mp_block(const smooth_ctx *c, const mp_view *v, size_t p0, size_t p1, int thread,
                       double mx) {
  uint32_t *pp = &c->mp_point[(size_t)thread * c->mp_cap];
  double *w = &c->mp_val[(size_t)thread * 4 * c->mp_cap], *tg = w + c->mp_cap;
  const size_t base = v->off[p0], np = v->off[p1] - base; /* the block's pairs, side by side */
  for (size_t p = p0, e = 0; p < p1; p++)
    for (size_t q = v->off[p]; q < v->off[p + 1]; q++)
      pp[e++] = (uint32_t)p;
  {
    /* ask for the records and positions of the next block's pairs now */
    const size_t q1 = p1 + MP_BLOCK < v->n ? p1 + MP_BLOCK : v->n;
    for (size_t e = v->off[p1], e1 = v->off[q1]; e < e1; e++) {
      const double *f = &c->fits[(size_t)v->fit[e] * c->stride];
      __builtin_prefetch(f);
      __builtin_prefetch(f + 8);
      __builtin_prefetch(f + 16);
      __builtin_prefetch(f + c->stride - 1);
      __builtin_prefetch(&v->cur[3 * (size_t)v->ctr[e]]);
    }
  }
  mp_pairs(c, v->cur, &v->ctr[base], &v->fit[base], pp, np, w, tg);
  size_t e = 0;
  for (size_t p = p0; p < p1; p++) {
    double P = 1.0, S = 0.0, T[3] = {0, 0, 0};
    for (size_t q = v->off[p]; q < v->off[p + 1]; q++, e++) {
      const double we = w[e];
      P *= 1.0 - we;
      S += we;
      for (int t = 0; t < 3; t++)
        T[t] += we * tg[3 * e + t];
    }
    double step2 = update_finish(&v->cur[3 * p], P, S, T, &v->next[3 * p]);
    if (step2 > mx) mx = step2;
  }
  return mx;
}

/* One block of points of a multipass pass over the whole cloud. */
static void gather_multipass_block(void *vc, int thread, size_t blk) {
  smooth_ctx *c = vc;
  const size_t p0 = blk * MP_BLOCK, p1 = p0 + MP_BLOCK < c->n ? p0 + MP_BLOCK : c->n;
  const mp_view v = {c->cur, c->next, c->n, c->act_off, c->act, c->act};
  c->tmax[8 * thread] = mp_block(c, &v, p0, p1, thread, c->tmax[8 * thread]);
}

/* ---- multipass time blocks: several passes per cache-sized region ------
 * A pass maps the positions x^t to x^(t+1); point p's x^(t+1) reads only
 * x^t at p and at the centres i of p's active pairs (and the fixed records
 * of those i). So s passes over a region R of MP_REGION consecutive ranks
 * (Morton order) need x^(t+s-1) on R, x^(t+s-2) on R and its pairs'
 * centres, and so on: levels of halo, each the centres of the level
 * before's pairs. A block reads x^t of all these rows from the whole
 * cloud's array, computes every pass on its own local rows (the halo rows
 * again, as their owners do: the same inputs give the same bits) while the
 * region's records stay in cache, and writes x^(t+s) of R only. Every row
 * is computed by mp_block with its pairs in its list's order, so the output
 * is the pass-by-pass output bit for bit, for any thread count (regions
 * read x^t and write disjoint rows of x^(t+s)).
 * The active lists must hold every pair with a weight at every pass of a
 * block; the lists are only a superset of those pairs (a listed pair
 * without a weight adds exactly nothing), so rebuilding them earlier than
 * the pass-by-pass loop would does not change the output. A block is
 * therefore run only when the points are expected to stay within the
 * margin, and is discarded and run again after a rebuild if they did not.
 * Blocks are kept to the passes whose halo rows are at most a tenth of the
 * rows computed (mp_regions_build): wide halos cost more than the cache
 * gives. */
#define MP_REGION 1024 /* ranks per region */
#define MP_SMAX 16     /* passes per block, at most */
#define MP_TSTRIDE 32  /* doubles per thread in tb_step (>= MP_SMAX, its own cache lines) */
static int mp_tblock_passes = 8, mp_tblock_any_halo = 0;
void bsurf_smooth_time_blocks(int passes, int any_halo) {
  mp_tblock_passes = passes < 1 ? 1 : (passes > MP_SMAX ? MP_SMAX : passes);
  mp_tblock_any_halo = any_halo;
}

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

/* *a with room for `need` elements of `size` bytes (grown by half); NULL
 * (and *a untouched) when memory is short. */
static void *mp_grow(void *a, size_t *cap, size_t need, size_t size) {
  if (need <= *cap) return a;
  const size_t nc = need + need / 2 + 64;
  void *b = realloc(a, nc * size);
  if (b) *cap = nc;
  return b;
}

static int cmp_u32(const void *a, const void *b) {
  const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
  return (x > y) - (x < y);
}

/* Region r's rows and pairs for blocks of up to tb_S passes, from the
 * compacted active lists: its own ranks, then the centres of their pairs
 * (the rows pass S - 1 must give), then the centres of those rows' pairs,
 * and so on down to the rows a block reads (level 0). */
static void mp_region_task(void *vc, int thread, size_t r) {
  smooth_ctx *c = vc;
  mp_region *g = &c->reg[r];
  uint32_t *map = &c->lmap[(size_t)thread * c->n];
  const int S = c->tb_S;
  const size_t r0 = r * MP_REGION, r1 = r0 + MP_REGION < c->n ? r0 + MP_REGION : c->n;
  size_t nrow = 0, np = 0;
  void *q;
  g->failed = 1;
  if (!(q = mp_grow(g->row, &g->row_cap, r1 - r0, sizeof *g->row))) return;
  g->row = q;
  for (size_t p = r0; p < r1; p++) {
    map[p] = (uint32_t)nrow;
    g->row[nrow++] = (uint32_t)p;
  }
  g->len[S] = nrow;
  size_t beg = 0;
  for (int j = S - 1; j >= 0; j--) {
    const size_t end = nrow;
    for (size_t l = beg; l < end; l++)
      for (size_t e = c->act_off[g->row[l]]; e < c->act_off[g->row[l] + 1]; e++) {
        const uint32_t i = c->act[e];
        if (map[i] != UINT32_MAX) continue;
        if (!(q = mp_grow(g->row, &g->row_cap, nrow + 1, sizeof *g->row))) goto out;
        g->row = q;
        map[i] = 0; /* seen; its row is set below */
        g->row[nrow++] = i;
      }
    qsort(&g->row[end], nrow - end, sizeof *g->row, cmp_u32);
    for (size_t l = end; l < nrow; l++)
      map[g->row[l]] = (uint32_t)l;
    g->len[j] = nrow;
    beg = end;
  }
  const size_t nc = g->len[1];
  for (size_t l = 0; l < nc; l++)
    np += c->act_off[g->row[l] + 1] - c->act_off[g->row[l]];
  if (!(q = mp_grow(g->off, &g->off_cap, nc + 1, sizeof *g->off))) goto out;
  g->off = q;
  /* two capacities: a shared one, reset before growing fit, let a later,
   * larger np skip growing ctr past its real size (found by ASan) */
  if (!(q = mp_grow(g->ctr, &g->ctr_cap, np ? np : 1, sizeof *g->ctr))) goto out;
  g->ctr = q;
  if (!(q = mp_grow(g->fit, &g->fit_cap, np ? np : 1, sizeof *g->fit))) goto out;
  g->fit = q;
  np = 0;
  for (size_t l = 0; l < nc; l++) {
    g->off[l] = np;
    for (size_t e = c->act_off[g->row[l]]; e < c->act_off[g->row[l] + 1]; e++, np++) {
      g->ctr[np] = map[c->act[e]];
      g->fit[np] = c->act[e];
    }
  }
  g->off[nc] = np;
  g->sub_max = 0;
  for (size_t l = 0; l < nc; l += MP_BLOCK) {
    const size_t l1 = l + MP_BLOCK < nc ? l + MP_BLOCK : nc;
    if (g->off[l1] - g->off[l] > g->sub_max) g->sub_max = g->off[l1] - g->off[l];
  }
  g->failed = 0;
out:
  for (size_t l = 0; l < nrow; l++)
    map[g->row[l]] = UINT32_MAX;
}

/* One region's block of tb_s passes (the last tb_s of the tb_S it is built
 * for): x^t of the rows it reads, then pass after pass on the local rows,
 * the last one written to the region's own rows of `next`. */
static void mp_tblock_task(void *vc, int thread, size_t r) {
  smooth_ctx *c = vc;
  const mp_region *g = &c->reg[r];
  const int S = c->tb_S, j0 = S - c->tb_s;
  double *a = &c->tb_pos[(size_t)thread * 6 * c->tb_cap], *b = a + 3 * c->tb_cap;
  double *step = &c->tb_step[(size_t)thread * MP_TSTRIDE];
  for (size_t l = 0; l < g->len[j0]; l++)
    memcpy(&a[3 * l], &c->cur[3 * (size_t)g->row[l]], 3 * sizeof(double));
  for (int j = j0 + 1; j <= S; j++) {
    const mp_view v = {
        a, j == S ? &c->next[3 * (size_t)g->row[0]] : b, g->len[j], g->off, g->ctr, g->fit};
    double mx = step[j - j0 - 1];
    for (size_t p0 = 0; p0 < v.n; p0 += MP_BLOCK)
      mx = mp_block(c, &v, p0, p0 + MP_BLOCK < v.n ? p0 + MP_BLOCK : v.n, thread, mx);
    step[j - j0 - 1] = mx;
    double *t = a;
    a = b;
    b = t;
  }
}

/* The regions for the current active lists (after a rebuild); room in the
 * per-thread scratch for their rows and blocks. */
static bsurf_status mp_regions_build(smooth_ctx *c, int T) {
  bsurf_status st = bsurf_parallel_sweep_chunk(c->nreg, T, 1, mp_region_task, c);
  size_t rows = 0, sub = c->mp_cap;
  for (size_t r = 0; r < c->nreg && st == BSURF_OK; r++) {
    if (c->reg[r].failed) return BSURF_ERR_NOMEM;
    if (c->reg[r].len[0] > rows) rows = c->reg[r].len[0];
    if (c->reg[r].sub_max > sub) sub = c->reg[r].sub_max;
  }
  if (st != BSURF_OK) return st;
  /* blocks of at most tb_max passes: the halo rows they compute again are
   * at most a tenth of the rows (many pairs per point, as with h2 = 1W,
   * give wide halos: there the blocks would cost more than the cache gives) */
  c->tb_max = 1;
  for (int s = 2; s <= c->tb_S; s++) {
    size_t rows_s = 0;
    for (size_t r = 0; r < c->nreg; r++)
      for (int j = c->tb_S - s + 1; j <= c->tb_S; j++)
        rows_s += c->reg[r].len[j];
    if (!mp_tblock_any_halo && (double)rows_s > 1.1 * (double)s * (double)c->n) break;
    c->tb_max = s;
  }
  if (sub > c->mp_cap) {
    free(c->mp_point);
    free(c->mp_val);
    c->mp_cap = sub;
    c->mp_point = bsurf_alloc_array((size_t)T * sub, sizeof(uint32_t));
    c->mp_val = bsurf_alloc_array((size_t)T * 4 * sub, sizeof(double));
    if (!c->mp_point || !c->mp_val) return BSURF_ERR_NOMEM;
  }
  if (rows > c->tb_cap) {
    free(c->tb_pos);
    c->tb_cap = rows;
    c->tb_pos = bsurf_alloc_array((size_t)T * 6 * rows, sizeof(double));
    if (!c->tb_pos) return BSURF_ERR_NOMEM;
  }
  return BSURF_OK;
}
#endif

/* The pairs (p, i) of the multipass that can carry a weight while no point
 * moves by more than the margin: i = p, or |p - i| < cut_i + 2 margin at the
 * positions `cur` (a pair further apart stays beyond theta_1's cut). Keeps
 * the order of the reverse list. */
static void active_task(void *vc, int thread, size_t p) {
  (void)thread;
  smooth_ctx *c = vc;
  const double *x = &c->cur[3 * p];
  uint32_t *act = &c->act[c->rev_off[p]];
  uint32_t cnt = 0;
  for (size_t e = c->rev_off[p]; e < c->rev_off[p + 1]; e++) {
    const uint32_t i = c->rev[e];
    if (!(c->e2[i] <= GAUSS_CUT)) continue; /* theta_2 alone is below the cut */
    if (i != p) {
      const double *ci = &c->cur[3 * (size_t)i];
      double d2 = (x[0] - ci[0]) * (x[0] - ci[0]) + (x[1] - ci[1]) * (x[1] - ci[1]) +
                  (x[2] - ci[2]) * (x[2] - ci[2]);
      if (!(d2 < c->reach2[i])) continue;
    }
    act[cnt++] = i;
  }
  c->act_n[p] = cnt;
}

/* The reverse lists: for every p, the i (ascending) whose first size(i)
 * neighbours contain p. size = NULL: all k. With a spatial order (perm[i'] =
 * i, rank[i] = i'), the lists are built in that order's indices: list rank[p]
 * holds the ranks of the neighbourhoods that contain p. */
static bsurf_status build_reverse(smooth_ctx *c, const int *size, const uint32_t *perm,
                                  const uint32_t *rank) {
  const size_t n = c->n;
  const int stride = c->nb->k;
  size_t *rev_off = bsurf_calloc_array(n + 1, sizeof(size_t));
  c->rev_off = rev_off;
  if (!rev_off) return BSURF_ERR_NOMEM;
  for (size_t r = 0; r < n; r++) {
    const size_t i = perm ? perm[r] : r;
    int kk = size ? size[i] : c->k;
    const uint32_t *idx = &c->nb->idx[i * (size_t)stride];
    for (int j = 0; j < kk; j++)
      rev_off[(rank ? rank[idx[j]] : idx[j]) + 1]++;
  }
  for (size_t p = 0; p < n; p++)
    rev_off[p + 1] += rev_off[p];
  uint32_t *rev = bsurf_alloc_array(rev_off[n] ? rev_off[n] : 1, sizeof(uint32_t));
  c->rev = rev;
  size_t *pos = bsurf_alloc_array(n ? n : 1, sizeof(size_t));
  if (!rev || !pos) {
    free(pos);
    return BSURF_ERR_NOMEM;
  }
  memcpy(pos, rev_off, n * sizeof(size_t));
  for (size_t r = 0; r < n; r++) {
    const size_t i = perm ? perm[r] : r;
    int kk = size ? size[i] : c->k;
    const uint32_t *idx = &c->nb->idx[i * (size_t)stride];
    for (int j = 0; j < kk; j++)
      rev[pos[rank ? rank[idx[j]] : idx[j]]++] = (uint32_t)r;
  }
  free(pos);
  return BSURF_OK;
}

/* ---- a spatially coherent order for the passes ------------------------ */
/* The passes read the positions of every point's neighbourhoods; in input
 * order (often random) each read is a cache miss, so they run in Morton
 * order (bsurf_spatial_order). */

/* a[r] = old a[perm[r]] for rows of `width` elements of `size` bytes */
static bsurf_status permute_rows(void **array, size_t n, size_t row_bytes, const uint32_t *perm) {
  unsigned char *src = *array, *dst = bsurf_alloc_array(n ? n : 1, row_bytes);
  if (!dst) return BSURF_ERR_NOMEM;
  for (size_t r = 0; r < n; r++)
    memcpy(dst + r * row_bytes, src + (size_t)perm[r] * row_bytes, row_bytes);
  free(src);
  *array = dst;
  return BSURF_OK;
}

/* Algorithm 4 step 3 in the thesis's order: for i = 1..N, the frame and fit
 * of neighbourhood i from the current positions, then Eq. 6.2 in place. */
static void bilateral_sequential(smooth_ctx *c) {
  bsurf_localfit *lf = &c->scr[0].lf;
  double *pred = c->scr[0].pred_full;
  double *w = c->scr[0].est_scratch; /* >= k doubles */
  const int k = c->k;
  for (size_t i = 0; i < c->n; i++) {
    const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
    const double e2 = c->e2[i];
    if (!(e2 <= GAUSS_CUT)) continue;
    bsurf_frame fr;
    bsurf_local_frame(c->out, idx, k, c->o.error.pca_center, &fr);
    bsurf_localfit_setup(lf, c->out, idx, k, &fr, c->degree);
    double coef[BSURF_TERMS_MAX];
    int d = solve_with_fallback(lf, c->degree, c->m, coef);
    bsurf_localfit_predict(lf, d, 1, coef, NULL, pred);
    double F[FIT_HEAD + BSURF_TERMS_MAX];
    if (c->o.guard) {
      fit_store(F, &fr, 1.0 / lf->scale, coef, c->m);
      guard_fit(c, &c->scr[0], GCOUNT(c, 0), c->out, idx, k, F, &d);
    }
    const double *z0 = &c->out[3 * (size_t)idx[0]];
    for (int j = 0; j < k; j++) {
      const double *z = &c->out[3 * (size_t)idx[j]];
      double dist = sqrt((z[0] - z0[0]) * (z[0] - z0[0]) + (z[1] - z0[1]) * (z[1] - z0[1]) +
                         (z[2] - z0[2]) * (z[2] - z0[2]));
      w[j] = weight_of(gauss_exponent(dist, c->h1) + e2);
    }
    for (int j = 0; j < k; j++) {
      if (w[j] < 0x1p-54) continue;
      double *z = &c->out[3 * (size_t)idx[j]];
      if (c->o.guard) { /* the guard's fit (or none: NAN) and its bound */
        double delta = fit_delta(F, d, c->m, z);
        if (isnan(delta)) continue;
        for (int t = 0; t < 3; t++)
          z[t] = (1.0 - w[j]) * z[t] + w[j] * (z[t] + delta * F[9 + t]);
        continue;
      }
      double delta = pred[j] - lf->z[j];
      for (int t = 0; t < 3; t++)
        z[t] = (1.0 - w[j]) * z[t] + w[j] * (z[t] + delta * fr.rot[2][t]);
    }
  }
}

/* One multipass pass in the thesis's order (in place, one thread). */
static void multipass_sequential_pass(smooth_ctx *c) {
  double *w = c->scr[0].est_scratch;
  for (size_t i = 0; i < c->n; i++) {
    const double e2 = c->e2[i];
    if (!(e2 <= GAUSS_CUT)) continue;
    const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
    const int kh = c->khat[i];
    const double *z0 = &c->out[3 * i];
    for (int j = 0; j < kh; j++) {
      const double *z = &c->out[3 * (size_t)idx[j]];
      double d2 = (z[0] - z0[0]) * (z[0] - z0[0]) + (z[1] - z0[1]) * (z[1] - z0[1]) +
                  (z[2] - z0[2]) * (z[2] - z0[2]);
      double e1 = d2 == 0 ? 0 : (c->inv_h1sq[i] > 0 ? d2 * c->inv_h1sq[i] : INFINITY);
      w[j] = weight_of(e1 + e2);
    }
    const double *F = &c->fits[i * (size_t)c->stride];
    for (int j = 0; j < kh; j++) {
      if (w[j] < 0x1p-54) continue;
      double *z = &c->out[3 * (size_t)idx[j]];
      double delta = fit_delta(F, c->fit_degree[i], c->m, z);
      if (isnan(delta)) continue;
      for (int t = 0; t < 3; t++)
        z[t] = (1.0 - w[j]) * z[t] + w[j] * (z[t] + delta * F[9 + t]);
    }
  }
}

static void ctx_init(smooth_ctx *c, const double *xyz, const bsurf_neighbors *nb,
                     const bsurf_smooth_options *o) {
  memset(c, 0, sizeof *c);
  c->xyz = xyz;
  c->nb = nb;
  c->n = nb ? nb->point_count : 0;
  c->k = o->error.k;
  c->degree = o->error.degree;
  c->m = bsurf_poly_terms(c->degree);
  c->stride = FIT_HEAD + c->m;
}

static void ctx_free(smooth_ctx *c, int T) {
  if (c->scr)
    for (int t = 0; t < T; t++)
      bsurf_error_scratch_free(&c->scr[t]);
  free(c->scr);
  free(c->fits);
  free(c->fit_degree);
  free(c->khat);
  free(c->dl);
  free(c->e2);
  free(c->w2);
  free(c->inv_h1sq);
  free((void *)c->rev_off);
  free((void *)c->rev);
  free(c->act);
  free(c->act_n);
  free(c->reach2);
  free(c->tmax);
  free(c->mp_point);
  free(c->act_off);
  free(c->mp_val);
  for (size_t r = 0; c->reg && r < c->nreg; r++) {
    free(c->reg[r].row);
    free(c->reg[r].off);
    free(c->reg[r].ctr);
    free(c->reg[r].fit);
  }
  free(c->reg);
  free(c->lmap);
  free(c->tb_pos);
  free(c->tb_step);
  free(c->gcount);
}

bsurf_status bsurf_smooth(const double *xyz, const bsurf_neighbors *nb,
                          const bsurf_smooth_options *opts, double *out_xyz,
                          bsurf_smooth_fields *fields, bsurf_smooth_report *report) {
  bsurf_smooth_options o = opts ? *opts : bsurf_smooth_options_default();
  if (report) memset(report, 0, sizeof *report);
  BSURF_REQUIRE(xyz, "xyz is NULL");
  BSURF_REQUIRE(out_xyz, "out_xyz is NULL");
  BSURF_REQUIRE(out_xyz != xyz, "out_xyz is xyz: the output may not alias the input");
  bsurf_status st = bsurf_error_check(&o.error, nb);
  if (st != BSURF_OK) return st;
  BSURF_REQUIRE(o.method >= BSURF_SMOOTH_NAIVE && o.method <= BSURF_SMOOTH_MULTIPASS,
                "method = %d: must be BSURF_SMOOTH_NAIVE, _BILATERAL or _MULTIPASS", (int)o.method);
  BSURF_REQUIRE(o.order == BSURF_ORDER_PARALLEL || o.order == BSURF_ORDER_SEQUENTIAL,
                "order = %d: must be BSURF_ORDER_PARALLEL or _SEQUENTIAL", (int)o.order);
  BSURF_REQUIRE((unsigned)o.estimator <= BSURF_SMOOTH_EST_632PLUS,
                "estimator = %d: must be BSURF_SMOOTH_EST_DEFAULT, _632 or _632PLUS",
                (int)o.estimator);
  BSURF_REQUIRE(!isnan(o.h1) && !isnan(o.h2) && !isnan(o.h2_fraction),
                "h1 = %g, h2 = %g, h2_fraction = %g: NaN is not allowed (<= 0 selects the default)",
                o.h1, o.h2, o.h2_fraction);
  BSURF_REQUIRE(!isnan(o.k_error) && !isnan(o.k_error_fraction),
                "k_error = %g, k_error_fraction = %g: NaN is not allowed", o.k_error,
                o.k_error_fraction);
  if (o.method == BSURF_SMOOTH_MULTIPASS) {
    BSURF_REQUIRE(o.a >= 0 && isfinite(o.a), "a = %g: must be finite and >= 0", o.a);
    BSURF_REQUIRE(o.iterations >= 0, "iterations = %d: must be >= 0", o.iterations);
    BSURF_REQUIRE(o.k_min >= 1 && o.k_min <= o.error.k, "k_min = %d: must be in [1, error.k = %d]",
                  o.k_min, o.error.k);
  }

  smooth_ctx c;
  ctx_init(&c, xyz, nb, &o);
  c.out = out_xyz;
  const size_t n = c.n;
  const int T = bsurf_threads_resolve(o.error.threads);
  const int seq = o.order == BSURF_ORDER_SEQUENTIAL;
  const int stages =
      o.method == BSURF_SMOOTH_NAIVE ? 1 : (o.method == BSURF_SMOOTH_BILATERAL ? 2 : 3);
  staged_progress sp = {o.error.progress, o.error.progress_user, 0, stages};
  o.error.progress = NULL;
  o.error.progress_user = NULL;

  double *own632 = NULL, *own632p = NULL, *own_moved = NULL;
  uint32_t *visit_owned = NULL;
  c.err_632 =
      fields && fields->err_632 ? fields->err_632 : (own632 = bsurf_alloc_array(n, sizeof(double)));
  c.err_632plus = fields && fields->err_632plus ? fields->err_632plus
                                                : (own632p = bsurf_alloc_array(n, sizeof(double)));
  c.scr = calloc((size_t)T, sizeof *c.scr);
  if (!c.err_632 || !c.err_632plus || !c.scr) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  for (int t = 0; t < T && st == BSURF_OK; t++)
    st = bsurf_error_scratch_alloc(&c.scr[t], c.k, o.error.bootstrap, c.degree);
  if (st != BSURF_OK) goto done;
  if (o.guard && !(c.gcount = bsurf_alloc_array((size_t)T * (size_t)c.k, sizeof(uint32_t)))) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  if ((o.method == BSURF_SMOOTH_BILATERAL && !seq) || o.method == BSURF_SMOOTH_MULTIPASS) {
    /* multipass: each fit also carries its point's e2, 1 / h1^2 and w2 (one
     * record per neighbourhood for the passes to read) */
    if (o.method == BSURF_SMOOTH_MULTIPASS) c.stride += MP_EXTRA;
    c.fits = bsurf_alloc_array(n * (size_t)c.stride, sizeof(double));
    c.fit_degree = bsurf_alloc_array(n, sizeof(int));
    if (!c.fits || !c.fit_degree) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
  }
  c.o = o;

  /* ---- stage 1: the bootstrap pass (Algorithm 4 step 1, Algorithm 5's
   * first loop) ---- */
  /* per-point stages visit the points in k-d tree order (cache locality;
   * each point writes only its own outputs, so no result depends on it) */
  const uint32_t *visit = bsurf_visit_order(nb, xyz, &visit_owned);
  if (!visit) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  st = bsurf_parallel_points_ordered(n, visit, T, boot_task, &c, staged_cb, &sp);
  if (st != BSURF_OK) goto done;
  if (report) {
    report->error.replicates_total = n * (size_t)o.error.bootstrap;
    for (int t = 0; t < T; t++) {
      report->error.replicates_skipped += c.scr[t].skipped;
      report->error.degree_reduced += c.scr[t].reduced;
      report->error.center_unestimated += c.scr[t].center_unestimated;
    }
  }
  c.W = bsurf_smooth_w_column(&o) ? c.err_632plus : c.err_632;
  double sumW = 0;
  for (size_t i = 0; i < n; i++)
    sumW += c.W[i];
  const double meanW = n ? sumW / (double)n : 0.0; /* |W| (Algorithm 4 step 2) */
  bsurf_smooth_options ro = o;
  bsurf_smooth_resolve(&ro, nb->h, meanW);
  c.h1 = ro.h1;
  c.h2 = ro.h2;
  if (report) {
    report->h = nb->h;
    report->mean_error = meanW;
  }

  if (o.method == BSURF_SMOOTH_NAIVE) {
    /* Eq. 6.1 only where W_i < threshold (6.2, Figs. 6.2-6.3) */
    double thr = ro.threshold;
    size_t projected = 0;
    for (size_t i = 0; i < n; i++)
      projected += naive_select(c.W[i], thr, &xyz[3 * i], &out_xyz[3 * i]);
    if (report) {
      report->threshold = thr;
      report->projected = projected;
    }
  } else if (o.method == BSURF_SMOOTH_BILATERAL) {
    c.e2 = bsurf_alloc_array(n, sizeof(double));
    c.w2 = bsurf_alloc_array(n, sizeof(double));
    if (!c.e2 || !c.w2) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    for (size_t i = 0; i < n; i++)
      set_theta2(&c, i, c.W[i]);
    c.inv_h1sq_global = 1.0 / (c.h1 * c.h1);
    sp.stage = 1;
    if (seq) {
      memcpy(out_xyz, xyz, n * 3 * sizeof(double));
      bilateral_sequential(&c);
      if (sp.fn && staged_cb(&sp, 1, 1)) st = BSURF_ERR_CANCELLED;
    } else {
      st = build_reverse(&c, NULL, NULL, NULL);
      if (st != BSURF_OK) goto done;
      c.cur = xyz;
      c.next = out_xyz;
      st = bsurf_parallel_points_ordered(n, visit, T, gather_bilateral_task, &c, staged_cb, &sp);
    }
    if (report) {
      report->h1 = c.h1;
      report->h2 = c.h2;
    }
  } else {
    /* ---- multipass: K_i, d_L and the fits, once ---- */
    /* 3 |W| by default (the thesis: |W|); errors below 1e-9 h are rounding, not noise, and their
     * ratios carry no information (exact data keeps K_i = K) */
    double kf = o.k_error_fraction > 0 ? o.k_error_fraction : 3.0;
    c.k_error = o.k_error > 0 ? o.k_error : fmax(kf * meanW, 1e-9 * nb->h);
    c.khat = bsurf_alloc_array(n, sizeof(int));
    c.dl = bsurf_alloc_array(n, sizeof(double));
    c.e2 = bsurf_alloc_array(n, sizeof(double));
    c.w2 = bsurf_alloc_array(n, sizeof(double));
    c.inv_h1sq = bsurf_alloc_array(n, sizeof(double));
    if (!c.khat || !c.dl || !c.e2 || !c.w2 || !c.inv_h1sq) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    sp.stage = 1;
    st = bsurf_parallel_points_ordered(n, visit, T, multipass_fit_task, &c, staged_cb, &sp);
    if (st != BSURF_OK) goto done;
    sp.stage = 2;
    double *buf = NULL, *pos = out_xyz;
    uint32_t *perm = NULL, *rank = NULL;
    memcpy(out_xyz, xyz, n * 3 * sizeof(double));
    /* the margin of the active pairs: a tenth of the mean spacing */
    const double margin = 0.1 * nb->h;
    double drift = INFINITY; /* how far points may have moved since the pairs were listed */
    if (!seq) {
      /* the passes run in a spatial order: every per-point array is permuted
       * (rank r holds point perm[r]) and the result is put back at the end */
      st = bsurf_spatial_order(xyz, n, &perm, &rank);
      if (st == BSURF_OK)
        st = permute_rows((void **)&c.fits, n, (size_t)c.stride * sizeof(double), perm);
      if (st == BSURF_OK) st = permute_rows((void **)&c.fit_degree, n, sizeof(int), perm);
      if (st == BSURF_OK) st = permute_rows((void **)&c.e2, n, sizeof(double), perm);
      if (st == BSURF_OK) st = permute_rows((void **)&c.w2, n, sizeof(double), perm);
      if (st == BSURF_OK) st = permute_rows((void **)&c.inv_h1sq, n, sizeof(double), perm);
      if (st == BSURF_OK) {
        pos = bsurf_alloc_array(n * 3, sizeof(double));
        if (!pos)
          st = BSURF_ERR_NOMEM;
        else
          for (size_t r = 0; r < n; r++)
            memcpy(&pos[3 * r], &xyz[3 * (size_t)perm[r]], 3 * sizeof(double));
      }
      if (st == BSURF_OK) st = build_reverse(&c, c.khat, perm, rank);
      buf = bsurf_alloc_array(n * 3, sizeof(double));
      c.act =
          bsurf_alloc_array(c.rev_off ? (c.rev_off[n] ? c.rev_off[n] : 1) : 1, sizeof(uint32_t));
      c.act_n = bsurf_alloc_array(n, sizeof(uint32_t));
      c.reach2 = bsurf_alloc_array(n, sizeof(double));
      c.tmax = bsurf_calloc_array((size_t)T * 8, sizeof(double));
      if (st == BSURF_OK && (!buf || !c.act || !c.act_n || !c.reach2 || !c.tmax))
        st = BSURF_ERR_NOMEM;
      if (st == BSURF_OK)
        for (size_t i = 0; i < n; i++) {
          /* theta_1 theta_2 >= 2^-54 needs d^2 / h1^2 <= GAUSS_CUT - e2 */
          double room = GAUSS_CUT - c.e2[i];
          double r = c.inv_h1sq[i] > 0 && room > 0 ? sqrt(room / c.inv_h1sq[i]) + 2 * margin : 0.0;
          c.reach2[i] = r * r;
        }
#ifdef MP_LANES
      if (st == BSURF_OK && c.m <= 10 && mp_blocks_on) {
        for (size_t p0 = 0; p0 < n; p0 += MP_BLOCK) {
          const size_t p1 = p0 + MP_BLOCK < n ? p0 + MP_BLOCK : n;
          if (c.rev_off[p1] - c.rev_off[p0] > c.mp_cap) c.mp_cap = c.rev_off[p1] - c.rev_off[p0];
        }
        c.mp_point = bsurf_alloc_array((size_t)T * (c.mp_cap ? c.mp_cap : 1), sizeof(uint32_t));
        c.mp_val = bsurf_alloc_array((size_t)T * 4 * (c.mp_cap ? c.mp_cap : 1), sizeof(double));
        c.act_off = bsurf_alloc_array(n + 1, sizeof(size_t));
        if (!c.mp_point || !c.mp_val || !c.act_off) st = BSURF_ERR_NOMEM;
        if (st == BSURF_OK && mp_tblock_passes > 1 && o.iterations > 1) {
          c.tb_S = mp_tblock_passes;
          c.nreg = (n + MP_REGION - 1) / MP_REGION;
          c.reg = bsurf_calloc_array(c.nreg ? c.nreg : 1, sizeof *c.reg);
          c.lmap = bsurf_alloc_array((size_t)T * (n ? n : 1), sizeof(uint32_t));
          c.tb_step = bsurf_alloc_array((size_t)T * MP_TSTRIDE, sizeof(double));
          if (!c.reg || !c.lmap || !c.tb_step)
            st = BSURF_ERR_NOMEM;
          else
            memset(c.lmap, 0xff, (size_t)T * n * sizeof(uint32_t));
        }
      }
#endif
    }
    int it = 0;
    double *from = pos, *to = buf; /* the passes read from and write to; swapped after each */
    double last = INFINITY;        /* the largest move of the last pass (none yet) */
    while (st == BSURF_OK && it < o.iterations) {
      int s = 1; /* passes done in this round */
      if (seq) {
        multipass_sequential_pass(&c);
      } else {
        c.cur = from;
        c.next = to;
        if (drift > margin) {
          st = bsurf_parallel_sweep(n, T, active_task, &c);
          drift = 0;
          if (c.act_off) {
            /* the lists side by side, for the block passes: each moves down
             * (its start is at most its slot range's) */
            size_t off = 0;
            for (size_t p = 0; p < n; p++) {
              c.act_off[p] = off;
              memmove(&c.act[off], &c.act[c.rev_off[p]], c.act_n[p] * sizeof(uint32_t));
              off += c.act_n[p];
            }
            c.act_off[n] = off;
          }
          if (st == BSURF_OK && c.reg) st = mp_regions_build(&c, T);
        }
        /* a time block of tb passes: only as long as every point is
         * expected to stay within the margin until its last pass starts (at
         * most tb - 1 more moves of 1.5 times the last pass's largest);
         * else pass by pass, up to the rebuild */
        int tb = c.reg ? (o.iterations - it < c.tb_max ? o.iterations - it : c.tb_max) : 1;
        while (tb > 1 && !(drift + (tb - 1) * 1.5 * last <= margin))
          tb--;
        if (st == BSURF_OK && tb > 1) {
          c.tb_s = tb;
          for (int t = 0; t < T; t++)
            for (int j = 0; j < tb; j++)
              c.tb_step[(size_t)t * MP_TSTRIDE + (size_t)j] = 0;
          st = bsurf_parallel_sweep_chunk(c.nreg, T, 1, mp_tblock_task, &c);
          /* the lists held every weighted pair if no pass of the block
           * started beyond the margin */
          double d = drift, mx = 0;
          int ok = 1;
          for (int j = 0; j < tb && st == BSURF_OK; j++) {
            double m = 0;
            for (int t = 0; t < T; t++)
              if (c.tb_step[(size_t)t * MP_TSTRIDE + (size_t)j] > m)
                m = c.tb_step[(size_t)t * MP_TSTRIDE + (size_t)j];
            if (d > margin) ok = 0;
            d += sqrt(m);
            if (m > mx) mx = m;
          }
          last = sqrt(mx);
          if (!ok) { /* discarded: run again after a rebuild, in fewer passes */
            drift = INFINITY;
            continue;
          }
          drift = d;
          s = tb;
        } else if (st == BSURF_OK) {
          for (int t = 0; t < T; t++)
            c.tmax[8 * t] = 0;
#ifdef MP_LANES
          if (c.mp_point)
            st = bsurf_parallel_sweep_chunk((n + MP_BLOCK - 1) / MP_BLOCK, T, 16,
                                            gather_multipass_block, &c);
          else
#endif
            st = bsurf_parallel_sweep(n, T, gather_multipass_task, &c);
          double mx = 0;
          for (int t = 0; t < T; t++)
            if (c.tmax[8 * t] > mx) mx = c.tmax[8 * t];
          last = sqrt(mx);
          drift += last;
        }
        double *t = from;
        from = to;
        to = t;
      }
      it += s;
      if (st == BSURF_OK && sp.fn && staged_cb(&sp, (size_t)it, (size_t)o.iterations))
        st = BSURF_ERR_CANCELLED;
    }
    if (st == BSURF_OK && !seq) {
      for (size_t r = 0; r < n; r++)
        memcpy(&out_xyz[3 * (size_t)perm[r]], &from[3 * r], 3 * sizeof(double));
    }
    free(buf);
    if (pos != out_xyz) free(pos);
    free(perm);
    free(rank);
    if (st != BSURF_OK) goto done;
    if (report) {
      report->h1 = 0;
      report->h2 = c.h2;
      report->k_error = c.k_error;
      report->iterations = it;
    }
    if (fields && fields->k_hat)
      for (size_t i = 0; i < n; i++)
        fields->k_hat[i] = c.khat[i];
    if (fields && fields->d_local) memcpy(fields->d_local, c.dl, n * sizeof(double));
  }
  if (st != BSURF_OK) goto done;

  /* ---- how far the points moved ---- */
  {
    double *moved = fields && fields->moved ? fields->moved
                                            : (own_moved = bsurf_alloc_array(n, sizeof(double)));
    if (!moved) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    double sum = 0, mx = 0;
    size_t count = 0;
    for (size_t i = 0; i < n; i++) {
      double d = moved_of(&xyz[3 * i], &out_xyz[3 * i]);
      moved[i] = d;
      sum += d;
      if (d > mx) mx = d;
      count += d > 0;
    }
    if (report) {
      report->moved_points = count;
      report->moved_mean = n ? sum / (double)n : 0;
      report->moved_max = mx;
    }
  }

done:
  ctx_free(&c, T);
  free(own632);
  free(own632p);
  free(own_moved);
  free(visit_owned);
  return st;
}

/* ---- tiled smoothing: the two stages (src/tile/tiles.c, docs/scaling.md) ----
 * bsurf_smooth above is stage 1 (boot_task at every point), the mean |W|
 * (an index-order sum) and stage 2 (naive_select, or gather_update over the
 * reverse neighbourhoods). A tiled run makes the same calls on pieces: stage 1
 * per tile, |W| summed in index order from the values kept by the engine,
 * stage 2 per tile (bilateral: with the reverse neighbours' stage 1 values)
 * or per range of points (naive). Sequential order and multipass are not
 * offered: the sweep makes each fit depend on the moves of every earlier
 * neighbourhood of the whole cloud (a chain as long as the cloud), and the
 * multipass runs `iterations` passes, each one ring further. */

size_t bsurf_smooth_stage_values(const bsurf_smooth_options *o) {
  if (!o || o->method == BSURF_SMOOTH_MULTIPASS) return 0;
  if (o->method == BSURF_SMOOTH_NAIVE) return 2 + 3;
  if (o->order != BSURF_ORDER_PARALLEL) return 0;
  return 2 + FIT_HEAD + (size_t)bsurf_poly_terms(o->error.degree);
}

int bsurf_smooth_w_column(const bsurf_smooth_options *o) {
  bsurf_smooth_estimator est = o->estimator;
  if (est == BSURF_SMOOTH_EST_DEFAULT)
    est = o->method == BSURF_SMOOTH_NAIVE ? BSURF_SMOOTH_EST_632PLUS : BSURF_SMOOTH_EST_632;
  return est == BSURF_SMOOTH_EST_632PLUS;
}

void bsurf_smooth_resolve(bsurf_smooth_options *o, double h, double mean_w) {
  /* h2 default: 2 |W|. Bilateral: the thesis shows 0.5-1 |W| (Figs.
   * 6.4-6.6), but on fandisk and the cube at noise 0.25 and 0.5 the distance
   * to the true surface keeps falling up to about 2 |W|, feature points
   * included. Multipass: the thesis's 0.3 |W| (6.4.1) gives a point at the
   * mean error theta_2 = e^-11 per pass, so 300 passes move it 0.5% of the
   * way to its fit (docs/smoothing.md, "Why the thesis's multipass barely
   * moves points") */
  double frac = o->h2_fraction > 0 ? o->h2_fraction : 2.0;
  o->h1 = o->h1 > 0 ? o->h1 : h;
  o->h2 = o->h2 > 0 ? o->h2 : frac * mean_w;
  /* naive: Eq. 6.1 only where W_i < threshold (6.2, Figs. 6.2-6.3) */
  if (isnan(o->threshold)) o->threshold = mean_w;
}

bsurf_status bsurf_smooth_stage1(const double *xyz, const bsurf_neighbors *nb,
                                 const bsurf_smooth_options *opts, double *values,
                                 bsurf_error_report *report) {
  if (report) memset(report, 0, sizeof *report);
  const size_t nv = bsurf_smooth_stage_values(opts);
  BSURF_REQUIRE(xyz && values, "xyz or values is NULL");
  BSURF_REQUIRE(nv, "method %d in order %d is not tiled (stage values 0)",
                opts ? (int)opts->method : -1, opts ? (int)opts->order : -1);
  bsurf_smooth_options o = *opts;
  bsurf_status st = bsurf_error_check(&o.error, nb);
  if (st != BSURF_OK) return st;
  smooth_ctx c;
  ctx_init(&c, xyz, nb, &o);
  o.error.progress = NULL;
  c.o = o;
  const size_t n = c.n;
  const int T = bsurf_threads_resolve(o.error.threads);
  c.err_632 = bsurf_alloc_array(n, sizeof(double));
  c.err_632plus = bsurf_alloc_array(n, sizeof(double));
  c.scr = calloc((size_t)T, sizeof *c.scr);
  if (o.method == BSURF_SMOOTH_NAIVE)
    c.out = bsurf_alloc_array(n, 3 * sizeof(double));
  else
    c.fits = bsurf_alloc_array(n, (size_t)c.stride * sizeof(double));
  if (o.guard) c.gcount = bsurf_alloc_array((size_t)T * (size_t)c.k, sizeof(uint32_t));
  if (!c.err_632 || !c.err_632plus || !c.scr || !(c.out || c.fits) || (o.guard && !c.gcount))
    st = BSURF_ERR_NOMEM;
  for (int t = 0; t < T && st == BSURF_OK; t++)
    st = bsurf_error_scratch_alloc(&c.scr[t], c.k, o.error.bootstrap, c.degree);
  if (st == BSURF_OK) st = bsurf_parallel_sweep(n, T, boot_task, &c);
  if (st == BSURF_OK) {
    const double *rest = c.out ? c.out : c.fits;
    const size_t w = nv - 2;
    for (size_t i = 0; i < n; i++) {
      values[i * nv] = c.err_632[i];
      values[i * nv + 1] = c.err_632plus[i];
      memcpy(&values[i * nv + 2], &rest[i * w], w * sizeof(double));
    }
    if (report) {
      report->replicates_total = n * (size_t)o.error.bootstrap;
      for (int t = 0; t < T; t++) {
        report->replicates_skipped += c.scr[t].skipped;
        report->degree_reduced += c.scr[t].reduced;
        report->center_unestimated += c.scr[t].center_unestimated;
      }
    }
  }
  free(c.err_632);
  free(c.err_632plus);
  free(c.out);
  ctx_free(&c, c.scr ? T : 0);
  return st;
}

bsurf_status bsurf_smooth_stage2(const double *xyz, size_t local_count, const double *values,
                                 size_t count, const uint32_t *point, const size_t *rev_off,
                                 const uint32_t *rev, const bsurf_smooth_options *o,
                                 double *out_xyz, double *moved) {
  const size_t nv = bsurf_smooth_stage_values(o);
  BSURF_REQUIRE(xyz && values && o && out_xyz && moved,
                "xyz, values, opts, out_xyz or moved is NULL");
  BSURF_REQUIRE(nv, "method %d in order %d is not tiled (stage values 0)", (int)o->method,
                (int)o->order);
  BSURF_REQUIRE(o->method != BSURF_SMOOTH_BILATERAL || rev_off,
                "rev_off is NULL (bilateral needs it)");
  const int wc = bsurf_smooth_w_column(o);
  bsurf_status st = BSURF_OK;
  if (o->method == BSURF_SMOOTH_NAIVE) {
    for (size_t r = 0; r < count; r++) {
      const size_t p = point ? point[r] : r;
      const double *v = &values[p * nv];
      memcpy(&out_xyz[3 * r], &v[2], 3 * sizeof(double));
      naive_select(v[wc], o->threshold, &xyz[3 * p], &out_xyz[3 * r]);
    }
  } else {
    smooth_ctx c;
    ctx_init(&c, xyz, NULL, o);
    c.n = count;
    c.stride = (int)nv;
    c.fits = (double *)values + 2; /* read only */
    c.h1 = o->h1;
    c.h2 = o->h2;
    c.inv_h1sq_global = 1.0 / (c.h1 * c.h1);
    c.rev_off = rev_off;
    c.rev = rev;
    c.self = point;
    c.cur = xyz;
    c.next = out_xyz;
    c.e2 = bsurf_alloc_array(local_count ? local_count : 1, sizeof(double));
    c.w2 = bsurf_alloc_array(local_count ? local_count : 1, sizeof(double));
    if (!c.e2 || !c.w2) st = BSURF_ERR_NOMEM;
    for (size_t i = 0; i < local_count && st == BSURF_OK; i++)
      set_theta2(&c, i, values[i * nv + (size_t)wc]);
    if (st == BSURF_OK)
      st = bsurf_parallel_sweep(count, bsurf_threads_resolve(o->error.threads),
                                gather_bilateral_task, &c);
    c.fits = NULL;
    c.rev_off = NULL;
    c.rev = NULL;
    ctx_free(&c, 0);
  }
  for (size_t r = 0; r < count && st == BSURF_OK; r++)
    moved[r] = moved_of(&xyz[3 * (point ? (size_t)point[r] : r)], &out_xyz[3 * r]);
  return st;
}
