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
 *    reading the others.
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
 *  - h (mean nearest-neighbour distance) is global: the squared distances are
 *    summed during the assembly, in index order with the cascade of
 *    src/search/neighbors.c, so it is bit-identical.
 *  - Distributed: the ranks compute the same grid and tiles (deterministic),
 *    take tiles round-robin, write their blocks at known offsets of the one
 *    scratch file, and rank 0 assembles the output, h and the per-tile
 *    accumulators in tile order.
 */
#define _DEFAULT_SOURCE /* madvise */
#include "common/common.h"
#include "io/io.h"

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

static bsurf_status map_input(const char *path, tile_map *m, bsurf_error *err) {
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
                                   bsurf_error *err) {
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
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot make a scratch file of %zu bytes beside %s: %s",
                      bytes, near, strerror(e));
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
  bsurf_cloud schema; /* the input's properties (point 0) */
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
  /* the tiles' results (assemble below): one block per tile at block[t] */
  int scr; /* file descriptor, -1 */
  size_t range; /* points per range of the output (the last may be shorter) */
  size_t nranges;
  size_t *block; /* ntiles + 1 offsets */
  double *tile_sums; /* ntiles x (nsums + 1): the accumulators, then duplicates */
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
    if (!bsurf_cloud_add_field(out, schema->fields[f].name, schema->fields[f].type)) st = BSURF_ERR_NOMEM;
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

/* ---- passes over the input ------------------------------------------------- */

#define PASS_DROP ((size_t)1 << 20) /* points between page drops */

/* Between two page drops the passes ask the progress callback (at 0 done)
 * whether to stop: an interrupt stops a pass within ~10^6 points. */
static int pass_cancelled(const tiles_ctx *c) {
  return c->ops->progress && c->ops->progress(c->ops->progress_user, 0, c->n);
}

/* Pass 1: every coordinate (and normal) finite, bounding box. */
static bsurf_status pass_bounds(tiles_ctx *c, bsurf_tile_report *rep) {
  bsurf_cloud one;
  bsurf_status st = cloud_like(&c->schema, 1, &one);
  if (st != BSURF_OK) return st;
  for (int a = 0; a < 3; a++) c->lo[a] = INFINITY, c->hi[a] = -INFINITY;
  for (size_t i = 0; i < c->n; i++) {
    io_ply_decode(&c->layout, c->in.data, i, &one, 0);
    const double *p = one.xyz, *q = one.normals;
    if (!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])) ||
        (q && !(isfinite(q[0]) && isfinite(q[1]) && isfinite(q[2])))) {
      rep->bad_point = i;
      st = BSURF_ERR_INVALID_VALUE;
      break;
    }
    for (int a = 0; a < 3; a++) {
      if (p[a] < c->lo[a]) c->lo[a] = p[a];
      if (p[a] > c->hi[a]) c->hi[a] = p[a];
    }
    if ((i + 1) % PASS_DROP == 0) {
      drop_pages(&c->in, c->layout.body + (i + 1 - PASS_DROP) * c->layout.record,
                 c->layout.body + (i + 1) * c->layout.record);
      if (pass_cancelled(c)) {
        st = BSURF_ERR_CANCELLED;
        break;
      }
    }
  }
  drop_pages(&c->in, 0, c->in.size);
  bsurf_cloud_free(&one);
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
  for (int a = 0; a < 3; a++) c->origin[a] = c->lo[a];
}

/* Passes 2 and 3: counts per cell, then the point indices sorted by cell
 * (increasing inside each cell) into the scratch file. */
static bsurf_status pass_sort(tiles_ctx *c, const char *output, bsurf_error *err) {
  c->cell_start = bsurf_calloc_array(c->cells + 1, sizeof *c->cell_start);
  uint64_t *cursor = bsurf_alloc_array(c->cells, sizeof *cursor);
  if (!c->cell_start || !cursor) {
    free(cursor);
    return BSURF_ERR_NOMEM;
  }
  double p[3];
  uint32_t cc[3];
  for (size_t i = 0; i < c->n; i++) {
    xyz_of(c, i, p);
    cell_coords(c, p, cc);
    c->cell_start[cell_id(c, cc) + 1]++;
    if ((i + 1) % PASS_DROP == 0) {
      drop_pages(&c->in, 0, c->in.size);
      if (pass_cancelled(c)) {
        free(cursor);
        return BSURF_ERR_CANCELLED;
      }
    }
  }
  for (size_t j = 0; j < c->cells; j++) c->cell_start[j + 1] += c->cell_start[j];
  memcpy(cursor, c->cell_start, c->cells * sizeof *cursor);
  bsurf_status st = scratch_create(output, c->n * sizeof(uint64_t), 1, &c->sorted, NULL, err);
  if (st == BSURF_OK) {
    uint64_t *sorted = (uint64_t *)c->sorted.data;
    for (size_t i = 0; i < c->n; i++) {
      xyz_of(c, i, p);
      cell_coords(c, p, cc);
      sorted[cursor[cell_id(c, cc)]++] = i;
      /* the writes land all over the file: drop them often (they stay in
       * the page cache, not in this process) */
      if ((i + 1) % (PASS_DROP / 16) == 0) drop_pages(&c->sorted, 0, c->sorted.size);
      if ((i + 1) % PASS_DROP == 0) {
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
      for (int a = 0; a < 3; a++) memset(slab[a], 0, (b.hi[a] - b.lo[a]) * sizeof(size_t));
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
  for (int a = 0; a < 3; a++) free(slab[a]);
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
  const uint64_t *core;
  size_t *pending; /* core positions to search */
  double rlo[3], rhi[3];
  int complete; /* the region holds the whole cloud */
  uint64_t *rows;  /* core x k global indices */
  double *nn2;     /* core */
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
    double tl = floor((rlo[a] - c->origin[a]) / c->cell) - 1, th = floor((rhi[a] - c->origin[a]) / c->cell) + 2;
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
        int in_tile = x >= b->lo[0] && x < b->hi[0] && y >= b->lo[1] && y < b->hi[1] && z >= b->lo[2] &&
                      z < b->hi[2];
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
    if (p[0] >= rlo[0] && p[0] <= rhi[0] && p[1] >= rlo[1] && p[1] <= rhi[1] && p[2] >= rlo[2] && p[2] <= rhi[2] &&
        u64_push(G, i)) {
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
  double *gx;
  uint64_t *rows;
  double *nn2;
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
  free(w->gx);
  free(w->rows);
  free(w->nn2);
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
 *   cuts[0 .. R]   uint64: cuts[r] = the tile's rows with index < r x range
 *   entries        per row, in increasing index: uint64 index, double nn2
 *                  (squared nearest-other distance, for h), the encoded row
 * and after the tiles rank 0 assembles the output range by range (R ranges
 * of `range` consecutive indices, each held in memory once): from every tile
 * the entries [cuts[r], cuts[r + 1]) of its block are read and placed, and
 * the range is written to the output sequentially. The blocks' offsets
 * follow from the tiles' point counts, which every rank knows, so ranks write
 * their blocks into the one scratch file without exchanging anything. */

#define BLOCK_CHUNK ((size_t)1 << 20) /* bytes per read or write of entries */

static size_t entry_bytes(const tiles_ctx *c) { return 16 + c->record; }

/* range, nranges and every tile's block offset (ntiles + 1 of them) */
static bsurf_status plan_blocks(tiles_ctx *c) {
  /* a range holds at least a tile's points (a tile's memory is many times
   * its rows') and at least 32 MiB, so that R x tiles reads stay few */
  size_t by_bytes = ((size_t)32 << 20) / (c->record + sizeof(double));
  c->range = c->ops->tile_points > by_bytes ? c->ops->tile_points : by_bytes;
  if (c->ops->range_points) c->range = c->ops->range_points;
  if (c->range > c->n) c->range = c->n;
  c->nranges = (c->n + c->range - 1) / c->range;
  c->block = bsurf_alloc_array(c->ntiles + 1, sizeof *c->block);
  if (!c->block) return BSURF_ERR_NOMEM;
  c->block[0] = 0;
  for (size_t t = 0; t < c->ntiles; t++)
    c->block[t + 1] = c->block[t] + (c->nranges + 1) * sizeof(uint64_t) + c->tiles[t].count * entry_bytes(c);
  return BSURF_OK;
}

static bsurf_status scratch_error(bsurf_error *err, const char *what, int e) {
  return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot %s the scratch file of the tiles' rows: %s", what,
                    strerror(e));
}

/* Tile t's block: core (increasing global indices), nn2 and the encoded rows
 * of its nc points. */
static bsurf_status write_block(const tiles_ctx *c, size_t t, const uint64_t *core, const double *nn2,
                                const unsigned char *enc, size_t nc, bsurf_error *err) {
  assert(nc == c->tiles[t].count);
  const size_t eb = entry_bytes(c), per = BLOCK_CHUNK / eb ? BLOCK_CHUNK / eb : 1;
  uint64_t *cuts = bsurf_alloc_array(c->nranges + 1, sizeof *cuts);
  unsigned char *buf = bsurf_alloc_array(per, eb);
  if (!cuts || !buf) {
    free(cuts);
    free(buf);
    return BSURF_ERR_NOMEM;
  }
  for (size_t r = 0; r < c->nranges; r++) cuts[r] = find_u64(core, nc, (uint64_t)(r * c->range));
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
      memcpy(p + 16, enc + (j + q) * c->record, c->record);
    }
    e = pwrite_all(c->scr, buf, m * eb, off);
    off += m * eb;
  }
  free(cuts);
  free(buf);
  return e ? scratch_error(err, "write", e) : BSURF_OK;
}

/* Rank 0's assembly, pulled by the sum for h (which visits the points in
 * index order): nn_at(i) loads the range of i after writing the previous
 * one to the output. */
typedef struct assembler {
  const tiles_ctx *c;
  int out; /* the output's descriptor */
  size_t next; /* the next range to load */
  size_t lo, hi; /* the range in memory: points [lo, hi) */
  unsigned char *rows; /* range x record */
  double *nn; /* range */
  unsigned char *buf; /* entries read */
  size_t per; /* entries per read */
  bsurf_status st;
  bsurf_error *err;
} assembler;

static void asm_flush(assembler *a) {
  const tiles_ctx *c = a->c;
  if (a->st != BSURF_OK || a->hi == a->lo) return;
  int e = pwrite_all(a->out, a->rows, (a->hi - a->lo) * c->record, c->header + a->lo * c->record);
  if (e) a->st = bsurf_fail(a->err, BSURF_ERR_IO, 0, -1, "cannot write the output: %s", strerror(e));
  a->lo = a->hi;
}

static void asm_load(assembler *a) {
  const tiles_ctx *c = a->c;
  const size_t eb = entry_bytes(c), r = a->next++;
  if (pass_cancelled(c)) {
    a->st = BSURF_ERR_CANCELLED;
    return;
  }
  a->lo = r * c->range;
  a->hi = a->lo + c->range < c->n ? a->lo + c->range : c->n;
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
    for (uint64_t j = cut[0]; j < cut[1] && !e; j += a->per) {
      size_t m = cut[1] - j < a->per ? (size_t)(cut[1] - j) : a->per;
      e = pread_all(c->scr, a->buf, m * eb, base + (size_t)j * eb);
      for (size_t q = 0; q < m && !e; q++) {
        const unsigned char *p = a->buf + q * eb;
        uint64_t i;
        memcpy(&i, p, 8);
        if (i < a->lo || i >= a->hi) {
          e = EIO;
          break;
        }
        memcpy(&a->nn[i - a->lo], p + 8, 8);
        memcpy(a->rows + (i - a->lo) * c->record, p + 16, c->record);
      }
      placed += m;
    }
  }
  /* the tiles partition the points: every row of the range exactly once */
  if (!e && placed != a->hi - a->lo) e = EIO;
  if (e) a->st = scratch_error(a->err, "read", e);
}

static double nn_at(assembler *a, size_t i) {
  while (a->st == BSURF_OK && i >= a->hi) {
    asm_flush(a);
    if (a->st == BSURF_OK) asm_load(a);
  }
  return a->st == BSURF_OK ? a->nn[i - a->lo] : 0.0;
}

/* The exact K-neighbourhoods of a tile's points (growing the halo until they
 * are proven), then the command's run and the output rows. */
static bsurf_status do_tile(tiles_ctx *c, size_t t, bsurf_tile_report *rep, bsurf_error *err) {
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
  const size_t nc = w.core.n;
  w.rows = bsurf_alloc_array(nc, (size_t)k * sizeof *w.rows);
  w.nn2 = bsurf_alloc_array(nc, sizeof *w.nn2);
  w.done = bsurf_calloc_array(nc, 1);
  w.dup = bsurf_calloc_array(nc, 1);
  w.pending = bsurf_alloc_array(nc, sizeof *w.pending);
  w.qidx = bsurf_alloc_array((size_t)T, (size_t)k * sizeof *w.qidx);
  w.qd2 = bsurf_alloc_array((size_t)T, (size_t)k * sizeof *w.qd2);
  if (!w.rows || !w.nn2 || !w.done || !w.dup || !w.pending || !w.qidx || !w.qd2) {
    free(by_cell);
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  size_t npend = nc;
  for (size_t j = 0; j < nc; j++) w.pending[j] = find_u64(w.core.v, nc, by_cell[j]);
  free(by_cell);

  double halo = c->cell, box_lo[3], box_hi[3];
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
    s.core = w.core.v;
    s.pending = w.pending;
    s.rows = w.rows;
    s.nn2 = w.nn2;
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

  /* The tile's cloud: its points and every neighbour they use, in
   * increasing global index (a subset of the last region's points). */
  const size_t m = w.G.n;
  w.mark = bsurf_calloc_array(m, 1);
  w.local = bsurf_alloc_array(m, sizeof *w.local);
  w.idx = bsurf_alloc_array(nc, (size_t)k * sizeof *w.idx);
  if (!w.mark || !w.local || !w.idx) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t e = 0; e < nc * (size_t)k; e++) {
    size_t pos = find_u64(w.G.v, m, w.rows[e]);
    w.idx[e] = (uint32_t)pos;
    w.mark[pos] = 1;
  }
  free(w.rows);
  w.rows = NULL;
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
  for (size_t e = 0; e < nc * (size_t)k; e++) w.idx[e] = w.local[w.idx[e]];
  free(w.gx);
  w.gx = NULL;

  /* the core points with every input property, prepared by the command */
  st = cloud_like(&c->schema, nc, &core);
  if (st != BSURF_OK) goto out;
  sweep sw = {&c->in, 0};
  for (size_t j = 0; j < nc; j++) {
    io_ply_decode(&c->layout, c->in.data, w.core.v[j], &core, j);
    sweep_at(&sw, c->layout.body + (size_t)w.core.v[j] * c->layout.record);
  }
  drop_pages(&c->in, 0, c->in.size);
  st = c->ops->prepare(c->ops->user, &core);
  if (st != BSURF_OK) goto out;

  bsurf_neighbors nb = {nc, k, w.idx, 0.0, NULL};
  bsurf_tile tile = {t, c->ntiles, nc, nl, w.lxyz, w.core.v, &nb, halo};
  double *sums = c->tile_sums + t * (c->ops->nsums + 1);
  st = c->ops->run(c->ops->user, &tile, &core, sums);
  if (st != BSURF_OK) goto out;
  size_t dups = 0;
  for (size_t j = 0; j < nc; j++) dups += w.dup[j];
  sums[c->ops->nsums] = (double)dups;

  /* the rows and squared nearest distances (for h) to the tile's block */
  w.enc = bsurf_alloc_array(nc, c->record);
  if (!w.enc) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  st = io_ply_encode(&core, w.enc);
  if (st != BSURF_OK) goto out;
  st = write_block(c, t, w.core.v, w.nn2, w.enc, nc, err);
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

/* ---- h: the cascade of src/search/neighbors.c over the assembled values --- */

/* sum_i sqrt(v[i]) in the binary-tree order of sum_sqrt in neighbors.c:
 * halves down to 64 values, each summed left to right. The leaves are
 * visited in index order, which drives the assembly of the output. */
static double sum_sqrt_asm(assembler *a, size_t first, size_t n) {
  if (n <= 64) {
    double s = 0.0;
    for (size_t i = 0; i < n; i++) s += sqrt(nn_at(a, first + i));
    return s;
  }
  return sum_sqrt_asm(a, first, n / 2) + sum_sqrt_asm(a, first + n / 2, n - n / 2);
}

/* Rank 0: the output's records in index order and h. */
static bsurf_status assemble(tiles_ctx *c, double *h, bsurf_error *err) {
  assembler a;
  memset(&a, 0, sizeof a);
  a.c = c;
  a.out = fileno(c->af.f);
  a.err = err;
  a.per = BLOCK_CHUNK / entry_bytes(c) ? BLOCK_CHUNK / entry_bytes(c) : 1;
  a.rows = bsurf_alloc_array(c->range, c->record);
  a.nn = bsurf_alloc_array(c->range, sizeof *a.nn);
  a.buf = bsurf_alloc_array(a.per, entry_bytes(c));
  if (!a.rows || !a.nn || !a.buf) a.st = BSURF_ERR_NOMEM;
  double s = a.st == BSURF_OK ? sum_sqrt_asm(&a, 0, c->n) : 0.0;
  asm_flush(&a);
  assert(a.st != BSURF_OK || a.next == c->nranges);
  free(a.rows);
  free(a.nn);
  free(a.buf);
  if (a.st == BSURF_OK) *h = s / (double)c->n;
  return a.st;
}

/* ---- the run ---------------------------------------------------------------- */

/* The worst status of all ranks (every rank must call it at the same place). */
static bsurf_status agree(const bsurf_tile_comm *cm, bsurf_status st) {
  return cm ? (bsurf_status)cm->max(cm->user, (int)st) : st;
}

/* Rank 0 creates the output (temporary name, header, space for every
 * record) and the scratch file of the tiles' blocks; every rank opens the
 * scratch file, then its name is removed (nothing is left behind on any
 * exit, however abrupt). */
static bsurf_status open_outputs(tiles_ctx *c, const char *output, bsurf_error *err) {
  const bsurf_tile_comm *cm = c->comm;
  const int rank = cm ? cm->rank : 0;
  char name[TILE_PATH_MAX];
  memset(name, 0, sizeof name);
  bsurf_status st = BSURF_OK;
  c->record = 3 * io_type_size(c->out_schema.xyz_type);
  if (c->out_schema.normals) c->record += 3 * io_type_size(c->out_schema.normal_type);
  for (size_t f = 0; f < c->out_schema.field_count; f++) c->record += io_type_size(c->out_schema.fields[f].type);
  st = plan_blocks(c);
  if (rank == 0 && st == BSURF_OK) {
    st = bsurf_atomic_open(&c->af, output, err);
    if (st == BSURF_OK) {
      c->af_open = 1;
      io_writer w = {c->af.f, 0, 0};
      size_t record = 0;
      st = io_ply_write_header(&w, &c->out_schema, c->n, &record);
      assert(st != BSURF_OK || record == c->record);
      if (fflush(c->af.f) != 0) w.failed = 1, w.err_no = errno;
      long pos = ftell(c->af.f);
      if (w.failed || pos < 0)
        st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write: %s", strerror(w.err_no ? w.err_no : EIO));
      c->header = (size_t)pos;
    }
    if (st == BSURF_OK) {
      size_t total = c->header + c->n * c->record;
      int e = posix_fallocate(fileno(c->af.f), 0, (off_t)total);
      if (e) st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot write %zu bytes: %s", total, strerror(e));
    }
    if (st == BSURF_OK) {
      tile_map m;
      st = scratch_create(output, c->block[c->ntiles], 0, &m, name, err);
      if (st == BSURF_OK) c->scr = m.fd;
    }
  }
  st = agree(cm, st);
  if (st != BSURF_OK) return st;
  if (cm) cm->broadcast(cm->user, name, sizeof name);
  if (rank != 0) {
    c->scr = open(name, O_RDWR);
    if (c->scr < 0) st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open %s: %s", name, strerror(errno));
  }
  st = agree(cm, st);
  /* every rank has the scratch file open: its name can go */
  if (rank == 0 && name[0]) unlink(name);
  return st;
}

bsurf_status bsurf_tiles_run(const char *input, const char *output, const bsurf_tile_ops *ops,
                             bsurf_tile_report *report, bsurf_error *err) {
  if (err) err->line = 0, err->byte = -1, err->message[0] = 0;
  if (!input || !output || !ops || !report || !ops->prepare || !ops->run || ops->k < 1 ||
      (ops->nsums && !report->sums))
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "invalid arguments");
  double *user_sums = report->sums;
  memset(report, 0, sizeof *report);
  report->sums = user_sums;
  tiles_ctx c;
  memset(&c, 0, sizeof c);
  c.ops = ops;
  c.comm = ops->comm;
  c.k = ops->k;
  c.in.fd = c.sorted.fd = c.scr = -1;
  bsurf_cloud_init(&c.schema);
  bsurf_cloud_init(&c.out_schema);
  const int rank = c.comm ? c.comm->rank : 0, ranks = c.comm ? c.comm->ranks : 1;

  bsurf_status st = map_input(input, &c.in, err);
  if (st == BSURF_OK) st = io_ply_map(c.in.data, c.in.size, &c.layout, &c.schema, err);
  if (st == BSURF_OK) {
    c.n = c.layout.count;
    report->points = c.n;
    if (c.n < (size_t)c.k || c.n == 0)
      st = bsurf_fail(err, BSURF_ERR_TOO_FEW_POINTS, 0, -1, "has %zu points, fewer than K = %d", c.n, c.k);
    else if (ops->tile_points < 2 * (size_t)c.k)
      st = bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "tiles of %zu points are too small for K = %d",
                      ops->tile_points, c.k);
  }
  if (st == BSURF_OK) {
    st = cloud_like(&c.schema, 1, &c.out_schema);
    if (st == BSURF_OK) st = ops->prepare(ops->user, &c.out_schema);
  }
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
  if (st == BSURF_OK) {
    report->tiles = c.ntiles;
    c.tile_sums = bsurf_calloc_array(c.ntiles, (ops->nsums + 1) * sizeof(double));
    if (!c.tile_sums) st = BSURF_ERR_NOMEM;
  }
  /* every rank reads and checks the same input: they agree on failures */
  st = agree(c.comm, st);
  if (st == BSURF_OK) st = open_outputs(&c, output, err);

  size_t done = 0, mine = 0;
  for (size_t t = (size_t)rank; t < c.ntiles; t += (size_t)ranks) mine += c.tiles[t].count;
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
    for (size_t i = 0; i < ops->nsums; i++) report->sums[i] = 0;
    for (size_t t = 0; t < c.ntiles; t++) {
      for (size_t i = 0; i < ops->nsums; i++) report->sums[i] += c.tile_sums[t * width + i];
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
          if (all[3 * r] > (double)report->max_tile_points) report->max_tile_points = (size_t)all[3 * r];
          if (all[3 * r + 1] > (double)report->max_local_points) report->max_local_points = (size_t)all[3 * r + 1];
          report->halo_grown += (size_t)all[3 * r + 2];
        }
        free(all);
      }
    }
  }
  /* every rank's blocks are written (the agreement above follows every
   * rank's last write): rank 0 assembles the output and h */
  if (st == BSURF_OK && rank == 0) st = assemble(&c, &report->h, err);
  if (c.comm) {
    st = agree(c.comm, st);
    if (st == BSURF_OK) c.comm->broadcast(c.comm->user, &report->h, sizeof report->h);
  }
  if (rank == 0 && c.af_open) {
    bsurf_error cerr;
    bsurf_status cst = bsurf_atomic_close(&c.af, st, 0, &cerr);
    if (st == BSURF_OK && cst != BSURF_OK) {
      st = cst;
      if (err) *err = cerr;
    }
  }
  if (c.comm) st = agree(c.comm, st);

  map_close(&c.in);
  map_close(&c.sorted);
  if (c.scr >= 0) close(c.scr);
  free(c.block);
  io_ply_layout_free(&c.layout);
  bsurf_cloud_free(&c.schema);
  bsurf_cloud_free(&c.out_schema);
  free(c.cell_start);
  free(c.tiles);
  free(c.tile_sums);
  return st;
}
