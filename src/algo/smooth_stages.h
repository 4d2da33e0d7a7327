/* Smoothing in two stages, for the tiled smoothing of bsurf_smooth_job
 * (src/jobs/smooth_job.c; internal: moved from bootsurf.h by issue 18). */
#ifndef BSURF_SMOOTH_STAGES_H
#define BSURF_SMOOTH_STAGES_H

#include "bootsurf.h"

/* Tiled smoothing (bsurf_tiles_run, docs/scaling.md): naive and bilateral in
 * parallel order as two stages with the bits of bsurf_smooth.
 * Stage 1, per point from its own K-neighbourhood: err_632, err_632plus,
 * then naive's projection of Eq. 6.1 (3 doubles) or bilateral's fit (frame,
 * scale and coefficients). The doubles per point; 0: the method and order
 * are not local enough to tile (sequential order, multipass). */
size_t bsurf_smooth_stage_values(const bsurf_smooth_options *opts);
/* The degree test applied (opts->degree_test with auto resolved: 0 or 1). */
int bsurf_smooth_degree_test(const bsurf_smooth_options *opts);
/* Which of the first two values is W_i (0: err_632, 1: err_632plus). */
int bsurf_smooth_w_column(const bsurf_smooth_options *opts);
/* Stage 1 for the nb->point_count rows of nb (row r is the point nb->idx[r k];
 * opts->error.point_index keys the draws): values out, rows x
 * bsurf_smooth_stage_values. report: the bootstrap counters (may be NULL). */
bsurf_status bsurf_smooth_stage1(const double *xyz, const bsurf_neighbors *nb,
                                 const bsurf_smooth_options *opts, double *values,
                                 bsurf_error_report *report);
/* The sigmas and the threshold bsurf_smooth applies, from h (mean spacing),
 * |W| (the mean of W_i over the cloud, summed in index order) and the
 * guard's noise variance (bsurf_smooth_noise's; NAN without the guard): sets
 * opts->h1, opts->h2 and opts->threshold. */
void bsurf_smooth_resolve(bsurf_smooth_options *opts, double h, double mean_w, double noise);
/* Stage 2 with resolved options, for `count` points at the local indices
 * point[] (NULL: 0..count-1) of xyz; values: stage 1's of every local point.
 * Bilateral: rev[rev_off[r] .. rev_off[r + 1]) are the local indices
 * (increasing global order) of every neighbourhood containing point r;
 * naive: rev NULL. noise: bsurf_smooth_noise's. out_xyz: count x 3; moved: count. */
bsurf_status bsurf_smooth_stage2(const double *xyz, size_t local_count, const double *values,
                                 size_t count, const uint32_t *point, const size_t *rev_off,
                                 const uint32_t *rev, const bsurf_smooth_options *opts,
                                 double noise, double *out_xyz, double *moved);
/* The guard's record of a sheet fit for its misfit test: residual variance,
 * degrees of freedom, the share of the noise variance the interval that
 * kept its points keeps, and the radius of its neighbourhood's ball (the
 * last BSURF_SMOOTH_SV of stage 1's values). */
#define BSURF_SMOOTH_SV 4
/* The guard's noise variance of the cloud (its misfit test, smooth_guard.c)
 * from the BSURF_SMOOTH_SV records at sv, rows of `stride` doubles, of stage
 * 1's values: pass it to stage 2 (NAN: no test).
 * scratch: n doubles. */
double bsurf_smooth_noise(const double *sv, size_t n, size_t stride, double *scratch);
/* The guard's noise variance from its two readings (docs/smoothing.md, "Two
 * readings of the noise"): the sheet fits' (bsurf_smooth_noise) and the K
 * selection's (bsurf_ksel_cloud_noise; NAN: none), with the share of the
 * cloud's points whose neighbourhoods the selection found section-sampled. */
double bsurf_smooth_noise_level(double fits, double select, double section_share);
/* The K selection's options for the guard's second reading (the noise
 * passes of `normals --select-k 10:80:5`, GLOBAL pool; threads T), and the
 * neighbourhood size they read (80): a cloud of no more points has no
 * second reading. */
#define BSURF_SMOOTH_SELECT_K 80
/* the share of section-sampled points above which the guard takes the
 * selection's reading (bsurf_smooth_noise_level; the section test's level) */
#define BSURF_SMOOTH_SECTION_SHARE 0.05
void bsurf_smooth_select_options(int T, bsurf_kselect_options *ko);
/* 1 when the fit of record sv fails the misfit test
 * at that noise (it moves nothing). */
int bsurf_smooth_misfit(const double *sv, double noise);

/* Memory plan (bsurf_smooth_job_memory): the bytes per point bsurf_smooth
 * holds at once, upper bounds counted from its allocations, besides xyz,
 * out_xyz, the fields it is given, the neighbour rows and their k-d tree
 * order. Stage 1's arrays, held to the end (and by the outer call while the
 * scale rule runs the method again on wider neighbourhoods): */
double bsurf_smooth_stage1_bytes(const bsurf_smooth_options *opts);
/* The arrays of the stage after it (the passes) with neighbourhoods of k
 * points, on T threads: *per_k (may be NULL) gets the part that grows with k,
 * per unit of k. opts->method resolved (not AUTO). */
double bsurf_smooth_passes_bytes(const bsurf_smooth_options *opts, int k, int T, double *per_k);

#endif /* BSURF_SMOOTH_STAGES_H */
