/* The best split of sorted values into two groups (two-means in one
 * dimension): the two-sheet tests of the smoothing guard (smooth_guard.c)
 * and of K selection (kselect.c) share it. */
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
