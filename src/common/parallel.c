/* The parallel loop over points shared by every per-point algorithm.
 *
 * Points are processed in chunks of BSURF_PROGRESS_CHUNK; inside a chunk
 * OpenMP threads take small dynamic blocks. After each chunk the calling
 * thread reports progress (and may be told to cancel). Each point's work
 * must write only that point's outputs and use the scratch of the thread
 * that runs it, so results do not depend on the thread count. */
#include "common/common.h"

bsurf_status bsurf_parallel_points(size_t n, int threads, bsurf_point_fn fn, void *ctx,
                                   bsurf_progress_fn progress, void *progress_user) {
  const int T = bsurf_threads_resolve(threads);
  for (size_t start = 0; start < n; start += BSURF_PROGRESS_CHUNK) {
    size_t end = start + BSURF_PROGRESS_CHUNK < n ? start + BSURF_PROGRESS_CHUNK : n;
    long long s0 = (long long)start, s1 = (long long)end;
#ifdef _OPENMP
#pragma omp parallel for num_threads(T) schedule(dynamic, 32)
#endif
    for (long long i = s0; i < s1; i++) {
#ifdef _OPENMP
      fn(ctx, omp_get_thread_num(), (size_t)i);
#else
      fn(ctx, 0, (size_t)i);
#endif
    }
    if (progress && progress(progress_user, end, n)) return BSURF_ERR_CANCELLED;
  }
  (void)T;
  return BSURF_OK;
}

typedef struct ordered_ctx {
  bsurf_point_fn fn;
  void *ctx;
  const uint32_t *order;
} ordered_ctx;

static void ordered_task(void *vctx, int thread, size_t r) {
  ordered_ctx *c = vctx;
  c->fn(c->ctx, thread, c->order[r]);
}

bsurf_status bsurf_parallel_points_ordered(size_t n, const uint32_t *order, int threads,
                                           bsurf_point_fn fn, void *ctx, bsurf_progress_fn progress,
                                           void *progress_user) {
  if (!order) return bsurf_parallel_points(n, threads, fn, ctx, progress, progress_user);
  ordered_ctx c = {fn, ctx, order};
  return bsurf_parallel_points(n, threads, ordered_task, &c, progress, progress_user);
}

bsurf_status bsurf_parallel_sweep(size_t n, int threads, bsurf_point_fn fn, void *ctx) {
  return bsurf_parallel_sweep_chunk(n, threads, 512, fn, ctx);
}

bsurf_status bsurf_parallel_sweep_chunk(size_t n, int threads, int chunk, bsurf_point_fn fn,
                                        void *ctx) {
  const int T = bsurf_threads_resolve(threads);
  long long nn = (long long)n;
  if (chunk < 1) chunk = 1;
#ifdef _OPENMP
#pragma omp parallel for num_threads(T) schedule(dynamic, chunk)
#endif
  for (long long i = 0; i < nn; i++) {
#ifdef _OPENMP
    fn(ctx, omp_get_thread_num(), (size_t)i);
#else
    fn(ctx, 0, (size_t)i);
#endif
  }
  (void)T;
  (void)chunk;
  return BSURF_OK;
}
