/* Pieces every job (src/jobs, issue 18) shares: the check of bsurf_job_io,
 * the in-memory neighbourhoods with the duplicate count, the tile engine's
 * options of a job's tiled stages and the summary's tile numbers. */
#ifndef BSURF_JOBS_H
#define BSURF_JOBS_H

#include "common/common.h"
#include "tile/tile_engine.h"

/* The start of every job: summary (summary_size bytes) not NULL, zeroed;
 * io either a cloud (in memory, with coordinates) or an input file with a
 * tile size. `func` names the job in the message. */
bsurf_status bsurf_jobs_begin(const char *func, const bsurf_job_io *io, void *summary,
                              size_t summary_size);

/* The neighbourhoods of an in-memory cloud (BSURF_ERR_TOO_FEW_POINTS with a
 * message when it has fewer than k points), h and the points at the same
 * place as another. */
bsurf_status bsurf_jobs_neighbors(const bsurf_cloud *c, int k, int threads,
                                  bsurf_progress_fn progress, void *progress_user,
                                  bsurf_neighbors *nb, size_t *duplicates);

/* The tile engine's options of one stage of a tiled job: io's tile size,
 * range and communicator, the job's progress. */
void bsurf_jobs_tile_ops(bsurf_tile_ops *ops, const bsurf_job_io *io, int k, int threads,
                         bsurf_progress_fn progress, void *progress_user, void *user);

/* The numbers of a tiled run every job summary holds (points, h,
 * duplicates, tiles, the first non-finite point) from the report of its
 * first stage. */
void bsurf_jobs_tiled_numbers(const bsurf_tile_report *tr, size_t *points, double *h,
                              size_t *duplicates, size_t *tiles, size_t *bad_point);

struct bsurf_ksel_run; /* algo/algo.h */
/* The MSE rule's first tiled stage (normals_mse_tiled.c, docs/scaling.md):
 * each point's pooled noise (pass 1 on the tiles' rings too, then pass 2),
 * kept in *pooled for the last stage, and with the GLOBAL pool the level,
 * their median read back, and (sections non-NULL) the count of points
 * whose neighbourhoods it found section-sampled (bsurf_ksel_sections);
 * K = k (the job's K_max, the ring's too). tr: the stage's report. */
bsurf_status bsurf_jobs_mse_stages(const bsurf_job_io *io, const bsurf_kselect_options *ko, int k,
                                   int threads, bsurf_progress_fn progress, void *progress_user,
                                   struct bsurf_ksel_run *run, bsurf_tile_values *pooled,
                                   double *level, size_t *sections, bsurf_tile_report *tr,
                                   bsurf_failure *err);
/* bsurf_ksel_section_bound tile by tile (the core's and the ring's rows,
 * ring_k = k): *bound, the same count as in memory; progress: the tiles
 * done. */
bsurf_status bsurf_jobs_section_bound(const bsurf_job_io *io, int k, int threads,
                                      bsurf_progress_fn progress, void *progress_user,
                                      struct bsurf_ksel_run *run, size_t *bound,
                                      bsurf_tile_report *tr, bsurf_failure *err);
/* The rings the last stage needs (its ring_k is the noise_k): 2 with the
 * empirical bias (bsurf_ksel_empirical: its references are the first
 * choices without it at the noise_k nearest of the points whose first
 * choices the tie-break reads), else 1. */
int bsurf_jobs_mse_rings(const struct bsurf_ksel_run *run);
/* The last stage's inputs in a tile from the pooled values (global: the
 * level instead): the noise by row (core, then rings), the first choices'
 * normals and M of the first ring's points by local point (pass 3 on its
 * rows; NAN elsewhere), and with the empirical bias the first choices
 * without it of every row's point (bref, bmref; else NULL), allocated. */
bsurf_status bsurf_jobs_mse_tile(struct bsurf_ksel_run *run, const bsurf_tile *t, int global,
                                 double level, double **noise, double **fref, double **fmref,
                                 double **bref, double **bmref);

/* The mean of n values summed in point order (what the summaries report). */
double bsurf_jobs_mean(const double *v, size_t n);
/* means[f] = sums[f] / points for the `count` fields of a tiled run. */
void bsurf_jobs_means(double *means, const double *sums, int count, size_t points);
/* A report's four counters in a tiled run's sums (sums[0..3]): added by
 * each tile, read back as counts at the end. */
void bsurf_jobs_add_counts(double *sums, size_t c0, size_t c1, size_t c2, size_t c3);
void bsurf_jobs_counts(const double *sums, size_t *c0, size_t *c1, size_t *c2, size_t *c3);

/* Adds the value of a field to the cloud's storage type in memory (names
 * and types: count of each); BSURF_ERR_NOMEM with a message. */
bsurf_status bsurf_jobs_add_fields(bsurf_cloud *c, const char *const *names,
                                   const bsurf_type *types, int count);

#endif /* BSURF_JOBS_H */
