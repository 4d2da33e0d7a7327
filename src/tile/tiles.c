/*
 * tiles.c — out-of-core and distributed runs: tiles with proven halos.
 *
 * Every estimate of bootsurf at point i depends only on the K nearest
 * neighbours of i (thesis 3.3) and on random draws keyed by (seed, i,
 * replicate). So a cloud of any size is processed in pieces with the bits of
 * the whole cloud in memory, if every piece gets
 *   1. exactly the K-neighbourhood the whole cloud gives each of its points,
 *      with the same order and the same ties (squared distance, then index);
 *   2. the point's global index for its random draws (point_index in the
 *      options of src/algo).
 *
 * How:
 *  - The binary PLY input is memory-mapped and validated like the in-memory
 *    reader (io_ply_map); nothing of it stays resident: pages are dropped
 *    (madvise) after every pass and every tile.
 *  - Three streaming passes in point order: finite check and bounding box;
 *    counts on a grid of cells (at most 2^22); a counting sort of the point
 *    indices by cell into a scratch file next to the output (8 bytes per
 *    point on disk), so the points of any box of cells are found without
 *    reading the others. With several ranks each sweeps its share of the
 *    indices and the results are combined into the one-process pass's bits.
 *  - Tiles: the grid is cut recursively (k-d style, along the widest side, at
 *    the cell plane nearest the median count) until a box holds at most
 *    tile_points points; no side of a cut gets fewer than K points.
 *  - A tile is loaded with a halo of width w around its box: region R = box
 *    expanded by w, and every point inside R (closed) is loaded, in
 *    increasing global index, so local order = global order and ties break
 *    as in the whole cloud. The K nearest of a tile point p found there, at
 *    distance r for the last, are exact if the closed ball B(p, r) lies in R
 *    (every point that could precede the K-th is loaded); the check uses a
 *    relative margin of 1e-9 that covers the rounding of r and of the box.
 *    Points that fail are searched again with w doubled, until all pass or
 *    R covers the whole cloud. Nothing is guessed from the density.
 *  - The tile's points and the neighbours they use become a small cloud
 *    (global index order again) handed to the command's run(); its output
 *    rows are encoded as the in-memory writer encodes them and written, with
 *    their indices and squared nearest-other distances, as one sequential
 *    block of a scratch file. At the end the output (header + N fixed-size
 *    records, space reserved first, renamed when complete) is assembled in
 *    index order, one range of indices in memory at a time, and written
 *    sequentially: about once, whatever the tile count and the file's order.
 *  - h (mean nearest-neighbour distance) is global: the ranges of the
 *    assembly are subtrees of the cascade of bsurf_sum_sqrt
 *    (src/search/neighbors.c), each summed where it is assembled and
 *    combined by the top of the tree, so it is bit-identical.
 *  - Distributed: the ranks split the passes, compute the same grid and
 *    tiles (deterministic), take tiles round-robin, write their blocks at
 *    known offsets of the one scratch file, then each assembles its share of
 *    the ranges and writes them at their offsets of the output; rank 0 writes
 *    the header and renames the file. The per-tile accumulators are reduced
 *    in tile order.
 *
 * Files: this one runs a stage (bsurf_tiles_run) and a pointwise stage
 * (bsurf_tiles_map); tile_io.c holds the mapped files and the ranks'
 * scratch, tile_grid.c the passes and the tiles, tile_halo.c one tile with
 * its proven halo, tile_output.c the blocks and the assembly
 * (tile_internal.h: what they share).
 */
#define _DEFAULT_SOURCE /* madvise */
#include "tile/tile_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

bsurf_status bsurf_tiles_run(const char *input, const char *output, const bsurf_tile_ops *ops,
                             bsurf_tile_report *report, bsurf_failure *err) {
  if (err) err->line = 0, err->byte = -1, err->message[0] = 0;
  if (!input || !output || !ops || !report || !ops->run || ops->k < 1 ||
      (ops->nsums && !report->sums) || (ops->nvalues && !ops->values_out) ||
      (ops->reverse && !ops->values_in) || (ops->ring_k && ops->reverse) || ops->ring_k < 0 ||
      ops->rings < 0 || ops->rings > 2)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "invalid arguments");
  double *user_sums = report->sums;
  memset(report, 0, sizeof *report);
  report->sums = user_sums;
  tiles_ctx c;
  memset(&c, 0, sizeof c);
  c.ops = ops;
  c.comm = ops->comm;
  c.k = ops->k;
  c.in.fd = c.sorted.fd = c.scr = c.vfd = c.vin.fd = c.out = -1;
  c.vcols = ops->nvalues ? ops->nvalues + 1 : 0;
  if (ops->values_out) ops->values_out->fd = -1;
  bsurf_cloud_init(&c.schema);
  bsurf_cloud_init(&c.out_schema);
  const int rank = c.comm ? c.comm->rank : 0, ranks = c.comm ? c.comm->ranks : 1;

  bsurf_status st = map_input(input, &c.in, err);
  if (st == BSURF_OK) st = io_ply_map(c.in.data, c.in.size, &c.layout, &c.schema, err);
  if (st == BSURF_OK) {
    c.n = c.layout.count;
    report->points = c.n;
    if (c.n < (size_t)c.k || c.n == 0)
      st = bsurf_fail(err, BSURF_ERR_TOO_FEW_POINTS, 0, -1, "has %zu points, fewer than K = %d",
                      c.n, c.k);
    else if (ops->tile_points < 2 * (size_t)c.k)
      st = bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "tiles of %zu points are too small for K = %d", ops->tile_points, c.k);
  }
  if (st == BSURF_OK) {
    st = cloud_like(&c.schema, 1, &c.out_schema);
    if (st == BSURF_OK && ops->prepare) st = ops->prepare(ops->user, &c.out_schema);
  }
  if (st == BSURF_OK && ops->values_in) {
    st = map_values(ops->values_in, c.n, &c.vin, err);
    c.vin_cols = ops->values_in->nvalues + 1;
  }
  /* the passes are collective: every rank starts them or none */
  st = agree(c.comm, st);
  if (st == BSURF_OK) {
    st = pass_bounds(&c, report);
    if (st == BSURF_ERR_INVALID_VALUE)
      bsurf_fail(err, st, 0, -1, "point %zu (0-based) has a NaN or infinite coordinate or normal",
                 report->bad_point);
  }
  if (st == BSURF_OK) {
    make_grid(&c);
    st = pass_sort(&c, output, err);
  }
  if (st == BSURF_OK) st = make_tiles(&c);
  if (st == BSURF_OK && ops->reverse && (st = cell_maxima(&c)) == BSURF_ERR_INVALID_VALUE)
    bsurf_fail(err, st, 0, -1, "the first stage's values are not of this input");
  if (st == BSURF_OK) {
    report->tiles = c.ntiles;
    c.tile_sums = bsurf_calloc_array(c.ntiles, (ops->nsums + 1) * sizeof(double));
    if (!c.tile_sums) st = BSURF_ERR_NOMEM;
  }
  /* every rank reads and checks the same input: they agree on failures */
  st = agree(c.comm, st);
  if (st == BSURF_OK) st = open_outputs(&c, output, err);

  size_t done = 0, mine = 0;
  for (size_t t = (size_t)rank; t < c.ntiles; t += (size_t)ranks)
    mine += c.tiles[t].count;
  for (size_t t = (size_t)rank; t < c.ntiles && st == BSURF_OK; t += (size_t)ranks) {
    st = do_tile(&c, t, report, err);
    done += c.tiles[t].count;
    if (st == BSURF_OK && ops->progress && ops->progress(ops->progress_user, done, mine))
      st = BSURF_ERR_CANCELLED;
  }
  if (st == BSURF_ERR_NOMEM && err && !err->message[0]) bsurf_fail(err, st, 0, -1, "out of memory");
  st = agree(c.comm, st);

  if (st == BSURF_OK) {
    /* the accumulators of every tile, then the totals in tile order */
    size_t width = ops->nsums + 1;
    if (c.comm) c.comm->sum(c.comm->user, c.tile_sums, c.ntiles * width);
    for (size_t i = 0; i < ops->nsums; i++)
      report->sums[i] = 0;
    for (size_t t = 0; t < c.ntiles; t++) {
      for (size_t i = 0; i < ops->nsums; i++)
        report->sums[i] += c.tile_sums[t * width + i];
      report->duplicates += (size_t)c.tile_sums[t * width + ops->nsums];
    }
    if (c.comm) {
      double v[3] = {(double)report->max_tile_points, (double)report->max_local_points,
                     (double)report->halo_grown};
      /* maxima of the first two, sum of the third: one sum of one-hot rows */
      double *all = bsurf_calloc_array((size_t)ranks * 3, sizeof(double));
      if (all) {
        memcpy(all + 3 * (size_t)rank, v, sizeof v);
        c.comm->sum(c.comm->user, all, (size_t)ranks * 3);
        report->halo_grown = 0;
        for (int r = 0; r < ranks; r++) {
          if (all[3 * r] > (double)report->max_tile_points)
            report->max_tile_points = (size_t)all[3 * r];
          if (all[3 * r + 1] > (double)report->max_local_points)
            report->max_local_points = (size_t)all[3 * r + 1];
          report->halo_grown += (size_t)all[3 * r + 2];
        }
        free(all);
      }
    }
  }
  /* every rank's blocks are written (the agreement above follows every
   * rank's last write): each rank assembles and writes its ranges */
  double *range_sum = NULL;
  if (st == BSURF_OK) {
    range_sum = bsurf_calloc_array(c.nranges * ((size_t)ranks + 1), sizeof *range_sum);
    st = range_sum ? assemble(&c, range_sum, err) : BSURF_ERR_NOMEM;
  }
  /* the other ranks' writes are done (closed: on a network file system,
   * flushed) before rank 0 syncs and renames the output */
  if (rank != 0 && c.out >= 0) {
    if (close(c.out) != 0 && st == BSURF_OK)
      st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write the output: %s", strerror(errno));
    c.out = -1;
  }
  st = agree(c.comm, st);
  if (st == BSURF_OK) {
    /* the ranges' sums, each from the rank that assembled it, then h by the
     * top of the cascade */
    if (c.comm) {
      double *all = range_sum + c.nranges;
      c.comm->allgather(c.comm->user, range_sum, all, c.nranges * sizeof *range_sum);
      for (int r = 0; r < ranks; r++)
        for (size_t q = share_start(c.nranges, r, ranks); q < share_start(c.nranges, r + 1, ranks);
             q++)
          range_sum[q] = all[(size_t)r * c.nranges + q];
    }
    size_t next = 0;
    report->h = cascade_top(&c, range_sum, c.n, &next) / (double)c.n;
    assert(next == c.nranges);
  }
  free(range_sum);
  if (rank == 0 && c.af_open) {
    bsurf_failure cerr;
    bsurf_status cst = bsurf_atomic_close(&c.af, st, 0, &cerr);
    if (st == BSURF_OK && cst != BSURF_OK) {
      st = cst;
      if (err) *err = cerr;
    }
  }
  if (c.comm) st = agree(c.comm, st);
  if (st == BSURF_OK && c.vcols) { /* the values go to the caller */
    ops->values_out->fd = c.vfd;
    ops->values_out->count = c.n;
    ops->values_out->nvalues = ops->nvalues;
    c.vfd = -1;
  }

  map_close(&c.in);
  map_close(&c.sorted);
  map_close(&c.vin);
  free(c.cellmax);
  if (c.scr >= 0) close(c.scr);
  if (c.vfd >= 0) close(c.vfd);
  free(c.block);
  free(c.range_lo);
  io_ply_layout_free(&c.layout);
  bsurf_cloud_free(&c.schema);
  bsurf_cloud_free(&c.out_schema);
  free(c.cell_start);
  free(c.tiles);
  free(c.tile_sums);
  return st;
}

/* ---- a pointwise second stage ------------------------------------------------ */

bsurf_status bsurf_tiles_map(const char *input, const char *output, const bsurf_tile_ops *ops,
                             const bsurf_tile_values *values, bsurf_tile_map_fn map,
                             bsurf_failure *err) {
  if (err) err->line = 0, err->byte = -1, err->message[0] = 0;
  if (!input || !output || !ops || !ops->prepare || !values || !map)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "invalid arguments");
  tiles_ctx c;
  memset(&c, 0, sizeof c);
  c.ops = ops;
  c.comm = ops->comm;
  c.in.fd = c.sorted.fd = c.scr = c.vfd = c.vin.fd = -1;
  bsurf_cloud_init(&c.schema);
  bsurf_cloud_init(&c.out_schema);
  bsurf_cloud part;
  bsurf_cloud_init(&part);
  unsigned char *enc = NULL;
  double *vals = NULL;
  bsurf_status st = BSURF_OK;
  if (!c.comm || c.comm->rank == 0) { /* the others wait */
    st = map_input(input, &c.in, err);
    if (st == BSURF_OK) st = io_ply_map(c.in.data, c.in.size, &c.layout, &c.schema, err);
    if (st == BSURF_OK) c.n = c.layout.count;
    if (st == BSURF_OK) st = map_values(values, c.n, &c.vin, err);
    if (st == BSURF_OK) st = cloud_like(&c.schema, 1, &c.out_schema);
    if (st == BSURF_OK) st = ops->prepare(ops->user, &c.out_schema);
    if (st == BSURF_OK) {
      c.record = record_of(&c.out_schema);
      st = create_output(&c, output, err);
    }
    const size_t nv = values->nvalues, cols = nv + 1;
    size_t range = ((size_t)32 << 20) / (c.record + cols * sizeof(double));
    if (ops->range_points) range = ops->range_points;
    if (range > c.n) range = c.n;
    if (st == BSURF_OK && c.n) {
      enc = bsurf_alloc_array(range, c.record);
      vals = bsurf_alloc_array(range, (nv ? nv : 1) * sizeof(double));
      if (!enc || !vals) st = BSURF_ERR_NOMEM;
    }
    const double *v = (const double *)c.vin.data;
    for (size_t first = 0; first < c.n && st == BSURF_OK; first += range) {
      size_t m = c.n - first < range ? c.n - first : range;
      if (ops->progress && ops->progress(ops->progress_user, first, c.n)) {
        st = BSURF_ERR_CANCELLED;
        break;
      }
      bsurf_cloud_free(&part);
      st = cloud_like(&c.schema, m, &part);
      for (size_t j = 0; j < m && st == BSURF_OK; j++) {
        io_ply_decode(&c.layout, c.in.data, first + j, &part, j);
        memcpy(vals + j * nv, v + (first + j) * cols, nv * sizeof(double));
      }
      if (st == BSURF_OK) st = ops->prepare(ops->user, &part);
      if (st == BSURF_OK) st = map(ops->user, first, &part, vals);
      if (st == BSURF_OK) st = io_ply_encode(&part, enc);
      int e = st == BSURF_OK
                  ? pwrite_all(fileno(c.af.f), enc, m * c.record, c.header + first * c.record)
                  : 0;
      if (e) st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write the output: %s", strerror(e));
      drop_pages(&c.in, c.layout.body + first * c.layout.record,
                 c.layout.body + (first + m) * c.layout.record);
      drop_pages(&c.vin, first * cols * sizeof(double), (first + m) * cols * sizeof(double));
    }
    if (st == BSURF_ERR_NOMEM && err && !err->message[0])
      bsurf_fail(err, st, 0, -1, "out of memory");
    if (c.af_open) {
      bsurf_failure cerr;
      bsurf_status cst = bsurf_atomic_close(&c.af, st, 0, &cerr);
      if (st == BSURF_OK && cst != BSURF_OK) {
        st = cst;
        if (err) *err = cerr;
      }
    }
  }
  st = agree(c.comm, st);
  bsurf_cloud_free(&part);
  free(enc);
  free(vals);
  map_close(&c.in);
  map_close(&c.vin);
  io_ply_layout_free(&c.layout);
  bsurf_cloud_free(&c.schema);
  bsurf_cloud_free(&c.out_schema);
  return st;
}
