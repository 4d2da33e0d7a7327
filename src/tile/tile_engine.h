/* The tile engine and the tiled stages (internal: not part of the installed
 * API, never exported from libbootsurf.so). Front ends run tiled jobs
 * through bootsurf.h (bsurf_job_io and the jobs of src/jobs); only the
 * library uses this header (issue 18, docs/architecture.md). */
#ifndef BSURF_TILE_ENGINE_H
#define BSURF_TILE_ENGINE_H

#include "bootsurf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------------ */
/* Tiled (out-of-core) and distributed runs                                  */
/* ------------------------------------------------------------------------ */

/* Every per-point estimate depends only on the point's K-neighbourhood and
 * on random draws keyed by its global index, so a cloud too large for memory
 * is processed tile by tile: space is cut into tiles of about tile_points
 * points; each tile is loaded with a halo grown until every tile point's K
 * nearest neighbours are proven to lie inside the loaded region (see
 * src/tile/tiles.c); results are written at the points' places in the
 * output. The input is a binary PLY file read by offset (memory-mapped), the
 * output a binary little-endian PLY file with the bytes the in-memory writer
 * gives. docs/scaling.md. */

/* One tile, as given to bsurf_tile_ops.run. */
typedef struct bsurf_tile {
  size_t index, tile_count;
  size_t core_count;           /* the tile's own points: the rows of nb */
  size_t local_count;          /* those and their neighbours in the halo */
  const double *xyz;           /* local_count x 3, in increasing global order */
  const uint64_t *point_index; /* core_count global indices (increasing) */
  const bsurf_neighbors *nb;   /* core_count (+ ring_count) rows of k local
                                  indices, each point first, exactly the rows
                                  the whole cloud gives (nb->h is 0: see
                                  report) */
  double halo;                 /* the widest halo the tile needed */
  /* Two-stage runs (bsurf_tile_ops.values_in / nvalues; docs/scaling.md): */
  const double *values; /* values_in: local_count x values_in->nvalues,
                           the first stage's values of every local point */
  double *values_out;   /* nvalues > 0: core_count x nvalues to fill */
  /* reverse: for core point r, the local indices (increasing) of every
   * point whose K-neighbourhood in the whole cloud contains it (itself
   * included): rev[rev_off[r] .. rev_off[r + 1]) */
  const size_t *rev_off;
  const uint32_t *rev;
  /* bsurf_tile_ops.ring_k: the rings' points (outside the tile) whose rows
   * follow the core's in nb, each ring in increasing global index:
   * ring_count in all, the first ring's ring_first of them first */
  size_t ring_count, ring_first;
} bsurf_tile;

/* Per-point values of a first tiled stage, kept by global index in a scratch
 * file beside the output (removed on every exit: it is unlinked while open)
 * for the reductions and the second stage of a two-stage run. */
typedef struct bsurf_tile_values {
  int fd;         /* -1: none */
  size_t count;   /* points */
  size_t nvalues; /* the stage's values per point (a last column, the
                     squared distance to the K-th neighbour, is the
                     engine's: it bounds the reverse neighbourhoods) */
} bsurf_tile_values;

/* Values [first, first + count) x nvalues into out, in index order. */
bsurf_status bsurf_tile_values_read(const bsurf_tile_values *v, size_t first, size_t count,
                                    double *out);
void bsurf_tile_values_close(bsurf_tile_values *v);

typedef struct bsurf_tile_ops {
  size_t tile_points; /* about this many points per tile (>= 2 k) */
  int k;              /* neighbourhood size, the point included */
  int threads;        /* for the neighbour search (0 = all cores) */
  void *user;
  /* Adds the command's output properties to a cloud that has the input's
   * (what the in-memory command does to the whole cloud); any point count. */
  bsurf_status (*prepare)(void *user, bsurf_cloud *cloud);
  /* Computes a tile: `core` holds its core points with every input property,
   * prepared; run fills the outputs and may add to sums[0 .. nsums-1] (the
   * tile's own accumulators, reduced in tile order). */
  bsurf_status (*run)(void *user, const bsurf_tile *tile, bsurf_cloud *core, double *sums);
  size_t nsums;
  const bsurf_tile_comm *comm; /* NULL: one process */
  bsurf_progress_fn progress;  /* points done of all (this rank's share) */
  void *progress_user;
  /* The output is assembled in ranges of at most this many points (record
   * + 8 bytes each in memory), at least 64; 0: the larger of tile_points
   * and 32 MiB of them, and with comm at most points / ranks. The ranges
   * are the subtrees of the cascade that sums h (each between half and all
   * of this size), split over the ranks. */
  size_t range_points;
  /* A first stage: run() fills tile->values_out with nvalues doubles per
   * core point; they are kept in index order in *values_out (which the
   * caller closes). prepare NULL: no output file (`output` then only names
   * where the scratch files go); with nvalues 0 too, the tiles keep what they
   * compute in `user` themselves (the report's h and sums are still made). */
  size_t nvalues;
  bsurf_tile_values *values_out;
  /* A second stage: the first stage's values, given for every local point
   * (tile->values); with `reverse`, tiles also get every point whose exact
   * K-neighbourhood contains a tile point (tile->rev_off, rev: the halo of
   * reverse neighbours, proven from the first stage's K-th distances). */
  const bsurf_tile_values *values_in;
  int reverse;
  /* A fused stage (not with reverse): ring_k > 0 gives the tile the exact
   * rows of its ring too, every point outside the tile among the first
   * ring_k entries of the core's rows (proven as the core's, the halo grown
   * as they need): nb then has core_count + ring_count rows. A value that a
   * point reads at those neighbours, computed from their own rows (a
   * 2-ring), is then computed in the same tile, without a stage between
   * (the MSE rule, normals_mse_tiled.c). rings = 2: then also the ring of
   * the first ring (the points outside the tile and the first ring among
   * the first ring_k entries of its rows), for a value read at a
   * neighbour's neighbours (a 3-ring); 0 or 1: one ring. */
  int ring_k, rings;
} bsurf_tile_ops;

typedef struct bsurf_tile_report {
  size_t points; /* in the input */
  size_t tiles;
  size_t max_tile_points;  /* core points of the largest tile */
  size_t max_local_points; /* tile + halo points of the largest */
  size_t halo_grown;       /* tile passes that had to widen the halo */
  size_t duplicates;       /* points at the same place as another */
  double h;                /* mean nearest-neighbour distance, bit-identical to
                              bsurf_neighbors_build on the whole cloud */
  double *sums;            /* nsums totals (owned by the caller: pass a buffer) */
  size_t bad_point;        /* BSURF_ERR_INVALID_VALUE: the first non-finite point */
} bsurf_tile_report;

/* Runs a local computation over a binary PLY file tile by tile and writes
 * the result to `output` (binary little-endian PLY, atomically: a temporary
 * file renamed at the end; nothing on failure). The tiles' rows go to a
 * scratch file beside the output (removed on every exit) and the output is
 * then written once in index order. report->sums must point to ops->nsums
 * doubles. With ops->comm, every rank calls it with the same arguments:
 * the streaming passes over the input are split by index range, tiles are
 * dealt round-robin, each rank writes its tiles' rows to the scratch file,
 * then assembles its share of the output's ranges and writes them at their
 * offsets; rank 0 writes the header and renames the file.
 * Errors name the file and place in err (as bsurf_read). */
bsurf_status bsurf_tiles_run(const char *input, const char *output, const bsurf_tile_ops *ops,
                             bsurf_tile_report *report, bsurf_failure *err);

/* A pointwise second stage: the input is streamed in index order, range by
 * range (ops->range_points), with the first stage's values; each range's
 * points (every input property, prepared by ops->prepare) go to map, which
 * fills the outputs; the rows are written as bsurf_tiles_run writes them.
 * With ops->comm, rank 0 writes and the others wait. Uses prepare, map,
 * range_points, comm and progress of ops. */
typedef bsurf_status (*bsurf_tile_map_fn)(void *user, size_t first, bsurf_cloud *points,
                                          const double *values);
bsurf_status bsurf_tiles_map(const char *input, const char *output, const bsurf_tile_ops *ops,
                             const bsurf_tile_values *values, bsurf_tile_map_fn map,
                             bsurf_failure *err);

/* Feature detection by the distance method (7.1) tile by tile: the file
 * bsurf_detect_features gives (its feature_dist and feature, the other
 * properties of the input), byte for byte, and its report (threshold, the
 * feature count, max radius, the points stopped at once, T_{a/c} at k_min).
 * Stages, each a tiled run: the sample's f(K) for the medians of
 * noise_factor (skipped when it is 0), the raw map, then `iterations`
 * passes of the bilateral filter (Eq. 7.1), each reading the previous
 * pass's values of the tile's neighbours; T_h over every value read back in
 * index order (auto: 8 bytes per point in memory); the output by a
 * pointwise stage (bsurf_tiles_map). ops: tile_points, threads, comm,
 * progress, range_points, and prepare (with user), which must add the
 * fields "feature_dist" and "feature" to the input's; the rest is set per
 * stage. tiles out: the raw map's run (points, tiles, h, duplicates). */
bsurf_status bsurf_features_distance_tiled(const char *input, const char *output,
                                           const bsurf_tile_ops *ops,
                                           const bsurf_feature_options *opts,
                                           bsurf_feature_report *report, bsurf_tile_report *tiles,
                                           bsurf_failure *err);

/* features --method variance with the NULL rule (src/algo/features_variance.c)
 * tile by tile: the same output as bsurf_detect_features (variance_z and
 * feature, byte for byte) and report (threshold, feature count, noise
 * level). Stages: bootstrap normals with u = nu tr, lambda0 and lambda0 / tr
 * per point (K = normals.k); their medians over the values read back; the
 * median filter of u (K = k_f); the threshold (null patch and Otsu over
 * every z in memory, 8 bytes per point); the output. ops as for
 * bsurf_features_distance_tiled, prepare adding "variance_z" and
 * "feature". quadric_noise: the cloud's noise variance for the quadric check
 * (bsurf_ksel_cloud_noise's, read by the caller; NAN: no check); its stage
 * (K = K_q) runs before the filter's. tiles out: the first stage's run. */
bsurf_status bsurf_features_variance_tiled(const char *input, const char *output,
                                           const bsurf_tile_ops *ops,
                                           const bsurf_feature_options *opts, double quadric_noise,
                                           bsurf_feature_report *report, bsurf_tile_report *tiles,
                                           bsurf_failure *err);

#ifdef __cplusplus
}
#endif

#endif /* BSURF_TILE_ENGINE_H */
