/* The tile engine's files (src/tile/tiles.c): the mapped input, scratch
 * files beside the output, the ranks' shared ones and a first stage's
 * values. */
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

/* ---- files ---------------------------------------------------------------- */

void map_close(tile_map *m) {
  if (m->data && m->size) munmap(m->data, m->size);
  if (m->fd >= 0) close(m->fd);
  m->data = NULL;
  m->size = 0;
  m->fd = -1;
}

/* Drops the resident pages of [from, to) of a mapping (page-aligned inside):
 * read-only pages are re-read from the page cache if needed again, written
 * pages of a shared mapping stay in the page cache and reach the file. */
void drop_pages(const tile_map *m, size_t from, size_t to) {
  size_t page = (size_t)sysconf(_SC_PAGESIZE);
  size_t a = (from + page - 1) / page * page, b = to / page * page;
  if (to >= m->size) b = m->size; /* the mapping's last, partial page too */
  if (b > a) madvise(m->data + a, b - a, MADV_DONTNEED);
}

void sweep_at(sweep *s, size_t offset) {
  if (offset > s->mark + ((size_t)64 << 20)) {
    drop_pages(s->m, s->mark, offset);
    s->mark = offset;
  }
}

bsurf_status map_input(const char *path, tile_map *m, bsurf_failure *err) {
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
int pwrite_all(int fd, const void *buf, size_t bytes, size_t offset) {
  const char *p = buf;
  while (bytes > 0) {
    ssize_t k = pwrite(fd, p, bytes, (off_t)offset);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return k < 0 ? errno : EIO;
    p += k, bytes -= (size_t)k, offset += (size_t)k;
  }
  return 0;
}

int pread_all(int fd, void *buf, size_t bytes, size_t offset) {
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

/* An empty cloud of n points with the properties of `schema`. */
bsurf_status cloud_like(const bsurf_cloud *schema, size_t n, bsurf_cloud *out) {
  bsurf_status st = bsurf_cloud_alloc(out, n, schema->normals != NULL);
  out->xyz_type = schema->xyz_type;
  out->normal_type = schema->normal_type;
  memcpy(out->shape, schema->shape, sizeof out->shape);
  for (size_t f = 0; f < schema->field_count && st == BSURF_OK; f++)
    if (!bsurf_cloud_add_field(out, schema->fields[f].name, schema->fields[f].type))
      st = BSURF_ERR_NOMEM;
  return st;
}

/* ---- the ranks --------------------------------------------------------------- */

int rank_of(const tiles_ctx *c) {
  return c->comm ? c->comm->rank : 0;
}
int ranks_of(const tiles_ctx *c) {
  return c->comm ? c->comm->ranks : 1;
}

/* The first of rank r's share of n items in order (contiguous shares that
 * differ by at most one; r = ranks gives n). */
size_t share_start(size_t n, int r, int ranks) {
  size_t q = n / (size_t)ranks, m = n % (size_t)ranks;
  return q * (size_t)r + ((size_t)r < m ? (size_t)r : m);
}

/* The worst status of all ranks (every rank must call it at the same place). */
bsurf_status agree(const bsurf_tile_comm *cm, bsurf_status st) {
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
bsurf_status shared_scratch(const tiles_ctx *c, const char *near, size_t bytes, int map,
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

/* ---- the values of a first stage ----------------------------------------- */

static size_t values_bytes(const bsurf_tile_values *v) {
  return v->count * (v->nvalues + 1) * sizeof(double);
}

/* The values of a first stage over the same input (n points), mapped
 * read-only (the descriptor stays the caller's). */
bsurf_status map_values(const bsurf_tile_values *v, size_t n, tile_map *m, bsurf_failure *err) {
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
