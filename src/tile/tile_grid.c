/* The tile engine's passes over the input (bounds, grid, counting sort by
 * cell) and the cut of the grid into tiles (src/tile/tiles.c). */
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

/* ---- passes over the input ------------------------------------------------- */

/* Each pass is split over the ranks: rank r sweeps its share [a, b) of the
 * point indices (share_start), and the results are combined so that they
 * are the one-process pass's, bit for bit. */

/* Between two page drops the passes ask the progress callback (at 0 done)
 * whether to stop: an interrupt stops a pass within ~10^6 points. */
int pass_cancelled(const tiles_ctx *c) {
  return c->ops->progress && c->ops->progress(c->ops->progress_user, 0, c->n);
}

/* One rank's pass 1: its box, and its first failure (a bad point, or what
 * stopped it). */
typedef struct bounds_part {
  double lo[3], hi[3];
  uint64_t bad;
  int32_t st, pad;
} bounds_part;

/* Pass 1: every coordinate (and normal) finite, bounding box. The ranks'
 * boxes are combined in rank order with the comparisons of the sweep (the
 * first of equal values stays), and the first rank that failed gives the
 * status: its bad point is the lowest index of any. */
bsurf_status pass_bounds(tiles_ctx *c, bsurf_tile_report *rep) {
  const size_t a = share_start(c->n, rank_of(c), ranks_of(c)),
               b = share_start(c->n, rank_of(c) + 1, ranks_of(c));
  bounds_part mine;
  memset(&mine, 0, sizeof mine);
  for (int d = 0; d < 3; d++)
    mine.lo[d] = INFINITY, mine.hi[d] = -INFINITY;
  bsurf_cloud one;
  bsurf_status st = cloud_like(&c->schema, 1, &one);
  for (size_t i = a; i < b && st == BSURF_OK; i++) {
    io_ply_decode(&c->layout, c->in.data, i, &one, 0);
    const double *p = one.xyz, *q = one.normals;
    if (!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])) ||
        (q && !(isfinite(q[0]) && isfinite(q[1]) && isfinite(q[2])))) {
      mine.bad = i;
      st = BSURF_ERR_INVALID_VALUE;
      break;
    }
    for (int d = 0; d < 3; d++) {
      if (p[d] < mine.lo[d]) mine.lo[d] = p[d];
      if (p[d] > mine.hi[d]) mine.hi[d] = p[d];
    }
    if ((i + 1 - a) % PASS_DROP == 0) {
      drop_pages(&c->in, c->layout.body + (i + 1 - PASS_DROP) * c->layout.record,
                 c->layout.body + (i + 1) * c->layout.record);
      if (pass_cancelled(c)) st = BSURF_ERR_CANCELLED;
    }
  }
  drop_pages(&c->in, 0, c->in.size);
  bsurf_cloud_free(&one);
  mine.st = (int32_t)st;
  const int ranks = ranks_of(c);
  bounds_part *all = &mine;
  if (c->comm) {
    /* every rank takes part even when it failed */
    all = bsurf_alloc_array((size_t)ranks, sizeof *all);
    int ok = agree(c->comm, all ? BSURF_OK : BSURF_ERR_NOMEM) == BSURF_OK;
    if (!ok) {
      free(all);
      return BSURF_ERR_NOMEM;
    }
    c->comm->allgather(c->comm->user, &mine, all, sizeof mine);
  }
  for (int d = 0; d < 3; d++)
    c->lo[d] = INFINITY, c->hi[d] = -INFINITY;
  st = BSURF_OK;
  for (int r = 0; r < ranks && st == BSURF_OK; r++) {
    st = (bsurf_status)all[r].st;
    if (st == BSURF_ERR_INVALID_VALUE) rep->bad_point = (size_t)all[r].bad;
    for (int d = 0; d < 3; d++) {
      if (all[r].lo[d] < c->lo[d]) c->lo[d] = all[r].lo[d];
      if (all[r].hi[d] > c->hi[d]) c->hi[d] = all[r].hi[d];
    }
  }
  if (all != &mine) free(all);
  return st;
}

/* The grid: cubic cells, about 512 per tile (at most TILE_MAX_CELLS). */
void make_grid(tiles_ctx *c) {
  double ext[3], maxext = 0, prod = 1;
  int d = 0;
  for (int a = 0; a < 3; a++) {
    ext[a] = c->hi[a] - c->lo[a];
    if (ext[a] > maxext) maxext = ext[a];
  }
  size_t want = 512 * (c->n / c->ops->tile_points + 1);
  if (want > TILE_MAX_CELLS / 2) want = TILE_MAX_CELLS / 2;
  for (int a = 0; a < 3; a++)
    if (ext[a] > 1e-9 * maxext && ext[a] > 0) prod *= ext[a], d++;
  double s = d ? pow(prod / (double)want, 1.0 / d) : 1.0;
  if (!(s > 0) || !isfinite(s)) s = maxext > 0 ? maxext : 1.0;
  for (;;) {
    size_t cells = 1;
    for (int a = 0; a < 3; a++) {
      double m = floor(ext[a] / s) + 1;
      c->dim[a] = m < 65536 ? (uint32_t)m : 65536;
      cells *= c->dim[a];
    }
    if (cells <= TILE_MAX_CELLS) {
      c->cells = cells;
      break;
    }
    s *= 1.25;
  }
  c->cell = s;
  for (int a = 0; a < 3; a++)
    c->origin[a] = c->lo[a];
}

/* Passes 2 and 3: counts per cell, then the point indices sorted by cell
 * (increasing inside each cell) into a scratch file every rank shares.
 * Rank r counts its share; the counts are summed over the ranks (the cells'
 * starts) and their exclusive prefix over the ranks places rank r's points
 * of a cell after those of ranks 0 .. r-1, so the file is the one-process
 * pass's whatever the rank count. */
bsurf_status pass_sort(tiles_ctx *c, const char *output, bsurf_failure *err) {
  const size_t a = share_start(c->n, rank_of(c), ranks_of(c)),
               b = share_start(c->n, rank_of(c) + 1, ranks_of(c));
  c->cell_start = bsurf_calloc_array(c->cells + 1, sizeof *c->cell_start);
  uint64_t *cursor = bsurf_calloc_array(c->cells, sizeof *cursor);
  bsurf_status st = c->cell_start && cursor ? BSURF_OK : BSURF_ERR_NOMEM;
  double p[3];
  uint32_t cc[3];
  for (size_t i = a; i < b && st == BSURF_OK; i++) {
    xyz_of(c, i, p);
    cell_coords(c, p, cc);
    cursor[cell_id(c, cc)]++;
    if ((i + 1 - a) % PASS_DROP == 0) {
      drop_pages(&c->in, 0, c->in.size);
      if (pass_cancelled(c)) st = BSURF_ERR_CANCELLED;
    }
  }
  drop_pages(&c->in, 0, c->in.size);
  st = agree(c->comm, st);
  if (st == BSURF_OK) {
    memcpy(c->cell_start + 1, cursor, c->cells * sizeof *cursor);
    if (c->comm) {
      c->comm->sum_u64(c->comm->user, c->cell_start + 1, c->cells);
      c->comm->exscan_u64(c->comm->user, cursor, c->cells);
    } else {
      memset(cursor, 0, c->cells * sizeof *cursor);
    }
    for (size_t j = 0; j < c->cells; j++) {
      c->cell_start[j + 1] += c->cell_start[j];
      cursor[j] += c->cell_start[j];
    }
    st = shared_scratch(c, output, c->n * sizeof(uint64_t), 1, &c->sorted, err);
  }
  if (st == BSURF_OK) {
    uint64_t *sorted = (uint64_t *)c->sorted.data;
    for (size_t i = a; i < b; i++) {
      xyz_of(c, i, p);
      cell_coords(c, p, cc);
      sorted[cursor[cell_id(c, cc)]++] = i;
      /* the writes land all over the file: drop them often (they stay in
       * the page cache, not in this process) */
      if ((i + 1 - a) % (PASS_DROP / 16) == 0) drop_pages(&c->sorted, 0, c->sorted.size);
      if ((i + 1 - a) % PASS_DROP == 0) {
        drop_pages(&c->in, 0, c->in.size);
        if (pass_cancelled(c)) {
          st = BSURF_ERR_CANCELLED;
          break;
        }
      }
    }
    drop_pages(&c->in, 0, c->in.size);
    drop_pages(&c->sorted, 0, c->sorted.size);
  }
  free(cursor);
  return st;
}

/* ---- tiles ------------------------------------------------------------------ */

static size_t box_count(const tiles_ctx *c, const tile_box *b, size_t *slab[3]) {
  size_t total = 0;
  for (uint32_t z = b->lo[2]; z < b->hi[2]; z++)
    for (uint32_t y = b->lo[1]; y < b->hi[1]; y++)
      for (uint32_t x = b->lo[0]; x < b->hi[0]; x++) {
        uint32_t cc[3] = {x, y, z};
        size_t j = cell_id(c, cc);
        size_t m = (size_t)(c->cell_start[j + 1] - c->cell_start[j]);
        total += m;
        if (slab) {
          slab[0][x - b->lo[0]] += m;
          slab[1][y - b->lo[1]] += m;
          slab[2][z - b->lo[2]] += m;
        }
      }
  return total;
}

/* Cuts the grid into tiles of at most tile_points points (when a cut with K
 * points on each side exists), depth first, the lower side first. */
bsurf_status make_tiles(tiles_ctx *c) {
  size_t cap = 64, top = 0;
  tile_box *stack = bsurf_alloc_array(cap, sizeof *stack);
  size_t *slab[3] = {bsurf_calloc_array(c->dim[0], sizeof(size_t)),
                     bsurf_calloc_array(c->dim[1], sizeof(size_t)),
                     bsurf_calloc_array(c->dim[2], sizeof(size_t))};
  size_t tcap = 16;
  c->tiles = bsurf_alloc_array(tcap, sizeof *c->tiles);
  bsurf_status st = BSURF_OK;
  if (!stack || !slab[0] || !slab[1] || !slab[2] || !c->tiles) st = BSURF_ERR_NOMEM;
  if (st == BSURF_OK) {
    tile_box root = {{0, 0, 0}, {c->dim[0], c->dim[1], c->dim[2]}, c->n};
    stack[top++] = root;
  }
  const size_t minpts = (size_t)c->k;
  while (st == BSURF_OK && top > 0) {
    tile_box b = stack[--top];
    int split = 0;
    tile_box lo_box = b, hi_box = b;
    if (b.count > c->ops->tile_points) {
      for (int a = 0; a < 3; a++)
        memset(slab[a], 0, (b.hi[a] - b.lo[a]) * sizeof(size_t));
      box_count(c, &b, slab);
      int order[3] = {0, 1, 2};
      for (int i = 0; i < 3; i++) /* widest side first (ties: x, y, z) */
        for (int j = i + 1; j < 3; j++)
          if (b.hi[order[j]] - b.lo[order[j]] > b.hi[order[i]] - b.lo[order[i]]) {
            int t = order[i];
            order[i] = order[j];
            order[j] = t;
          }
      for (int oi = 0; oi < 3 && !split; oi++) {
        int a = order[oi];
        uint32_t len = b.hi[a] - b.lo[a], best = 0;
        size_t left = 0, best_dev = SIZE_MAX, best_left = 0;
        for (uint32_t s = 1; s < len; s++) {
          left += slab[a][s - 1];
          size_t right = b.count - left;
          if (left < minpts || right < minpts) continue;
          size_t dev = left > b.count / 2 ? left - b.count / 2 : b.count / 2 - left;
          if (dev < best_dev) best_dev = dev, best = s, best_left = left;
        }
        if (best) {
          split = 1;
          lo_box.hi[a] = b.lo[a] + best;
          hi_box.lo[a] = b.lo[a] + best;
          lo_box.count = best_left;
          hi_box.count = b.count - best_left;
        }
      }
    }
    if (split) {
      if (top + 2 > cap) {
        tile_box *ns = realloc(stack, 2 * cap * sizeof *stack);
        if (!ns) {
          st = BSURF_ERR_NOMEM;
          break;
        }
        stack = ns;
        cap *= 2;
      }
      stack[top++] = hi_box; /* popped after the lower side */
      stack[top++] = lo_box;
    } else if (b.count > 0) {
      if (c->ntiles == tcap) {
        tile_box *nt = realloc(c->tiles, 2 * tcap * sizeof *nt);
        if (!nt) {
          st = BSURF_ERR_NOMEM;
          break;
        }
        c->tiles = nt;
        tcap *= 2;
      }
      c->tiles[c->ntiles++] = b;
    }
  }
  free(stack);
  for (int a = 0; a < 3; a++)
    free(slab[a]);
  return st;
}
