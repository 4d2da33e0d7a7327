/*
 * neighbors.c — the K-nearest neighbourhoods of a whole cloud, computed once
 * and shared by every stage, and the cloud's unit length h.
 *
 * Thesis 3.3: each point d_i is analysed within its neighbourhood P_i of the
 * K nearest points (here d_i itself first). The thesis measures noise levels,
 * displacements and filter widths in units of h, "the average, throughout the
 * model, of the distance between a point and its nearest neighbour" (4.2, 5.x,
 * 6.x), which is what bsurf_neighbors_build and bsurf_mean_spacing return.
 *
 * h is summed in point-index order with a fixed pairwise (cascade) summation
 * after the parallel search, so it is bit-identical for any thread count.
 */
#include "search/search.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

double bsurf_sum_sqrt(const double *v, size_t n) {
  if (n <= 64) {
    double s = 0.0;
    for (size_t i = 0; i < n; i++)
      s += sqrt(v[i]);
    return s;
  }
  return bsurf_sum_sqrt(v, n / 2) + bsurf_sum_sqrt(v + n / 2, n - n / 2);
}

/* Builds a temporary index and runs the all-kNN; idx may be NULL; order
 * (may be NULL) receives the tree order of the points. */
static bsurf_status knn_with_spacing(const double *xyz, size_t point_count, int k, int threads,
                                     uint32_t *idx, uint32_t *order, double *h,
                                     bsurf_progress_fn progress, void *user) {
  /* The tree orders non-finite points too (bsurf_knn_*), but h and every
   * neighbourhood-based estimate would be NaN: refuse them here. */
  for (size_t i = 0; i < 3 * point_count; i++)
    if (!isfinite(xyz[i]))
      return bsurf_set_message(BSURF_ERR_INVALID_VALUE,
                               "point %zu has a NaN or infinite coordinate (%g)", i / 3, xyz[i]);
  bsurf_knn_index *index = NULL;
  double *nn;
  bsurf_status st;

  nn = bsurf_alloc_array(point_count, sizeof *nn);
  if (!nn) return BSURF_ERR_NOMEM;
  st = bsurf_knn_build_threads(&index, xyz, point_count, threads);
  if (st == BSURF_OK) {
    st = bsurf_knn_all_ex(index, k, threads, idx, NULL, nn, progress, user);
    if (order) memcpy(order, bsurf_knn_tree_ids(index), point_count * sizeof *order);
    bsurf_knn_free(index);
  }
  if (st == BSURF_OK) *h = bsurf_sum_sqrt(nn, point_count) / (double)point_count;
  free(nn);
  return st;
}

bsurf_status bsurf_neighbors_build(bsurf_neighbors *nb, const double *xyz, size_t point_count,
                                   int k, int threads, bsurf_progress_fn progress,
                                   void *progress_user) {
  bsurf_status st;
  uint32_t *idx;
  double h = 0.0;

  BSURF_REQUIRE(nb, "nb is NULL");
  memset(nb, 0, sizeof *nb);
  BSURF_REQUIRE(xyz, "xyz is NULL");
  BSURF_REQUIRE(k >= 2, "k = %d: must be at least 2 (the point and a neighbour)", k);
  BSURF_REQUIRE(point_count <= UINT32_MAX, "point_count = %zu: at most 2^32 - 1 points",
                point_count);
  if (point_count == 0 || (size_t)k > point_count)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS,
                             "bsurf_neighbors_build: k = %d exceeds the %zu points", k,
                             point_count);

  idx = bsurf_alloc_array(point_count, (size_t)k * sizeof *idx);
  uint32_t *order = bsurf_alloc_array(point_count, sizeof *order);
  if (!idx || !order) {
    free(idx);
    free(order);
    return BSURF_ERR_NOMEM;
  }
  st = knn_with_spacing(xyz, point_count, k, threads, idx, order, &h, progress, progress_user);
  if (st != BSURF_OK) {
    free(idx);
    free(order);
    return st;
  }
  nb->point_count = point_count;
  nb->k = k;
  nb->idx = idx;
  nb->order = order;
  nb->h = h;
  return BSURF_OK;
}

void bsurf_neighbors_free(bsurf_neighbors *nb) {
  if (!nb) return;
  free(nb->idx);
  free(nb->order);
  memset(nb, 0, sizeof *nb);
}

bsurf_status bsurf_mean_spacing_progress(const double *xyz, size_t point_count, int threads,
                                         double *h, bsurf_progress_fn progress, void *user) {
  BSURF_REQUIRE(h, "h is NULL");
  BSURF_REQUIRE(xyz, "xyz is NULL");
  BSURF_REQUIRE(point_count <= UINT32_MAX, "point_count = %zu: at most 2^32 - 1 points",
                point_count);
  if (point_count < 2)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS,
                             "bsurf_mean_spacing: %zu points, at least 2 needed", point_count);
  return knn_with_spacing(xyz, point_count, 2, threads, NULL, NULL, h, progress, user);
}

bsurf_status bsurf_mean_spacing(const double *xyz, size_t point_count, int threads, double *h) {
  return bsurf_mean_spacing_progress(xyz, point_count, threads, h, NULL, NULL);
}
