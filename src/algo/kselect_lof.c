/* Where the quadric does not hold: the lack-of-fit test of the MSE rule's
 * bias model and the empirical bias that replaces it there (docs/normals.md,
 * "Choosing K", *where the quadric does not fit*; issues 24 and 25).
 *
 * The rule's bias term (a) reads the PCA plane's tilt off a least-squares
 * quadric of the same K points, and (b) the drift from the smaller
 * candidates. Both under-read on a crease: a crease is no quadric, so the
 * quadric's Hessian is a compromise between the faces, and the drift
 * measures bias relative to the smallest candidate, itself biased when the
 * point lies within a neighbourhood of the edge. On Fandisk's vertices at
 * u0.5 the true sin^2 of the edge vertices grows from 0.033 at K = 20 to
 * 0.134 at K = 80 while V + bias^2 reads 0.012 to 0.033 (medians), and the
 * rule chose mean K 44 there against the per-point oracle's 22.
 *
 * The quadric's own residuals say where it fails. With the noise variance
 * s2 (the rule's pooled estimate, many degrees of freedom), the residual
 * variance RSS / (K - 6) of a quadric that holds is s2 chi^2_nu / nu, nu =
 * K - 6; a larger value rejects the quadric at that scale (the classical
 * lack-of-fit test against a pure-error variance). The level is a
 * Bonferroni share of 5% over the candidates, LOF_ALPHA / nk per test, the
 * quantile of chi^2_nu / nu by Wilson-Hilferty. The neighbourhoods are
 * nested, so from the first candidate that rejects on, every larger one
 * holds the structure the quadric missed: those candidates' bias is not
 * trusted (Lepski's logic: the first scale where the model breaks). Where
 * the smallest candidate already rejects, the sampling does not resolve the
 * surface at any candidate (a coarse vertex set: elephant's vertices reject
 * at K = 15 at 65-84% of the points), the neighbours' normals share that
 * misfit, and the test says nothing about scale: the rule is left as it is.
 *
 * For a candidate whose quadric is rejected the bias comes from the data,
 * as in the thesis's test error (Eq. 5.10), without the bootstrap: against
 * the first choices n_j of the point's noise_k - 1 nearest neighbours, each
 * with its own estimated MSE M_j (the rule's criterion at its first
 * choice; the references of the tie-break), the precision-weighted mean
 *     T(K) = sum_j w_j sin^2(n_K, n_j) / sum_j w_j,   w_j = 1 / M_j,
 * estimates E sin^2 between n_K and a reference, which, to first order and
 * with independent errors, is the candidate's MSE V(K) + bias^2(K) plus the
 * references' mean MSE, whose precision-weighted mean is the harmonic mean
 * R = m / sum_j w_j of the m assessed references. So
 *     bias^2_emp(K) = max(0, T(K) - R - V(K)),
 * and the candidate's bias^2 is the larger of it and the model's. At an
 * edge the neighbours on the point's own face confirm a small K and the
 * candidate that leans across the edge pays its lean.
 *
 * The residuals' other tail, a plane thinner than the noise allows, is the
 * thin-plane test (ksel_thin_plane, below). */
#include "algo/kselect.h"

#include <math.h>

/* the family level of the lack-of-fit tests over a point's candidates */
#define LOF_ALPHA 0.05

/* The standard normal's upper quantile z(p), P(Z > z) = p, 0 < p < 0.5:
 * Newton's method on erfc from the logistic start (a few steps to the
 * double's precision; the same bits on every machine with the same libm). */
double ksel_normal_upper_quantile(double p) {
  double z = sqrt(-2.0 * log(p)); /* above the quantile: the tail's bound */
  for (int it = 0; it < 50; it++) {
    const double f = 0.5 * erfc(z / sqrt(2.0)) - p;
    const double d = exp(-0.5 * z * z) / sqrt(2.0 * 3.14159265358979323846);
    const double step = f / d;
    z += step;
    if (fabs(step) < 1e-12 * (1.0 + fabs(z))) break;
  }
  return z;
}

double ksel_level_z(int nk) {
  return ksel_normal_upper_quantile(LOF_ALPHA / (nk > 1 ? nk : 1));
}

/* The other tail (docs/normals.md, "Planes thinner than the noise"): a
 * surface's K points with noise of variance s2 along its normal leave about
 * the best plane a residual sum of squares K l3 (l3 the covariance's
 * smallest eigenvalue) of at least s2 chi^2_{K-3} -- the true tangent plane's
 * is s2 chi^2_K, the plane's three parameters take three degrees of freedom,
 * and curvature only adds to it. A smaller value, K l3 < s2 (K - 3) q with q
 * the lower LOF_ALPHA / nk quantile of chi^2_{K-3} / (K - 3) (Wilson-Hilferty;
 * z = ksel_level_z(nk)), rejects that the PCA plane is the surface's tangent
 * plane: the noise lies in the plane, as where the K points sample a plane
 * curve whose plane holds the surface normal (ring-sampled CAD vertices).
 * The test needs the noise resolved: a ball of radius R_K keeps only the
 * heights within about R_K of the point, so it is made only where R_K is at
 * least THIN_RES noise deviations (the noise estimate's own condition,
 * kselect_noise.c). */
#define THIN_RES 5.0
int ksel_thin_plane(int K, double l3, double rk2, double s2, double z) {
  if (!(s2 > 0) || K <= 3 || rk2 < THIN_RES * THIN_RES * s2) return 0;
  return K * l3 < (K - 3) * s2 * bsurf_chi2_ratio_wh(K - 3, -z);
}

/* Whether K points are a surface patch rather than a curve's run: their two
 * tangent eigenvalues l1 >= l2 (ev ascending, ev[2] and ev[1]) no more
 * unequal than K points uniform on a disc give at the level LOF_ALPHA. On a
 * disc of radius r (the K nearest of a surface point) the coordinates' second
 * moments are r^2 / 4 and the fourth E x^4 = r^4 / 8, E x^2 y^2 = r^4 / 24, so
 * the sample covariance's a - b and 2 c (a, b the variances, c the
 * covariance) are asymptotically independent N(0, r^4 / (6 K)), and
 * (l1 - l2)^2 = (a - b)^2 + 4 c^2 is r^4 / (6 K) times chi^2_2, whose upper
 * tail is exp(-x / 2); with l1 + l2 -> r^2 / 2 the ratio q = (l1 - l2) /
 * (l1 + l2) exceeds 2 sqrt(-ln(alpha) / (3 K)) with probability alpha.
 * About the sample centroid (PCA_CENTROID) the covariance has K - 1
 * degrees of freedom, as a Wishart's n = K - 1, and K - 1 in place of K
 * gives the level at finite K (numpy, 200,000 discs: 4.7%, 5.1%, 5.0% at
 * K = 10, 30, 80 against 6.8%, 5.6%, 5.2% with K; a point's K nearest in a
 * uniform plane, the point at the centre: 6.0%, 5.5%, 5.3%). A run
 * of a curve (a ring's arc, a feature curve's vertices) has l2 of the order
 * of the noise and q near 1; but K points spread evenly over most of a
 * closed curve's turn are as isotropic as a disc (a full circle has q = 0;
 * at K = 80 an even arc above about 290 degrees passes), so where K_max
 * holds most of one ring (a thin limb) the test reads a patch and the
 * ring's plane for the surface's. ksel_disc_level gives the critical value
 * once a run. */
double ksel_disc_level(int K) {
  return 2.0 * sqrt(-log(LOF_ALPHA) / (3.0 * (K - 1)));
}

int ksel_disc(const double ev[3], double q) {
  return (ev[2] - ev[1]) <= q * (ev[2] + ev[1]);
}

/* Which of the thin plane's two explanations holds (docs/normals.md,
 * "Planes thinner than the noise"). ksel_thin_plane rejects that the K
 * points' plane is a surface's tangent plane *with the cloud's noise
 * level*; it does not say which of the two alternatives holds: a plane
 * curve whose plane holds the surface normal (a ring: the plane is a
 * cross-section, its normal perpendicular to the surface's), or the surface
 * itself with less noise there than the level (a clean patch of a cloud
 * whose noise, or misfit read as noise, lies elsewhere: the plane is the
 * tangent plane, its normal the surface's). The K_max neighbours' PCA
 * normal N stands for the surface's (beyond the rings) where they are a
 * surface patch (ksel_disc; a run of one ring is a curve, and its PCA
 * normal the ring plane's: kselect.c asks both); n is the thin
 * plane's. 1 where n is nearer parallel to N than perpendicular, (n . N)^2
 * >= 1/2: the nearer of the two hypotheses at equal angular distance, as
 * the cross-section noise's own test (kselect_noise.c, section_noise). */
int ksel_same_plane(const double n[3], const double N[3]) {
  const double d = n[0] * N[0] + n[1] * N[1] + n[2] * N[2];
  return d * d >= 0.5;
}

int ksel_lof_gate(const double *rssv, const int *ks, int nk, double s2, double z, int *gate) {
  int on = 0, any = 0;
  for (int a = 0; a < nk; a++) {
    const double nu = ks[a] - QT;
    const int rej = isfinite(rssv[a]) && s2 > 0 && rssv[a] > s2 * bsurf_chi2_ratio_wh(nu, z);
    if (a == 0 && rej) { /* not resolved at the smallest candidate: no gate */
      for (int b = 0; b < nk; b++)
        gate[b] = 0;
      return 0;
    }
    on |= rej;
    gate[a] = on;
    any |= on;
  }
  return any;
}

void ksel_emp_bias(const ksel_ctx *c, const uint32_t *idx, const double *nrm, const double *var,
                   const int *gate, int nk, double *eb) {
  double wsum = 0;
  int m = 0;
  for (int a = 0; a < nk; a++)
    eb[a] = 0;
  for (int j = 0; j < c->o->noise_k; j++) {
    const uint32_t r = idx[j];
    if (r == idx[0]) continue;
    const double w = 1.0 / c->bmref[r];
    if (w > 0) wsum += w, m++;
  }
  if (!(wsum > 0)) return; /* no assessed reference */
  const double R = m / wsum;
  for (int a = 0; a < nk; a++) {
    if (!gate[a] || !isfinite(var[a])) continue;
    const double *na = &nrm[3 * a];
    double t = 0;
    for (int j = 0; j < c->o->noise_k; j++) {
      const uint32_t r = idx[j];
      if (r == idx[0]) continue;
      const double w = 1.0 / c->bmref[r];
      if (!(w > 0)) continue;
      const double *nr = &c->bref[3 * (size_t)r];
      t += w * ksel_sin2(na, nr);
    }
    const double b = t / wsum - R - var[a];
    eb[a] = b > 0 ? b : 0;
  }
}
