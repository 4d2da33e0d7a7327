/* PCA and the local frame of a neighbourhood (thesis 2.2 Eq. 2.1, 3.3
 * Eqs. 3.4-3.6).
 *
 * M (Eq. 3.4) has rows X', Y', n. Because M maps X' to X, a point's local
 * coordinates are p' = M (p - d): the thesis's Eq. 3.5 prints M^T, which is
 * the inverse rotation; applying it would put a point lying on the tangent
 * plane at a non-zero height (tests/test_local.c checks this). Going back
 * (Eq. 3.6) is then p = M^T p' + d. */
#include "local/local.h"

#include <math.h>

/* Flip v so that its component of largest magnitude is positive: PCA
 * eigenvectors have an arbitrary sign, this makes frames canonical. */
static void canonical_sign(double v[3]) {
  int best = 0;
  for (int i = 1; i < 3; i++)
    if (fabs(v[i]) > fabs(v[best])) best = i;
  if (v[best] < 0)
    for (int i = 0; i < 3; i++)
      v[i] = -v[i];
}

void bsurf_local_frame(const double *xyz, const uint32_t *idx, int k, bsurf_pca_center center,
                       bsurf_frame *frame) {
  const double *d = &xyz[3 * (size_t)idx[0]];
  double c[3] = {d[0], d[1], d[2]};
  if (center == BSURF_PCA_CENTROID) {
    /* centroid, accumulated relative to d for accuracy far from the origin */
    double s[3] = {0, 0, 0};
    for (int j = 0; j < k; j++) {
      const double *p = &xyz[3 * (size_t)idx[j]];
      for (int t = 0; t < 3; t++)
        s[t] += p[t] - d[t];
    }
    for (int t = 0; t < 3; t++)
      c[t] = d[t] + s[t] / k;
  }
  double cov[3][3] = {{0}};
  for (int j = 0; j < k; j++) {
    const double *p = &xyz[3 * (size_t)idx[j]];
    double q[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    for (int a = 0; a < 3; a++)
      for (int b = a; b < 3; b++)
        cov[a][b] += q[a] * q[b];
  }
  for (int a = 0; a < 3; a++)
    for (int b = a; b < 3; b++) {
      cov[a][b] /= k;
      cov[b][a] = cov[a][b];
    }
  double ev[3][3];
  bsurf_eigen_sym3(cov, frame->eigenvalues, ev);
  double n[3] = {ev[0][0], ev[0][1], ev[0][2]};
  double x[3] = {ev[2][0], ev[2][1], ev[2][2]};
  canonical_sign(n);
  canonical_sign(x);
  /* Y' = n x X' makes (X', Y', n) right-handed. */
  double y[3] = {n[1] * x[2] - n[2] * x[1], n[2] * x[0] - n[0] * x[2], n[0] * x[1] - n[1] * x[0]};
  for (int t = 0; t < 3; t++) {
    frame->origin[t] = d[t];
    frame->rot[0][t] = x[t];
    frame->rot[1][t] = y[t];
    frame->rot[2][t] = n[t];
  }
}

void bsurf_frame_to_local(const bsurf_frame *f, const double p[3], double out[3]) {
  double q[3] = {p[0] - f->origin[0], p[1] - f->origin[1], p[2] - f->origin[2]};
  for (int r = 0; r < 3; r++)
    out[r] = f->rot[r][0] * q[0] + f->rot[r][1] * q[1] + f->rot[r][2] * q[2];
}

void bsurf_frame_dir_to_global(const bsurf_frame *f, const double l[3], double out[3]) {
  for (int t = 0; t < 3; t++)
    out[t] = f->rot[0][t] * l[0] + f->rot[1][t] * l[1] + f->rot[2][t] * l[2];
}

void bsurf_frame_to_global(const bsurf_frame *f, const double l[3], double out[3]) {
  bsurf_frame_dir_to_global(f, l, out);
  for (int t = 0; t < 3; t++)
    out[t] += f->origin[t];
}
