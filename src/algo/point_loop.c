/* The per-point loops of the estimators (normals, errors): one scratch per
 * thread, points in k-d tree order, counters tallied after the run
 * (bsurf_point_loop in algo.h). */
#include "algo/algo.h"
#include "common/common.h"
#include "search/search.h"

#include <stdlib.h>

typedef struct loop_ctx {
  const bsurf_point_loop *loop;
  void *ctx;
  char *scratch; /* threads x loop->scratch_size */
  const uint32_t *order;
  const bsurf_neighbors *nb;
  const double *xyz;
} loop_ctx;

/* How far ahead (in visit order) the neighbour list and then the neighbours'
 * coordinates are prefetched. The lists are stored by point index and the
 * points are visited in tree order, so each point's list is a cache miss
 * and its neighbours' coordinates often too (about half of the gather of a
 * `normals -k 30 -B 0` point, perf); no effect on the results. */
enum { AHEAD_LIST = 8, AHEAD_XYZ = 4 };

static void loop_task(void *vctx, int thread, size_t r) {
  loop_ctx *c = vctx;
  const size_t n = c->nb->point_count, k = (size_t)c->nb->k;
#if defined(__GNUC__)
  if (r + AHEAD_LIST < n) {
    const char *row = (const char *)&c->nb->idx[c->order[r + AHEAD_LIST] * k];
    for (size_t b = 0; b < k * sizeof(uint32_t); b += 64)
      __builtin_prefetch(row + b);
  }
  if (c->xyz && r + AHEAD_XYZ < n) {
    const uint32_t *row = &c->nb->idx[c->order[r + AHEAD_XYZ] * k];
    for (size_t j = 0; j < k; j++)
      __builtin_prefetch(&c->xyz[3 * (size_t)row[j]]);
  }
#endif
  c->loop->point(c->ctx, c->scratch + (size_t)thread * c->loop->scratch_size, c->order[r]);
}

bsurf_status bsurf_point_loop_run(const bsurf_point_loop *loop, const void *arg, void *ctx,
                                  const bsurf_neighbors *nb, const double *xyz, double work,
                                  int threads, bsurf_progress_fn progress, void *progress_user) {
  const int T = bsurf_threads_resolve(threads);
  const size_t size = loop->scratch_size;
  char *scr = bsurf_calloc_array((size_t)T, size);
  if (!scr) return BSURF_ERR_NOMEM;
  bsurf_status st = BSURF_OK;
  for (int t = 0; t < T && st == BSURF_OK; t++)
    st = loop->alloc(scr + (size_t)t * size, arg);
  uint32_t *owned = NULL;
  const uint32_t *order = NULL;
  if (st == BSURF_OK && !(order = bsurf_visit_order(nb, xyz, &owned))) st = BSURF_ERR_NOMEM;
  if (st == BSURF_OK) {
    loop_ctx c = {loop, ctx, scr, order, nb, xyz};
    st = bsurf_parallel_points_chunk(nb->point_count, bsurf_progress_chunk(work), T, loop_task, &c,
                                     progress, progress_user);
  }
  free(owned);
  for (int t = 0; t < T; t++) {
    if (st == BSURF_OK && loop->tally) loop->tally(ctx, scr + (size_t)t * size);
    loop->release(scr + (size_t)t * size);
  }
  free(scr);
  return st;
}
