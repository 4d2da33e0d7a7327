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
} loop_ctx;

static void loop_task(void *vctx, int thread, size_t i) {
  loop_ctx *c = vctx;
  c->loop->point(c->ctx, c->scratch + (size_t)thread * c->loop->scratch_size, i);
}

bsurf_status bsurf_point_loop_run(const bsurf_point_loop *loop, const void *arg, void *ctx,
                                  const bsurf_neighbors *nb, const double *xyz, int threads,
                                  bsurf_progress_fn progress, void *progress_user) {
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
    loop_ctx c = {loop, ctx, scr};
    st = bsurf_parallel_points_ordered(nb->point_count, order, T, loop_task, &c, progress,
                                       progress_user);
  }
  free(owned);
  for (int t = 0; t < T; t++) {
    if (st == BSURF_OK && loop->tally) loop->tally(ctx, scr + (size_t)t * size);
    loop->release(scr + (size_t)t * size);
  }
  free(scr);
  return st;
}
