/* The best split of sorted values into two groups (two-means in one
 * dimension): the two-sheet tests of the smoothing guard (smooth_guard.c),
 * of K selection (kselect.c) and of the variance features
 * (features_variance.c) share it. */
#include "common/common.h"

#include <math.h>

double bsurf_split_share(const double *v, int n, int q, double min_total, double *cut) {
  if (cut) *cut = NAN;
  if (q < 1) q = 1;
  if (n < 2 * q) return 1.0;
  double s1 = 0, s2 = 0;
  for (int i = 0; i < n; i++)
    s1 += v[i], s2 += v[i] * v[i];
  const double tot = s2 - s1 * s1 / n;
  if (!(tot > min_total) || !(tot > 0)) return 1.0;
  double l1 = 0, l2 = 0, best = 1.0;
  for (int i = 0; i < n - q; i++) {
    l1 += v[i], l2 += v[i] * v[i];
    const int nl = i + 1, nr = n - nl;
    if (nl < q) continue;
    const double r1 = s1 - l1, r2 = s2 - l2;
    const double share = ((l2 - l1 * l1 / nl) + (r2 - r1 * r1 / nr)) / tot;
    if (share < best) {
      best = share;
      if (cut) *cut = 0.5 * (v[i] + v[i + 1]);
    }
  }
  return best;
}

/* Two sheets mixed: the best split of the sorted residuals v[0..n-1] into
 * two groups, as a test. For any symmetric unimodal noise the split at the
 * centre leaves at least a quarter of the variance within the groups (such a
 * distribution is a mixture of uniforms U[-a, a] (Khintchine), whose
 * within-group share is 1 - 3/4 (E a)^2 / E a^2 >= 1/4 by Jensen; 1/4 for a
 * single uniform, 1 - 2/pi for a Gaussian), while two sheets farther apart
 * than their noise leave less (two uniform sheets 1.27 noise half-widths
 * apart: 0.17). The sample share, minimised over the splits with at least
 * q = max(n/4, 3) points a side, is below 1/4 - 0.635 / sqrt(n) with
 * probability 1% for uniform noise (the least favourable unimodal case:
 * simulated, n = 12 to 200, 4,000 draws each; the constant varies by 1% over
 * that range). Residuals whose spread is rounding (sum of squares not above
 * n tiny^2) are not tested. */
int bsurf_split_bimodal(const double *v, int n, double tiny, double *cut) {
  const double share = bsurf_split_share(v, n, n / 4 > 3 ? n / 4 : 3, (double)n * tiny * tiny, cut);
  return share < 0.25 - 0.635 / sqrt((double)n);
}
