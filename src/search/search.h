/* Internal interface of the neighbourhood search (src/search/), for the other
 * files of the library. The public part is the "Neighbourhoods" section of
 * bootsurf.h. */
#ifndef BSURF_SEARCH_H
#define BSURF_SEARCH_H

#include "common/common.h"

#include <stddef.h>
#include <stdint.h>

/* Number of points in an index. */
size_t bsurf_knn_point_count(const bsurf_knn_index *index);
/* bsurf_knn_build with `threads` threads (0: all; bsurf_threads_resolve):
 * the subtrees of the top levels built at once. The same tree for any
 * count. */
bsurf_status bsurf_knn_build_threads(bsurf_knn_index **index, const double *xyz, size_t point_count,
                                     int threads);

/* bsurf_knn_all with two internal extras:
 *  - idx may be NULL (only distances wanted);
 *  - nn_dist2 out: point_count, may be NULL: the squared distance from each
 *    point to its nearest other point (column 1 of dist2); needs k >= 2.
 * Used by bsurf_neighbors_build and bsurf_mean_spacing to get h without a
 * point_count x k distance array. Same validation, order, determinism and
 * progress/cancellation as bsurf_knn_all. */
bsurf_status bsurf_knn_all_ex(const bsurf_knn_index *index, int k, int threads, uint32_t *idx,
                              double *dist2, double *nn_dist2, bsurf_progress_fn progress,
                              void *progress_user);

/* The all-kNN without the point_count x k array: each point's row (itself,
 * then its k - 1 nearest others, as bsurf_knn_all's) handed to row(user,
 * thread, point, ids, xyz) while it is in cache, in place of being stored;
 * xyz: the row's coordinates (k x 3, the same values as the cloud's, copied
 * from the tree's arrays the search has just read). Rows come in tree
 * order, from `threads` threads at once (thread in [0,
 * bsurf_threads_resolve(threads))); ids and xyz are the thread's own arrays,
 * valid during the call. nn_dist2, progress and cancellation as
 * bsurf_knn_all_ex. */
typedef void (*bsurf_knn_row_fn)(void *user, int thread, uint32_t point, const uint32_t *ids,
                                 const double *xyz);
bsurf_status bsurf_knn_stream(const bsurf_knn_index *index, int k, int threads,
                              bsurf_knn_row_fn row, void *row_user, double *nn_dist2,
                              bsurf_progress_fn progress, void *progress_user);

/* bsurf_neighbors_build streamed (bsurf_knn_stream): the same checks, the same
 * rows handed to row() instead of stored, *h as nb->h, and *duplicates the
 * points whose nearest other neighbour is at the same place (the count of
 * the jobs, bsurf_same_place). */
bsurf_status bsurf_neighbors_stream(const double *xyz, size_t point_count, int k, int threads,
                                    bsurf_knn_row_fn row, void *row_user, double *h,
                                    size_t *duplicates, bsurf_progress_fn progress,
                                    void *progress_user);

/* For the tests: the all-kNN's paths (knn_all.c). batches 0: every query
 * by the tree search; simd: the batches' scan, at most AVX-512 (2), AVX2 (1)
 * or the portable one (0), the best the processor has within that. The
 * default is (1, 2). Not to be called while an all-kNN runs. */
void bsurf_knn_set_paths(int batches, int simd);
/* The scan the batches use now: 2 AVX-512, 1 AVX2, 0 portable. */
int bsurf_knn_simd(void);
/* For the tests: the last all-kNN's batches searched through their gathered
 * candidates [0] and through the tree [1], and its queries answered from the
 * first gather's candidates [2] and after they fell short (from a second
 * gather or by the tree search) [3]. */
void bsurf_knn_path_counts(size_t counts[4]);

/* 1 when the points at a and b have the same coordinates. */
static inline int bsurf_same_place(const double *a, const double *b) {
  return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

/* The original index of each tree position (n entries): the points in the
 * index's spatially coherent order. */
const uint32_t *bsurf_knn_tree_ids(const bsurf_knn_index *index);

/* The order in which a per-point pass visits the points: nb->order when
 * set, else a Morton order of xyz, returned in *owned (free it). NULL with
 * *owned NULL when memory runs out. */
const uint32_t *bsurf_visit_order(const bsurf_neighbors *nb, const double *xyz, uint32_t **owned);

/* Morton order of the points (order.c): perm[r] = the index of the r-th
 * point in the order; rank (may be NULL) its inverse. Both allocated (n
 * entries), freed by the caller. */
bsurf_status bsurf_spatial_order(const double *xyz, size_t n, uint32_t **perm, uint32_t **rank);

/* sum_i sqrt(v[i]) in a fixed binary-tree order (accurate and deterministic):
 * halves (n / 2 first) down to 64 values, each run summed left to right. h
 * of bsurf_neighbors_build is this sum over the nearest-other distances
 * divided by n; the tiled runs (src/tile/tiles.c) sum subtrees of the same
 * tree and combine them by its top. */
double bsurf_sum_sqrt(const double *v, size_t n);

#endif
