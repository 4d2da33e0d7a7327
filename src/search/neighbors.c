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

/* A streamed run's wrapper of the caller's row function: the duplicates
 * counted per thread (a cache line apart), then the caller's function. */
typedef struct stream_ctx {
  bsurf_knn_row_fn row;
  void *user;
  size_t *dup; /* threads x 8 */
} stream_ctx;

static void stream_row(void *vctx, int thread, uint32_t point, const uint32_t *ids,
                       const double *xyz) {
  stream_ctx *c = vctx;
  c->dup[8 * (size_t)thread] += bsurf_same_place(xyz, xyz + 3); /* the point, its nearest */
  c->row(c->user, thread, point, ids, xyz);
}

/* Builds a temporary index and runs the all-kNN; idx may be NULL; order
 * (may be NULL) receives the tree order of the points; with stream (idx
 * NULL) the rows go to it instead. */
static bsurf_status knn_with_spacing(const double *xyz, size_t point_count, int k, int threads,
                                     uint32_t *idx, uint32_t *order, stream_ctx *stream, double *h,
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
    st = stream ? bsurf_knn_stream(index, k, threads, stream_row, stream, nn, progress, user)
                : bsurf_knn_all_ex(index, k, threads, idx, NULL, nn, progress, user);
    if (order) memcpy(order, bsurf_knn_tree_ids(index), point_count * sizeof *order);
    bsurf_knn_free(index);
  }
  if (st == BSURF_OK) *h = bsurf_sum_sqrt(nn, point_count) / (double)point_count;
  free(nn);
  return st;
}

/* The checks of bsurf_neighbors_build and _stream (messages name `who`). */
static bsurf_status neighbors_check(const char *who, const double *xyz, size_t point_count, int k) {
  BSURF_REQUIRE_IN(who, xyz, "xyz is NULL");
  BSURF_REQUIRE_IN(who, k >= 2, "k = %d: must be at least 2 (the point and a neighbour)", k);
  BSURF_REQUIRE_IN(who, point_count <= UINT32_MAX, "point_count = %zu: at most 2^32 - 1 points",
                   point_count);
  if (point_count == 0 || (size_t)k > point_count)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "%s: k = %d exceeds the %zu points", who, k,
                             point_count);
  return BSURF_OK;
}

bsurf_status bsurf_neighbors_build(bsurf_neighbors *nb, const double *xyz, size_t point_count,
                                   int k, int threads, bsurf_progress_fn progress,
                                   void *progress_user) {
  bsurf_status st;
  uint32_t *idx;
  double h = 0.0;

  BSURF_REQUIRE(nb, "nb is NULL");
  memset(nb, 0, sizeof *nb);
  st = neighbors_check("bsurf_neighbors_build", xyz, point_count, k);
  if (st != BSURF_OK) return st;

  idx = bsurf_alloc_array(point_count, (size_t)k * sizeof *idx);
  uint32_t *order = bsurf_alloc_array(point_count, sizeof *order);
  if (!idx || !order) {
    free(idx);
    free(order);
    return BSURF_ERR_NOMEM;
  }
  st =
      knn_with_spacing(xyz, point_count, k, threads, idx, order, NULL, &h, progress, progress_user);
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

bsurf_status bsurf_neighbors_stream(const double *xyz, size_t point_count, int k, int threads,
                                    bsurf_knn_row_fn row, void *row_user, double *h,
                                    size_t *duplicates, bsurf_progress_fn progress,
                                    void *progress_user) {
  BSURF_REQUIRE(row && h && duplicates, "row, h and duplicates must not be NULL");
  bsurf_status st = neighbors_check("bsurf_neighbors_stream", xyz, point_count, k);
  if (st != BSURF_OK) return st;
  const int T = bsurf_threads_resolve(threads);
  size_t *dup = bsurf_calloc_array((size_t)(T > 0 ? T : 1) * 8, sizeof *dup);
  if (!dup) return BSURF_ERR_NOMEM;
  stream_ctx sc = {row, row_user, dup};
  st = knn_with_spacing(xyz, point_count, k, threads, NULL, NULL, &sc, h, progress, progress_user);
  *duplicates = 0;
  for (int t = 0; t < T; t++)
    *duplicates += dup[8 * (size_t)t];
  free(dup);
  return st;
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
  return knn_with_spacing(xyz, point_count, 2, threads, NULL, NULL, NULL, h, progress, user);
}

bsurf_status bsurf_mean_spacing(const double *xyz, size_t point_count, int threads, double *h) {
  return bsurf_mean_spacing_progress(xyz, point_count, threads, h, NULL, NULL);
}
