/* Pieces every job shares (src/jobs/jobs.h). */
#include "jobs/jobs.h"
#include "search/search.h"

#include <string.h>

static bsurf_status jobs_check_io(const char *func, const bsurf_job_io *io) {
  BSURF_REQUIRE_IN(func, io, "io is NULL");
  BSURF_REQUIRE_IN(func, !io->cloud != !io->input,
                   "give either io->cloud (in memory) or io->input (tiled), not %s",
                   io->cloud ? "both" : "neither");
  if (io->cloud) {
    BSURF_REQUIRE_IN(func, io->cloud->xyz || !io->cloud->point_count,
                     "io->cloud has no coordinates");
    return BSURF_OK;
  }
  BSURF_REQUIRE_IN(func, io->tile_points > 0,
                   "io->tile_points = 0: a tiled run needs the tile size");
  return BSURF_OK;
}

bsurf_status bsurf_jobs_begin(const char *func, const bsurf_job_io *io, void *summary,
                              size_t summary_size) {
  BSURF_REQUIRE_IN(func, summary, "summary is NULL");
  memset(summary, 0, summary_size);
  return jobs_check_io(func, io);
}

bsurf_status bsurf_jobs_neighbors(const bsurf_cloud *c, int k, int threads,
                                  bsurf_progress_fn progress, void *progress_user,
                                  bsurf_neighbors *nb, size_t *duplicates) {
  memset(nb, 0, sizeof *nb);
  const size_t n = c->point_count;
  if (n < (size_t)k)
    return bsurf_set_message(BSURF_ERR_TOO_FEW_POINTS, "has %zu points, fewer than K = %d", n, k);
  bsurf_status st = bsurf_neighbors_build(nb, c->xyz, n, k, threads, progress, progress_user);
  if (st != BSURF_OK) return st;
  /* points at the same place as another: the nearest other neighbour (the
   * point itself comes first) is at distance 0 */
  size_t dup = 0;
  for (size_t i = 0; i < n; i++) {
    dup += bsurf_same_place(c->xyz + 3 * i, c->xyz + 3 * (size_t)nb->idx[i * (size_t)nb->k + 1]);
  }
  *duplicates = dup;
  return BSURF_OK;
}

void bsurf_jobs_tile_ops(bsurf_tile_ops *ops, const bsurf_job_io *io, int k, int threads,
                         bsurf_progress_fn progress, void *progress_user, void *user) {
  memset(ops, 0, sizeof *ops);
  ops->tile_points = io->tile_points;
  ops->k = k;
  ops->threads = threads;
  ops->user = user;
  ops->comm = io->comm;
  ops->progress = progress;
  ops->progress_user = progress_user;
  ops->range_points = io->range_points;
}

void bsurf_jobs_tiled_numbers(const bsurf_tile_report *tr, size_t *points, double *h,
                              size_t *duplicates, size_t *tiles, size_t *bad_point) {
  *points = tr->points;
  *h = tr->h;
  *duplicates = tr->duplicates;
  *tiles = tr->tiles;
  *bad_point = tr->bad_point;
}

double bsurf_jobs_mean(const double *v, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++)
    s += v[i];
  return n ? s / (double)n : 0.0;
}

void bsurf_jobs_means(double *means, const double *sums, int count, size_t points) {
  for (int f = 0; f < count; f++)
    means[f] = sums[f] / (double)points;
}

void bsurf_jobs_add_counts(double *sums, size_t c0, size_t c1, size_t c2, size_t c3) {
  sums[0] += (double)c0;
  sums[1] += (double)c1;
  sums[2] += (double)c2;
  sums[3] += (double)c3;
}

void bsurf_jobs_counts(const double *sums, size_t *c0, size_t *c1, size_t *c2, size_t *c3) {
  *c0 = (size_t)sums[0];
  *c1 = (size_t)sums[1];
  *c2 = (size_t)sums[2];
  *c3 = (size_t)sums[3];
}

bsurf_status bsurf_jobs_add_fields(bsurf_cloud *c, const char *const *names,
                                   const bsurf_type *types, int count) {
  for (int f = 0; f < count; f++)
    if (!bsurf_cloud_add_field(c, names[f], types[f]))
      return bsurf_set_message(BSURF_ERR_NOMEM, "out of memory adding the field %s", names[f]);
  return BSURF_OK;
}
