/* The bootstrap engine (thesis chapter 4): resampling and the estimators. */
#ifndef BSURF_BOOTSTRAP_H
#define BSURF_BOOTSTRAP_H

#include "bootsurf.h"

/* Multinomial counts of one bootstrap sample S_b (4.1.1): k draws with
 * replacement from k points; counts out: k. The draws come from the stream
 * keyed by (seed, point, replicate), so they do not depend on threads. */
void bsurf_boot_counts(uint64_t seed, uint64_t point, uint32_t replicate, int k, uint16_t *counts);

/* The counts of nrep (<= 4) consecutive replicates replicate, replicate + 1,
 * ... (counts out: nrep x k), exactly those of bsurf_boot_counts, four
 * streams at a time in vector lanes. draws (nrep x k, may be NULL): each
 * replicate's k indices in the order they were drawn (the accepted draws
 * of the stream's first k, then the replacements of rejected ones). */
void bsurf_boot_counts4(uint64_t seed, uint64_t point, uint32_t replicate, int nrep, int k,
                        uint16_t *counts, uint16_t *draws);
/* bsurf_boot_counts4's counts interleaved: replicate l's count of point j
 * at counts[4 j + l] (4k; lanes l >= nrep zero), the layout of four lanes
 * of weights. */
void bsurf_boot_counts4_lanes(uint64_t seed, uint64_t point, uint32_t replicate, int nrep, int k,
                              uint16_t *counts);

/* The multiplicities of B resamples (Eq. 4.2; replicate b the stream (seed,
 * point, b), as bsurf_boot_counts) as weights in vector lanes: Wt (k x B,
 * Wt[j B + b]), the layout of bsurf_nested_sums, whose distinct counts then
 * tell how many points each replicate drew. counts: 4k scratch. */
void bsurf_boot_weight_lanes(uint64_t seed, uint64_t point, int B, int k, uint16_t *counts,
                             double *Wt);
/* The B resamples of bsurf_boot_weight_lanes as integers only: counts (B x
 * k) the multiplicities, draws (B x k) the indices in the order drawn,
 * valid[b] as there. For the fits from draws (bsurf_localfit_normal_eq_draws)
 * and the residual sums, which read counts where the dense product read
 * weights: a quarter of the bytes. */
void bsurf_boot_draw_rows(uint64_t seed, uint64_t point, int B, int k, int min_distinct,
                          uint16_t *counts, uint16_t *draws, unsigned char *valid);
/* Poisson(1) weights of B replicates over a sorted neighbour list of kmax
 * points (the nested resampling of docs/normals.md): replicate b takes the
 * stream (seed, point, b); neighbour j gets an independent Poisson(1) count,
 * j = 0, 1, ... in order, from the 32-bit halves of the stream's outputs
 * (low half first) by inversion. Restricted to the first K neighbours the
 * counts are the Poisson bootstrap of that K-point neighbourhood, for every
 * K at once, so nested candidates share (and are compared on) the same
 * resamples. Wt out: kmax x B, transposed (Wt[j B + b], the layout of
 * bsurf_nested_sums); u (kmax) scratch. */
void bsurf_boot_poisson_rows(uint64_t seed, uint64_t point, int B, int kmax, uint32_t *u,
                             double *Wt);
/* The number of distinct points of a resample: its nonzero counts (k). */
int bsurf_boot_distinct(int k, const uint16_t *counts);
/* B + 1 rows rounded up to a multiple of 4 (whole groups of vector lanes). */
int bsurf_boot_rows(int B);

/* gamma = 1/k^2 sum_j sum_l |pred_j - y_l| (Eq. 4.10), in O(k log k) by
 * sorting. y_sorted: the k observed heights in ascending order; y_prefix:
 * k+1 prefix sums of y_sorted; scratch: k doubles. */
double bsurf_boot_gamma(int k, const double *pred, const double *y_sorted, const double *y_prefix,
                        double *scratch);

/* Reference O(k^2) version of Eq. 4.10 for the tests. */
double bsurf_boot_gamma_naive(int k, const double *pred, const double *y);

/* Sorts ascending (insertion sort for small n, otherwise qsort). */
void bsurf_sort_doubles(double *a, int n);

typedef struct bsurf_boot_result {
  double err_train, err_boot, err_loo, err_loo_center, err_632, err_632plus;
  double gamma, overfit_rate;
  int valid_replicates;   /* replicates with a full-rank fit */
  int center_unestimated; /* no valid replicate missed the centre */
} bsurf_boot_result;

/* The estimators of chapter 4 for one neighbourhood of k points, the centre
 * being point 0:
 *   y          in: k observed heights y_j
 *   pred_full  in: k predictions of the fit to the whole neighbourhood f(x_j)
 *   pred_boot  in: B x k predictions of the replicates' fits f*b(x_j)
 *   missing    in: B x k, 1.0 where point j is not in S_b (b in C_j), else 0.0
 *   valid      in: B, 0 for a replicate whose fit failed (skipped)
 *   scratch    6k + 1 doubles
 * gamma follows `mode` (Eq. 4.10 on the full fit, or the mean or maximum over
 * the replicates of the same formula with f*b, 4.2.1). */
void bsurf_boot_estimate(int k, int B, const double *y, const double *pred_full,
                         const double *pred_boot, const double *missing, const unsigned char *valid,
                         bsurf_gamma_mode mode, double *scratch, bsurf_boot_result *out);

/* The same estimators from per-point sums over the nvalid valid replicates,
 * each summed over b in increasing order: boot_j[j] = sum_b |f*b(x_j) - y_j|,
 * loo_sum[j] = the same over b in C_j, loo_cnt[j] = |C_j|; gamma_sum and
 * gamma_max: sum and maximum over the replicates of Eq. 4.10 with f*b (used
 * by the modes mean and max only). scratch: 3k + 1 doubles. This is the
 * second half of bsurf_boot_estimate (same bits). */
void bsurf_boot_estimate_sums(int k, int nvalid, const double *y, const double *pred_full,
                              const double *boot_j, const double *loo_sum, const double *loo_cnt,
                              double gamma_sum, double gamma_max, bsurf_gamma_mode mode,
                              double *scratch, bsurf_boot_result *out);

#endif
