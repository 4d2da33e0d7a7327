/* Nested neighbourhoods: the moments of every candidate K from one pass over
 * a point's sorted neighbours (issue 25's machinery; one shared piece).
 *
 * The K nearest neighbours of a point are a prefix of its K_max nearest, so
 * running sums of q = p_j - d and q q^T over j = 0..K_max-1, read off at each
 * candidate K, give every candidate's centroid and covariance (the PCA of
 * thesis 2.2 / 5.2) at the cost of one K_max-point sum instead of one sum
 * per candidate. Sums are relative to the point d for accuracy far from the
 * origin; the covariance is formed as S2/K - mu mu^T, which loses no
 * accuracy that matters at neighbourhood scale (|mu| is at most the
 * neighbourhood radius). */
#include "local/local.h"

void bsurf_nested_moments(const double *xyz, const uint32_t *idx, const int *ks, int nk, double *mu,
                          double *cov) {
  const double *d = &xyz[3 * (size_t)idx[0]];
  double s1[3] = {0, 0, 0}, s2[6] = {0, 0, 0, 0, 0, 0};
  int j = 0;
  for (int a = 0; a < nk; a++) {
    for (; j < ks[a]; j++) {
      const double *p = &xyz[3 * (size_t)idx[j]];
      const double q0 = p[0] - d[0], q1 = p[1] - d[1], q2 = p[2] - d[2];
      s1[0] += q0;
      s1[1] += q1;
      s1[2] += q2;
      s2[0] += q0 * q0;
      s2[1] += q0 * q1;
      s2[2] += q0 * q2;
      s2[3] += q1 * q1;
      s2[4] += q1 * q2;
      s2[5] += q2 * q2;
    }
    const double inv = 1.0 / ks[a];
    double *m = &mu[3 * a], *c = &cov[6 * a];
    for (int t = 0; t < 3; t++)
      m[t] = s1[t] * inv;
    c[0] = s2[0] * inv - m[0] * m[0];
    c[1] = s2[1] * inv - m[0] * m[1];
    c[2] = s2[2] * inv - m[0] * m[2];
    c[3] = s2[3] * inv - m[1] * m[1];
    c[4] = s2[4] * inv - m[1] * m[2];
    c[5] = s2[5] * inv - m[2] * m[2];
  }
}
