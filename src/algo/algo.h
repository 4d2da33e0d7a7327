/* Internal to src/algo: the per-point bootstrap fit of chapter 4, shared by
 * the error estimates (error.c) and the smoothing of chapter 6 (smooth.c),
 * so both run the very same fits. */
#ifndef BSURF_ALGO_H
#define BSURF_ALGO_H

#include "bootstrap/bootstrap.h"
#include "local/local.h"

/* One thread's scratch for bsurf_error_point. */
typedef struct bsurf_error_scratch {
  bsurf_localfit lf;
  double *pred_full; /* k */
  double *pred_boot; /* B x k */
  uint16_t *counts;  /* 4 x k: four replicates' multiplicities */
  double *weights;   /* R x k, R = B + 1 rounded up to 4: counts as doubles,
                        row B all ones (the full fit), then zero rows */
  double *missing;   /* B x k: 1 where the point is not in the replicate */
  double *rows;      /* R x ncols: normal equations (bsurf_gemm_lanes layout) */
  double *coefs;     /* B x terms */
  unsigned char *valid; /* B */
  double *est_scratch;  /* 6k + 1 */
  size_t skipped, reduced, center_unestimated;
} bsurf_error_scratch;

bsurf_status bsurf_error_scratch_alloc(bsurf_error_scratch *s, int k, int B, int degree);
void bsurf_error_scratch_free(bsurf_error_scratch *s);

/* What a point's fits leave beyond the estimators. */
typedef struct bsurf_error_fit {
  bsurf_frame frame;             /* PCA frame; origin = the point itself */
  double inv_scale;              /* u = x' * inv_scale, v = y' * inv_scale */
  int degree;                    /* degree of the full fit (may be reduced) */
  double coef[BSURF_TERMS_MAX];  /* full fit, zero-padded to the asked degree */
  double boot_center;            /* (1/B) sum_b f*b(x_0) over valid replicates:
                                    the height of Eq. 6.1 (the full fit's when
                                    no replicate is valid) */
  bsurf_boot_result r;           /* the estimators */
} bsurf_error_fit;

/* Algorithm 1 at point i with neighbourhood idx[0..o->k-1] (idx[0] = i):
 * writes the point's entries of `out` (whose pointers may be NULL) and, when
 * `fit` is not NULL, fills it. test_xyz may be NULL. */
void bsurf_error_point(const double *xyz, const uint32_t *idx, const double *test_xyz,
                       const bsurf_error_options *o, size_t i, bsurf_error_scratch *s,
                       bsurf_error_fields *out, bsurf_error_fit *fit);

/* Validates error options against the neighbourhoods (as bsurf_estimate_error). */
bsurf_status bsurf_error_check(const bsurf_error_options *o, const bsurf_neighbors *nb);

#endif
