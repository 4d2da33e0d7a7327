/* Nested neighbourhoods (docs/normals.md, "Nested neighbourhoods"): for a
 * point with its sorted neighbour list of kmax points, the candidate
 * neighbourhoods P_K (the first K neighbours, K in an increasing list) are
 * prefixes of one another. One pass over the kmax neighbours with running
 * sums of (weighted) moments gives every candidate's weight, centroid and
 * covariance at once; with the weights of R bootstrap replicates in vector
 * lanes, every candidate's covariance of every replicate.
 *
 * Used by the per-point K selection of the normals (normals.c, Eqs. 5.9-5.10,
 * Algorithm 3); meant for any rule that compares neighbourhood sizes by their
 * covariances. */
#include "algo/algo.h"
#include "common/common.h"

#include <math.h>
#include <string.h>

void bsurf_nested_terms(const double *xyz, const uint32_t *idx, int kmax, double *terms) {
  const double *d = &xyz[3 * (size_t)idx[0]];
  for (int j = 0; j < kmax; j++) {
    const double *p = &xyz[3 * (size_t)idx[j]];
    const double q[3] = {p[0] - d[0], p[1] - d[1], p[2] - d[2]};
    double *r = &terms[(size_t)j * BSURF_NESTED_COLS];
    r[0] = q[0] * q[0];
    r[1] = q[0] * q[1];
    r[2] = q[0] * q[2];
    r[3] = q[1] * q[1];
    r[4] = q[1] * q[2];
    r[5] = q[2] * q[2];
    r[6] = q[0];
    r[7] = q[1];
    r[8] = q[2];
    r[9] = 1.0;
  }
}

#if defined(__GNUC__)
typedef double sums_v8d __attribute__((vector_size(64)));
typedef long long sums_v8l __attribute__((vector_size(64)));
typedef double sums_v4d __attribute__((vector_size(32)));
typedef long long sums_v4l __attribute__((vector_size(32)));

/* Lanes r0 .. r0 + L - 1 (L = 8 or 4, the vector type V) of every
 * candidate's weighted sums: the ten columns' accumulators kept in
 * registers over the kmax neighbours (w * t, then the add, in the order
 * j = 0, 1, ...: the bits of the one-neighbour-at-a-time loop through
 * memory this replaces, which loaded and stored every accumulator once a
 * neighbour), stored where a candidate's prefix ends; the nonzero weights
 * counted alongside. */
#define SUMS_LANES(V, VL, L)                                                                       \
  do {                                                                                             \
    V acc[BSURF_NESTED_COLS];                                                                      \
    VL cnt;                                                                                        \
    for (int col = 0; col < BSURF_NESTED_COLS; col++)                                              \
      acc[col] = (V){0};                                                                           \
    cnt = (VL){0};                                                                                 \
    int c = 0;                                                                                     \
    for (int j = 0; j < kmax && c < nk; j++) {                                                     \
      const double *t = &terms[(size_t)j * BSURF_NESTED_COLS];                                     \
      V w;                                                                                         \
      memcpy(&w, &Wt[(size_t)j * R + r0], sizeof w);                                               \
      for (int col = 0; col < BSURF_NESTED_COLS; col++)                                            \
        acc[col] += w * t[col];                                                                    \
      cnt -= (VL)(w != 0);                                                                         \
      if (j + 1 == ks[c]) { /* candidate c complete */                                             \
        double *o = sums + (size_t)c * block + r0;                                                 \
        for (int col = 0; col < BSURF_NESTED_COLS; col++)                                          \
          memcpy(o + (size_t)col * R, &acc[col], sizeof acc[col]);                                 \
        if (nz)                                                                                    \
          for (int l = 0; l < (L); l++)                                                            \
            nz[(size_t)c * R + r0 + l] = (int)cnt[l];                                              \
        c++;                                                                                       \
      }                                                                                            \
    }                                                                                              \
  } while (0)

static inline __attribute__((always_inline)) void
sums_lanes8(const double *restrict terms, int kmax, int R, int r0, const double *restrict Wt,
            const int *ks, int nk, size_t block, double *restrict sums, int *restrict nz) {
  SUMS_LANES(sums_v8d, sums_v8l, 8);
}

static inline __attribute__((always_inline)) void
sums_lanes4(const double *restrict terms, int kmax, int R, int r0, const double *restrict Wt,
            const int *ks, int nk, size_t block, double *restrict sums, int *restrict nz) {
  SUMS_LANES(sums_v4d, sums_v4l, 4);
}
#undef SUMS_LANES
#endif

/* One lane r of the weighted sums, as the vector blocks. */
static void sums_lane1(const double *restrict terms, int kmax, int R, int r,
                       const double *restrict Wt, const int *ks, int nk, size_t block,
                       double *restrict sums, int *restrict nz) {
  double acc[BSURF_NESTED_COLS] = {0};
  int cnt = 0, c = 0;
  for (int j = 0; j < kmax && c < nk; j++) {
    const double *t = &terms[(size_t)j * BSURF_NESTED_COLS];
    const double w = Wt[(size_t)j * R + r];
    for (int col = 0; col < BSURF_NESTED_COLS; col++)
      acc[col] += w * t[col];
    cnt += w != 0;
    if (j + 1 == ks[c]) {
      for (int col = 0; col < BSURF_NESTED_COLS; col++)
        sums[(size_t)c * block + (size_t)col * R + r] = acc[col];
      if (nz) nz[(size_t)c * R + r] = cnt;
      c++;
    }
  }
}

/* The weighted sums, R lanes: eight at a time where the clone has 512-bit
 * vectors (the ten accumulators then fit its 32 registers), else four; a
 * last partial group is the last full width of lanes again (R - 8 .. R - 1:
 * the lanes done twice get the same values twice), fewer than four lanes
 * one by one. Every lane is the same sequence of operations whichever width
 * runs it, so the bits do not depend on the clone or on R. */
BSURF_CLONES
static void sums_weighted(const double *restrict terms, int kmax, int R, const double *restrict Wt,
                          const int *ks, int nk, double *sums, int *nz) {
  const size_t block = (size_t)BSURF_NESTED_COLS * R;
  int r0 = 0;
#if defined(__GNUC__)
#if defined(__x86_64__) && !defined(__clang__)
  if (R >= 8 && __builtin_cpu_supports("avx512f")) {
    for (; r0 < R; r0 += 8)
      sums_lanes8(terms, kmax, R, r0 + 8 <= R ? r0 : R - 8, Wt, ks, nk, block, sums, nz);
    return;
  }
#endif
  if (R >= 4) {
    for (; r0 < R; r0 += 4)
      sums_lanes4(terms, kmax, R, r0 + 4 <= R ? r0 : R - 4, Wt, ks, nk, block, sums, nz);
    return;
  }
#endif
  for (; r0 < R; r0++)
    sums_lane1(terms, kmax, R, r0, Wt, ks, nk, block, sums, nz);
}

void bsurf_nested_sums(const double *terms, int kmax, int R, const double *Wt, const int *ks,
                       int nk, double *sums, int *distinct) {
  if (Wt) {
    sums_weighted(terms, kmax, R, Wt, ks, nk, sums, distinct);
    return;
  }
  const size_t block = (size_t)BSURF_NESTED_COLS * R;
  double *acc = sums;
  int *nz = distinct;
  memset(acc, 0, block * sizeof *acc);
  if (nz) memset(nz, 0, (size_t)R * sizeof *nz);
  int c = 0;
  for (int j = 0; j < kmax && c < nk; j++) {
    const double *t = &terms[(size_t)j * BSURF_NESTED_COLS];
    for (int col = 0; col < BSURF_NESTED_COLS; col++)
      acc[col] += t[col];
    if (nz) nz[0]++;
    if (j + 1 == ks[c]) { /* candidate c complete: carry its sums on */
      if (c + 1 < nk) {
        memcpy(acc + block, acc, block * sizeof *acc);
        if (nz) memcpy(nz + R, nz, (size_t)R * sizeof *nz);
      }
      acc += block;
      if (nz) nz += R;
      c++;
    }
  }
}

int bsurf_nested_cov(const double *sums, size_t stride, bsurf_pca_center center, double mu[3],
                     double cov[6]) {
  const double w = sums[9 * stride];
  if (!(w > 0)) return -1;
  for (int t = 0; t < 3; t++)
    mu[t] = sums[(6 + t) * stride] / w;
  /* second moments about the centroid, or about d_i (Eq. 2.1) */
  double m[3] = {0, 0, 0};
  if (center == BSURF_PCA_CENTROID)
    for (int t = 0; t < 3; t++)
      m[t] = mu[t];
  cov[0] = sums[0] / w - m[0] * m[0];
  cov[1] = sums[stride] / w - m[0] * m[1];
  cov[2] = sums[2 * stride] / w - m[0] * m[2];
  cov[3] = sums[3 * stride] / w - m[1] * m[1];
  cov[4] = sums[4 * stride] / w - m[1] * m[2];
  cov[5] = sums[5 * stride] / w - m[2] * m[2];
  return 0;
}

/* Cephes' atan: P (degree 4) and Q (monic, degree 5) of x + x z P(z) / Q(z),
 * z = x^2, for |x| <= 0.66; pi / 4 split in two for the reduction. */
static const double P0 = -8.750608600031904122785e-1, P1 = -1.615753718733365076637e1,
                    P2 = -7.500855792314704667340e1, P3 = -1.228866684490136173410e2,
                    P4 = -6.485021904942025371773e1;
static const double Q0 = 2.485846490142306297962e1, Q1 = 1.650270098316988542046e2,
                    Q2 = 4.328810604912902668951e2, Q3 = 4.853903996359136964868e2,
                    Q4 = 1.945506571482613964425e2;
static const double PIO4 = 7.85398163397448309616e-1, MOREBITS = 6.123233995736765886130e-17,
                    PIO2 = 1.57079632679489661923;

/* atan(t) for 0 <= t <= 1 (Cephes' atan: below 0.66 a rational function of
 * t^2, above it pi/4 + atan((t - 1) / (t + 1))), written branch-free so that
 * a loop of them runs in vector lanes; zn / zd is the reduced argument. */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#endif
static inline __attribute__((always_inline)) double
atan_reduced(double num, double den) {
  /* t = num / den <= 1; above 0.66 (num > 0.66 den) reduce */
  const double dif = num - den, tot = num + den; /* both computed: no branches */
  const int big = num > 0.66 * den;
  const double zn = big ? dif : num, zd = big ? tot : den;
  const double x = zn / zd; /* zd >= den > 0 for unit vectors */
  const double z = x * x;
  const double p = (((P0 * z + P1) * z + P2) * z + P3) * z + P4;
  const double q = ((((z + Q0) * z + Q1) * z + Q2) * z + Q3) * z + Q4;
  const double r = x * (z * p / q) + x;
  const double rb = PIO4 + (r + 0.5 * MOREBITS);
  return big ? rb : r;
}

/* atan2(|c|, |dot|) (c = g x r, dot = g . r: the unoriented angle between g
 * and r) with atan2 of the first quadrant reduced to atan of a ratio <= 1
 * (pi/2 - atan(x / y) above the diagonal). */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#endif
static inline __attribute__((always_inline)) double
q1_angle(double c0, double c1, double c2, double dot) {
  const double y = sqrt(c0 * c0 + c1 * c1 + c2 * c2);
  const double x = fabs(dot);
  const double lo = y > x ? x : y, hi = y > x ? y : x;
  const double a = atan_reduced(lo, hi);
  const double as = (PIO2 - a) + MOREBITS;
  return y > x ? as : a;
}

/* Eq. 5.10's inner sums of many (candidate, replicate) pairs at once, the
 * pairs in vector lanes: each neighbour j's reference normal is broadcast
 * and the angles of every pair still using it (kl[p] > j) evaluated in
 * lanes, each added to one of four running sums by j mod 4 (from +0),
 * combined as (s0 + s1) + (s2 + s3): a fixed order, so a pair's sum has the
 * same bits whatever the other lanes (a lane past its own count adds +0,
 * which leaves a sum of non-negative angles unchanged). Pairs come in
 * non-decreasing kl, so the lanes in use at j are a suffix: the loops over
 * them are long and nearly full, where loops over one pair's K neighbours
 * were short (K / 8 vectors with a padded tail and a second pass to sum). */
enum { PAIR_CHUNK = 256 };

#if defined(__GNUC__) && !defined(__clang__)
/* selects between computed values, not branches: the values are the same,
 * but GCC vectorises the loop only when it may ignore FP exception flags */
__attribute__((optimize("no-trapping-math")))
#endif
BSURF_CLONES static void
pair_chunk(int nv, const double *restrict vk, const double *restrict kl, const double *restrict gx,
           const double *restrict gy, const double *restrict gz, const double *restrict rx,
           const double *restrict ry, const double *restrict rz, double *restrict acc) {
  const int np = 8 * nv;
  int v0 = 0; /* the first vector of 8 lanes with a lane still in use */
  for (int j = 0;; j++) {
    const double jd = j;
    while (v0 < nv && !(vk[v0] > jd))
      v0++;
    if (v0 == nv) break; /* every pair's K reached: rx[j] may be past the arrays */
    double *restrict a = acc + (size_t)(j & 3) * PAIR_CHUNK;
    const double r0 = rx[j], r1 = ry[j], r2 = rz[j];
    for (int l = 8 * v0; l < np; l++) {
      const double g0 = gx[l], g1 = gy[l], g2 = gz[l];
      const double c0 = g1 * r2 - g2 * r1, c1 = g2 * r0 - g0 * r2, c2 = g0 * r1 - g1 * r0;
      const double t = q1_angle(c0, c1, c2, g0 * r0 + g1 * r1 + g2 * r2);
      a[l] += kl[l] > jd ? t : 0.0;
    }
  }
}

void bsurf_nested_angle_sums(size_t P, const double *g, const unsigned char *valid, const int *kl,
                             const double *rx, const double *ry, const double *rz, double *sums) {
  _Alignas(64) double gx[PAIR_CHUNK], gy[PAIR_CHUNK], gz[PAIR_CHUNK], klf[PAIR_CHUNK];
  _Alignas(64) double acc[4 * PAIR_CHUNK];
  double vk[PAIR_CHUNK / 8];
  for (size_t p0 = 0; p0 < P; p0 += PAIR_CHUNK) {
    const int n = P - p0 < PAIR_CHUNK ? (int)(P - p0) : PAIR_CHUNK, nv = (n + 7) / 8;
    for (int l = 0; l < 8 * nv; l++) {
      /* lanes past P and invalid pairs: g = (0, 0, 1), their sums not used */
      const size_t p = p0 + (size_t)l;
      const int use = l < n && (!valid || valid[p]);
      gx[l] = use ? g[3 * p] : 0.0;
      gy[l] = use ? g[3 * p + 1] : 0.0;
      gz[l] = use ? g[3 * p + 2] : 1.0;
      klf[l] = l < n ? kl[p] : 0.0;
    }
    for (int v = 0; v < nv; v++) { /* the largest count of each vector */
      double m = 0;
      for (int l = 8 * v; l < 8 * v + 8; l++)
        m = klf[l] > m ? klf[l] : m;
      vk[v] = m;
    }
    memset(acc, 0, sizeof acc);
    pair_chunk(nv, vk, klf, gx, gy, gz, rx, ry, rz, acc);
    const double *s0 = acc, *s1 = s0 + PAIR_CHUNK, *s2 = s1 + PAIR_CHUNK, *s3 = s2 + PAIR_CHUNK;
    for (int l = 0; l < n; l++)
      sums[p0 + l] = (s0[l] + s1[l]) + (s2[l] + s3[l]);
  }
}

double bsurf_nested_angle_sum(const double g[3], const double *rx, const double *ry,
                              const double *rz, int k) {
  double s;
  bsurf_nested_angle_sums(1, g, NULL, &k, rx, ry, rz, &s);
  return s;
}

/* The angle in [0, pi] between unit g and each (rx, ry, rz)[j]:
 * atan2(|g x r|, g . r) as libm's atan2 in bsurf_angle_between (oriented),
 * by q1_angle of |g . r| (Cephes' atan, within 2 ulp of atan2 over the
 * first quadrant) reflected to pi - a where g . r < 0 (pi split in two as
 * pi / 2 is). In vector lanes: Eq. 5.5's variance took libm's atan2 one
 * call at a time, 6-9% of `normals -B 50` (tests/test_nested.c). */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#endif
BSURF_CLONES static void
oriented_angles(const double g[3], const double *restrict rx, const double *restrict ry,
                const double *restrict rz, int k, double *restrict out) {
  const double g0 = g[0], g1 = g[1], g2 = g[2];
  for (int j = 0; j < k; j++) {
    const double c0 = g1 * rz[j] - g2 * ry[j], c1 = g2 * rx[j] - g0 * rz[j],
                 c2 = g0 * ry[j] - g1 * rx[j];
    const double dot = g0 * rx[j] + g1 * ry[j] + g2 * rz[j];
    const double a = q1_angle(c0, c1, c2, dot);
    const double ar = (2 * PIO2 - a) + 2 * MOREBITS;
    out[j] = dot < 0 ? ar : a;
  }
}

/* One lane r of bsurf_nested_cov_lanes. */
static inline void cov_one(const double *block, int R, int r, int about_centroid, double *cov,
                           int *ok) {
  const double w = block[9 * R + r];
  const double m0 = block[6 * R + r] / w, m1 = block[7 * R + r] / w, m2 = block[8 * R + r] / w;
  const double a0 = about_centroid ? m0 : 0.0, a1 = about_centroid ? m1 : 0.0,
               a2 = about_centroid ? m2 : 0.0;
  cov[r] = block[r] / w - a0 * a0;
  cov[R + r] = block[R + r] / w - a0 * a1;
  cov[2 * R + r] = block[2 * R + r] / w - a0 * a2;
  cov[3 * R + r] = block[3 * R + r] / w - a1 * a1;
  cov[4 * R + r] = block[4 * R + r] / w - a1 * a2;
  cov[5 * R + r] = block[5 * R + r] / w - a2 * a2;
  ok[r] = w > 0;
}

#if defined(__GNUC__)
typedef double cov_v4d __attribute__((vector_size(32)));

/* Lanes r..r+3 of bsurf_nested_cov_lanes in GCC vector types (GCC left the
 * scalar loop scalar: nine divisions a lane, one lane at a time): the same
 * expressions, so the same bits; about the point (not the centroid) a
 * multiplies 0 * 0 = 0 and subtracts it, as the scalar code does.
 * about_centroid is a constant at each call (bsurf_nested_cov_lanes has one
 * loop per centre), so the conditionals fold away: with it a run-time value,
 * GCC 12 with -fwrapv (Debian's python3 CFLAGS, which a pip build of the
 * package inherited) selected m0 in lane 0 only, by `?:` or by an if alike,
 * leaving the centroid out of lanes 1-3 (the bootstrap's covariances about
 * the point: normal_var about 3x too large); test_nested_wrapv builds this
 * file with -fwrapv. */
static inline __attribute__((always_inline)) void cov4(const double *block, int R, int r,
                                                       int about_centroid, double *cov, int *ok) {
  cov_v4d x[10];
  for (int t = 0; t < 10; t++)
    memcpy(&x[t], &block[(size_t)t * R + r], sizeof x[t]);
  const cov_v4d w = x[9], zero = {0, 0, 0, 0};
  const cov_v4d m0 = x[6] / w, m1 = x[7] / w, m2 = x[8] / w;
  const cov_v4d a0 = about_centroid ? m0 : zero, a1 = about_centroid ? m1 : zero,
                a2 = about_centroid ? m2 : zero;
  const cov_v4d c[6] = {x[0] / w - a0 * a0, x[1] / w - a0 * a1, x[2] / w - a0 * a2,
                        x[3] / w - a1 * a1, x[4] / w - a1 * a2, x[5] / w - a2 * a2};
  for (int t = 0; t < 6; t++)
    memcpy(&cov[(size_t)t * R + r], &c[t], sizeof c[t]);
  for (int l = 0; l < 4; l++)
    ok[r + l] = w[l] > 0;
}
#endif

BSURF_CLONES
void bsurf_nested_cov_lanes(const double *block, int R, bsurf_pca_center center, double *cov,
                            int *ok) {
  const int about_centroid = center == BSURF_PCA_CENTROID;
  int r = 0;
#if defined(__GNUC__)
  if (about_centroid)
    for (; r + 4 <= R; r += 4)
      cov4(block, R, r, 1, cov, ok);
  else
    for (; r + 4 <= R; r += 4)
      cov4(block, R, r, 0, cov, ok);
#endif
  for (; r < R; r++)
    cov_one(block, R, r, about_centroid, cov, ok);
}

bsurf_status bsurf_nested_check_ks(const char *who, const int *ks, int nk, int kmin,
                                   const bsurf_neighbors *nb) {
  BSURF_REQUIRE_IN(who, ks && nk >= 1, "ks = %p, nk = %d: at least one candidate K",
                   (const void *)ks, nk);
  BSURF_REQUIRE_IN(who, ks[0] >= kmin, "ks[0] = %d must be at least %d", ks[0], kmin);
  for (int a = 1; a < nk; a++)
    BSURF_REQUIRE_IN(who, ks[a] > ks[a - 1], "ks[%d] = %d must be above ks[%d] = %d (increasing)",
                     a, ks[a], a - 1, ks[a - 1]);
  BSURF_REQUIRE_IN(who, ks[nk - 1] <= 65535 && ks[nk - 1] <= nb->k,
                   "ks[%d] = %d must be at most the neighbourhoods' k = %d (and 65535)", nk - 1,
                   ks[nk - 1], nb->k);
  if ((size_t)ks[nk - 1] > nb->point_count)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "%s: ks[%d] = %d exceeds the %zu points",
                             who, nk - 1, ks[nk - 1], nb->point_count);
  return BSURF_OK;
}

double bsurf_angle_between(const double a[3], const double b[3], int unoriented) {
  double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  if (unoriented) d = fabs(d);
  return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), d);
}

int bsurf_nested_summary(int B, const double nP[3], double *bn, const unsigned char *valid,
                         double nrm[3], double *var, double *ang) {
  /* orient to n_P (5.2.1), Eq. 5.4 */
  double sum[3] = {0, 0, 0};
  int nvalid = 0, first = -1;
  for (int b = 0; b < B; b++) {
    if (!valid[b]) continue;
    double *n = &bn[3 * b];
    if (n[0] * nP[0] + n[1] * nP[1] + n[2] * nP[2] < 0)
      for (int t = 0; t < 3; t++)
        n[t] = -n[t];
    for (int t = 0; t < 3; t++)
      sum[t] += n[t];
    if (first < 0) first = b;
    nvalid++;
  }
  const double len = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
  for (int t = 0; t < 3; t++)
    nrm[t] = (nvalid > 0 && len > 0) ? sum[t] / len : nP[t];
  /* Eq. 5.5 */
  double v = 0;
  if (nvalid >= 2) {
    /* the angles to n_1 in blocks of replicates as vectors (the invalid ones
     * replaced by (0, 0, 1) and not used) */
    enum { BLK = 64 };
    double rx[BLK], ry[BLK], rz[BLK];
    for (int b0 = 0; b0 < B; b0 += BLK) {
      const int nb = B - b0 < BLK ? B - b0 : BLK;
      for (int j = 0; j < nb; j++) {
        const double *n = &bn[3 * (size_t)(b0 + j)];
        const int ok = valid[b0 + j];
        rx[j] = ok ? n[0] : 0.0, ry[j] = ok ? n[1] : 0.0, rz[j] = ok ? n[2] : 1.0;
      }
      oriented_angles(&bn[3 * first], rx, ry, rz, nb, &ang[b0]);
    }
    double mean = 0;
    for (int b = 0; b < B; b++)
      if (valid[b]) mean += ang[b];
    mean /= nvalid;
    for (int b = 0; b < B; b++)
      if (valid[b]) {
        const double d = ang[b] - mean;
        v += d * d;
      }
    v /= nvalid - 1;
  }
  *var = v;
  return nvalid;
}

/* The gradient of f = sum_t coef[t] phi_t (degree M, graded basis) as two
 * polynomials of degree M - 1 in the same basis, times `factor`: f_u =
 * sum_b coef[src[b]] mul[b] phi_b, f_v = sum_b coef[src[mg + b]] mul[mg +
 * b] phi_b, b < mg = terms(M - 1). */
static void grad_map(int degree, double factor, int *src, double *mul) {
  const int mg = bsurf_poly_terms(degree - 1);
  for (int d = 1; d <= degree; d++)
    for (int e = 0; e <= d; e++) { /* u^i v^e, i = d - e */
      const int i = d - e, t = d * (d + 1) / 2 + e, lo = (d - 1) * d / 2;
      if (i > 0) src[lo + e] = t, mul[lo + e] = factor * i;
      if (e > 0) src[mg + lo + e - 1] = t, mul[mg + lo + e - 1] = factor * e;
    }
}

/* Cephes' atanf: x + x z P(z), z = x^2, for |x| <= tan(pi / 8). */
enum { ECOL = 64 }; /* replicates summed in float before a double sum */
static const float FP0 = 8.05374449538e-2f, FP1 = -1.38776856032e-1f, FP2 = 1.99777106478e-1f,
                   FP3 = -3.33329491539e-1f, FPIO4 = 0.785398163397448309616f,
                   FPIO2 = 1.57079632679489661923f, FTAN8 = 0.414213562373095f;

/* Eq. 5.10's angles of `nrep` polynomial normal fields at the neighbours,
 * single precision, added to acc[j] (j < L): replicate b's field at j is
 * g = (gx, gy, gz), gx = sum_t e[t ECOL + b] ph[t kq + j], gy with e[(mg +
 * t) ECOL + b], gz = e[2 mg ECOL + b] (the slopes pre-scaled so that none
 * exceeds 1: float neither overflows nor loses the direction); the
 * unoriented angle to (rx, ry, rz)[j] is atan2(|g x r|, |g . r|), the first
 * quadrant reduced to atan of a ratio <= 1 (pi / 2 - atan(x / y) above the
 * diagonal), Cephes' atanf (reduction by pi / 4 above tan(pi / 8), one
 * division). Products and sums as fmaf: exactly rounded wherever it runs
 * (an instruction on the x86-64-v3/v4 clones, libm's on the baseline one),
 * so the bits do not depend on the clone. L (16 or 8) and mg are constant
 * in each instance: the loop over j is one vector with the small sums
 * unrolled, the replicates one after the other inside it (their sums in
 * registers, the basis and references loaded once); every lane is the same
 * sequence of operations whatever the vector width. */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#endif
static inline __attribute__((always_inline)) void
field_block(int L, int mg, int nrep, const float *restrict e, const float *restrict ph, size_t kq,
            const float *restrict rx, const float *restrict ry, const float *restrict rz,
            float *restrict acc) {
  float aL[16];
  for (int l = 0; l < L; l++)
    aL[l] = acc[l];
  for (int b = 0; b < nrep; b++) {
    const float *restrict eb = e + b; /* column-major: entry q at eb[q ECOL] */
    const float gz = eb[2 * mg * ECOL];
    for (int l = 0; l < L; l++) {
      float gx = 0.0f, gy = 0.0f;
      for (int t = 0; t < mg; t++) {
        gx = fmaf(eb[t * ECOL], ph[(size_t)t * kq + l], gx);
        gy = fmaf(eb[(mg + t) * ECOL], ph[(size_t)t * kq + l], gy);
      }
      const float r0 = rx[l], r1 = ry[l], r2 = rz[l];
      const float c0 = fmaf(gy, r2, -(gz * r1)), c1 = fmaf(gz, r0, -(gx * r2)),
                  c2 = fmaf(gx, r1, -(gy * r0));
      const float y = sqrtf(fmaf(c0, c0, fmaf(c1, c1, c2 * c2)));
      const float x = fabsf(fmaf(gx, r0, fmaf(gy, r1, gz * r2)));
      const float lo = y > x ? x : y, hi = y > x ? y : x;
      const int big = lo > FTAN8 * hi;
      const float num = big ? lo - hi : lo, den0 = big ? lo + hi : hi;
      const float den = den0 > 1e-30f ? den0 : 1e-30f; /* g = 0 (never in a fit): 0 */
      const float t = num / den, z = t * t;
      const float p = fmaf(fmaf(fmaf(fmaf(FP0, z, FP1), z, FP2), z, FP3), z * t, t);
      const float ap = big ? p + FPIO4 : p;
      aL[l] += y > x ? FPIO2 - ap : ap;
    }
  }
  for (int l = 0; l < L; l++)
    acc[l] = aL[l];
}

/* n a multiple of 8: 16 neighbours at a time (one 512-bit vector), a last
 * 8; the replicates inside, their sums in registers, the basis and the
 * references loaded once per block */
static inline __attribute__((always_inline)) void
field_acc(int mg, int nrep, const float *restrict e, const float *restrict phi, size_t kq,
          const float *restrict rx, const float *restrict ry, const float *restrict rz, int n,
          float *restrict acc) {
  int j0 = 0;
  for (; j0 + 16 <= n; j0 += 16)
    field_block(16, mg, nrep, e, phi + j0, kq, rx + j0, ry + j0, rz + j0, acc + j0);
  if (j0 < n) field_block(8, mg, nrep, e, phi + j0, kq, rx + j0, ry + j0, rz + j0, acc + j0);
}

#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#endif
BSURF_CLONES static void
field_acc_m(int mg, int nrep, const float *e, const float *phi, size_t kq, const float *rx,
            const float *ry, const float *rz, int n, float *acc) {
  switch (mg) { /* the degrees 1..4 */
  case 1: field_acc(1, nrep, e, phi, kq, rx, ry, rz, n, acc); break;
  case 3: field_acc(3, nrep, e, phi, kq, rx, ry, rz, n, acc); break;
  case 6: field_acc(6, nrep, e, phi, kq, rx, ry, rz, n, acc); break;
  default: field_acc(mg, nrep, e, phi, kq, rx, ry, rz, n, acc); break;
  }
}

/* The kernel's rows of `used` replicates (bi: their indices), column-major
 * (field_block): (f_u, f_v, 1) / big, big the largest of 1 and the
 * slopes' coefficients, so that the largest entry is 1; entries below 1e-30
 * of it (no float subnormals) are 0, negligible beside it. */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#endif
BSURF_CLONES static void
field_rows(int mg, int m, int used, const int *bi, const int *src, const double *mul,
           const double *coefs, float *e) {
  double g[2 * BSURF_TERMS_MAX * ECOL], big[ECOL];
  for (int u = 0; u < used; u++)
    big[u] = 1.0;
  for (int q = 0; q < 2 * mg; q++)
    for (int u = 0; u < used; u++) {
      const double v = coefs[(size_t)bi[u] * m + src[q]] * mul[q];
      g[q * ECOL + u] = v;
      big[u] = fabs(v) > big[u] ? fabs(v) : big[u];
    }
  for (int u = 0; u < used; u++)
    big[u] = 1.0 / big[u];
  for (int q = 0; q < 2 * mg; q++)
    for (int u = 0; u < used; u++) {
      const double a = g[q * ECOL + u] * big[u];
      e[q * ECOL + u] = fabs(a) < 1e-30 ? 0.0f : (float)a;
    }
  for (int u = 0; u < used; u++)
    e[2 * mg * ECOL + u] = big[u] < 1e-30 ? 0.0f : (float)big[u];
}

double bsurf_nested_field_angle_total(int degree, int nrep, const double *coefs,
                                      const unsigned char *valid, double inv_scale,
                                      const float *phif, size_t kq, const float *rf, int k,
                                      float *accf, double *accd) {
  const int m = bsurf_poly_terms(degree), mg = degree >= 1 ? bsurf_poly_terms(degree - 1) : 1;
  /* the gradient's coefficients: f_u's q < mg, f_v's mg + q, each the
   * coefficient src[q] of f times its exponent and -1 / s */
  int src[2 * BSURF_TERMS_MAX];
  double mul[2 * BSURF_TERMS_MAX];
  if (degree >= 1) {
    grad_map(degree, -inv_scale, src, mul);
  } else { /* a constant height: g = (0, 0, 1) */
    src[0] = src[1] = 0;
    mul[0] = mul[1] = 0.0;
  }
  /* up to ECOL replicates at a time, column-major: (f_u, f_v, 1) of
   * replicate u at e[q ECOL + u] */
  float e[(2 * BSURF_TERMS_MAX + 1) * ECOL];
  int bi[ECOL];
  const float *rx = rf, *ry = rf + kq, *rz = ry + kq;
  const int n = (k + 7) / 8 * 8; /* the lanes evaluated (<= kq) */
  for (int j = 0; j < n; j++)
    accd[j] = 0.0;
  for (int b0 = 0; b0 < nrep;) {
    int used = 0;
    for (; b0 < nrep && used < ECOL; b0++)
      if (!valid || valid[b0]) bi[used++] = b0;
    if (used == 0) break;
    field_rows(mg, m, used, bi, src, mul, coefs, e);
    for (int j = 0; j < n; j++)
      accf[j] = 0.0f;
    field_acc_m(mg, used, e, phif, kq, rx, ry, rz, n, accf);
    for (int j = 0; j < n; j++)
      accd[j] += accf[j];
  }
  /* sum_j, j < k, as four running sums (j mod 4) then combined: a fixed order */
  double s[4] = {0, 0, 0, 0};
  for (int j = 0; j < k; j++)
    s[j & 3] += accd[j];
  return (s[0] + s[1]) + (s[2] + s[3]);
}
