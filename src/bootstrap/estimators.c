/* Bootstrap test-error estimators (thesis 4.1.2 and 4.2).
 *
 *  err_train       Eq. 4.6   (1/K) sum_j |f(x_j) - y_j|
 *  err_boot        Eq. 4.3   (1/(B K)) sum_b sum_j |f*b(x_j) - y_j|
 *  err_loo         Eq. 4.4   (1/K) sum_j (1/|C_j|) sum_{b in C_j} |f*b(x_j) - y_j|
 *  err_loo_center  Eq. 4.11  the same for the centre point only
 *  err_632         Eq. 4.5   .368 err_train + .632 err_loo
 *  err_632plus     Eqs. 4.7-4.10 (1 - w) err_train + w err_loo,
 *                  w = .632 / (1 - .368 R), R = (err_loo - err)/(gamma - err)
 *
 * Conventions where the thesis is silent:
 *  - B counts only the replicates whose fit is full rank (the others are
 *    skipped and counted by the caller);
 *  - in Eq. 4.4, points that are in every valid replicate (|C_j| = 0) are left
 *    out of the average over j (Efron 1983); if every point is, err_loo falls
 *    back to err_boot;
 *  - R is clipped to [0, 1] (4.2.1) and is 0 when gamma <= err_train or
 *    err_loo <= err_train (no measurable overfitting), so w is in [.632, 1];
 *  - with no valid replicate at all, every bootstrap estimate equals
 *    err_train and R = 0 (nothing is known beyond the training error). */
#include "bootstrap/bootstrap.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Sorts up to 128 values by counting each one's rank: value i goes to the
 * number of values below it plus the equal ones before it (a stable sort,
 * as the insertion sort this replaced, so even -0 and +0 keep their order).
 * K^2 comparisons, but branch-free and vectorised: a point's two sorts
 * (heights and predictions, for gamma) were ~5% of `error` as an insertion
 * sort, mostly mispredicted branches. */
#if defined(__GNUC__)
typedef double v4d_ __attribute__((vector_size(32)));
typedef long long v4l_ __attribute__((vector_size(32)));
#endif

BSURF_CLONES
static void rank_sort(double *a, int n) {
#if defined(__GNUC__)
  /* padded with +inf, which no finite value exceeds or equals */
  double v[128 + 4];
  for (int i = 0; i < n; i++)
    v[i] = a[i];
  for (int i = n; i < (n + 3) / 4 * 4; i++)
    v[i] = INFINITY;
  for (int i = 0; i < n; i++) {
    const double x = v[i];
    const v4d_ xv = {x, x, x, x};
    const v4l_ iv = {i, i, i, i};
    v4l_ cnt = {0, 0, 0, 0}, jv = {0, 1, 2, 3};
    const v4l_ four = {4, 4, 4, 4};
    for (int j = 0; j < n; j += 4) { /* below x, or equal and before: -1 per lane */
      v4d_ y;
      memcpy(&y, &v[j], sizeof y);
      cnt += (v4l_)(y < xv) | ((v4l_)(y == xv) & (jv < iv));
      jv += four;
    }
    a[-(cnt[0] + cnt[1] + cnt[2] + cnt[3])] = x;
  }
#else
  double v[128];
  for (int i = 0; i < n; i++)
    v[i] = a[i];
  for (int i = 0; i < n; i++) {
    const double x = v[i];
    int r = 0;
    for (int j = 0; j < i; j++)
      r += v[j] <= x;
    for (int j = i + 1; j < n; j++)
      r += v[j] < x;
    a[r] = x;
  }
#endif
}

void bsurf_sort_doubles(double *a, int n) {
  if (n > 128) { /* (up to 128 the MSE rule's two-sheet residuals, K_max = 80) */
    qsort(a, (size_t)n, sizeof *a, bsurf_cmp_double);
    return;
  }
  rank_sort(a, n);
}

double bsurf_boot_gamma(int k, const double *pred, const double *y_sorted, const double *y_prefix,
                        double *scratch) {
  /* For sorted predictions a and sorted observations y,
   *   sum_l |a_j - y_l| = (c a_j - S_c) + ((S_k - S_c) - (k - c) a_j)
   * where c = #{y_l <= a_j} and S_c the sum of the first c values; c only
   * grows with j, so one merge pass does all of them. */
  for (int j = 0; j < k; j++)
    scratch[j] = pred[j];
  bsurf_sort_doubles(scratch, k);
  double total = 0;
  int c = 0;
  for (int j = 0; j < k; j++) {
    double a = scratch[j];
    while (c < k && y_sorted[c] <= a)
      c++;
    total += (c * a - y_prefix[c]) + ((y_prefix[k] - y_prefix[c]) - (k - c) * a);
  }
  return total / ((double)k * (double)k);
}

double bsurf_boot_gamma_naive(int k, const double *pred, const double *y) {
  double total = 0;
  for (int j = 0; j < k; j++)
    for (int l = 0; l < k; l++)
      total += fabs(pred[j] - y[l]);
  return total / ((double)k * (double)k);
}

/* One replicate's part of Eqs. 4.3, 4.4: elementwise over the points. Kept
 * out of line: inlined into the replicate loop, GCC loses the restrict
 * qualifiers and does not vectorise it. */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
BSURF_CLONES static void
accumulate_replicate(int k, const double *restrict pb, const double *restrict mb,
                     const double *restrict y, double *restrict boot_j, double *restrict loo_sum,
                     double *restrict loo_cnt) {
  for (int j = 0; j < k; j++) {
    /* mb[j] = 1 when point j is not in the replicate (b in C_j); e is finite
     * (a full-rank fit's prediction), so mb[j] * e adds exactly e or +0 */
    const double e = fabs(pb[j] - y[j]);
    boot_j[j] += e;
    loo_sum[j] += mb[j] * e;
    loo_cnt[j] += mb[j];
  }
}

static void sort_heights(int k, const double *y, double *y_sorted, double *y_prefix) {
  for (int j = 0; j < k; j++)
    y_sorted[j] = y[j];
  bsurf_sort_doubles(y_sorted, k);
  y_prefix[0] = 0;
  for (int j = 0; j < k; j++)
    y_prefix[j + 1] = y_prefix[j] + y_sorted[j];
}

BSURF_CLONES
void bsurf_boot_estimate(int k, int B, const double *y, const double *pred_full,
                         const double *pred_boot, const double *missing, const unsigned char *valid,
                         bsurf_gamma_mode mode, double *scratch, bsurf_boot_result *out) {
  double *y_sorted = scratch;                     /* k */
  double *y_prefix = scratch + k;                 /* k + 1 */
  double *gscratch = scratch + 2 * (size_t)k + 1; /* k */
  double *loo_sum = scratch + 3 * (size_t)k + 1;  /* k */
  double *loo_cnt = scratch + 4 * (size_t)k + 1;  /* k */
  double *boot_j = scratch + 5 * (size_t)k + 1;   /* k */
  if (mode != BSURF_GAMMA_FIT) sort_heights(k, y, y_sorted, y_prefix);

  /* Eq. 4.3 summed per point j (then over j), and Eqs. 4.4 / 4.11: for each
   * point j, the replicates b in C_j (those not containing j); each sum runs
   * over b = 0, 1, ... in order, elementwise over j (vectorised). */
  double gamma_sum = 0, gamma_max = 0;
  int nvalid = 0;
  for (int j = 0; j < k; j++)
    boot_j[j] = loo_sum[j] = loo_cnt[j] = 0;
  for (int b = 0; b < B; b++) {
    if (!valid[b]) continue;
    nvalid++;
    const double *pb = &pred_boot[(size_t)b * k];
    accumulate_replicate(k, pb, &missing[(size_t)b * k], y, boot_j, loo_sum, loo_cnt);
    if (mode != BSURF_GAMMA_FIT) {
      /* the replicate's fit evaluated on the original neighbourhood */
      double g = bsurf_boot_gamma(k, pb, y_sorted, y_prefix, gscratch);
      gamma_sum += g;
      if (g > gamma_max) gamma_max = g;
    }
  }
  bsurf_boot_estimate_sums(k, nvalid, y, pred_full, boot_j, loo_sum, loo_cnt, gamma_sum, gamma_max,
                           mode, scratch, out);
}

void bsurf_boot_estimate_sums(int k, int nvalid, const double *y, const double *pred_full,
                              const double *boot_j, const double *loo_sum, const double *loo_cnt,
                              double gamma_sum, double gamma_max, bsurf_gamma_mode mode,
                              double *scratch, bsurf_boot_result *out) {
  double *y_sorted = scratch;                     /* k */
  double *y_prefix = scratch + k;                 /* k + 1 */
  double *gscratch = scratch + 2 * (size_t)k + 1; /* k */
  sort_heights(k, y, y_sorted, y_prefix);

  double err = 0; /* Eq. 4.6 */
  for (int j = 0; j < k; j++)
    err += fabs(pred_full[j] - y[j]);
  err /= k;
  double gamma_fit = bsurf_boot_gamma(k, pred_full, y_sorted, y_prefix, gscratch);

  double boot_sum = 0;
  for (int j = 0; j < k; j++)
    boot_sum += boot_j[j];
  double loo = 0, loo_center = 0;
  int loo_points = 0, center_ok = 0;
  for (int j = 0; j < k; j++) {
    if (loo_cnt[j] > 0) {
      loo += loo_sum[j] / loo_cnt[j];
      loo_points++;
      if (j == 0) {
        loo_center = loo_sum[j] / loo_cnt[j];
        center_ok = 1;
      }
    }
  }

  out->err_train = err;
  out->valid_replicates = nvalid;
  out->center_unestimated = 0;
  if (nvalid == 0) {
    out->err_boot = out->err_loo = out->err_loo_center = err;
    out->err_632 = out->err_632plus = err;
    out->gamma = gamma_fit;
    out->overfit_rate = 0;
    out->center_unestimated = 1;
    return;
  }
  out->err_boot = boot_sum / ((double)nvalid * k);
  out->err_loo = loo_points > 0 ? loo / loo_points : out->err_boot;
  if (center_ok) {
    out->err_loo_center = loo_center;
  } else {
    out->err_loo_center = out->err_loo;
    out->center_unestimated = 1;
  }
  double gamma = gamma_fit;
  if (mode == BSURF_GAMMA_MEAN) gamma = gamma_sum / nvalid;
  if (mode == BSURF_GAMMA_MAX) gamma = gamma_max;
  out->gamma = gamma;
  out->err_632 = 0.368 * err + 0.632 * out->err_loo; /* Eq. 4.5 */
  double R = 0;                                      /* Eq. 4.9, clipped */
  if (gamma > err && out->err_loo > err) {
    R = (out->err_loo - err) / (gamma - err);
    if (R > 1) R = 1;
  }
  double w = 0.632 / (1.0 - 0.368 * R); /* Eq. 4.8 */
  out->overfit_rate = R;
  out->err_632plus = (1.0 - w) * err + w * out->err_loo; /* Eq. 4.7 */
}
