/* The tile engine's output (src/tile/tiles.c): the tiles' blocks in a
 * scratch file, then the output assembled in index order, range by range. */
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

/* ---- the output: tile blocks, then ranges in index order ------------------ */

/* Writing each tile's rows at their places in the output would spread them
 * over the whole file when its point order is not spatial, and every tile
 * would dirty nearly every page of it (the kernel writing the file back once
 * per tile). Instead each tile appends one block to a scratch file, in one
 * sequential write:
 *   cuts[0 .. R]   uint64: cuts[r] = the tile's rows with index < range_lo[r]
 *   entries        per row, in increasing index: uint64 index, double nn2
 *                  (squared nearest-other distance, for h), in a first
 *                  stage its values and its squared K-th distance, the
 *                  encoded row (if there is an output file)
 * and after the tiles the ranks assemble the output range by range (R ranges
 * of at most `range` consecutive indices, each held in memory once, split
 * over the ranks): from every tile the entries [cuts[r], cuts[r + 1]) of its
 * block are read and placed, and the range is written at its offset in the
 * output in one pwrite (a first stage's values at theirs in the values
 * file). The blocks' offsets
 * follow from the tiles' point counts, which every rank knows, so ranks write
 * their blocks into the one scratch file without exchanging anything. */

#define BLOCK_CHUNK ((size_t)1 << 20) /* bytes per read or write of entries */

static size_t entry_bytes(const tiles_ctx *c) {
  return 16 + c->vcols * sizeof(double) + c->record;
}

/* The ranges are the subtrees of bsurf_sum_sqrt's cascade (halves, the
 * lower n / 2 first) that hold at most c->range points, in index order: each
 * range's sum for h is a whole subtree, computed by whichever rank assembles
 * the range, and the top of the tree combines them (cascade_top), so h is
 * the one-process double for any rank count. With lo NULL, the ranges are
 * counted in *next; otherwise their first points are stored in lo. */
static void range_cut(const tiles_ctx *c, size_t first, size_t n, size_t *next, size_t *lo) {
  if (n <= c->range) {
    if (lo) lo[*next] = first;
    ++*next;
    return;
  }
  range_cut(c, first, n / 2, next, lo);
  range_cut(c, first + n / 2, n - n / 2, next, lo);
}

/* sum_i sqrt(nn2_i) over all points by the cascade, from the ranges' sums */
double cascade_top(const tiles_ctx *c, const double *range_sum, size_t n, size_t *next) {
  if (n <= c->range) return range_sum[(*next)++];
  return cascade_top(c, range_sum, n / 2, next) + cascade_top(c, range_sum, n - n / 2, next);
}

/* the ranges and every tile's block offset (ntiles + 1 of them) */
static bsurf_status plan_blocks(tiles_ctx *c) {
  /* a range holds at least a tile's points (a tile's memory is many times
   * its rows') and at least 32 MiB, so that R x tiles reads stay few; with
   * several ranks, at most n / ranks, so that every rank has a share */
  size_t by_bytes = ((size_t)32 << 20) / (c->record + (c->vcols + 1) * sizeof(double));
  c->range = c->ops->tile_points > by_bytes ? c->ops->tile_points : by_bytes;
  if (c->ops->range_points) c->range = c->ops->range_points;
  size_t per_rank = (c->n + (size_t)ranks_of(c) - 1) / (size_t)ranks_of(c);
  if (c->range > per_rank) c->range = per_rank;
  if (c->range < 64) c->range = 64; /* a leaf of the cascade is never cut */
  c->nranges = 0;
  range_cut(c, 0, c->n, &c->nranges, NULL);
  c->range_lo = bsurf_alloc_array(c->nranges + 1, sizeof *c->range_lo);
  c->block = bsurf_alloc_array(c->ntiles + 1, sizeof *c->block);
  if (!c->range_lo || !c->block) return BSURF_ERR_NOMEM;
  size_t r = 0;
  range_cut(c, 0, c->n, &r, c->range_lo);
  c->range_lo[c->nranges] = c->n;
  c->block[0] = 0;
  for (size_t t = 0; t < c->ntiles; t++)
    c->block[t + 1] =
        c->block[t] + (c->nranges + 1) * sizeof(uint64_t) + c->tiles[t].count * entry_bytes(c);
  return BSURF_OK;
}

static bsurf_status scratch_error(bsurf_failure *err, const char *what, int e) {
  return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot %s the scratch file of the tiles' rows: %s",
                    what, strerror(e));
}

/* Tile t's block: core (increasing global indices), nn2, the values (vcols
 * each) and the encoded rows of its nc points. */
bsurf_status write_block(const tiles_ctx *c, size_t t, const uint64_t *core, const double *nn2,
                         const double *vals, const unsigned char *enc, size_t nc,
                         bsurf_failure *err) {
  assert(nc == c->tiles[t].count);
  const size_t eb = entry_bytes(c), per = BLOCK_CHUNK / eb ? BLOCK_CHUNK / eb : 1;
  uint64_t *cuts = bsurf_alloc_array(c->nranges + 1, sizeof *cuts);
  unsigned char *buf = bsurf_alloc_array(per, eb);
  if (!cuts || !buf) {
    free(cuts);
    free(buf);
    return BSURF_ERR_NOMEM;
  }
  for (size_t r = 0; r < c->nranges; r++)
    cuts[r] = find_u64(core, nc, (uint64_t)c->range_lo[r]);
  cuts[c->nranges] = nc;
  size_t off = c->block[t];
  int e = pwrite_all(c->scr, cuts, (c->nranges + 1) * sizeof *cuts, off);
  off += (c->nranges + 1) * sizeof *cuts;
  for (size_t j = 0; j < nc && !e; j += per) {
    size_t m = nc - j < per ? nc - j : per;
    for (size_t q = 0; q < m; q++) {
      unsigned char *p = buf + q * eb;
      memcpy(p, &core[j + q], 8);
      memcpy(p + 8, &nn2[j + q], 8);
      if (c->vcols) memcpy(p + 16, vals + (j + q) * c->vcols, c->vcols * sizeof(double));
      if (c->record)
        memcpy(p + 16 + c->vcols * sizeof(double), enc + (j + q) * c->record, c->record);
    }
    e = pwrite_all(c->scr, buf, m * eb, off);
    off += m * eb;
  }
  free(cuts);
  free(buf);
  return e ? scratch_error(err, "write", e) : BSURF_OK;
}

/* Range r of the output: every tile's entries of it, read from the blocks
 * and placed in rows (record bytes each), vals (vcols doubles each: a first
 * stage's values) and nn (squared nearest distances); buf holds `per`
 * entries. */
static bsurf_status load_range(const tiles_ctx *c, size_t r, unsigned char *rows, double *vals,
                               double *nn, unsigned char *buf, size_t per, bsurf_failure *err) {
  const size_t eb = entry_bytes(c), lo = c->range_lo[r], hi = c->range_lo[r + 1];
  size_t placed = 0;
  int e = 0;
  for (size_t t = 0; t < c->ntiles && !e; t++) {
    uint64_t cut[2];
    e = pread_all(c->scr, cut, sizeof cut, c->block[t] + r * sizeof(uint64_t));
    if (e) break;
    size_t base = c->block[t] + (c->nranges + 1) * sizeof(uint64_t);
    if (cut[0] > cut[1] || cut[1] > c->tiles[t].count) {
      e = EIO;
      break;
    }
    for (uint64_t j = cut[0]; j < cut[1] && !e; j += per) {
      size_t m = cut[1] - j < per ? (size_t)(cut[1] - j) : per;
      e = pread_all(c->scr, buf, m * eb, base + (size_t)j * eb);
      for (size_t q = 0; q < m && !e; q++) {
        const unsigned char *p = buf + q * eb;
        uint64_t i;
        memcpy(&i, p, 8);
        if (i < lo || i >= hi) {
          e = EIO;
          break;
        }
        memcpy(&nn[i - lo], p + 8, 8);
        if (c->vcols) memcpy(vals + (i - lo) * c->vcols, p + 16, c->vcols * sizeof(double));
        if (c->record)
          memcpy(rows + (i - lo) * c->record, p + 16 + c->vcols * sizeof(double), c->record);
      }
      placed += m;
    }
  }
  /* the tiles partition the points: every row of the range exactly once */
  if (!e && placed != hi - lo) e = EIO;
  return e ? scratch_error(err, "read", e) : BSURF_OK;
}

/* This rank's share of the ranges (contiguous, share_start): each one
 * assembled in memory, written at its offset in the output (pwrite, one
 * sequential write) and, for a first stage, its values at their offset in
 * the values file; its sum for h stored in range_sum[r] (bsurf_sum_sqrt
 * over the range: a subtree of the cascade). The ranges are independent, so
 * the ranks assemble theirs at the same time. */
bsurf_status assemble(const tiles_ctx *c, double *range_sum, bsurf_failure *err) {
  const size_t r0 = share_start(c->nranges, rank_of(c), ranks_of(c));
  const size_t r1 = share_start(c->nranges, rank_of(c) + 1, ranks_of(c));
  const size_t per = BLOCK_CHUNK / entry_bytes(c) ? BLOCK_CHUNK / entry_bytes(c) : 1;
  const size_t vb = c->vcols * sizeof(double);
  if (r0 == r1) return BSURF_OK; /* more ranks than ranges */
  unsigned char *rows = c->record ? bsurf_alloc_array(c->range, c->record) : NULL;
  double *vals = vb ? bsurf_alloc_array(c->range, vb) : NULL;
  double *nn = bsurf_alloc_array(c->range, sizeof *nn);
  unsigned char *buf = bsurf_alloc_array(per, entry_bytes(c));
  bsurf_status st = (rows || !c->record) && (vals || !vb) && nn && buf ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t r = r0; r < r1 && st == BSURF_OK; r++) {
    const size_t lo = c->range_lo[r], m = c->range_lo[r + 1] - lo;
    if (pass_cancelled(c)) st = BSURF_ERR_CANCELLED;
    if (st == BSURF_OK) st = load_range(c, r, rows, vals, nn, buf, per, err);
    if (st != BSURF_OK) break;
    range_sum[r] = bsurf_sum_sqrt(nn, m);
    int e = c->record ? pwrite_all(c->out, rows, m * c->record, c->header + lo * c->record) : 0;
    if (e) st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write the output: %s", strerror(e));
    if (st == BSURF_OK && vb && (e = pwrite_all(c->vfd, vals, m * vb, lo * vb)))
      st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write the scratch file of the values: %s",
                      strerror(e));
  }
  free(rows);
  free(vals);
  free(nn);
  free(buf);
  return st;
}

/* ---- the run ---------------------------------------------------------------- */

/* The bytes of a record of the output. */
size_t record_of(const bsurf_cloud *schema) {
  size_t record = 3 * io_type_size(schema->xyz_type);
  if (schema->normals) record += 3 * io_type_size(schema->normal_type);
  for (size_t f = 0; f < schema->field_count; f++)
    record += io_type_size(schema->fields[f].type);
  return record;
}

/* Rank 0: the output under a temporary name, its header, and the space of
 * every record reserved (a full disk fails here, not later). */
bsurf_status create_output(tiles_ctx *c, const char *output, bsurf_failure *err) {
  bsurf_status st = bsurf_atomic_open(&c->af, output, err);
  if (st != BSURF_OK) return st;
  c->af_open = 1;
  if (c->af.direct) /* its ranges are written at their offsets */
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1,
                      "tiled runs write a regular file, not a FIFO or device");
  io_writer w = {c->af.f, 0, 0};
  size_t record = 0;
  st = io_ply_write_header(&w, &c->out_schema, c->n, &record);
  assert(st != BSURF_OK || record == c->record);
  if (fflush(c->af.f) != 0) w.failed = 1, w.err_no = errno;
  long pos = ftell(c->af.f);
  if (w.failed || pos < 0)
    st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write: %s",
                    strerror(w.err_no ? w.err_no : EIO));
  c->header = (size_t)pos;
  if (st == BSURF_OK) {
    size_t total = c->header + c->n * c->record;
    int e = posix_fallocate(fileno(c->af.f), 0, (off_t)total);
    if (e)
      st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write %zu bytes: %s", total, strerror(e));
  }
  return st;
}

/* Rank 0 creates the output (temporary name, header, space for every
 * record) unless the run has none (a first stage), and every rank opens it
 * to write its ranges; then the scratch files, shared by every rank
 * (shared_scratch): the tiles' blocks, and the values of a first stage. */
bsurf_status open_outputs(tiles_ctx *c, const char *output, bsurf_failure *err) {
  const bsurf_tile_comm *cm = c->comm;
  const int rank = rank_of(c);
  c->record = c->ops->prepare ? record_of(&c->out_schema) : 0;
  bsurf_status st = plan_blocks(c);
  if (rank == 0 && st == BSURF_OK && c->ops->prepare) {
    st = create_output(c, output, err);
    if (st == BSURF_OK) c->out = fileno(c->af.f);
  }
  st = agree(cm, st);
  if (st == BSURF_OK && cm && c->ops->prepare) {
    /* the other ranks write their ranges through the temporary name */
    struct {
      uint64_t header;
      char name[TILE_PATH_MAX];
    } out;
    memset(&out, 0, sizeof out);
    if (rank == 0) {
      out.header = c->header;
      if (strlen(c->af.tmp) < sizeof out.name)
        strcpy(out.name, c->af.tmp);
      else
        st = bsurf_fail(err, BSURF_ERR_IO, 0, -1,
                        "the output's path is too long for a distributed run");
    }
    st = agree(cm, st);
    if (st == BSURF_OK) cm->broadcast(cm->user, &out, sizeof out);
    if (st == BSURF_OK && rank != 0) {
      c->header = (size_t)out.header;
      c->out = open(out.name, O_WRONLY);
      if (c->out < 0)
        st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open %s: %s", out.name, strerror(errno));
    }
    st = agree(cm, st);
  }
  tile_map m;
  if (st == BSURF_OK) {
    st = shared_scratch(c, output, c->block[c->ntiles], 0, &m, err);
    c->scr = m.fd;
  }
  if (st == BSURF_OK && c->vcols) {
    st = shared_scratch(c, output, c->n * c->vcols * sizeof(double), 0, &m, err);
    c->vfd = m.fd;
  }
  return st;
}
