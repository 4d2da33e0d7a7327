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
 */
#define _DEFAULT_SOURCE /* madvise */
#include "common/common.h"
#include "tile/tile_engine.h"
#include "io/io.h"
#include "search/search.h"

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#define TILE_MAX_CELLS ((size_t)1 << 22)
#define TILE_PATH_MAX 4200

/* ---- files ---------------------------------------------------------------- */

typedef struct tile_map {
  char *data;
  size_t size;
  int fd;
} tile_map;

static void map_close(tile_map *m) {
  if (m->data && m->size) munmap(m->data, m->size);
  if (m->fd >= 0) close(m->fd);
  m->data = NULL;
  m->size = 0;
  m->fd = -1;
}

/* Drops the resident pages of [from, to) of a mapping (page-aligned inside):
 * read-only pages are re-read from the page cache if needed again, written
 * pages of a shared mapping stay in the page cache and reach the file. */
static void drop_pages(const tile_map *m, size_t from, size_t to) {
  size_t page = (size_t)sysconf(_SC_PAGESIZE);
  size_t a = (from + page - 1) / page * page, b = to / page * page;
  if (to >= m->size) b = m->size; /* the mapping's last, partial page too */
  if (b > a) madvise(m->data + a, b - a, MADV_DONTNEED);
}

/* Drops pages behind a sweep through a mapping in increasing offsets, so
 * that at most about 64 MB of it is resident: a tile's points are spread
 * over the whole file when the file's order is not spatial. */
typedef struct sweep {
  const tile_map *m;
  size_t mark;
} sweep;

static void sweep_at(sweep *s, size_t offset) {
  if (offset > s->mark + ((size_t)64 << 20)) {
    drop_pages(s->m, s->mark, offset);
    s->mark = offset;
  }
}

static bsurf_status map_input(const char *path, tile_map *m, bsurf_failure *err) {
  m->data = NULL;
  m->size = 0;
  m->fd = open(path, O_RDONLY);
  if (m->fd < 0) return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open: %s", strerror(errno));
  struct stat sb;
  if (fstat(m->fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
    map_close(m);
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot read: not a regular file");
  }
  m->size = (size_t)sb.st_size;
  if (m->size == 0) return BSURF_OK; /* io_ply_map says "empty" */
  m->data = mmap(NULL, m->size, PROT_READ, MAP_PRIVATE, m->fd, 0);
  if (m->data == MAP_FAILED) {
    m->data = NULL;
    int e = errno;
    map_close(m);
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot map: %s", strerror(e));
  }
  return BSURF_OK;
}

/* The directory part of a path ("." for none) followed by `name`. */
static void path_beside(char *out, size_t cap, const char *path, const char *name) {
  const char *slash = strrchr(path, '/');
  if (!slash)
    snprintf(out, cap, "./%s", name);
  else
    snprintf(out, cap, "%.*s/%s", (int)(slash - path), path, name);
}

/* A scratch file of `bytes` (space reserved) next to `near`, mapped shared
 * and writable when `map`; its name goes to `name` (to be unlinked by the
 * caller) or, when name is NULL, it is unlinked at once. */
static bsurf_status scratch_create(const char *near, size_t bytes, int map, tile_map *m, char *name,
                                   bsurf_failure *err) {
  char tmp[TILE_PATH_MAX];
  path_beside(tmp, sizeof tmp, near, ".bootsurf-tiles.XXXXXX");
  m->data = NULL;
  m->size = bytes;
  m->fd = mkstemp(tmp);
  if (m->fd < 0)
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot create a scratch file beside %s: %s", near,
                      strerror(errno));
  if (name)
    strcpy(name, tmp);
  else
    unlink(tmp);
  int e = bytes ? posix_fallocate(m->fd, 0, (off_t)bytes) : 0;
  if (e == 0 && bytes && map) {
    m->data = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, m->fd, 0);
    if (m->data == MAP_FAILED) m->data = NULL, e = errno;
  }
  if (e) {
    if (name) unlink(tmp);
    map_close(m);
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1,
                      "cannot make a scratch file of %zu bytes beside %s: %s", bytes, near,
                      strerror(e));
  }
  return BSURF_OK;
}

/* Writes or reads all of [buf, buf + bytes) at `offset` (short transfers
 * and interrupted calls are resumed); 0 or an errno. */
static int pwrite_all(int fd, const void *buf, size_t bytes, size_t offset) {
  const char *p = buf;
  while (bytes > 0) {
    ssize_t k = pwrite(fd, p, bytes, (off_t)offset);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return k < 0 ? errno : EIO;
    p += k, bytes -= (size_t)k, offset += (size_t)k;
  }
  return 0;
}

static int pread_all(int fd, void *buf, size_t bytes, size_t offset) {
  char *p = buf;
  while (bytes > 0) {
    ssize_t k = pread(fd, p, bytes, (off_t)offset);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return k < 0 ? errno : EIO; /* 0: the file is shorter than it must be */
    p += k, bytes -= (size_t)k, offset += (size_t)k;
  }
  return 0;
}

/* ---- the run's state --------------------------------------------------------- */

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

static void xyz_of(const tiles_ctx *c, uint64_t i, double p[3]) {
  io_ply_xyz(&c->layout, c->in.data, (size_t)i, p);
}

/* An empty cloud of n points with the properties of `schema`. */
static bsurf_status cloud_like(const bsurf_cloud *schema, size_t n, bsurf_cloud *out) {
  bsurf_status st = bsurf_cloud_alloc(out, n, schema->normals != NULL);
  out->xyz_type = schema->xyz_type;
  out->normal_type = schema->normal_type;
  memcpy(out->shape, schema->shape, sizeof out->shape);
  for (size_t f = 0; f < schema->field_count && st == BSURF_OK; f++)
    if (!bsurf_cloud_add_field(out, schema->fields[f].name, schema->fields[f].type))
      st = BSURF_ERR_NOMEM;
  return st;
}

static void cell_coords(const tiles_ctx *c, const double p[3], uint32_t cc[3]) {
  for (int a = 0; a < 3; a++) {
    double t = floor((p[a] - c->origin[a]) / c->cell);
    cc[a] = !(t > 0) ? 0 : t >= (double)c->dim[a] ? c->dim[a] - 1 : (uint32_t)t;
  }
}

static size_t cell_id(const tiles_ctx *c, const uint32_t cc[3]) {
  return ((size_t)cc[2] * c->dim[1] + cc[1]) * c->dim[0] + cc[0];
}

/* ---- the ranks --------------------------------------------------------------- */

static int rank_of(const tiles_ctx *c) {
  return c->comm ? c->comm->rank : 0;
}
static int ranks_of(const tiles_ctx *c) {
  return c->comm ? c->comm->ranks : 1;
}

/* The first of rank r's share of n items in order (contiguous shares that
 * differ by at most one; r = ranks gives n). */
static size_t share_start(size_t n, int r, int ranks) {
  size_t q = n / (size_t)ranks, m = n % (size_t)ranks;
  return q * (size_t)r + ((size_t)r < m ? (size_t)r : m);
}

/* The worst status of all ranks (every rank must call it at the same place). */
static bsurf_status agree(const bsurf_tile_comm *cm, bsurf_status st) {
  return cm ? (bsurf_status)cm->max(cm->user, (int)st) : st;
}

/* Opens (and maps, when `map`) the scratch file `name` another rank made. */
static bsurf_status scratch_open(const char *name, size_t bytes, int map, tile_map *m,
                                 bsurf_failure *err) {
  m->data = NULL;
  m->size = bytes;
  m->fd = open(name, O_RDWR);
  int e = m->fd < 0 ? errno : 0;
  if (!e && bytes && map) {
    m->data = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, m->fd, 0);
    if (m->data == MAP_FAILED) m->data = NULL, e = errno;
  }
  if (e) {
    map_close(m);
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open the scratch file %s: %s", name,
                      strerror(e));
  }
  return BSURF_OK;
}

/* A scratch file every rank shares (collective): rank 0 creates it beside
 * `near`, the others open it by name, and the name is removed as soon as
 * every rank has it open, so no exit, however abrupt, leaves it behind. */
static bsurf_status shared_scratch(const tiles_ctx *c, const char *near, size_t bytes, int map,
                                   tile_map *m, bsurf_failure *err) {
  const bsurf_tile_comm *cm = c->comm;
  m->data = NULL;
  m->size = 0;
  m->fd = -1;
  if (!cm) return scratch_create(near, bytes, map, m, NULL, err);
  char name[TILE_PATH_MAX];
  memset(name, 0, sizeof name);
  bsurf_status st = cm->rank == 0 ? scratch_create(near, bytes, map, m, name, err) : BSURF_OK;
  st = agree(cm, st);
  if (st != BSURF_OK) return st; /* rank 0's failure: it made nothing */
  cm->broadcast(cm->user, name, sizeof name);
  if (cm->rank != 0) st = scratch_open(name, bytes, map, m, err);
  st = agree(cm, st);
  if (cm->rank == 0) unlink(name);
  return st;
}

/* ---- passes over the input ------------------------------------------------- */

/* Each pass is split over the ranks: rank r sweeps its share [a, b) of the
 * point indices (share_start), and the results are combined so that they
 * are the one-process pass's, bit for bit. */

#define PASS_DROP ((size_t)1 << 20) /* points between page drops */

/* Between two page drops the passes ask the progress callback (at 0 done)
 * whether to stop: an interrupt stops a pass within ~10^6 points. */
static int pass_cancelled(const tiles_ctx *c) {
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
static bsurf_status pass_bounds(tiles_ctx *c, bsurf_tile_report *rep) {
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
static void make_grid(tiles_ctx *c) {
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
static bsurf_status pass_sort(tiles_ctx *c, const char *output, bsurf_failure *err) {
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
static bsurf_status make_tiles(tiles_ctx *c) {
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

/* ---- one tile ------------------------------------------------------------------- */

static int cmp_u64(const void *a, const void *b) {
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return x < y ? -1 : x > y;
}

static size_t find_u64(const uint64_t *v, size_t n, uint64_t x) {
  size_t lo = 0, hi = n;
  while (lo < hi) {
    size_t mid = lo + (hi - lo) / 2;
    if (v[mid] < x)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}

typedef struct u64vec {
  uint64_t *v;
  size_t n, cap;
} u64vec;

static int u64_push(u64vec *a, uint64_t x) {
  if (a->n == a->cap) {
    size_t nc = a->cap ? 2 * a->cap : 1024;
    uint64_t *nv = realloc(a->v, nc * sizeof *nv);
    if (!nv) return -1;
    a->v = nv;
    a->cap = nc;
  }
  a->v[a->n++] = x;
  return 0;
}

typedef struct search_ctx {
  const tiles_ctx *c;
  const uint64_t *G; /* loaded points, increasing global index */
  const double *gx;  /* their coordinates */
  size_t m;
  const bsurf_knn_index *index;
  const uint64_t *core; /* the points searched (the tile's, and in reverse mode its candidates) */
  size_t *pending;      /* their positions to search */
  double rlo[3], rhi[3];
  int complete;   /* the region holds the whole cloud */
  uint64_t *rows; /* core x k global indices */
  double *nn2;    /* core */
  double *kth2;   /* core: squared distance to the K-th (the row's last) */
  uint8_t *done, *dup;
  uint32_t *qidx; /* threads x k */
  double *qd2;    /* threads x k */
} search_ctx;

/* The row of one pending core point, kept when its ball is inside R. */
static void search_point(void *vctx, int thread, size_t t) {
  search_ctx *s = vctx;
  const int k = s->c->k;
  size_t j = s->pending[t];
  size_t self = find_u64(s->G, s->m, s->core[j]);
  if (self >= s->m || s->G[self] != s->core[j]) return; /* not loaded yet: a wider region */
  const double *p = s->gx + 3 * self;
  uint32_t *qi = s->qidx + (size_t)thread * (size_t)k;
  double *qd = s->qd2 + (size_t)thread * (size_t)k;
  bsurf_knn_query(s->index, p, k, qi, qd);
  /* the all-kNN row: the point, then the k - 1 nearest others (the query
   * returns the k nearest of all; the point itself is among them unless k
   * of its duplicates have smaller indices) */
  uint64_t *row = s->rows + j * (size_t)k;
  double r2 = 0, first = 0;
  int c = 1, seen_self = 0;
  row[0] = s->core[j];
  for (int q = 0; q < k && c < k; q++) {
    if (!seen_self && qi[q] == self) {
      seen_self = 1;
      continue;
    }
    if (c == 1) first = qd[q];
    row[c++] = s->G[qi[q]];
    r2 = qd[q];
  }
  int ok = s->complete;
  if (!ok) {
    ok = 1;
    double need = r2 * (1 + 1e-9);
    for (int a = 0; a < 3 && ok; a++) {
      double g1 = p[a] - s->rlo[a], g2 = s->rhi[a] - p[a];
      ok = g1 >= 0 && g2 >= 0 && g1 * g1 >= need && g2 * g2 >= need;
    }
  }
  if (!ok) return;
  s->done[j] = 1;
  s->nn2[j] = k > 1 ? first : 0.0;
  s->kth2[j] = r2;
  if (k > 1) {
    const double *q = s->gx + 3 * find_u64(s->G, s->m, row[1]);
    s->dup[j] = p[0] == q[0] && p[1] == q[1] && p[2] == q[2];
  }
}

/* Loads every point inside R (closed) or in the tile's cells, in increasing
 * index order. */
static bsurf_status gather(const tiles_ctx *c, const tile_box *b, const double rlo[3],
                           const double rhi[3], u64vec *G) {
  uint32_t clo[3], chi[3];
  for (int a = 0; a < 3; a++) {
    double tl = floor((rlo[a] - c->origin[a]) / c->cell) - 1,
           th = floor((rhi[a] - c->origin[a]) / c->cell) + 2;
    clo[a] = !(tl > 0) ? 0 : tl >= c->dim[a] ? c->dim[a] : (uint32_t)tl;
    chi[a] = !(th > 0) ? 0 : th >= c->dim[a] ? c->dim[a] : (uint32_t)th;
    if (clo[a] > b->lo[a]) clo[a] = b->lo[a];
    if (chi[a] < b->hi[a]) chi[a] = b->hi[a];
  }
  const uint64_t *sorted = (const uint64_t *)c->sorted.data;
  G->n = 0;
  u64vec cand = {NULL, 0, 0}; /* points of the cells around the tile */
  double p[3];
  for (uint32_t z = clo[2]; z < chi[2]; z++)
    for (uint32_t y = clo[1]; y < chi[1]; y++)
      for (uint32_t x = clo[0]; x < chi[0]; x++) {
        uint32_t cc[3] = {x, y, z};
        size_t j = cell_id(c, cc);
        int in_tile = x >= b->lo[0] && x < b->hi[0] && y >= b->lo[1] && y < b->hi[1] &&
                      z >= b->lo[2] && z < b->hi[2];
        for (uint64_t s = c->cell_start[j]; s < c->cell_start[j + 1]; s++) {
          if (u64_push(in_tile ? G : &cand, sorted[s])) {
            free(cand.v);
            return BSURF_ERR_NOMEM;
          }
        }
      }
  /* those inside R, read in file order */
  if (cand.n > 1) qsort(cand.v, cand.n, sizeof *cand.v, cmp_u64);
  sweep sw = {&c->in, 0};
  for (size_t j = 0; j < cand.n; j++) {
    uint64_t i = cand.v[j];
    xyz_of(c, i, p);
    sweep_at(&sw, c->layout.body + (size_t)i * c->layout.record);
    if (p[0] >= rlo[0] && p[0] <= rhi[0] && p[1] >= rlo[1] && p[1] <= rhi[1] && p[2] >= rlo[2] &&
        p[2] <= rhi[2] && u64_push(G, i)) {
      free(cand.v);
      return BSURF_ERR_NOMEM;
    }
  }
  free(cand.v);
  drop_pages(&c->in, 0, c->in.size);
  if (G->n > 1) qsort(G->v, G->n, sizeof *G->v, cmp_u64);
  return BSURF_OK;
}

typedef struct tile_work {
  u64vec core, G;
  u64vec cand, S; /* reverse mode: candidates; the points searched (core + candidates) */
  double *gx;
  uint64_t *rows;
  double *nn2, *kth2;
  size_t *cpos; /* core j -> its position in S */
  size_t *rev_off;
  uint32_t *rev;
  double *lvals, *vout, *vblock; /* values_in of the local points; values_out; the block's */
  uint8_t *done, *dup, *mark;
  size_t *pending;
  uint32_t *qidx;
  double *qd2;
  uint32_t *local; /* G position -> local index */
  double *lxyz;
  uint32_t *idx;
  unsigned char *enc;
} tile_work;

static void work_free(tile_work *w) {
  free(w->core.v);
  free(w->G.v);
  free(w->cand.v);
  free(w->S.v);
  free(w->gx);
  free(w->rows);
  free(w->nn2);
  free(w->kth2);
  free(w->cpos);
  free(w->rev_off);
  free(w->rev);
  free(w->lvals);
  free(w->vout);
  free(w->vblock);
  free(w->done);
  free(w->dup);
  free(w->mark);
  free(w->pending);
  free(w->qidx);
  free(w->qd2);
  free(w->local);
  free(w->lxyz);
  free(w->idx);
  free(w->enc);
  memset(w, 0, sizeof *w);
}

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
static double cascade_top(const tiles_ctx *c, const double *range_sum, size_t n, size_t *next) {
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
static bsurf_status write_block(const tiles_ctx *c, size_t t, const uint64_t *core,
                                const double *nn2, const double *vals, const unsigned char *enc,
                                size_t nc, bsurf_failure *err) {
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
static bsurf_status assemble(const tiles_ctx *c, double *range_sum, bsurf_failure *err) {
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

/* ---- reverse neighbours (the second stage of a two-stage run) ------------- */

/* A bound on how far a point can lie outside the box of its cell (the
 * rounding of floor((p - origin) / cell)), used with a relative margin of
 * 1e-9 on the distances. */
static double cell_slack(const tiles_ctx *c) {
  double m = 0;
  for (int a = 0; a < 3; a++)
    m = fmax(m, fmax(fabs(c->lo[a]), fabs(c->hi[a])));
  return 1e-9 * c->cell + 1e-12 * m;
}

/* The extent on axis a of the cells [lo, hi), widened by slack; the outer
 * cells reach to infinity (the grid clamps points beyond it into them). */
static void cells_span(const tiles_ctx *c, int a, uint32_t lo, uint32_t hi, double slack,
                       double *blo, double *bhi) {
  *blo = lo == 0 ? -INFINITY : c->origin[a] + c->cell * lo - slack;
  *bhi = hi >= c->dim[a] ? INFINITY : c->origin[a] + c->cell * hi + slack;
}

/* Squared distance from p to a box (0 inside). */
static double box_dist2(const double p[3], const double lo[3], const double hi[3]) {
  double d2 = 0;
  for (int a = 0; a < 3; a++) {
    double g = fmax(0.0, fmax(lo[a] - p[a], p[a] - hi[a]));
    d2 += g * g;
  }
  return d2;
}

static double values_kth2(const tiles_ctx *c, uint64_t i) {
  const double *v = (const double *)c->vin.data;
  return v[(size_t)i * c->vin_cols + c->vin_cols - 1];
}

/* Before the tiles of a reverse run: per cell, the largest squared distance
 * r_i^2 from a point i to its K-th neighbour (the first stage's last
 * column), streaming the input and the values in index order. */
static bsurf_status cell_maxima(tiles_ctx *c) {
  c->cellmax = bsurf_calloc_array(c->cells, sizeof *c->cellmax);
  if (!c->cellmax) return BSURF_ERR_NOMEM;
  double p[3];
  uint32_t cc[3];
  bsurf_status st = BSURF_OK;
  for (size_t i = 0; i < c->n && st == BSURF_OK; i++) {
    double r2 = values_kth2(c, i);
    xyz_of(c, i, p);
    cell_coords(c, p, cc);
    size_t j = cell_id(c, cc);
    if (!(r2 >= 0)) st = BSURF_ERR_INVALID_VALUE; /* not a first stage of this input */
    if (r2 > c->cellmax[j]) c->cellmax[j] = r2;
    if (r2 > c->rmax2) c->rmax2 = r2;
    if ((i + 1) % PASS_DROP == 0) {
      drop_pages(&c->in, 0, c->in.size);
      drop_pages(&c->vin, 0, c->vin.size);
      if (pass_cancelled(c)) st = BSURF_ERR_CANCELLED;
    }
  }
  drop_pages(&c->in, 0, c->in.size);
  drop_pages(&c->vin, 0, c->vin.size);
  return st;
}

/* The points outside tile b whose K-neighbourhood can contain a point of
 * the tile: p in N_K(i) gives |p - i| <= r_i, and p lies in the tile's
 * cells, so dist(i, tile) <= r_i. Cells farther from the tile than the
 * largest r_i of their points are skipped, then every point of the others
 * is tested with its own r_i. A superset (margins for rounding): the exact
 * K-neighbourhoods of the candidates, searched with the tile's, decide.
 * *r2max: the candidates' largest r_i^2. */
static bsurf_status reverse_candidates(const tiles_ctx *c, const tile_box *b, u64vec *cand,
                                       double *r2max) {
  const double slack = cell_slack(c), reach = sqrt(c->rmax2) * (1 + 1e-9) + 2 * slack;
  double blo[3], bhi[3];
  uint32_t clo[3], chi[3];
  for (int a = 0; a < 3; a++) {
    cells_span(c, a, b->lo[a], b->hi[a], slack, &blo[a], &bhi[a]);
    double w = ceil(reach / c->cell) + 1, l = (double)b->lo[a] - w, h = (double)b->hi[a] + w;
    clo[a] = l > 0 ? (uint32_t)l : 0;
    chi[a] = h < (double)c->dim[a] ? (uint32_t)h : c->dim[a];
  }
  const uint64_t *sorted = (const uint64_t *)c->sorted.data;
  cand->n = 0;
  *r2max = 0;
  for (uint32_t z = clo[2]; z < chi[2]; z++)
    for (uint32_t y = clo[1]; y < chi[1]; y++)
      for (uint32_t x = clo[0]; x < chi[0]; x++) {
        uint32_t cc[3] = {x, y, z};
        size_t j = cell_id(c, cc);
        if (c->cell_start[j] == c->cell_start[j + 1]) continue;
        if (x >= b->lo[0] && x < b->hi[0] && y >= b->lo[1] && y < b->hi[1] && z >= b->lo[2] &&
            z < b->hi[2])
          continue; /* the tile's own */
        double d2 = 0;
        for (int a = 0; a < 3; a++) {
          double lo, hi;
          cells_span(c, a, cc[a], cc[a] + 1, slack, &lo, &hi);
          double g = fmax(0.0, fmax(lo - bhi[a], blo[a] - hi));
          d2 += g * g;
        }
        double r = sqrt(c->cellmax[j]) * (1 + 1e-9) + slack;
        if (d2 > r * r) continue;
        for (uint64_t s = c->cell_start[j]; s < c->cell_start[j + 1]; s++)
          if (u64_push(cand, sorted[s])) return BSURF_ERR_NOMEM;
      }
  if (cand->n > 1) qsort(cand->v, cand->n, sizeof *cand->v, cmp_u64);
  sweep sw = {&c->in, 0}, sv = {&c->vin, 0};
  size_t kept = 0;
  for (size_t q = 0; q < cand->n; q++) {
    uint64_t i = cand->v[q];
    double p[3], r2 = values_kth2(c, i);
    xyz_of(c, i, p);
    sweep_at(&sw, c->layout.body + (size_t)i * c->layout.record);
    sweep_at(&sv, (size_t)i * c->vin_cols * sizeof(double));
    double r = sqrt(r2) * (1 + 1e-9) + slack;
    if (box_dist2(p, blo, bhi) <= r * r) {
      cand->v[kept++] = i;
      if (r2 > *r2max) *r2max = r2;
    }
  }
  cand->n = kept;
  drop_pages(&c->vin, 0, c->vin.size);
  return BSURF_OK;
}

/* The exact K-neighbourhoods of a tile's points (growing the halo until they
 * are proven), then the command's run and the output rows. In reverse mode
 * the candidates of reverse_candidates are searched with them, and the
 * reverse lists follow from their exact rows. */
static bsurf_status do_tile(tiles_ctx *c, size_t t, bsurf_tile_report *rep, bsurf_failure *err) {
  const tile_box *b = &c->tiles[t];
  const int k = c->k;
  const int T = bsurf_threads_resolve(c->ops->threads);
  const uint64_t *sorted = (const uint64_t *)c->sorted.data;
  tile_work w;
  memset(&w, 0, sizeof w);
  bsurf_status st = BSURF_OK;
  bsurf_cloud core;
  bsurf_cloud_init(&core);

  for (uint32_t z = b->lo[2]; z < b->hi[2] && st == BSURF_OK; z++)
    for (uint32_t y = b->lo[1]; y < b->hi[1] && st == BSURF_OK; y++)
      for (uint32_t x = b->lo[0]; x < b->hi[0] && st == BSURF_OK; x++) {
        uint32_t cc[3] = {x, y, z};
        size_t j = cell_id(c, cc);
        for (uint64_t s = c->cell_start[j]; s < c->cell_start[j + 1]; s++)
          if (u64_push(&w.core, sorted[s])) st = BSURF_ERR_NOMEM;
      }
  double r2cand = 0;
  if (st == BSURF_OK && c->ops->reverse) st = reverse_candidates(c, b, &w.cand, &r2cand);
  if (st != BSURF_OK) goto out;
  /* searched in cell order (neighbouring queries share the tree's leaves),
   * stored in index order */
  uint64_t *by_cell = bsurf_alloc_array(w.core.n, sizeof *by_cell);
  if (!by_cell) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  if (w.core.n) memcpy(by_cell, w.core.v, w.core.n * sizeof *by_cell);
  if (w.core.n > 1) qsort(w.core.v, w.core.n, sizeof *w.core.v, cmp_u64);
  const size_t nc = w.core.n, ns = nc + w.cand.n;
  /* the points searched: the core and the candidates (outside the tile's
   * cells: disjoint), in increasing index */
  w.S.v = bsurf_alloc_array(ns, sizeof *w.S.v);
  w.rows = bsurf_alloc_array(ns, (size_t)k * sizeof *w.rows);
  w.nn2 = bsurf_alloc_array(ns, sizeof *w.nn2);
  w.kth2 = bsurf_alloc_array(ns, sizeof *w.kth2);
  w.done = bsurf_calloc_array(ns, 1);
  w.dup = bsurf_calloc_array(ns, 1);
  w.pending = bsurf_alloc_array(ns, sizeof *w.pending);
  w.cpos = bsurf_alloc_array(nc, sizeof *w.cpos);
  w.qidx = bsurf_alloc_array((size_t)T, (size_t)k * sizeof *w.qidx);
  w.qd2 = bsurf_alloc_array((size_t)T, (size_t)k * sizeof *w.qd2);
  if (!w.S.v || !w.rows || !w.nn2 || !w.kth2 || !w.done || !w.dup || !w.pending || !w.cpos ||
      !w.qidx || !w.qd2) {
    free(by_cell);
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t q = 0, a = 0, e = 0; q < ns; q++)
    w.S.v[q] =
        e >= w.cand.n || (a < nc && w.core.v[a] < w.cand.v[e]) ? w.core.v[a++] : w.cand.v[e++];
  w.S.n = w.S.cap = ns;
  size_t npend = ns;
  for (size_t j = 0; j < nc; j++)
    w.pending[j] = find_u64(w.S.v, ns, by_cell[j]);
  for (size_t q = 0; q < w.cand.n; q++)
    w.pending[nc + q] = find_u64(w.S.v, ns, w.cand.v[q]);
  for (size_t j = 0; j < nc; j++)
    w.cpos[j] = find_u64(w.S.v, ns, w.core.v[j]);
  free(by_cell);

  /* the candidates lie within r_i of the tile and their balls within 2 r_i:
   * a halo that holds them at once (a narrower one is only slower) */
  double halo = c->cell, box_lo[3], box_hi[3];
  if (w.cand.n) halo = fmax(halo, 2 * sqrt(r2cand) * (1 + 1e-6) + 4 * cell_slack(c));
  for (int a = 0; a < 3; a++) {
    box_lo[a] = c->origin[a] + c->cell * b->lo[a];
    box_hi[a] = c->origin[a] + c->cell * b->hi[a];
  }
  for (int round = 0;; round++) {
    search_ctx s;
    memset(&s, 0, sizeof s);
    s.complete = 1;
    for (int a = 0; a < 3; a++) {
      s.rlo[a] = box_lo[a] - halo;
      s.rhi[a] = box_hi[a] + halo;
      if (s.rlo[a] > c->lo[a] || s.rhi[a] < c->hi[a]) s.complete = 0;
    }
    st = gather(c, b, s.rlo, s.rhi, &w.G);
    if (st != BSURF_OK) goto out;
    free(w.gx);
    w.gx = bsurf_alloc_array(w.G.n, 3 * sizeof *w.gx);
    if (!w.gx) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    sweep sw = {&c->in, 0};
    for (size_t j = 0; j < w.G.n; j++) {
      xyz_of(c, w.G.v[j], w.gx + 3 * j);
      sweep_at(&sw, c->layout.body + (size_t)w.G.v[j] * c->layout.record);
    }
    drop_pages(&c->in, 0, c->in.size);
    bsurf_knn_index *index = NULL;
    st = bsurf_knn_build(&index, w.gx, w.G.n);
    if (st != BSURF_OK) goto out;
    s.c = c;
    s.G = w.G.v;
    s.gx = w.gx;
    s.m = w.G.n;
    s.index = index;
    s.core = w.S.v;
    s.pending = w.pending;
    s.rows = w.rows;
    s.nn2 = w.nn2;
    s.kth2 = w.kth2;
    s.done = w.done;
    s.dup = w.dup;
    s.qidx = w.qidx;
    s.qd2 = w.qd2;
    bsurf_parallel_sweep(npend, T, search_point, &s);
    bsurf_knn_free(index);
    size_t left = 0;
    for (size_t q = 0; q < npend; q++)
      if (!w.done[w.pending[q]]) w.pending[left++] = w.pending[q];
    npend = left;
    if (npend == 0) break;
    assert(!s.complete);
    if (round == 0) rep->halo_grown++;
    halo *= 2;
  }

  /* The tile's cloud: its points, every neighbour they use and, in reverse
   * mode, every point whose row contains one of them, in increasing global
   * index (a subset of the last region's points). */
  const size_t m = w.G.n;
  w.mark = bsurf_calloc_array(m, 1);
  w.local = bsurf_alloc_array(m, sizeof *w.local);
  w.idx = bsurf_alloc_array(nc, (size_t)k * sizeof *w.idx);
  if (c->ops->reverse) w.rev_off = bsurf_calloc_array(nc + 1, sizeof *w.rev_off);
  if (!w.mark || !w.local || !w.idx || (c->ops->reverse && !w.rev_off)) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t j = 0; j < nc; j++)
    for (int e = 0; e < k; e++) {
      size_t pos = find_u64(w.G.v, m, w.rows[w.cpos[j] * (size_t)k + (size_t)e]);
      w.idx[j * (size_t)k + (size_t)e] = (uint32_t)pos;
      w.mark[pos] = 1;
    }
  if (c->ops->reverse) { /* how many rows contain each core point */
    for (size_t q = 0; q < ns; q++)
      for (int e = 0; e < k; e++) {
        uint64_t u = w.rows[q * (size_t)k + (size_t)e];
        size_t j = find_u64(w.core.v, nc, u);
        if (j < nc && w.core.v[j] == u) {
          w.rev_off[j + 1]++;
          w.mark[find_u64(w.G.v, m, w.S.v[q])] = 1;
        }
      }
    for (size_t j = 0; j < nc; j++)
      w.rev_off[j + 1] += w.rev_off[j];
  }
  size_t nl = 0;
  for (size_t j = 0; j < m; j++)
    if (w.mark[j]) w.local[j] = (uint32_t)nl++;
  w.lxyz = bsurf_alloc_array(nl, 3 * sizeof *w.lxyz);
  if (!w.lxyz) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t j = 0; j < m; j++)
    if (w.mark[j]) memcpy(w.lxyz + 3 * (size_t)w.local[j], w.gx + 3 * j, 3 * sizeof(double));
  for (size_t e = 0; e < nc * (size_t)k; e++)
    w.idx[e] = w.local[w.idx[e]];
  if (c->ops->reverse) { /* the lists, each in increasing index (S is) */
    size_t *fill = bsurf_alloc_array(nc + 1, sizeof *fill);
    w.rev = bsurf_alloc_array(w.rev_off[nc] + 1, sizeof *w.rev);
    if (!fill || !w.rev) {
      free(fill);
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    memcpy(fill, w.rev_off, (nc + 1) * sizeof *fill);
    for (size_t q = 0; q < ns; q++) {
      uint32_t lq = w.local[find_u64(w.G.v, m, w.S.v[q])];
      for (int e = 0; e < k; e++) {
        uint64_t u = w.rows[q * (size_t)k + (size_t)e];
        size_t j = find_u64(w.core.v, nc, u);
        if (j < nc && w.core.v[j] == u) w.rev[fill[j]++] = lq;
      }
    }
    free(fill);
  }
  if (c->ops->values_in) { /* the first stage's values of every local point */
    const size_t nv = c->vin_cols - 1;
    w.lvals = bsurf_alloc_array(nl ? nl : 1, (nv ? nv : 1) * sizeof(double));
    if (!w.lvals) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    sweep sv = {&c->vin, 0};
    for (size_t j = 0; j < m; j++)
      if (w.mark[j]) {
        size_t off = (size_t)w.G.v[j] * c->vin_cols * sizeof(double);
        memcpy(w.lvals + (size_t)w.local[j] * nv, c->vin.data + off, nv * sizeof(double));
        sweep_at(&sv, off);
      }
    drop_pages(&c->vin, 0, c->vin.size);
  }
  free(w.rows);
  w.rows = NULL;
  free(w.gx);
  w.gx = NULL;
  /* the core's entries of S, in place (cpos increases, cpos[j] >= j) */
  for (size_t j = 0; j < nc; j++) {
    w.nn2[j] = w.nn2[w.cpos[j]];
    w.kth2[j] = w.kth2[w.cpos[j]];
    w.dup[j] = w.dup[w.cpos[j]];
  }

  /* the core points with every input property, prepared by the command */
  st = cloud_like(&c->schema, nc, &core);
  if (st != BSURF_OK) goto out;
  sweep sw = {&c->in, 0};
  for (size_t j = 0; j < nc; j++) {
    io_ply_decode(&c->layout, c->in.data, w.core.v[j], &core, j);
    sweep_at(&sw, c->layout.body + (size_t)w.core.v[j] * c->layout.record);
  }
  drop_pages(&c->in, 0, c->in.size);
  if (c->ops->prepare) st = c->ops->prepare(c->ops->user, &core);
  if (st != BSURF_OK) goto out;
  if (c->ops->nvalues && !(w.vout = bsurf_calloc_array(nc, c->ops->nvalues * sizeof(double)))) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }

  bsurf_neighbors nb = {nc, k, w.idx, 0.0, NULL};
  bsurf_tile tile = {t,   c->ntiles, nc,      nl,     w.lxyz,    w.core.v,
                     &nb, halo,      w.lvals, w.vout, w.rev_off, w.rev};
  double *sums = c->tile_sums + t * (c->ops->nsums + 1);
  st = c->ops->run(c->ops->user, &tile, &core, sums);
  if (st != BSURF_OK) goto out;
  size_t dups = 0;
  for (size_t j = 0; j < nc; j++)
    dups += w.dup[j];
  sums[c->ops->nsums] = (double)dups;

  /* the rows, values and squared nearest distances (for h) to the block */
  if (c->record) {
    w.enc = bsurf_alloc_array(nc, c->record);
    if (!w.enc) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    st = io_ply_encode(&core, w.enc);
    if (st != BSURF_OK) goto out;
  }
  if (c->vcols) {
    const size_t nv = c->ops->nvalues;
    w.vblock = bsurf_alloc_array(nc, c->vcols * sizeof(double));
    if (!w.vblock) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    for (size_t j = 0; j < nc; j++) {
      memcpy(w.vblock + j * c->vcols, w.vout + j * nv, nv * sizeof(double));
      w.vblock[j * c->vcols + nv] = w.kth2[j];
    }
  }
  st = write_block(c, t, w.core.v, w.nn2, w.vblock, w.enc, nc, err);
  if (st != BSURF_OK) goto out;
  if (nc > rep->max_tile_points) rep->max_tile_points = nc;
  if (nl > rep->max_local_points) rep->max_local_points = nl;
out:
  bsurf_cloud_free(&core);
  work_free(&w);
  /* nothing of the files stays resident between tiles */
  drop_pages(&c->in, 0, c->in.size);
  drop_pages(&c->sorted, 0, c->sorted.size);
  return st;
}

/* ---- the run ---------------------------------------------------------------- */

/* The bytes of a record of the output. */
static size_t record_of(const bsurf_cloud *schema) {
  size_t record = 3 * io_type_size(schema->xyz_type);
  if (schema->normals) record += 3 * io_type_size(schema->normal_type);
  for (size_t f = 0; f < schema->field_count; f++)
    record += io_type_size(schema->fields[f].type);
  return record;
}

/* Rank 0: the output under a temporary name, its header, and the space of
 * every record reserved (a full disk fails here, not later). */
static bsurf_status create_output(tiles_ctx *c, const char *output, bsurf_failure *err) {
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
static bsurf_status open_outputs(tiles_ctx *c, const char *output, bsurf_failure *err) {
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

/* ---- the values of a first stage ----------------------------------------- */

static size_t values_bytes(const bsurf_tile_values *v) {
  return v->count * (v->nvalues + 1) * sizeof(double);
}

/* The values of a first stage over the same input (n points), mapped
 * read-only (the descriptor stays the caller's). */
static bsurf_status map_values(const bsurf_tile_values *v, size_t n, tile_map *m,
                               bsurf_failure *err) {
  m->fd = -1;
  m->data = NULL;
  m->size = 0;
  if (v->fd < 0 || v->count != n)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "the first stage's values are of %zu points, not %zu", v->count, n);
  m->data = mmap(NULL, values_bytes(v), PROT_READ, MAP_SHARED, v->fd, 0);
  if (m->data == MAP_FAILED) {
    m->data = NULL;
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot map the scratch file of the values: %s",
                      strerror(errno));
  }
  m->size = values_bytes(v);
  return BSURF_OK;
}

bsurf_status bsurf_tile_values_read(const bsurf_tile_values *v, size_t first, size_t count,
                                    double *out) {
  BSURF_REQUIRE(v && v->fd >= 0, "no values file (v is NULL or closed)");
  BSURF_REQUIRE(first <= v->count && count <= v->count - first,
                "points [%zu, %zu + %zu) outside [0, %zu)", first, first, count, v->count);
  BSURF_REQUIRE(out || !count, "out is NULL");
  const size_t cols = v->nvalues + 1, per = 65536;
  double *buf = bsurf_alloc_array(per, cols * sizeof(double));
  if (!buf) return BSURF_ERR_NOMEM;
  int e = 0;
  for (size_t j = 0; j < count && !e; j += per) {
    size_t m = count - j < per ? count - j : per;
    e = pread_all(v->fd, buf, m * cols * sizeof(double), (first + j) * cols * sizeof(double));
    for (size_t q = 0; q < m && !e; q++)
      memcpy(out + (j + q) * v->nvalues, buf + q * cols, v->nvalues * sizeof(double));
  }
  free(buf);
  return e ? BSURF_ERR_IO : BSURF_OK;
}

void bsurf_tile_values_close(bsurf_tile_values *v) {
  if (v && v->fd >= 0) close(v->fd);
  if (v) v->fd = -1;
}

bsurf_status bsurf_tiles_run(const char *input, const char *output, const bsurf_tile_ops *ops,
                             bsurf_tile_report *report, bsurf_failure *err) {
  if (err) err->line = 0, err->byte = -1, err->message[0] = 0;
  if (!input || !output || !ops || !report || !ops->run || ops->k < 1 ||
      (ops->nsums && !report->sums) || (ops->nvalues && !ops->values_out) ||
      (ops->reverse && !ops->values_in))
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
