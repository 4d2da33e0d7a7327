/* Order statistics shared by every layer: the qsort comparisons (doubles,
 * 64- and 32-bit keys) and the median (the features' noise levels and filters, the smoothing
 * guard's robust scale, K selection's pooling, the angle statistics of
 * eval). One rule for the median of an even count: the mean of the two
 * middle values. */
#include "common/common.h"

#include <math.h>

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

int bsurf_cmp_double(const void *pa, const void *pb) {
  const double a = *(const double *)pa, b = *(const double *)pb;
  return (a > b) - (a < b);
}

int bsurf_cmp_u64(const void *pa, const void *pb) {
  const uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
  return (a > b) - (a < b);
}

int bsurf_cmp_u32(const void *pa, const void *pb) {
  const uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
  return (a > b) - (a < b);
}

double bsurf_median_sorted(const double *v, size_t n) {
  if (!n) return 0;
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double bsurf_median(double *v, size_t n) {
  if (!n) return 0;
  qsort(v, n, sizeof *v, bsurf_cmp_double);
  return bsurf_median_sorted(v, n);
}

double bsurf_kth_smallest(double *v, size_t n, size_t k) {
  /* Wirth's selection (Hoare's partition about the median of the first,
   * middle and last, which is one of the values: the scans stop at it) */
  ptrdiff_t lo = 0, hi = (ptrdiff_t)n - 1;
  const ptrdiff_t kk = (ptrdiff_t)k;
  while (lo < hi) {
    const double a = v[lo], b = v[lo + (hi - lo) / 2], c = v[hi];
    const double p = a < b ? (b < c ? b : a < c ? c : a) : (a < c ? a : b < c ? c : b);
    ptrdiff_t i = lo, j = hi;
    while (i <= j) {
      while (v[i] < p)
        i++;
      while (v[j] > p)
        j--;
      if (i <= j) {
        const double t = v[i];
        v[i++] = v[j];
        v[j--] = t;
      }
    }
    /* v[lo..j] <= p <= v[i..hi], and what lies between equals p */
    if (kk <= j)
      hi = j;
    else if (kk >= i)
      lo = i;
    else
      break;
  }
  return v[k];
}

double bsurf_chi2_ratio_wh(double nu, double z) {
  const double a = 2.0 / (9.0 * nu), b = 1.0 - a + z * sqrt(a);
  return b > 0 ? b * b * b : 0.0;
}

double bsurf_f_quantile_paulson(double nu1, double nu2, double z) {
  /* Paulson (1942), Ann. Math. Statist. 13: with y = F^(1/3), a = 2 / (9
   * nu1), b = 2 / (9 nu2), ((1 - b) y - (1 - a)) / sqrt(b y^2 + a) is about
   * standard normal; solved for y, the root on z's side of the median */
  const double a = 2.0 / (9.0 * nu1), b = 2.0 / (9.0 * nu2);
  const double A = (1.0 - b) * (1.0 - b) - z * z * b, B = (1.0 - a) * (1.0 - b);
  const double C = (1.0 - a) * (1.0 - a) - z * z * a, D = B * B - A * C;
  if (!(A > 0) || D < 0) return z > 0 ? INFINITY : 0.0;
  const double y = (B + (z > 0 ? 1.0 : -1.0) * sqrt(D)) / A;
  return y > 0 ? y * y * y : 0.0;
}
