/* The MSE rule's noise passes (docs/normals.md, "Choosing K"; the
 * derivation at the top of kselect.c, "Noise s2"): the residual variance
 * of a local quadric per point at a scale chosen per point (the truncation
 * rule, then Lepski's method over the nested scales, below) and the
 * Richardson extrapolation of its misfit, pooled as the lower quartile
 * over the K_max neighbours, then (BSURF_NOISE_POOL_GLOBAL) as the median
 * over the cloud; where the K_max neighbours are section-sampled (a CAD
 * mesh's vertices on rings, the noise within each ring's plane: below), the
 * noise read by a conic within the cross-section's plane instead. */
#include "algo/kselect.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The noise's pooling: the lower quartile of the neighbours' estimates,
 * each divided by the lower quartile of chi^2_nu / nu (see the top of the
 * file); Z_Q is the standard normal's quartile. */
#define POOL_Q 0.25
#define Z_Q (-0.6744897501960817)

/* the POOL_Q quantile of chi^2_nu / nu (Wilson-Hilferty) */
static double chi2_quantile_ratio(int nu) {
  return bsurf_chi2_ratio_wh(nu, Z_Q);
}

/* Pass 1: the residual variance of a quadric on the point's K nearest
 * neighbours, in their own PCA frame, at a scale K chosen per point among
 * the nested scales noise_k < K_1 < K_2 < ... (the candidates above
 * noise_k). Stored divided by the lower quartile of chi^2_nu / nu, for the
 * quartile pooling of pass 2.
 *
 * The scale. The residual variance v_K reads sigma^2 only where the
 * quadric holds and the ball holds the noise: too small a ball truncates
 * the heights (v_K low), too large a one holds the surface's misfit (v_K
 * high, growing with K). So:
 *  - Truncation. A scale whose K-th neighbour lies less than TRUNC
 *    residual standard deviations away, R_K^2 < TRUNC^2 v_K, is truncated
 *    (see the top of the file): no estimate of sigma^2.
 *  - Lepski's method (Lepski, Mammen & Spokoiny 1997, Ann. Statist. 25;
 *    the intersection of confidence intervals of Goldenshluger & Nemirovski
 *    1997 and Katkovnik 1999): the scales are taken in increasing order,
 *    and the point keeps the largest scale K whose estimate agrees with
 *    every smaller untruncated scale j's; the first that does not holds
 *    structure the smaller ones did not (misfit), and so does every larger
 *    one (nested). Agreement is tested on the log scale, where chi^2_nu /
 *    nu has the variance 2 / nu whatever sigma (the variance-stabilising
 *    transform of a sample variance, Bartlett & Kendall 1946), and the
 *    nested samples make Var(ln v_j - ln v_K) = 2 / nu_j - 2 / nu_K (the
 *    larger sample's estimate is the efficient one: the Hausman identity
 *    of kselect.c's drift): K is rejected when
 *        ln(v_K / v_j) > z sqrt(2 / nu_j - 2 / nu_K),
 *    z the lack-of-fit tests' level (kselect_lof.c, 5% over the
 *    candidates, Bonferroni). A fall is not tested: misfit only adds
 *    to the residual variance as K grows.
 *  - Every accepted smaller scale j constrains K (each passed its own
 *    truncation test, R_j^2 >= TRUNC^2 v_j), except where its PCA plane is
 *    thinner than K's level allows a surface's (ksel_thin_plane,
 *    kselect_lof.c: the neighbours lie in a plane that holds the noise,
 *    ring-sampled CAD vertices, and read no noise). A further condition
 *    that j could have read K's level, R_j^2 >= TRUNC^2 v_K, was measured
 *    and dropped: it lets the statistic under test choose its own
 *    witnesses, so the larger K's rise (the more misfit), the fewer smaller
 *    scales test it (elephant's vertices at g0.6: 1.083 times the best
 *    fixed K's mean angle error with it, 1.036 without; docs/normals.md,
 *    "The noise fit's scale per point").
 * Where no scale is untruncated, the largest (the truncation rule's
 * stop at K_max), its residual variance read as the share of the noise its
 * ball keeps (quad_estimate, bsurf_ball_noise). */
#define TRUNC 5.0
/* the residual variance of a quadric on the first K neighbours in their own
 * PCA frame, the mean sixth power of their tangential distances (the scale
 * of a cubic's misfit) and (fo non-NULL) the frame, with (sco) the scale of
 * the local coordinates left in s->u, s->v; -1 when rank-deficient */
static int quad_resid(const double *xyz, const uint32_t *idx, int K, ksel_scratch *s, double *var,
                      double *m6, bsurf_frame *fo, double *sco) {
  bsurf_frame f;
  const double sc = local_coords(xyz, idx, K, K, &f, s->u, s->v, s->z);
  if (fo) *fo = f;
  if (sco) *sco = sc;
  quad_sums q;
  memset(&q, 0, sizeof q);
  double r6 = 0;
  for (int j = 0; j < K; j++) {
    quad_add(&q, s->u[j], s->v[j], s->z[j]);
    const double r2 = s->u[j] * s->u[j] + s->v[j] * s->v[j];
    r6 += r2 * r2 * r2;
  }
  double coef[QT], rss;
  if (quad_solve(&q, coef, &rss, NULL) != 0) return -1;
  *var = rss / (K - QT);
  *m6 = r6 / K * sc * sc * sc * sc * sc * sc;
  return 0;
}

int bsurf_ksel_quad_variance(const double *xyz, const uint32_t *idx, int K, double *work,
                             double *var) {
  ksel_scratch s;
  memset(&s, 0, sizeof s);
  s.u = work;
  s.v = work + K;
  s.z = work + 2 * (size_t)K;
  double m6;
  return quad_resid(xyz, idx, K, &s, var, &m6, NULL, NULL);
}

/* The noise within a cross-section's plane (docs/normals.md, "The noise
 * within a cross-section's plane"). A CAD mesh's vertices often lie on
 * rings, cross-sections of the surface that hold its normal; displaced
 * along the normal, the noise stays within each ring's plane, so a point's
 * noise_k nearest (one ring's arc) lie in a plane with no noise across it:
 * the quadric's heights read none at any scale below the ring spacing, and
 * misfit above it. The noise is read instead by an implicit conic fitted
 * to the points' coordinates in the plane of their first two PCA axes:
 * Taubin's fit (Taubin 1991, IEEE PAMI 13(11), Eq. 3.6-3.9: the algebraic
 * residuals' sum of squares over that of their gradients, the constant
 * eliminated, a 5 x 5 generalised eigenproblem), whose geometric residuals
 * f / |grad f| (Sampson's first-order distances) give
 *     s2c = sum r^2 / (K - 5).
 * A point is section-sampled where three tests hold, each at SECT_ALPHA:
 *  - thin: its plane is thinner than the conic's noise allows, s3 =
 *    K l3 / (K - 3) < s2c F_alpha(K - 3, K - 5) (the lower tail; the two
 *    are independent residual variances of the same noise where the plane
 *    is a surface patch's: docs/normals.md, "Planes thinner than the
 *    noise");
 *  - curve: the conic explains the in-plane spread better than a line,
 *    the nested models' F test: ((K l2 - (K - 5) s2c) / 3) / s2c >
 *    F_{1-alpha}(3, K - 5) (the line's residual sum of squares K l2, two
 *    parameters against the conic's five);
 *  - section: the plane holds the surface's normal: its normal is nearer
 *    perpendicular to the PCA normal of the K_max neighbours (beyond the
 *    rings) than parallel to it, |n . N| < 1 / sqrt(2) -- the nearer of the
 *    two hypotheses (a patch of surface: n = N; a cross-section: n . N =
 *    0), at equal angular distance (ksel_same_plane, kselect_lof.c). A
 *    patch of scattered points under light noise passes the first two (a
 *    conic through them leaves misfit for s2c) and fails this one.
 * The estimate stands only where the point's quadric estimate is
 * significantly below it (noise_point). Pass 2 uses the conic's estimate
 * where the neighbourhood is section-sampled and its quadric level again
 * significantly below (pool_point). */
#define SECT_ALPHA 0.05 /* each test's level */
#define CT 5            /* the conic's terms u^2, uv, v^2, u, v (the constant eliminated) */

/* Taubin's conic through the K points (u, v) (scaled coordinates): its
 * geometric residual variance in the scaled units, sum r^2 / (K - 5);
 * -1 where the fit is degenerate */
static int conic_resid(const double *u, const double *v, int K, double *s2c) {
  double M[CT + 1][CT + 1] = {{0}}, N[CT][CT] = {{0}};
  for (int j = 0; j < K; j++) {
    const double x = u[j], y = v[j];
    const double z[CT + 1] = {x * x, x * y, y * y, x, y, 1.0};
    const double gx[CT] = {2 * x, y, 0, 1, 0}, gy[CT] = {0, x, 2 * y, 0, 1};
    for (int a = 0; a <= CT; a++)
      for (int b = a; b <= CT; b++)
        M[a][b] += z[a] * z[b];
    for (int a = 0; a < CT; a++)
      for (int b = a; b < CT; b++)
        N[a][b] += gx[a] * gx[b] + gy[a] * gy[b];
  }
  /* the constant's optimum f0 = -m . a / M00 eliminated: Mr = M - m m^T / K */
  double Mr[CT][CT], Np[CT * (CT + 1) / 2];
  for (int a = 0; a < CT; a++)
    for (int b = a; b < CT; b++) {
      Mr[a][b] = Mr[b][a] = M[a][b] - M[a][CT] * M[b][CT] / M[CT][CT];
      Np[bsurf_packed_index(a, b)] = N[a][b];
    }
  /* N = L D L^T (the fits' factorisation, local.h; rank-deficient: -1);
   * Mr a = l N a becomes S y = l y, S = D^-1/2 L^-1 Mr L^-T D^-1/2, and
   * a = L^-T D^-1/2 y */
  bsurf_ldl f;
  if (bsurf_ldl_factor_packed(CT, Np, BSURF_RANK_TOL, &f) != 0) return -1;
  const double *L = f.L;
  double W[CT][CT], S[CT * CT], ev[CT], vec[CT * CT], rd[CT];
  for (int a = 0; a < CT; a++)
    rd[a] = sqrt(f.inv[a]);
  for (int c = 0; c < CT; c++) /* W = L^-1 Mr, column by column */
    for (int a = 0; a < CT; a++) {
      double t = Mr[a][c];
      for (int k = 0; k < a; k++)
        t -= L[a * CT + k] * W[k][c];
      W[a][c] = t;
    }
  for (int r = 0; r < CT; r++) /* L^-1 W^T (Mr symmetric), row r of W */
    for (int a = 0; a < CT; a++) {
      double t = W[r][a];
      for (int k = 0; k < a; k++)
        t -= L[a * CT + k] * S[r * CT + k];
      S[r * CT + a] = t;
    }
  for (int a = 0; a < CT; a++) /* D^-1/2 on both sides, symmetric up to rounding */
    for (int b = a; b < CT; b++)
      S[a * CT + b] = S[b * CT + a] = 0.5 * (S[a * CT + b] + S[b * CT + a]) * rd[a] * rd[b];
  bsurf_eigen_sym(CT, S, ev, vec);
  double co[CT + 1]; /* a = L^-T D^-1/2 y for the smallest eigenvalue */
  for (int a = CT - 1; a >= 0; a--) {
    double t = vec[a] * rd[a];
    for (int k = a + 1; k < CT; k++)
      t -= L[k * CT + a] * co[k];
    co[a] = t;
  }
  co[CT] = 0;
  for (int a = 0; a < CT; a++)
    co[CT] -= M[a][CT] * co[a] / M[CT][CT];
  double rss = 0;
  for (int j = 0; j < K; j++) {
    const double x = u[j], y = v[j];
    const double f = co[0] * x * x + co[1] * x * y + co[2] * y * y + co[3] * x + co[4] * y + co[5];
    const double fx = 2 * co[0] * x + co[1] * y + co[3], fy = co[1] * x + 2 * co[2] * y + co[4];
    const double g2 = fx * fx + fy * fy;
    if (!(g2 > 0)) return -1;
    rss += f * f / g2;
  }
  *s2c = rss / (K - CT);
  return isfinite(*s2c) ? 0 : -1;
}

/* Point i's conic residual variance s2c (above, uncorrected), or NAN where
 * the noise_k points are not section-sampled: f the noise_k frame, sc its
 * coordinates' scale (the points in s->u, s->v) */
static double section_noise(const ksel_ctx *c, const uint32_t *idx, int K, const bsurf_frame *f,
                            double sc, const ksel_scratch *s) {
  double s2c;
  if (K <= CT + 1 || conic_resid(s->u, s->v, K, &s2c) != 0) return NAN;
  s2c *= sc * sc;
  const double s3 = K * f->eigenvalues[0] / (K - 3), l2 = f->eigenvalues[1];
  if (!(s2c > 0) || !(s3 < s2c * c->sect.thin)) return NAN;
  if (!((K * l2 - (K - CT) * s2c) / (3.0 * s2c) > c->sect.curve)) return NAN;
  bsurf_frame F;
  bsurf_local_frame(c->xyz, idx, c->kmax, BSURF_PCA_CENTROID, &F);
  if (ksel_same_plane(f->rot[2], F.rot[2])) return NAN;
  return s2c;
}

/* Whether scale K's estimate v rose beyond what the m accepted smaller
 * scales allow (Lepski's test above); sc holds, per accepted scale, K, v,
 * l3 and R^2. */
static int rose(const double *sc, int m, int K, double v, double z) {
  for (int t = 0; t < m; t++) {
    const double *j = &sc[4 * t];
    const int Kj = (int)j[0];
    if (ksel_thin_plane(Kj, j[2], j[3], v, z)) continue;
    if (log(v / j[1]) > z * sqrt(2.0 * (1.0 / (Kj - QT) - 1.0 / (K - QT)))) return 1;
  }
  return 0;
}

/* Pass 1 at one point: out[0] the quadric's estimate (above; NAN: none),
 * *s2c the noise_k points' cross-section residual variance (NAN: not
 * section-sampled) */
static void quad_estimate(ksel_ctx *c, ksel_scratch *s, const uint32_t *idx, double *out,
                          double *s2c) {
  const bsurf_kselect_options *o = c->o;
  const double *d = &c->xyz[3 * (size_t)idx[0]];
  out[0] = *s2c = NAN;
  int ka = 0, m = 0; /* the kept scale; the untruncated scales accepted */
  double va = 0, m6a = 0, R2a = 0;
  for (int a = -1; a < o->nk; a++) {
    const int K = a < 0 ? o->noise_k : o->ks[a];
    if (a >= 0 && K <= o->noise_k) continue;
    double v, m6, sc;
    bsurf_frame f;
    if (quad_resid(c->xyz, idx, K, s, &v, &m6, &f, &sc) != 0) continue;
    if (a < 0) *s2c = section_noise(c, idx, K, &f, sc, s);
    const double *p = &c->xyz[3 * (size_t)idx[K - 1]];
    const double R2 = (p[0] - d[0]) * (p[0] - d[0]) + (p[1] - d[1]) * (p[1] - d[1]) +
                      (p[2] - d[2]) * (p[2] - d[2]);
    if (R2 < TRUNC * TRUNC * v) { /* truncated: kept only until a scale is not */
      if (!m) ka = K, va = v, m6a = m6, R2a = R2;
      continue;
    }
    if (rose(s->scales, m, K, v, c->lof_z)) break; /* misfit from K on */
    double *e = &s->scales[4 * m++];
    e[0] = K, e[1] = v, e[2] = f.eigenvalues[0], e[3] = R2;
    ka = K, va = v, m6a = m6;
  }
  if (!ka) return;
  if (!m) {
    /* every scale truncated (noise heavy against the K_max ball): the
     * largest's residual variance is what its ball keeps of the noise, a
     * share kappa(R / sigma) (ball_scale.c: the smoothing guard's model of
     * the heights a K-ball holds), so the noise is the variance that keeps
     * it; no misfit is extrapolated from a truncated scale. The quartile
     * correction follows the inversion, as for every other estimate here;
     * the inversion is not linear in v, and the other order (v corrected
     * first) reads 1.030 of sigma on test_kselect_noise's plane at 3 h
     * against this order's 1.005 (measured, not benchmarked on the sets) */
    out[0] = bsurf_ball_noise(va, sqrt(R2a)) / chi2_quantile_ratio(ka - QT);
    return;
  }
  out[0] = va / chi2_quantile_ratio(ka - QT);
  /* Richardson extrapolation of the quadric's misfit (see the top of the
   * file): a second fit on twice the points, the misfit's share removed */
  const int kb = 2 * ka < c->kmax ? 2 * ka : c->kmax;
  if (kb <= ka + QT) return;
  double vb, m6b;
  if (quad_resid(c->xyz, idx, kb, s, &vb, &m6b, NULL, NULL) != 0 || !(m6b > m6a)) return;
  const double e = (va * m6b - vb * m6a) / (m6b - m6a);
  /* degenerate: the residual variance grew from ka to kb points faster
   * than the misfit's sixth-power law allows with no noise at all (the
   * doubled neighbourhood crosses an edge or wraps round a thin part), so
   * the extrapolation says nothing about the noise: no estimate, as for a
   * rank-deficient fit (formerly clamped to 0, which the lower-quartile
   * pool then picked) */
  if (!(e > 0)) {
    out[0] = NAN;
    return;
  }
  /* the extrapolated estimate e = w va - (w - 1) vb, w = m6b / (m6b - m6a),
   * scatters more than va: with Var(v) = 2 s2^2 / nu and, the samples
   * nested, Cov(va, vb) = Var(vb), Var(e) = 2 s2^2 (w^2 / nu_a + (1 - w^2)
   * / nu_b); its quartile is that of chi^2 / nu at Satterthwaite's
   * effective degrees of freedom nu = 2 s2^2 / Var(e) */
  const double w = m6b / (m6b - m6a), na = ka - QT, nb = kb - QT;
  const double nu = 1.0 / (w * w / na + (1.0 - w * w) / nb);
  out[0] = (e < va ? e : va) / bsurf_chi2_ratio_wh(nu, Z_Q);
}

void noise_point(void *vctx, int thread, size_t i) {
  ksel_ctx *c = vctx;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  double *out = &c->s2[2 * i], s2c;
  quad_estimate(c, &c->scr[thread], idx, out, &s2c);
  /* the cross-section estimate stands only where the quadric's reads
   * significantly less noise than it, the variance ratio's lower 5% tail
   * (two estimates of the same noise where both models hold, each
   * corrected to its quartile), as where the quadric's heights lie within
   * a section and read none, or its misfit's extrapolation takes all it
   * read. Where the quadric reached across the sections (rows of a plane,
   * dense rings of a cylinder) it read the noise, and the conic -- poorly
   * determined on nearly straight rows, its curve test then passing more
   * often than its level, and its s2c low among those that pass -- is not
   * needed (docs/normals.md, Cross-sections) */
  out[1] = NAN;
  if (isnan(s2c)) return;
  const double conic = s2c / c->sect.q;
  if (isnan(out[0]) || out[0] < conic * c->sect.below) out[1] = conic;
}

/* The section test alone: a superset of the points whose pass 1 keeps a
 * cross-section estimate (noise_point keeps section_noise's value only
 * where the quadric's estimate is also significantly below it, and
 * quad_estimate computes it from these same coordinates), and so, counted
 * over the K_max neighbours as pool_point counts, a superset of the points
 * pass 2 gives a cross-section level. */
void section_point(void *vctx, int thread, size_t i) {
  ksel_ctx *c = vctx;
  ksel_scratch *s = &c->scr[thread];
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  const int K = c->o->noise_k;
  bsurf_frame f;
  const double sc = local_coords(c->xyz, idx, K, K, &f, s->u, s->v, s->z);
  c->s2[2 * i] = NAN;
  c->s2[2 * i + 1] = section_noise(c, idx, K, &f, sc, s);
}

void section_flag_point(void *vctx, int thread, size_t i) {
  (void)thread;
  ksel_ctx *c = vctx;
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  int m = 0;
  for (int j = 0; j < c->kmax; j++)
    m += !isnan(c->s2[2 * (size_t)idx[j] + 1]);
  c->noise[i] = m >= c->sect.count;
}

/* The lower quartile of m values (pool_point): the order statistic nearest
 * the quartile, interpolated; the lo-th smallest by selection, the next the
 * smallest above it (the values of a full sort). */
static double lower_quartile(double *pool, int m) {
  const double r = POOL_Q * (m - 1);
  const int lo = (int)r;
  const double vlo = bsurf_kth_smallest(pool, (size_t)m, (size_t)lo);
  double vhi = vlo;
  if (lo + 1 < m) {
    vhi = pool[lo + 1];
    for (int j = lo + 2; j < m; j++)
      vhi = pool[j] < vhi ? pool[j] : vhi;
  }
  return lo + 1 < m ? vlo + (r - lo) * (vhi - vlo) : vlo;
}

/* The fewest section-sampled points among n neighbours that say the
 * neighbourhood is section-sampled: more than the upper SECT_ALPHA
 * quantile of Binomial(n, SECT_ALPHA), the count each point's test, at its
 * level SECT_ALPHA, would give by chance on a surface (the exact tail) */
static int section_count(int n, double z) {
  const double p = SECT_ALPHA;
  double pmf = pow(1.0 - p, n), tail = 1.0 - pmf;
  /* (1 - p)^n underflows beyond about 14,000 neighbours: there the normal
   * approximation (n p (1 - p) > 600), with its continuity correction */
  if (!(pmf > 1e-280)) return (int)floor(n * p + z * sqrt(n * p * (1.0 - p)) + 0.5) + 1;
  int c = 0;
  while (tail > SECT_ALPHA && c < n) {
    pmf *= (double)(n - c) / (c + 1) * p / (1.0 - p);
    tail -= pmf;
    c++;
  }
  return c + 1;
}

void ksel_section_levels(ksel_ctx *c) {
  const int K = c->o->noise_k, nc = K - CT;
  const double z = ksel_normal_upper_quantile(SECT_ALPHA);
  c->sect.thin = bsurf_f_quantile_paulson(K - 3, nc, -z);
  c->sect.curve = bsurf_f_quantile_paulson(3, nc, z);
  c->sect.below = bsurf_f_quantile_paulson(nc, nc, -z);
  c->sect.count = section_count(c->kmax, z);
  c->sect.q = bsurf_chi2_ratio_wh(nc, Z_Q);
}

/* Pass 2: the lower quartile of the (quartile-corrected) residual
 * variances over the point's kmax neighbours (the largest candidate's
 * neighbourhood; see the top of the file), noise[2 i]; and where more of
 * them are section-sampled than chance allows (section_count), the lower
 * quartile of those neighbours' cross-section estimates, noise[2 i + 1]
 * (NAN elsewhere): the quadric reads no noise there, at the section-sampled
 * points and at their neighbours on the same rings alike (docs/normals.md,
 * "The noise within a cross-section's plane"). ksel_level chooses. */
void pool_point(void *vctx, int thread, size_t i) {
  ksel_ctx *c = vctx;
  ksel_scratch *s = &c->scr[thread];
  const uint32_t *idx = &c->nb->idx[i * (size_t)c->nb->k];
  int m = 0;
  for (int j = 0; j < c->kmax; j++)
    if (!isnan(c->s2[2 * (size_t)idx[j] + 1])) s->pool[m++] = c->s2[2 * (size_t)idx[j] + 1];
  c->noise[2 * i + 1] = m >= c->sect.count ? lower_quartile(s->pool, m) : NAN;
  m = 0;
  for (int j = 0; j < c->kmax; j++)
    if (!isnan(c->s2[2 * (size_t)idx[j]])) s->pool[m++] = c->s2[2 * (size_t)idx[j]];
  c->noise[2 * i] = m ? lower_quartile(s->pool, m) : 0;
  /* and the neighbourhood's quadric level again reads significantly less
   * than its cross-section level (noise_point's test, on the pools) */
  if (!(c->noise[2 * i] < c->noise[2 * i + 1] * c->sect.below)) c->noise[2 * i + 1] = NAN;
}

double bsurf_ksel_point_level(const double pooled[2]) {
  return isnan(pooled[1]) ? pooled[0] : pooled[1];
}

/* Pass 2b (BSURF_NOISE_POOL_GLOBAL): one noise level for the cloud, the
 * median of the points' pooled estimates (see the top of the file), of a
 * sorted copy: the same whatever the threads. The points whose
 * neighbourhoods are section-sampled and the others read the noise through
 * different models, each biased where the other holds (the quadric reads
 * none in a cross-section's plane, the conic reads misfit where the points
 * are no section). So the cloud is one or the other, by its majority (the
 * population the median of all would lie in): section-sampled, the median
 * of those points' cross-section estimates (the others' are the biased
 * quadric's); else the median of every point's quadric estimate, the
 * minority's section estimates not moving it. */
bsurf_status pool_global(double *noise, size_t n) {
  double *tmp = bsurf_alloc_array(n ? n : 1, sizeof(double));
  if (!tmp) return BSURF_ERR_NOMEM;
  size_t ns = 0, m = 0;
  for (size_t i = 0; i < n; i++)
    ns += !isnan(noise[2 * i + 1]);
  const int sect = 2 * ns > n;
  for (size_t i = 0; i < n; i++)
    if (!sect)
      tmp[m++] = noise[2 * i];
    else if (!isnan(noise[2 * i + 1]))
      tmp[m++] = noise[2 * i + 1];
  const double med = m ? bsurf_median(tmp, m) : 0;
  for (size_t i = 0; i < n; i++)
    noise[i] = med;
  free(tmp);
  return BSURF_OK;
}
