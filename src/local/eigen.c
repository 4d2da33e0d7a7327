/* Symmetric 3x3 eigen-decomposition for PCA (thesis 2.2, 3.3).
 *
 * Cyclic Jacobi: a few sweeps of plane rotations, each annihilating one
 * off-diagonal entry. It is accurate for nearly equal eigenvalues (flat or
 * isotropic neighbourhoods), where closed-form cubic solutions lose digits,
 * and its arithmetic is fixed, so results are reproducible. */
#include "local/local.h"

#include <math.h>
#include <string.h>

void bsurf_eigen_sym3(double a_in[3][3], double evals[3], double evecs[3][3]) {
  double a[3][3], v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  memcpy(a, a_in, sizeof a);
  for (int sweep = 0; sweep < 50; sweep++) {
    double off = fabs(a[0][1]) + fabs(a[0][2]) + fabs(a[1][2]);
    double diag = fabs(a[0][0]) + fabs(a[1][1]) + fabs(a[2][2]);
    if (off == 0.0 || off <= 1e-300 || off < 1e-18 * diag) break;
    for (int p = 0; p < 2; p++) {
      for (int q = p + 1; q < 3; q++) {
        double apq = a[p][q];
        if (apq == 0.0) continue;
        double theta = (a[q][q] - a[p][p]) / (2.0 * apq);
        double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
        if (!isfinite(t)) t = 0.0; /* theta overflowed: apq negligible */
        double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
        for (int k = 0; k < 3; k++) { /* A <- J^T A J */
          double akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < 3; k++) {
          double apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 3; k++) { /* V <- V J, columns are eigenvectors */
          double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
    }
  }
  int order[3] = {0, 1, 2};
  double d[3] = {a[0][0], a[1][1], a[2][2]};
  for (int i = 1; i < 3; i++) /* stable insertion sort, ascending */
    for (int j = i; j > 0 && d[order[j]] < d[order[j - 1]]; j--) {
      int t = order[j];
      order[j] = order[j - 1];
      order[j - 1] = t;
    }
  for (int i = 0; i < 3; i++) {
    evals[i] = d[order[i]];
    for (int k = 0; k < 3; k++) evecs[i][k] = v[k][order[i]];
  }
}
