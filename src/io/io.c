/* The file layer's entry points (format dispatch by extension and content,
 * whole-file reads, atomic writes through a temporary file) and the growable
 * arrays and checked output shared by the per-format readers and writers
 * (text scanning: text.c; value types and their text form: values.c). */
#define _DEFAULT_SOURCE /* mmap's MAP_POPULATE */
#include "io/io.h"

#include <errno.h>
#include <float.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#if defined(__linux__)
#include <sys/mman.h>
#endif

/* ------------------------------------------------------------------------ */
/* Growable arrays                                                           */
/* ------------------------------------------------------------------------ */

void io_faces_init(io_faces *f) {
  memset(f, 0, sizeof *f);
}

void io_faces_free(io_faces *f) {
  free(f->tri);
  io_faces_init(f);
}

void io_faces_begin(io_faces *f) {
  f->corners = 0;
}

bsurf_status io_faces_corner(io_faces *f, uint32_t index) {
  if (f->corners >= 2) {
    if (f->count == f->cap) {
      size_t cap = f->cap ? 2 * f->cap : 1024;
      if (cap > (size_t)-1 / (3 * sizeof(uint32_t))) return BSURF_ERR_NOMEM;
      uint32_t *tri = realloc(f->tri, cap * 3 * sizeof(uint32_t));
      if (!tri) return BSURF_ERR_NOMEM;
      f->tri = tri;
      f->cap = cap;
    }
    uint32_t *t = f->tri + 3 * f->count++;
    t[0] = f->first;
    t[1] = f->prev;
    t[2] = index;
  } else if (f->corners == 0) {
    f->first = index;
  }
  f->prev = index;
  f->corners++;
  return BSURF_OK;
}

void io_faces_move(io_faces *f, bsurf_cloud *cloud) {
  free(cloud->faces);
  cloud->faces = NULL;
  cloud->face_count = 0;
  if (f->count) {
    uint32_t *tri = realloc(f->tri, f->count * 3 * sizeof(uint32_t));
    cloud->faces = tri ? tri : f->tri;
    cloud->face_count = f->count;
  } else {
    free(f->tri);
  }
  io_faces_init(f);
}

bsurf_status io_nomem(bsurf_failure *err) {
  return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
}

bsurf_status io_dvec_push(io_dvec *d, const double *values, size_t count) {
  if (count > d->cap - d->n) {
    size_t cap = d->cap ? d->cap : 4096;
    while (cap - d->n < count) {
      if (cap > (size_t)-1 / (2 * sizeof(double))) return BSURF_ERR_NOMEM;
      cap *= 2;
    }
    double *v = realloc(d->v, cap * sizeof(double));
    if (!v) return BSURF_ERR_NOMEM;
    d->v = v;
    d->cap = cap;
  }
  memcpy(d->v + d->n, values, count * sizeof(double));
  d->n += count;
  return BSURF_OK;
}

double *io_dvec_take(io_dvec *d) {
  double *v = d->v;
  if (d->n == 0) {
    free(v);
    v = NULL;
  } else if (d->n < d->cap) {
    double *s = realloc(v, d->n * sizeof(double));
    if (s) v = s;
  }
  d->v = NULL;
  d->n = d->cap = 0;
  return v;
}

/* ------------------------------------------------------------------------ */
/* Checked output                                                            */
/* ------------------------------------------------------------------------ */

void io_write_bytes(io_writer *w, const void *p, size_t n) {
  if (w->failed || n == 0) return;
  errno = 0;
  if (fwrite(p, 1, n, w->f) != n) {
    w->failed = 1;
    w->err_no = errno ? errno : EIO;
  }
}

void io_write_str(io_writer *w, const char *s) {
  io_write_bytes(w, s, strlen(s));
}

void io_write_fmt(io_writer *w, const char *fmt, ...) {
  if (w->failed) return;
  va_list ap;
  va_start(ap, fmt);
  errno = 0;
  int r = vfprintf(w->f, fmt, ap);
  va_end(ap);
  if (r < 0) {
    w->failed = 1;
    w->err_no = errno ? errno : EIO;
  }
}

/* ------------------------------------------------------------------------ */
/* Formats                                                                   */
/* ------------------------------------------------------------------------ */

static int ext_is(const char *ext, const char *name) {
  size_t n = strlen(name);
  if (strlen(ext) != n) return 0;
  for (size_t i = 0; i < n; i++) {
    char c = ext[i];
    if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
    if (c != name[i]) return 0;
  }
  return 1;
}

bsurf_format bsurf_format_from_path(const char *path) {
  if (!path) return BSURF_FORMAT_UNKNOWN;
  const char *base = strrchr(path, '/');
  base = base ? base + 1 : path;
  const char *dot = strrchr(base, '.');
  if (!dot || dot == base) return BSURF_FORMAT_UNKNOWN;
  const char *ext = dot + 1;
  if (ext_is(ext, "ply")) return BSURF_FORMAT_PLY;
  if (ext_is(ext, "off")) return BSURF_FORMAT_OFF;
  if (ext_is(ext, "obj")) return BSURF_FORMAT_OBJ;
  if (ext_is(ext, "xyz") || ext_is(ext, "txt") || ext_is(ext, "pts")) return BSURF_FORMAT_XYZ;
  return bsurf_format_from_name(ext);
}

/* ---- formats by name and by content (docs/formats.md) ---- */

bsurf_format bsurf_format_from_name(const char *name) {
  static const struct {
    const char *name;
    bsurf_format format;
  } names[] = {{"ply", BSURF_FORMAT_PLY}, {"off", BSURF_FORMAT_OFF}, {"obj", BSURF_FORMAT_OBJ},
               {"xyz", BSURF_FORMAT_XYZ}, {"txt", BSURF_FORMAT_XYZ}, {"pts", BSURF_FORMAT_XYZ},
               {"pcd", BSURF_FORMAT_PCD}, {"las", BSURF_FORMAT_LAS}, {"laz", BSURF_FORMAT_LAS},
               {"csv", BSURF_FORMAT_CSV}, {"asc", BSURF_FORMAT_CSV}};
  if (!name) return BSURF_FORMAT_UNKNOWN;
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
    if (ext_is(name, names[i].name)) return names[i].format;
  return BSURF_FORMAT_UNKNOWN;
}

const char *bsurf_format_name(bsurf_format format) {
  static const char *const names[] = {"", "ply", "off", "obj", "xyz", "pcd", "las", "csv"};
  return (unsigned)format < sizeof names / sizeof names[0] ? names[format] : "";
}

/* The first line of the data (at most 64 bytes of it) starts with `word`
 * followed by the end of the line or a blank. */
static int starts_with_word(const char *p, size_t size, const char *word) {
  size_t n = strlen(word);
  if (size < n || memcmp(p, word, n) != 0) return 0;
  return size == n || p[n] == '\n' || p[n] == '\r' || p[n] == ' ' || p[n] == '\t';
}

bsurf_format bsurf_format_detect(const void *data, size_t size) {
  const char *p = data;
  if (!p) return BSURF_FORMAT_UNKNOWN;
  if (size >= 3 && memcmp(p, "\xEF\xBB\xBF", 3) == 0) { /* a UTF-8 byte order mark */
    p += 3;
    size -= 3;
  }
  if (size >= 4 && memcmp(p, "LASF", 4) == 0) return BSURF_FORMAT_LAS;
  if (starts_with_word(p, size, "ply")) return BSURF_FORMAT_PLY;
  if (size >= 6 && memcmp(p, "# .PCD", 6) == 0) return BSURF_FORMAT_PCD;
  if (starts_with_word(p, size, "VERSION")) return BSURF_FORMAT_PCD;
  /* OFF's keyword, after comment and blank lines: OFF NOFF COFF STOFF ... */
  size_t i = 0;
  while (i < size) {
    while (i < size && (p[i] == ' ' || p[i] == '\t' || p[i] == '\r' || p[i] == '\n'))
      i++;
    if (i < size && p[i] == '#') {
      while (i < size && p[i] != '\n')
        i++;
      continue;
    }
    break;
  }
  size_t j = i;
  while (j < size && j - i < 16 && p[j] >= 'A' && p[j] <= 'Z')
    j++;
  if (j - i >= 3 && memcmp(p + j - 3, "OFF", 3) == 0 &&
      (j == size || p[j] == '\n' || p[j] == '\r' || p[j] == ' ' || p[j] == '\t' ||
       (p[j] >= '0' && p[j] <= '9')))
    return BSURF_FORMAT_OFF;
  return BSURF_FORMAT_UNKNOWN;
}

/* Text without a signature or a known extension: OBJ when a line starts
 * with "v ", else a point list (CSV/XYZ, header line or not). */
static bsurf_format sniff_text(const char *p, size_t size) {
  size_t n = size < 65536 ? size : 65536;
  for (size_t i = 0; i + 1 < n; i++)
    if ((i == 0 || p[i - 1] == '\n') && p[i] == 'v' && (p[i + 1] == ' ' || p[i + 1] == '\t'))
      return BSURF_FORMAT_OBJ;
  return BSURF_FORMAT_CSV;
}

int bsurf_format_keeps_fields(bsurf_format format) {
  return format == BSURF_FORMAT_PLY || format == BSURF_FORMAT_PCD || format == BSURF_FORMAT_LAS ||
         format == BSURF_FORMAT_CSV;
}

static void clear_error(bsurf_failure *err) {
  if (err) {
    err->line = 0;
    err->byte = -1;
    err->message[0] = '\0';
  }
}

static const char k_unknown_ext[] =
    "unknown file extension (use .ply, .pcd, .las, .csv, .asc, .off, .obj, .xyz, .txt or .pts)";

/* ------------------------------------------------------------------------ */
/* Reading                                                                   */
/* ------------------------------------------------------------------------ */

bsurf_status bsurf_read_buffer(const void *data, size_t size, bsurf_format format,
                               bsurf_cloud *cloud, bsurf_failure *err) {
  clear_error(err);
  if (!cloud) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no cloud given");
  bsurf_cloud_init(cloud);
  if (!data && size) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no data given");
  const char *p = data ? (const char *)data : "";
  /* Text files saved by Windows tools may start with a UTF-8 byte order
   * mark (PLY keeps every byte: binary offsets must stay exact). */
  if (format != BSURF_FORMAT_PLY && format != BSURF_FORMAT_LAS && size >= 3 &&
      memcmp(p, "\xEF\xBB\xBF", 3) == 0) {
    p += 3;
    size -= 3;
  }
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  bsurf_status st;
  switch (format) {
  case BSURF_FORMAT_PLY: st = bsurf_io_read_ply(p, size, &c, err); break;
  case BSURF_FORMAT_OFF: st = bsurf_io_read_off(p, size, &c, err); break;
  case BSURF_FORMAT_OBJ: st = bsurf_io_read_obj(p, size, &c, err); break;
  case BSURF_FORMAT_XYZ:
  case BSURF_FORMAT_CSV: st = bsurf_io_read_xyz(p, size, &c, err); break;
  case BSURF_FORMAT_PCD: st = bsurf_io_read_pcd(p, size, &c, err); break;
  case BSURF_FORMAT_LAS: st = bsurf_io_read_las(p, size, &c, err); break;
  case BSURF_FORMAT_UNKNOWN:
  default: st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1, "unknown file format"); break;
  }
  if (st != BSURF_OK) {
    bsurf_cloud_free(&c);
    if (err && !err->message[0])
      bsurf_fail(err, st, err->line, err->byte, "%s", bsurf_strerror(st));
    return st;
  }
  *cloud = c;
  return BSURF_OK;
}

/* The format of the bytes buf[0..n) read from path, and the cloud from them. */
static bsurf_status read_content(const char *path, bsurf_format format, const char *buf, size_t n,
                                 bsurf_cloud *cloud, bsurf_failure *err) {
  /* the content's own signature wins over the extension; text without one
   * and without a known extension is sniffed (docs/formats.md) */
  bsurf_format declared = bsurf_format_detect(buf, n);
  if (declared != BSURF_FORMAT_UNKNOWN &&
      !(declared == BSURF_FORMAT_OFF && format == BSURF_FORMAT_OBJ))
    format = declared;
  else if (format == BSURF_FORMAT_UNKNOWN) {
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    if (dot && dot != base) /* an extension bootsurf does not know, and no signature */
      return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1,
                        "%s; the content is not PLY, PCD, LAS or OFF either", k_unknown_ext);
    format = sniff_text(buf, n); /* no extension (or standard input): text */
  }
  return bsurf_read_buffer(buf, n, format, cloud, err);
}

/* Files from this size are mapped (read-only, pages populated at once)
 * instead of read into a buffer: the kernel then neither zeroes a buffer's
 * fresh pages nor copies the file into them (3% of the CPU time of
 * `normals -k 30 -B 0` on a 48 MB PLY, all of it before the threads start). */
#define READ_MAP_MIN ((size_t)4 << 20)

bsurf_status bsurf_read(const char *path, bsurf_cloud *cloud, bsurf_failure *err) {
  clear_error(err);
  if (!cloud) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no cloud given");
  bsurf_cloud_init(cloud);
  if (!path) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no path given");
  bsurf_format format = bsurf_format_from_path(path);
  int is_stdin = strcmp(path, "-") == 0;

  FILE *f = is_stdin ? stdin : fopen(path, "rb");
  if (!f) return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open: %s", strerror(errno));
  struct stat sb;
  size_t cap = 1 << 16;
  if (fstat(fileno(f), &sb) == 0) {
    if (S_ISDIR(sb.st_mode)) {
      if (!is_stdin) fclose(f);
      return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot read: it is a directory");
    }
    if (S_ISREG(sb.st_mode)) {
      if ((unsigned long long)sb.st_size >= (unsigned long long)((size_t)-1 / 2)) {
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "the file is too large (%lld bytes)",
                          (long long)sb.st_size);
      }
      cap = (size_t)sb.st_size + 1; /* +1: reach EOF without growing */
#if defined(__linux__) && defined(MAP_POPULATE)
      if (!is_stdin && (size_t)sb.st_size >= READ_MAP_MIN) {
        const size_t size = (size_t)sb.st_size;
        void *map = mmap(NULL, size, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fileno(f), 0);
        if (map != MAP_FAILED) {
          fclose(f);
          bsurf_status st = read_content(path, format, map, size, cloud, err);
          munmap(map, size);
          return st;
        } /* else read it */
      }
#endif
    }
  }
  char *buf = bsurf_alloc_array(cap, 1); /* huge pages for a large file */
  size_t n = 0;
  if (!buf) {
    if (!is_stdin) fclose(f);
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory reading the file (%zu bytes)",
                      cap);
  }
  for (;;) {
    if (n == cap) {
      if (cap > (size_t)-1 / 4) {
        free(buf);
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "the file is too large");
      }
      char *nb = realloc(buf, cap * 2);
      if (!nb) {
        free(buf);
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory reading the file");
      }
      buf = nb;
      cap *= 2;
    }
    size_t got = fread(buf + n, 1, cap - n, f);
    n += got;
    if (got == 0 || n < cap) {
      if (ferror(f)) {
        int e = errno;
        free(buf);
        if (!is_stdin) fclose(f);
        return bsurf_fail(err, BSURF_ERR_IO, 0, (long long)n, "read failed: %s",
                          strerror(e ? e : EIO));
      }
      if (feof(f)) break;
    }
  }
  if (!is_stdin) fclose(f);
  bsurf_status st = read_content(path, format, buf, n, cloud, err);
  free(buf);
  return st;
}

/* The header check of bsurf_read_header; *ascii_short: ascii data
 * too short for the header's counts (the whole file, read, names the line). */
static bsurf_status header_check(const void *data, size_t size, uint64_t file_size,
                                 bsurf_format format, uint64_t *points, int *ascii_short,
                                 bsurf_failure *err) {
  clear_error(err);
  *points = 0;
  *ascii_short = 0;
  if (format != BSURF_FORMAT_PLY) return BSURF_OK;
  if (!data && size) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no data given");
  unsigned long long n = 0;
  bsurf_status st =
      io_ply_probe(data ? (const char *)data : "", size, file_size, &n, ascii_short, err);
  if (st != BSURF_OK && err && !err->message[0])
    bsurf_fail(err, st, err->line, err->byte, "%s", bsurf_strerror(st));
  *points = n;
  return st;
}

/* The end of a PLY header ("end_header" and the bytes of its line break) is
 * in buf[0..n). */
static int has_header_end(const char *buf, size_t n, size_t from) {
  static const char word[] = "end_header";
  const size_t wl = sizeof word - 1;
  for (size_t i = from; i + wl + 2 <= n; i++)
    if (buf[i] == 'e' && i > 0 && (buf[i - 1] == '\n' || buf[i - 1] == '\r') &&
        memcmp(buf + i, word, wl) == 0)
      return 1;
  return 0;
}

bsurf_status bsurf_read_header(const char *path, uint64_t *points, bsurf_failure *err) {
  clear_error(err);
  *points = 0;
  if (!path) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no path given");
  bsurf_format format = bsurf_format_from_path(path);
  if (format != BSURF_FORMAT_PLY) return BSURF_OK;
  FILE *f = fopen(path, "rb");
  if (!f) return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open: %s", strerror(errno));
  struct stat sb;
  if (fstat(fileno(f), &sb) != 0 || !S_ISREG(sb.st_mode)) {
    fclose(f); /* pipes and devices: read whole by bsurf_read, checked there */
    return BSURF_OK;
  }
  /* read until the header's end (any size: a header of 100,000 properties
   * is 2.5 MB), doubling the buffer */
  size_t cap = 1 << 16, n = 0;
  char *buf = NULL;
  bsurf_status st = BSURF_OK;
  for (;;) {
    char *nb = realloc(buf, cap);
    if (!nb) {
      st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory reading the header");
      break;
    }
    buf = nb;
    size_t from = n > 16 ? n - 16 : 0;
    size_t got = fread(buf + n, 1, cap - n, f);
    n += got;
    if (ferror(f)) {
      st = bsurf_fail(err, BSURF_ERR_IO, 0, (long long)n, "read failed: %s",
                      strerror(errno ? errno : EIO));
      break;
    }
    if (got == 0 || feof(f) || has_header_end(buf, n, from)) break;
    if (cap > (size_t)-1 / 4) break;
    cap *= 2;
  }
  fclose(f);
  int ascii_short = 0;
  if (st == BSURF_OK)
    st = header_check(buf, n, (uint64_t)sb.st_size, format, points, &ascii_short, err);
  free(buf);
  if (st != BSURF_OK && ascii_short) {
    /* ascii data too short for its header: the file, read whole, names the
     * line where the data ends (the reader stores no vertex then) */
    bsurf_cloud unused;
    st = bsurf_read(path, &unused, err);
    bsurf_cloud_free(&unused);
    if (st == BSURF_OK) st = BSURF_ERR_PARSE; /* not reached: the check is the reader's own */
  }
  return st;
}

/* ------------------------------------------------------------------------ */
/* Writing                                                                   */
/* ------------------------------------------------------------------------ */

static bsurf_status check_cloud(const bsurf_cloud *cloud, bsurf_failure *err) {
  if (cloud->point_count && !cloud->xyz)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "the cloud has no coordinates");
  for (size_t i = 0; i < cloud->field_count; i++)
    if (cloud->point_count && !cloud->fields[i].values)
      return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "field '%s' has no values",
                        cloud->fields[i].name);
  if (cloud->face_count && !cloud->faces)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "the cloud has no face array");
  for (size_t i = 0; i < 3 * cloud->face_count; i++)
    if (cloud->faces[i] >= cloud->point_count)
      return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                        "face %zu refers to point %lu but the cloud has %zu points", i / 3,
                        (unsigned long)cloud->faces[i], cloud->point_count);
  return BSURF_OK;
}

/* The fields of `view` (an array of field_count + 1) from the cloud's, with
 * float32 types (opts->float32) and PLY names for a viewer (opts->ply_names:
 * docs/formats.md). */
static bsurf_status write_view(bsurf_cloud *view, const bsurf_cloud *cloud,
                               const bsurf_write_options *opts, bsurf_format format,
                               bsurf_ply_names *names, bsurf_failure *err) {
  bsurf_field *fields = view->fields;
  if (cloud->field_count) memcpy(fields, cloud->fields, cloud->field_count * sizeof *fields);
  if (opts->float32) {
    if (view->xyz_type == BSURF_FLOAT64) view->xyz_type = BSURF_FLOAT32;
    if (view->normal_type == BSURF_FLOAT64) view->normal_type = BSURF_FLOAT32;
    for (size_t i = 0; i < cloud->field_count; i++)
      if (fields[i].type == BSURF_FLOAT64) fields[i].type = BSURF_FLOAT32;
  }
  if (format != BSURF_FORMAT_PLY) return BSURF_OK;
  if (opts->ply_names == BSURF_PLY_NAMES_CLOUDCOMPARE) {
    /* CloudCompare loads a vertex property as a scalar field only when its
     * name contains "scal" (or "intensity", "gray", "grey"), and removes a
     * leading "scalar_" when it does */
    for (size_t i = 0; i < cloud->field_count; i++) {
      char name[2 * BSURF_FIELD_NAME_MAX];
      snprintf(name, sizeof name, "scalar_%s", fields[i].name);
      if (strlen(name) >= BSURF_FIELD_NAME_MAX)
        return bsurf_fail(
            err, BSURF_ERR_INVALID_ARG, 0, -1,
            "field '%s': with the prefix scalar_ the name is longer than %d characters",
            fields[i].name, BSURF_FIELD_NAME_MAX - 1);
      memcpy(fields[i].name, name, strlen(name) + 1);
    }
    *names = BSURF_PLY_NAMES_CLOUDCOMPARE;
  } else if (opts->ply_names == BSURF_PLY_NAMES_MESHLAB && cloud->field_count &&
             !bsurf_cloud_field(cloud, "quality")) {
    /* MeshLab (vcglib's PLY importer) keeps one per-vertex scalar, "quality" */
    fields[cloud->field_count] = fields[0];
    snprintf(fields[cloud->field_count].name, BSURF_FIELD_NAME_MAX, "quality");
    fields[cloud->field_count].type = BSURF_FLOAT32;
    view->field_count = cloud->field_count + 1;
    *names = BSURF_PLY_NAMES_MESHLAB;
  }
  return BSURF_OK;
}

bsurf_status bsurf_write(const char *path, const bsurf_cloud *cloud,
                         const bsurf_write_options *opts, bsurf_failure *err) {
  clear_error(err);
  if (!path || !cloud)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no path or no cloud given");
  bsurf_format format = opts && opts->format ? opts->format : bsurf_format_from_path(path);
  /* a FIFO or device without an extension (-o /dev/null) gets PLY, the
   * format that keeps everything */
  if (format == BSURF_FORMAT_UNKNOWN && bsurf_output_is_stream(path)) format = BSURF_FORMAT_PLY;
  struct stat sd; /* a directory, whatever its name, is named as one (the CLI's words) */
  if (strcmp(path, "-") != 0 && stat(path, &sd) == 0 && S_ISDIR(sd.st_mode))
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "is a directory");
  if (format == BSURF_FORMAT_UNKNOWN)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1, "%s",
                      strcmp(path, "-") == 0 ? "standard output needs a format (--format)"
                                             : k_unknown_ext);
  bsurf_status st = check_cloud(cloud, err);
  if (st != BSURF_OK) return st;
  /* --float32 and --ply-names: a view of the cloud with other field types and
   * names (the values are shared, not copied) */
  bsurf_cloud view = *cloud;
  bsurf_field *fields = NULL;
  bsurf_ply_names names = BSURF_PLY_NAMES_PLAIN;
  if (opts && (opts->float32 || (format == BSURF_FORMAT_PLY && opts->ply_names))) {
    fields = bsurf_alloc_array(cloud->field_count + 1, sizeof *fields);
    if (!fields) return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
    view.fields = fields;
    st = write_view(&view, cloud, opts, format, &names, err);
  }
  if (st == BSURF_OK && bsurf_format_keeps_fields(format)) st = bsurf_io_ply_check(&view, err);
  if (st == BSURF_OK && format == BSURF_FORMAT_LAS) st = bsurf_io_las_check(&view, err);
  if (st != BSURF_OK) {
    free(fields);
    return st;
  }

  bsurf_atomic_file af;
  st = bsurf_atomic_open(&af, path, err);
  if (st != BSURF_OK) {
    free(fields);
    return st;
  }
  io_writer w = {af.f, 0, 0};
  int ascii = opts && opts->ascii;
  switch (format) {
  case BSURF_FORMAT_PLY: st = bsurf_io_write_ply(&w, &view, ascii, names, err); break;
  case BSURF_FORMAT_OFF: st = bsurf_io_write_off(&w, &view, err); break;
  case BSURF_FORMAT_OBJ: st = bsurf_io_write_obj(&w, &view, err); break;
  case BSURF_FORMAT_PCD: st = bsurf_io_write_pcd(&w, &view, ascii, err); break;
  case BSURF_FORMAT_LAS: st = bsurf_io_write_las(&w, &view, opts && opts->las_legacy, err); break;
  case BSURF_FORMAT_CSV: {
    const char *dot = strrchr(path, '.');
    st = bsurf_io_write_csv(&w, &view, dot && ext_is(dot + 1, "asc"), err);
    break;
  }
  case BSURF_FORMAT_XYZ:
  case BSURF_FORMAT_UNKNOWN:
  default: st = bsurf_io_write_xyz(&w, &view, err); break;
  }
  free(fields);
  return bsurf_atomic_close(&af, st, w.failed ? (w.err_no ? w.err_no : EIO) : 0, err);
}
