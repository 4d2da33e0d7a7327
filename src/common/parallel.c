/* The parallel loop over points shared by every per-point algorithm.
 *
 * Points are processed in chunks (BSURF_PROGRESS_CHUNK points, or fewer for
 * heavy points: bsurf_progress_chunk); inside a chunk
 * OpenMP threads take small dynamic blocks. After each chunk the calling
 * thread reports progress (and may be told to cancel). Each point's work
 * must write only that point's outputs and use the scratch of the thread
 * that runs it, so results do not depend on the thread count. */
#include "common/common.h"

size_t bsurf_progress_chunk(double work) {
  if (!(work > BSURF_PROGRESS_REF_WORK)) return BSURF_PROGRESS_CHUNK; /* also NaN */
  const double c = BSURF_PROGRESS_CHUNK * (BSURF_PROGRESS_REF_WORK / work);
  return c < 16 ? 16 : (size_t)c;
}

int bsurf_progress_hold_cb(void *user, size_t done, size_t total) {
  const bsurf_progress_hold *h = user;
  if (!h->fn) return 0;
  size_t d = 0;
  if (h->span)
    d = !total || done >= total ? h->span
        : h->span == total      ? done
                                : (size_t)((double)done / (double)total * (double)h->span);
  return h->fn(h->user, h->done + d, h->total);
}

bsurf_status bsurf_parallel_points(size_t n, int threads, bsurf_point_fn fn, void *ctx,
                                   bsurf_progress_fn progress, void *progress_user) {
  return bsurf_parallel_points_chunk(n, BSURF_PROGRESS_CHUNK, threads, fn, ctx, progress,
                                     progress_user);
}

bsurf_status bsurf_parallel_points_chunk(size_t n, size_t chunk, int threads, bsurf_point_fn fn,
                                         void *ctx, bsurf_progress_fn progress,
                                         void *progress_user) {
  const int T = bsurf_threads_resolve(threads);
  if (chunk < 1) chunk = 1;
  for (size_t start = 0; start < n; start += chunk) {
    size_t end = start + chunk < n ? start + chunk : n;
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
