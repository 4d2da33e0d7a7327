/* Order statistics shared by every layer: the qsort comparisons (doubles,
 * 64- and 32-bit keys) and the median (the features' noise levels and filters, the smoothing
 * guard's robust scale, K selection's pooling, the angle statistics of
 * eval). One rule for the median of an even count: the mean of the two
 * middle values. */
#include "common/common.h"

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
