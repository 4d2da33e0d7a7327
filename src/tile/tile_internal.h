/* The tile engine's internals shared by its files (src/tile/tiles.c: the
 * run; tile_io.c, tile_grid.c, tile_halo.c, tile_output.c). Not installed;
 * the functions are global inside the library only (bsurf_i_ names). */
#ifndef BSURF_TILE_INTERNAL_H
#define BSURF_TILE_INTERNAL_H

#include "common/common.h"
#include "io/io.h"
#include "search/search.h"
#include "tile/tile_engine.h"

#include <assert.h>
#include <math.h>
#include <string.h>

#define TILE_MAX_CELLS ((size_t)1 << 22)
#define TILE_PATH_MAX 4200
#define PASS_DROP ((size_t)1 << 20) /* points between page drops */

typedef struct tile_map {
  char *data;
  size_t size;
  int fd;
} tile_map;

/* Drops pages behind a sweep through a mapping in increasing offsets, so
 * that at most about 64 MB of it is resident: a tile's points are spread
 * over the whole file when the file's order is not spatial. */
typedef struct sweep {
  const tile_map *m;
  size_t mark;
} sweep;

typedef struct tile_box {
  uint32_t lo[3], hi[3]; /* cells [lo, hi) */
  size_t count;
} tile_box;

typedef struct tiles_ctx {
  const bsurf_tile_ops *ops;
  const bsurf_tile_comm *comm;
  tile_map in;
  io_ply_layout layout;
  bsurf_cloud schema;     /* the input's properties (point 0) */
  bsurf_cloud out_schema; /* the same prepared by the command */
  size_t n;
  int k;
  double lo[3], hi[3]; /* bounding box of the cloud */
  /* grid */
  double origin[3], cell;
  uint32_t dim[3];
  size_t cells;
  uint64_t *cell_start; /* cells + 1 */
  tile_map sorted;      /* n uint64: point indices by cell */
  tile_box *tiles;
  size_t ntiles;
  /* output */
  size_t header, record;
  bsurf_atomic_file af; /* rank 0 */
  int af_open;
  int out; /* the output's (temporary) file: every rank, -1 */
  /* the tiles' results (assemble below): one block per tile at block[t] */
  int scr;      /* file descriptor, -1 */
  size_t range; /* at most this many points per range of the output */
  size_t nranges;
  size_t *range_lo;  /* nranges + 1: range r is the points [range_lo[r], range_lo[r + 1]) */
  size_t *block;     /* ntiles + 1 offsets */
  double *tile_sums; /* ntiles x (nsums + 1): the accumulators, then duplicates */
  /* two-stage runs (docs/scaling.md) */
  size_t vcols;    /* values per point written: nvalues + the K-th squared distance; 0: none */
  int vfd;         /* the values file in index order (every rank has it open), -1 */
  tile_map vin;    /* values_in, mapped read-only */
  size_t vin_cols; /* its columns (values_in->nvalues + 1) */
  double *cellmax; /* reverse: per cell, the largest K-th squared distance of its points */
  double rmax2;    /* the largest of all */
} tiles_ctx;

static inline void xyz_of(const tiles_ctx *c, uint64_t i, double p[3]) {
  io_ply_xyz(&c->layout, c->in.data, (size_t)i, p);
}

static inline void cell_coords(const tiles_ctx *c, const double p[3], uint32_t cc[3]) {
  for (int a = 0; a < 3; a++) {
    double t = floor((p[a] - c->origin[a]) / c->cell);
    cc[a] = !(t > 0) ? 0 : t >= (double)c->dim[a] ? c->dim[a] - 1 : (uint32_t)t;
  }
}

static inline size_t cell_id(const tiles_ctx *c, const uint32_t cc[3]) {
  return ((size_t)cc[2] * c->dim[1] + cc[1]) * c->dim[0] + cc[0];
}

/* Shared by the engine's files (defined in the file named). */
#define map_close bsurf_i_tile_map_close
#define drop_pages bsurf_i_tile_drop_pages
#define sweep_at bsurf_i_tile_sweep_at
#define map_input bsurf_i_tile_map_input
#define pwrite_all bsurf_i_tile_pwrite_all
#define pread_all bsurf_i_tile_pread_all
#define cloud_like bsurf_i_tile_cloud_like
#define rank_of bsurf_i_tile_rank_of
#define ranks_of bsurf_i_tile_ranks_of
#define share_start bsurf_i_tile_share_start
#define agree bsurf_i_tile_agree
#define shared_scratch bsurf_i_tile_shared_scratch
#define map_values bsurf_i_tile_map_values
#define pass_cancelled bsurf_i_tile_pass_cancelled
#define pass_bounds bsurf_i_tile_pass_bounds
#define make_grid bsurf_i_tile_make_grid
#define pass_sort bsurf_i_tile_pass_sort
#define make_tiles bsurf_i_tile_make_tiles
#define find_u64 bsurf_i_tile_find_u64
#define cell_maxima bsurf_i_tile_cell_maxima
#define do_tile bsurf_i_tile_do_tile
#define cascade_top bsurf_i_tile_cascade_top
#define write_block bsurf_i_tile_write_block
#define assemble bsurf_i_tile_assemble
#define record_of bsurf_i_tile_record_of
#define create_output bsurf_i_tile_create_output
#define open_outputs bsurf_i_tile_open_outputs
/* tile_io.c */
void map_close(tile_map *m);
void drop_pages(const tile_map *m, size_t from, size_t to);
void sweep_at(sweep *s, size_t offset);
bsurf_status map_input(const char *path, tile_map *m, bsurf_failure *err);
int pwrite_all(int fd, const void *buf, size_t bytes, size_t offset);
int pread_all(int fd, void *buf, size_t bytes, size_t offset);
bsurf_status cloud_like(const bsurf_cloud *schema, size_t n, bsurf_cloud *out);
int rank_of(const tiles_ctx *c);
int ranks_of(const tiles_ctx *c);
size_t share_start(size_t n, int r, int ranks);
bsurf_status agree(const bsurf_tile_comm *cm, bsurf_status st);
bsurf_status shared_scratch(const tiles_ctx *c, const char *near, size_t bytes, int map,
                            tile_map *m, bsurf_failure *err);
bsurf_status map_values(const bsurf_tile_values *v, size_t n, tile_map *m, bsurf_failure *err);
/* tile_grid.c */
int pass_cancelled(const tiles_ctx *c);
bsurf_status pass_bounds(tiles_ctx *c, bsurf_tile_report *rep);
void make_grid(tiles_ctx *c);
bsurf_status pass_sort(tiles_ctx *c, const char *output, bsurf_failure *err);
bsurf_status make_tiles(tiles_ctx *c);
/* tile_halo.c */
size_t find_u64(const uint64_t *v, size_t n, uint64_t x);
bsurf_status cell_maxima(tiles_ctx *c);
bsurf_status do_tile(tiles_ctx *c, size_t t, bsurf_tile_report *rep, bsurf_failure *err);
/* tile_output.c */
double cascade_top(const tiles_ctx *c, const double *range_sum, size_t n, size_t *next);
bsurf_status write_block(const tiles_ctx *c, size_t t, const uint64_t *core, const double *nn2,
                         const double *vals, const unsigned char *enc, size_t nc,
                         bsurf_failure *err);
bsurf_status assemble(const tiles_ctx *c, double *range_sum, bsurf_failure *err);
size_t record_of(const bsurf_cloud *schema);
bsurf_status create_output(tiles_ctx *c, const char *output, bsurf_failure *err);
bsurf_status open_outputs(tiles_ctx *c, const char *output, bsurf_failure *err);

#endif /* BSURF_TILE_INTERNAL_H */
