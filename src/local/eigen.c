/* Symmetric eigen-decompositions: 3x3 for PCA (thesis 2.2, 3.3), up to
 * BSURF_EIGEN_MAX for the small generalised problems of implicit fits
 * (the conic of kselect_noise.c).
 *
 * Cyclic Jacobi: a few sweeps of plane rotations, each annihilating one
 * off-diagonal entry. It is accurate for nearly equal eigenvalues (flat or
 * isotropic neighbourhoods), where closed-form cubic solutions lose digits,
 * and its arithmetic is fixed, so results are reproducible. */
#include "common/common.h"
#include "local/local.h"

#include <math.h>
#include <string.h>

/* inlined into both entry points, so that n = 3 is unrolled as the 3 x 3
 * sweeps always were (kselect.c calls it per candidate) */
static inline __attribute__((always_inline)) void jacobi(int n, const double *a_in, double *evals,
                                                         double *evecs) {
  double a[BSURF_EIGEN_MAX][BSURF_EIGEN_MAX], v[BSURF_EIGEN_MAX][BSURF_EIGEN_MAX];
  for (int p = 0; p < n; p++)
    for (int q = 0; q < n; q++) {
      a[p][q] = a_in[p * n + q];
      v[p][q] = p == q;
    }
  for (int sweep = 0; sweep < 50; sweep++) {
    double off = 0, diag = 0;
    for (int p = 0; p < n; p++)
      for (int q = p + 1; q < n; q++)
        off += fabs(a[p][q]);
    for (int p = 0; p < n; p++)
      diag += fabs(a[p][p]);
    if (off == 0.0 || off <= 1e-300 || off < 1e-18 * diag) break;
    for (int p = 0; p < n - 1; p++) {
      for (int q = p + 1; q < n; q++) {
        double apq = a[p][q];
        if (apq == 0.0) continue;
        double theta = (a[q][q] - a[p][p]) / (2.0 * apq);
        double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
        if (!isfinite(t)) t = 0.0; /* theta overflowed: apq negligible */
        double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
        for (int k = 0; k < n; k++) { /* A <- J^T A J */
          double akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < n; k++) {
          double apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < n; k++) { /* V <- V J, columns are eigenvectors */
          double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
    }
  }
  int order[BSURF_EIGEN_MAX];
  double d[BSURF_EIGEN_MAX];
  for (int i = 0; i < n; i++)
    order[i] = i, d[i] = a[i][i];
  for (int i = 1; i < n; i++) /* stable insertion sort, ascending */
    for (int j = i; j > 0 && d[order[j]] < d[order[j - 1]]; j--) {
      int t = order[j];
      order[j] = order[j - 1];
      order[j - 1] = t;
    }
  for (int i = 0; i < n; i++) {
    evals[i] = d[order[i]];
    for (int k = 0; k < n; k++)
      evecs[i * n + k] = v[k][order[i]];
  }
}

void bsurf_eigen_sym(int n, const double *a, double *evals, double *evecs) {
  jacobi(n, a, evals, evecs);
}

void bsurf_eigen_sym3(double a_in[3][3], double evals[3], double evecs[3][3]) {
  jacobi(3, &a_in[0][0], evals, &evecs[0][0]);
}

int bsurf_eigen_sym3_normal(const double c[6], double n[3]) {
  double C[3][3] = {{c[0], c[1], c[2]}, {c[1], c[3], c[4]}, {c[2], c[4], c[5]}};
  double ev[3], V[3][3];
  bsurf_eigen_sym3(C, ev, V);
  for (int t = 0; t < 3; t++)
    n[t] = V[0][t];
  return (ev[2] > 0 && ev[1] > 1e-12 * ev[2]) ? 0 : -1;
}

/* The eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix
 * (the PCA normal), without the other two vectors.
 *
 * With the matrix scaled to unit trace, the smallest eigenvalue l0 is the
 * smallest root of the characteristic polynomial
 *   p(l) = det(A - l I) = det - m l + tr l^2 - l^3 = (l0 - l)(l1 - l)(l2 - l),
 * reached by Newton's method from l = 0 <= l0: left of its smallest root a
 * polynomial with real roots is convex or concave up to its first inflection
 * point (tr / 3 >= l0), so the iterates increase monotonically to l0 (a
 * few steps: the first is det / m ~ l0 (1 - l0 / l1 - l0 / l2)). The
 * columns of adj(A - l0 I) = (l1 - l0)(l2 - l0) v0 v0^T are the cross
 * products of the rows of A - l0 I; the largest one is v0 times at least
 * (l1 - l0)(l2 - l0) / sqrt(3), so its direction is as accurate as the gap
 * l1 - l0 allows (the eigenvector's own condition number, as for Jacobi).
 * When that gap is tiny (below about 1e-5 of the trace: nearly collinear or
 * isotropic points, where the normal is undetermined anyway) or the
 * iteration does not settle, the Jacobi sweeps above decide. Returns the
 * same verdict as a PCA fit on the full decomposition: 0, or -1 when
 * l2 <= 0 or l1 <= 1e-12 l2 (a degenerate plane). */
int bsurf_eigen_sym3_smallest(const double c[6], double n[3]) {
  const double tr0 = c[0] + c[3] + c[5];
  int jacobi = !(tr0 > 0) || !isfinite(tr0);
  double l1 = 0, l2 = 0;
  if (!jacobi) {
    const double s = 1.0 / tr0;
    const double a = c[0] * s, b = c[1] * s, e = c[2] * s, d = c[3] * s, f = c[4] * s, g = c[5] * s;
    /* a b e / b d f / e f g */
    const double tr = a + d + g;
    const double m = (a * d - b * b) + (a * g - e * e) + (d * g - f * f);
    const double det = a * (d * g - f * f) - b * (b * g - f * e) + e * (b * f - d * e);
    double l = 0;
    int it = 0;
    for (; it < 64; it++) {
      const double p = det - l * (m - l * (tr - l));
      const double dp = -m + l * (2 * tr - 3 * l);
      if (!(dp < 0)) break;
      const double nl = l - p / dp;
      if (!(nl > l)) break;
      l = nl;
    }
    /* l1 + l2 = tr - l0, l1 l2 = m - l0 (l1 + l2) */
    const double sum = tr - l, prod = m - l * sum;
    const double disc = sum * sum - 4 * prod;
    l2 = 0.5 * (sum + sqrt(disc > 0 ? disc : 0));
    l1 = l2 > 0 ? prod / l2 : 0;
    const double r0[3] = {a - l, b, e}, r1[3] = {b, d - l, f}, r2[3] = {e, f, g - l};
    double x[3][3];
    const double *rows[3][2] = {{r0, r1}, {r0, r2}, {r1, r2}};
    double best = -1;
    int bi = 0;
    for (int t = 0; t < 3; t++) {
      const double *u = rows[t][0], *v = rows[t][1];
      x[t][0] = u[1] * v[2] - u[2] * v[1];
      x[t][1] = u[2] * v[0] - u[0] * v[2];
      x[t][2] = u[0] * v[1] - u[1] * v[0];
      const double nn = x[t][0] * x[t][0] + x[t][1] * x[t][1] + x[t][2] * x[t][2];
      if (nn > best) best = nn, bi = t;
    }
    if (it == 64 || !(best > 1e-10)) {
      jacobi = 1;
    } else {
      const double inv = 1.0 / sqrt(best);
      for (int t = 0; t < 3; t++)
        n[t] = x[bi][t] * inv;
    }
  }
  if (jacobi) return bsurf_eigen_sym3_normal(c, n);
  return (l2 > 0 && l1 > 1e-12 * l2) ? 0 : -1;
}

/* bsurf_eigen_sym3_smallest for R matrices at once in vector lanes: the
 * same expressions, with Newton run a fixed SMALLEST_STEPS steps (a lane that
 * has settled stays put: its next step is no progress again) and the lanes
 * that have not settled by then, or need the sweeps, redone by the scalar
 * function; so every lane gets exactly the scalar result. */
#define SMALLEST_STEPS 6

/* The lanes' arithmetic is written once over eig_vec: four doubles (GCC
 * vector types: AVX2 in the x86-64-v3 clone, SSE2 pairs otherwise) or one
 * double elsewhere. Comparisons give masks (all ones or all zeros); EIG_SEL
 * picks between computed values lane by lane. GCC did not vectorise the
 * scalar loop this replaces (the selects and the status array defeated it),
 * so every lane ran alone. */
#if defined(__GNUC__)
#define EIG_LANES 4
typedef double eig_vec __attribute__((vector_size(32)));
typedef long long eig_mask __attribute__((vector_size(32)));
/* macros, since vector arguments change the ABI of the default clone */
#define EIG_SEL(m, a, b) ((eig_vec)(((eig_mask)(a) & (m)) | ((eig_mask)(b) & ~(m))))
#define EIG_MASK(cond) (cond)
#define EIG_LANE(v, t) ((v)[t])
#define EIG_BCAST(x) ((eig_vec){(x), (x), (x), (x)})
#else
#define EIG_LANES 1
typedef double eig_vec;
typedef long long eig_mask;
#define EIG_SEL(m, a, b) ((m) ? (a) : (b))
#define EIG_MASK(cond) (-(long long)(cond))
#define EIG_LANE(v, t) ((void)(t), (v))
#define EIG_BCAST(x) (x)
#endif

static inline void eig_sqrt(eig_vec *x) {
  double t[EIG_LANES];
  memcpy(t, x, sizeof t);
  for (int l = 0; l < EIG_LANES; l++)
    t[l] = sqrt(t[l]);
  memcpy(x, t, sizeof t);
}

/* Lanes r .. r + EIG_LANES - 1 of the R matrices c (six rows of R: entry e
 * of matrix r at c[e R + r]): bsurf_eigen_sym3_smallest's expressions, with
 * Newton run SMALLEST_STEPS steps; status 1 where the lane must be redone
 * by the scalar function (not settled, the sweeps needed). */
static inline __attribute__((always_inline)) void
smallest_block(int R, int r, const double *restrict c, double *restrict n, int *restrict status) {
  eig_vec c0, c1, c2, c3, c4, c5;
  memcpy(&c0, &c[r], sizeof c0);
  memcpy(&c1, &c[R + r], sizeof c1);
  memcpy(&c2, &c[2 * R + r], sizeof c2);
  memcpy(&c3, &c[3 * R + r], sizeof c3);
  memcpy(&c4, &c[4 * R + r], sizeof c4);
  memcpy(&c5, &c[5 * R + r], sizeof c5);
  const eig_vec one = EIG_BCAST(1.0), zero = EIG_BCAST(0.0), inf = EIG_BCAST(INFINITY);
  const eig_vec tr0 = c0 + c3 + c5;
  const eig_vec s = one / tr0;
  const eig_vec a = c0 * s, b = c1 * s, e = c2 * s, d = c3 * s, f = c4 * s, g = c5 * s;
  const eig_vec tr = a + d + g;
  const eig_vec m = (a * d - b * b) + (a * g - e * e) + (d * g - f * f);
  const eig_vec det = a * (d * g - f * f) - b * (b * g - f * e) + e * (b * f - d * e);
  eig_vec l = zero;
  for (int it = 0; it < SMALLEST_STEPS; it++) {
    const eig_vec p = det - l * (m - l * (tr - l));
    const eig_vec dp = -m + l * (2 * tr - 3 * l);
    const eig_vec nl = l - p / dp;
    l = EIG_SEL(EIG_MASK(dp < 0) & EIG_MASK(nl > l), nl, l);
  }
  const eig_vec p = det - l * (m - l * (tr - l));
  const eig_vec dp = -m + l * (2 * tr - 3 * l);
  const eig_vec nl = l - p / dp;
  const eig_mask unsettled = EIG_MASK(dp < 0) & EIG_MASK(nl > l);
  /* l1 + l2 = tr - l0, l1 l2 = m - l0 (l1 + l2) */
  const eig_vec sum = tr - l, prod = m - l * sum;
  const eig_vec disc = sum * sum - 4 * prod;
  eig_vec root = EIG_SEL(EIG_MASK(disc > 0), disc, zero);
  eig_sqrt(&root);
  const eig_vec l2 = 0.5 * (sum + root);
  const eig_vec q = prod / l2;
  const eig_vec l1 = EIG_SEL(EIG_MASK(l2 > 0), q, zero);
  const eig_vec r00 = a - l, r11 = d - l, r22 = g - l;
  /* the cross products of the rows (r00 b e), (b r11 f), (e f r22) */
  const eig_vec x0 = b * f - e * r11, x1 = e * b - r00 * f, x2 = r00 * r11 - b * b;
  const eig_vec y0 = b * r22 - e * f, y1 = e * e - r00 * r22, y2 = r00 * f - b * e;
  const eig_vec z0 = r11 * r22 - f * f, z1 = f * e - b * r22, z2 = b * f - r11 * e;
  const eig_vec nx = x0 * x0 + x1 * x1 + x2 * x2, ny = y0 * y0 + y1 * y1 + y2 * y2,
                nz = z0 * z0 + z1 * z1 + z2 * z2;
  eig_vec best = nx, v0 = x0, v1 = x1, v2 = x2;
  best = EIG_SEL(EIG_MASK(ny > best), ny, best);
  const eig_mask ywin = EIG_MASK(ny > nx);
  v0 = EIG_SEL(ywin, y0, v0);
  v1 = EIG_SEL(ywin, y1, v1);
  v2 = EIG_SEL(ywin, y2, v2);
  const eig_mask zwin = EIG_MASK(nz > best);
  best = EIG_SEL(zwin, nz, best);
  v0 = EIG_SEL(zwin, z0, v0);
  v1 = EIG_SEL(zwin, z1, v1);
  v2 = EIG_SEL(zwin, z2, v2);
  eig_vec rbest = best;
  eig_sqrt(&rbest);
  const eig_vec inv = one / rbest;
  v0 = v0 * inv;
  v1 = v1 * inv;
  v2 = v2 * inv;
  memcpy(&n[r], &v0, sizeof v0);
  memcpy(&n[R + r], &v1, sizeof v1);
  memcpy(&n[2 * R + r], &v2, sizeof v2);
  const eig_mask redo =
      ~(EIG_MASK(tr0 > 0) & EIG_MASK(tr0 < inf)) | unsettled | ~EIG_MASK(best > 1e-10);
  const eig_mask plane = EIG_MASK(l2 > 0) & EIG_MASK(l1 > 1e-12 * l2);
  for (int t = 0; t < EIG_LANES; t++)
    status[r + t] = EIG_LANE(redo, t) ? 1 : EIG_LANE(plane, t) ? 0 : -1;
}

/* All R lanes, EIG_LANES at a time; the last R % EIG_LANES through a
 * padded copy (its extra lanes repeat the last matrix, and are dropped). */
BSURF_CLONES static void smallest_lanes(int R, const double *restrict c, double *restrict n,
                                        int *restrict status) {
  int r = 0;
  for (; r + EIG_LANES <= R; r += EIG_LANES)
    smallest_block(R, r, c, n, status);
  if (r < R) {
    double tc[6 * EIG_LANES], tn[3 * EIG_LANES];
    int ts[EIG_LANES];
    for (int l = 0; l < EIG_LANES; l++) {
      const int src = r + l < R ? r + l : R - 1;
      for (int e = 0; e < 6; e++)
        tc[e * EIG_LANES + l] = c[(size_t)e * R + src];
    }
    smallest_block(EIG_LANES, 0, tc, tn, ts);
    for (int l = 0; r + l < R; l++) {
      for (int t = 0; t < 3; t++)
        n[(size_t)t * R + r + l] = tn[t * EIG_LANES + l];
      status[r + l] = ts[l];
    }
  }
}

void bsurf_eigen_sym3_smallest_lanes(int R, const double *c, double *n, int *status) {
  smallest_lanes(R, c, n, status);
  for (int r = 0; r < R; r++)
    if (status[r] == 1) {
      const double m[6] = {c[r], c[R + r], c[2 * R + r], c[3 * R + r], c[4 * R + r], c[5 * R + r]};
      double v[3];
      status[r] = bsurf_eigen_sym3_smallest(m, v);
      for (int t = 0; t < 3; t++)
        n[t * R + r] = v[t];
    }
}
