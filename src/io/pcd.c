/* PCD (the Point Cloud Library's point cloud data format, v0.7): reads
 * DATA ascii, binary and binary_compressed (LZF, decompressed by lzf_decode
 * below: docs/formats.md says why it is written here), every TYPE/SIZE/COUNT
 * (I U F of 1, 2, 4, 8 bytes; a field with COUNT n > 1 becomes the fields
 * name_0 .. name_{n-1}); writes ascii and binary.
 *
 * Names: x y z are the coordinates, normal_x normal_y normal_z the normals;
 * PCL's packed colour (`rgb`, 4 bytes, 0x00RRGGBB in the bits of a float, or
 * `rgba` with alpha in the top byte) becomes the uint8 fields red green blue
 * (and alpha), and is written back packed; `_` (PCL's padding) is skipped.
 * Like the PLY reader, the header is never trusted: counts times record
 * sizes are checked against the bytes there before anything is allocated. */
#include "io/io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PCD_MAX_FIELDS 4096
#define PCD_MAX_COLUMNS 65536
#define PCD_MAX_COUNT_OUT 64 /* COUNT of a field written from name_0 .. name_63 */

typedef struct pcd_field {
  io_token name;
  size_t size;   /* bytes of one element: 1 2 4 8 */
  char kind;     /* 'I' 'U' 'F' */
  size_t count;  /* elements */
  size_t offset; /* in a binary record */
} pcd_field;

/* Where one element goes. */
enum { DST_SKIP, DST_XYZ, DST_NORMAL, DST_FIELD, DST_RGB, DST_RGBA };

typedef struct pcd_column {
  const pcd_field *f;
  size_t elem; /* element index inside the field */
  int dst;
  size_t at; /* coordinate 0..2 or field index (DST_RGB: index of red) */
  bsurf_type type;
  int wide; /* 8-byte integer: converted with an exactness check */
} pcd_column;

static bsurf_status nomem(bsurf_failure *err) {
  return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
}

static int token_eq_ci(io_token t, const char *w) {
  size_t n = strlen(w);
  if (t.len != n) return 0;
  for (size_t i = 0; i < n; i++) {
    char c = t.s[i];
    if (c >= 'a' && c <= 'z') c = (char)(c - 'a' + 'A');
    if (c != w[i]) return 0;
  }
  return 1;
}

/* ---- LZF ------------------------------------------------------------------ */

/* LZF (Marc Lehmann's liblzf format, which PCL's binary_compressed uses): a
 * control byte c < 32 copies c + 1 literal bytes; otherwise the top 3 bits
 * are a length (7: plus the next byte) and, with the next byte, an offset
 * back into the output: length + 2 bytes are copied from there (they may
 * overlap the bytes being written). Returns the bytes written, or (size_t)-1
 * when the input is corrupt (a reference before the start, a run past the
 * end of either buffer); *bad is the input offset where it went wrong. */
static size_t lzf_decode(const unsigned char *in, size_t in_len, unsigned char *out, size_t out_len,
                         size_t *bad) {
  size_t ip = 0, op = 0;
  while (ip < in_len) {
    size_t at = ip;
    unsigned ctrl = in[ip++];
    if (ctrl < 32) {
      size_t run = (size_t)ctrl + 1;
      if (run > in_len - ip || run > out_len - op) {
        *bad = at;
        return (size_t)-1;
      }
      memcpy(out + op, in + ip, run);
      ip += run;
      op += run;
    } else {
      size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in_len) {
          *bad = at;
          return (size_t)-1;
        }
        len += in[ip++];
      }
      if (ip >= in_len) {
        *bad = at;
        return (size_t)-1;
      }
      size_t back = ((size_t)(ctrl & 0x1f) << 8) + in[ip++] + 1;
      len += 2;
      if (back > op || len > out_len - op) {
        *bad = at;
        return (size_t)-1;
      }
      for (size_t k = 0; k < len; k++, op++)
        out[op] = out[op - back]; /* may overlap */
    }
  }
  return op;
}

/* ---- header ---------------------------------------------------------------- */

typedef struct pcd_header {
  pcd_field *fields;
  size_t nfields;
  unsigned long long width, height, points;
  int have_width, have_height, have_points, have_size, have_type, have_count;
  int data;       /* 0 ascii, 1 binary, 2 binary_compressed */
  size_t body;    /* offset of the first byte after the DATA line */
  long body_line; /* its line number */
  size_t record;  /* binary bytes per point */
  char shape[BSURF_FIELD_NAME_MAX];
} pcd_header;

static bsurf_status expect_per_field(io_cursor *c, const pcd_header *h, long ln, const char *kw,
                                     bsurf_failure *err) {
  if (!h->fields) return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "%s before FIELDS", kw);
  size_t k = io_count_tokens(c);
  if (k != h->nfields)
    return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "%s has %zu entries for %zu FIELDS", kw, k,
                      h->nfields);
  return BSURF_OK;
}

static bsurf_status parse_header(const char *data, size_t size, pcd_header *h, bsurf_failure *err) {
  io_text t;
  io_text_init(&t, data, size);
  const char *line;
  size_t len;
  char a[48];
  int have_data = 0;
  if (size == 0)
    return bsurf_fail(err, BSURF_ERR_PARSE, 1, -1, "not a PCD file: the file is empty");
  while (!have_data && io_text_next_line(&t, &line, &len)) {
    long ln = t.line;
    io_cursor c;
    io_token kw, tok;
    io_cursor_init(&c, line, len, IO_SEP_SPACE);
    if (!io_next_token(&c, &kw)) continue;
    if (kw.s[0] == '#') {
      /* "# bootsurf shape NAME" (bsurf_cloud.shape); other comments are ignored */
      io_token w1, w2, name, extra;
      if (io_token_is(kw, "#") && io_next_token(&c, &w1) && io_token_is(w1, "bootsurf") &&
          io_next_token(&c, &w2) && io_token_is(w2, "shape") && io_next_token(&c, &name) &&
          !io_next_token(&c, &extra) && name.len < BSURF_FIELD_NAME_MAX) {
        memcpy(h->shape, name.s, name.len);
        h->shape[name.len] = 0;
      }
      continue;
    }
    if (io_token_is(kw, "VERSION")) {
      if (!io_next_token(&c, &tok))
        return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "VERSION without a version");
      double v;
      if (!io_parse_double(tok.s, tok.len, &v) || v < 0.5 || v > 0.7 + 1e-9)
        return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, ln, -1,
                          "PCD version '%s' is not supported (expected 0.7 or earlier)",
                          io_token_repr(tok, a));
    } else if (io_token_is(kw, "FIELDS") || io_token_is(kw, "COLUMNS")) {
      if (h->fields) return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "a second FIELDS line");
      size_t k = io_count_tokens(&c);
      if (k == 0) return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "FIELDS names no field");
      if (k > PCD_MAX_FIELDS)
        return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, ln, -1,
                          "%zu fields is more than the %d supported", k, PCD_MAX_FIELDS);
      h->fields = calloc(k, sizeof *h->fields);
      if (!h->fields) return nomem(err);
      h->nfields = k;
      for (size_t i = 0; i < k; i++) {
        io_next_token(&c, &h->fields[i].name);
        h->fields[i].count = 1;
        h->fields[i].size = 4;
        h->fields[i].kind = 'F';
        if (h->fields[i].name.len >= BSURF_FIELD_NAME_MAX)
          return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, ln, -1, "field name '%s' is too long",
                            io_token_repr(h->fields[i].name, a));
      }
    } else if (io_token_is(kw, "SIZE")) {
      bsurf_status st = expect_per_field(&c, h, ln, "SIZE", err);
      if (st != BSURF_OK) return st;
      for (size_t i = 0; i < h->nfields; i++) {
        unsigned long long v;
        io_next_token(&c, &tok);
        if (!io_parse_u64(tok.s, tok.len, &v) || (v != 1 && v != 2 && v != 4 && v != 8))
          return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1,
                            "SIZE '%s' of field %zu is not 1, 2, 4 or 8", io_token_repr(tok, a),
                            i + 1);
        h->fields[i].size = (size_t)v;
      }
      h->have_size = 1;
    } else if (io_token_is(kw, "TYPE")) {
      bsurf_status st = expect_per_field(&c, h, ln, "TYPE", err);
      if (st != BSURF_OK) return st;
      for (size_t i = 0; i < h->nfields; i++) {
        io_next_token(&c, &tok);
        if (tok.len != 1 || (tok.s[0] != 'I' && tok.s[0] != 'U' && tok.s[0] != 'F'))
          return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "TYPE '%s' of field %zu is not I, U or F",
                            io_token_repr(tok, a), i + 1);
        h->fields[i].kind = tok.s[0];
      }
      h->have_type = 1;
    } else if (io_token_is(kw, "COUNT")) {
      bsurf_status st = expect_per_field(&c, h, ln, "COUNT", err);
      if (st != BSURF_OK) return st;
      for (size_t i = 0; i < h->nfields; i++) {
        unsigned long long v;
        io_next_token(&c, &tok);
        if (!io_parse_u64(tok.s, tok.len, &v) || v == 0 || v > PCD_MAX_COLUMNS)
          return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1,
                            "COUNT '%s' of field %zu is not between 1 and %d",
                            io_token_repr(tok, a), i + 1, PCD_MAX_COLUMNS);
        h->fields[i].count = (size_t)v;
      }
      h->have_count = 1;
    } else if (io_token_is(kw, "WIDTH") || io_token_is(kw, "HEIGHT") || io_token_is(kw, "POINTS")) {
      unsigned long long v;
      io_token extra;
      if (!io_next_token(&c, &tok) || io_next_token(&c, &extra) ||
          !io_parse_u64(tok.s, tok.len, &v))
        return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1,
                          "%.*s must be followed by one non-negative integer", (int)kw.len, kw.s);
      if (io_token_is(kw, "WIDTH")) {
        h->width = v;
        h->have_width = 1;
      } else if (io_token_is(kw, "HEIGHT")) {
        h->height = v;
        h->have_height = 1;
      } else {
        h->points = v;
        h->have_points = 1;
      }
    } else if (io_token_is(kw, "VIEWPOINT")) {
      /* the sensor pose: kept by PCL, not by bootsurf; 7 numbers */
      size_t k = io_count_tokens(&c);
      if (k != 7)
        return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "VIEWPOINT has %zu numbers, not 7", k);
      for (int i = 0; i < 7; i++) {
        double v;
        io_next_token(&c, &tok);
        if (!io_parse_double(tok.s, tok.len, &v))
          return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "VIEWPOINT value '%s' is not a number",
                            io_token_repr(tok, a));
      }
    } else if (io_token_is(kw, "DATA")) {
      io_token extra;
      if (!io_next_token(&c, &tok) || io_next_token(&c, &extra))
        return bsurf_fail(
            err, BSURF_ERR_PARSE, ln, -1,
            "the DATA line must read 'DATA ascii', 'DATA binary' or 'DATA binary_compressed'");
      if (token_eq_ci(tok, "ASCII"))
        h->data = 0;
      else if (token_eq_ci(tok, "BINARY"))
        h->data = 1;
      else if (token_eq_ci(tok, "BINARY_COMPRESSED"))
        h->data = 2;
      else
        return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, ln, -1,
                          "unknown DATA kind '%s' (expected ascii, binary or binary_compressed)",
                          io_token_repr(tok, a));
      have_data = 1;
      h->body = t.pos;
      h->body_line = t.line + 1;
    } else {
      return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "not a PCD header line: unknown keyword '%s'",
                        io_token_repr(kw, a));
    }
  }
  long end = t.line ? t.line : 1;
  if (!have_data) {
    if (!h->fields)
      return bsurf_fail(err, BSURF_ERR_PARSE, end, -1,
                        "not a PCD file: no FIELDS and no DATA line");
    return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "the header ends without a DATA line");
  }
  if (!h->fields) return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "the header has no FIELDS line");
  if (!h->have_size)
    return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "the header has no SIZE line");
  if (!h->have_type)
    return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "the header has no TYPE line");
  if (!h->have_width && !h->have_points)
    return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "the header has neither WIDTH nor POINTS");
  if (!h->have_height) h->height = 1;
  if (!h->have_width) h->width = h->points;
  if (h->width && h->height > ~0ULL / h->width)
    return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "WIDTH x HEIGHT overflows");
  if (!h->have_points) h->points = h->width * h->height;
  if (h->points != h->width * h->height)
    return bsurf_fail(err, BSURF_ERR_PARSE, end, -1,
                      "POINTS %llu is not WIDTH x HEIGHT = %llu x %llu", h->points, h->width,
                      h->height);
  size_t columns = 0;
  h->record = 0;
  for (size_t i = 0; i < h->nfields; i++) {
    pcd_field *f = &h->fields[i];
    if (f->kind == 'F' && f->size != 4 && f->size != 8)
      return bsurf_fail(err, BSURF_ERR_PARSE, end, -1,
                        "field '%s': TYPE F needs SIZE 4 or 8, not %zu", io_token_repr(f->name, a),
                        f->size);
    f->offset = h->record;
    h->record += f->size * f->count;
    columns += f->count;
  }
  if (columns > PCD_MAX_COLUMNS)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, end, -1,
                      "%zu values per point is more than the %d supported", columns,
                      PCD_MAX_COLUMNS);
  return BSURF_OK;
}

/* ---- columns --------------------------------------------------------------- */

static bsurf_type field_type(const pcd_field *f, int *wide) {
  *wide = 0;
  if (f->kind == 'F') return f->size == 4 ? BSURF_FLOAT32 : BSURF_FLOAT64;
  int s = f->kind == 'I';
  switch (f->size) {
  case 1: return s ? BSURF_INT8 : BSURF_UINT8;
  case 2: return s ? BSURF_INT16 : BSURF_UINT16;
  case 4: return s ? BSURF_INT32 : BSURF_UINT32;
  default: *wide = 1; return BSURF_FLOAT64;
  }
}

static int name_is(const pcd_field *f, const char *w) {
  return f->count == 1 && io_token_is(f->name, w);
}

/* The columns (one per element) and the cloud's arrays and fields. */
static bsurf_status setup(const pcd_header *h, bsurf_cloud *cloud, pcd_column **out, size_t *ncols,
                          bsurf_failure *err) {
  size_t n = 0;
  for (size_t i = 0; i < h->nfields; i++)
    n += h->fields[i].count;
  pcd_column *cols = calloc(n, sizeof *cols);
  if (!cols) return nomem(err);
  *out = cols;
  *ncols = n;
  int have[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
  static const char *const xyz[3] = {"x", "y", "z"};
  static const char *const nn[3] = {"normal_x", "normal_y", "normal_z"};
  for (size_t i = 0; i < h->nfields; i++)
    for (int k = 0; k < 3; k++) {
      if (name_is(&h->fields[i], xyz[k])) have[k]++;
      if (name_is(&h->fields[i], nn[k])) nrm[k]++;
    }
  if (have[0] != 1 || have[1] != 1 || have[2] != 1)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, -1,
                      "the PCD file needs one each of the fields x, y and z");
  int with_normals = nrm[0] == 1 && nrm[1] == 1 && nrm[2] == 1;
  if (h->points > (size_t)-1 / 24) return nomem(err);
  if (bsurf_cloud_alloc(cloud, (size_t)h->points, with_normals) != BSURF_OK) return nomem(err);
  size_t c = 0;
  for (size_t i = 0; i < h->nfields; i++) {
    const pcd_field *f = &h->fields[i];
    int wide;
    bsurf_type type = field_type(f, &wide);
    /* the name as written (a name bsurf writes has at most 63 characters;
     * io_unique_name shortens a COUNT > 1 element's name to fit its suffix) */
    char base[BSURF_FIELD_NAME_MAX];
    size_t blen = f->name.len < sizeof base - 1 ? f->name.len : sizeof base - 1;
    memcpy(base, f->name.s, blen);
    base[blen] = 0;
    for (size_t q = 0; q < blen; q++) /* a NUL or control byte in a name */
      if ((unsigned char)base[q] < 0x21 || base[q] == 0x7f) base[q] = '_';
    for (size_t e = 0; e < f->count; e++, c++) {
      pcd_column *col = &cols[c];
      col->f = f;
      col->elem = e;
      col->type = type;
      col->wide = wide;
      int k;
      for (k = 0; k < 3 && !name_is(f, xyz[k]); k++) {
      }
      if (k < 3) {
        col->dst = DST_XYZ;
        col->at = (size_t)k;
        cloud->xyz_type = type;
        continue;
      }
      for (k = 0; k < 3 && !name_is(f, nn[k]); k++) {
      }
      if (k < 3 && with_normals) {
        col->dst = DST_NORMAL;
        col->at = (size_t)k;
        cloud->normal_type = type;
        continue;
      }
      if (io_token_is(f->name, "_")) {
        col->dst = DST_SKIP;
        continue;
      }
      int rgba = name_is(f, "rgba");
      if ((name_is(f, "rgb") || rgba) && f->size == 4) {
        static const char *const comp[4] = {"red", "green", "blue", "alpha"};
        col->dst = rgba ? DST_RGBA : DST_RGB;
        col->at = cloud->field_count;
        for (int q = 0; q < (rgba ? 4 : 3); q++) {
          char name[BSURF_FIELD_NAME_MAX];
          io_unique_name(cloud, comp[q], name);
          if (!bsurf_cloud_add_field(cloud, name, BSURF_UINT8)) return nomem(err);
        }
        continue;
      }
      char name[BSURF_FIELD_NAME_MAX], want[BSURF_FIELD_NAME_MAX + 24];
      if (f->count > 1)
        snprintf(want, sizeof want, "%s_%zu", base, e);
      else
        snprintf(want, sizeof want, "%s", base);
      for (char *p = want; *p; p++)
        if ((unsigned char)*p < 0x21 || *p == 0x7f) *p = '_';
      io_unique_name(cloud, want, name);
      col->dst = DST_FIELD;
      col->at = cloud->field_count;
      if (!bsurf_cloud_add_field(cloud, name, type)) return nomem(err);
    }
  }
  return BSURF_OK;
}

/* Stores one element of point i. */
static void store(bsurf_cloud *cloud, const pcd_column *col, size_t i, double v, uint32_t bits) {
  switch (col->dst) {
  case DST_XYZ: cloud->xyz[3 * i + col->at] = v; break;
  case DST_NORMAL: cloud->normals[3 * i + col->at] = v; break;
  case DST_FIELD: cloud->fields[col->at].values[i] = v; break;
  case DST_RGB:
  case DST_RGBA:
    cloud->fields[col->at].values[i] = (double)((bits >> 16) & 0xff);
    cloud->fields[col->at + 1].values[i] = (double)((bits >> 8) & 0xff);
    cloud->fields[col->at + 2].values[i] = (double)(bits & 0xff);
    if (col->dst == DST_RGBA) cloud->fields[col->at + 3].values[i] = (double)(bits >> 24);
    break;
  default: break;
  }
}

/* One binary element; *ok cleared for an 8-byte integer a double cannot hold. */
static double load(const unsigned char *p, const pcd_column *col, uint32_t *bits, int *ok) {
  if (col->f->size == 4) *bits = io_le32(p);
  if (col->wide)
    return col->f->kind == 'I' ? io_i64_exact((int64_t)io_le64(p), ok)
                               : io_u64_exact(io_le64(p), ok);
  return io_le_value(p, col->type);
}

static bsurf_status too_wide(bsurf_failure *err, const pcd_column *col, size_t i) {
  char a[48];
  return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1,
                    "point %zu: the 8-byte integer in field '%s' is beyond 2^53, which a double "
                    "cannot hold exactly",
                    i, io_token_repr(col->f->name, a));
}

static bsurf_status read_binary(const pcd_header *h, const char *data, size_t size,
                                bsurf_cloud *cloud, const pcd_column *cols, size_t ncols,
                                bsurf_failure *err) {
  size_t n = cloud->point_count;
  size_t have = size - h->body;
  if (h->record && n > have / h->record)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)h->body,
                      "POINTS %zu needs %zu bytes of binary data (%zu per point) but the file has "
                      "%zu after the header",
                      n, h->record, h->record, have);
  const unsigned char *body = (const unsigned char *)data + h->body;
  for (size_t i = 0; i < n; i++) {
    const unsigned char *rec = body + i * h->record;
    for (size_t c = 0; c < ncols; c++) {
      const pcd_column *col = &cols[c];
      if (col->dst == DST_SKIP) continue;
      uint32_t bits = 0;
      int ok = 1;
      double v = load(rec + col->f->offset + col->elem * col->f->size, col, &bits, &ok);
      if (!ok) return too_wide(err, col, i);
      store(cloud, col, i, v, bits);
    }
  }
  return BSURF_OK;
}

static bsurf_status read_compressed(const pcd_header *h, const char *data, size_t size,
                                    bsurf_cloud *cloud, const pcd_column *cols, size_t ncols,
                                    bsurf_failure *err) {
  size_t n = cloud->point_count;
  const unsigned char *p = (const unsigned char *)data + h->body;
  size_t have = size - h->body;
  if (have < 8)
    return bsurf_fail(
        err, BSURF_ERR_PARSE, 0, (long long)h->body,
        "binary_compressed data need 8 bytes of sizes, the file has %zu after the header", have);
  size_t csize = io_le32(p), usize = io_le32(p + 4);
  if (h->record && n > (size_t)-1 / h->record) return nomem(err);
  if (usize != n * h->record)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)h->body + 4,
                      "the uncompressed size %zu is not POINTS x record = %zu x %zu", usize, n,
                      h->record);
  if (csize > have - 8)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)h->body,
                      "the compressed size %zu is beyond the file (%zu bytes after the sizes)",
                      csize, have - 8);
  /* an LZF reference of 3 bytes expands to at most 264: anything above that
   * ratio cannot be decompressed, so nothing that large is allocated */
  if (usize / 88 > csize + 1)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)h->body + 4,
                      "%zu compressed bytes cannot expand to %zu", csize, usize);
  unsigned char *raw = malloc(usize ? usize : 1);
  if (!raw) return nomem(err);
  size_t bad = 0;
  size_t got = lzf_decode(p + 8, csize, raw, usize, &bad);
  if (got != usize) {
    free(raw);
    if (got == (size_t)-1)
      return bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)(h->body + 8 + bad),
                        "corrupt LZF data (a reference outside the data)");
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)h->body + 8,
                      "the LZF data expand to %zu bytes, not the %zu declared", got, usize);
  }
  /* field by field: all points' values of field 0, then field 1, ... */
  for (size_t c = 0; c < ncols; c++) {
    const pcd_column *col = &cols[c];
    if (col->dst == DST_SKIP) continue;
    size_t esz = col->f->size * col->f->count;
    const unsigned char *base = raw + n * col->f->offset + col->elem * col->f->size;
    for (size_t i = 0; i < n; i++) {
      uint32_t bits = 0;
      int ok = 1;
      double v = load(base + i * esz, col, &bits, &ok);
      if (!ok) {
        free(raw);
        return too_wide(err, col, i);
      }
      store(cloud, col, i, v, bits);
    }
  }
  free(raw);
  return BSURF_OK;
}

/* An ascii element: a number that the field's type holds (integers in
 * range), or for a packed colour the uint32 PCL writes (or a float's bits). */
static bsurf_status ascii_value(io_token tok, const pcd_column *col, double *v, uint32_t *bits,
                                long ln, bsurf_failure *err) {
  char a[48], b[48];
  if (col->dst == DST_RGB || col->dst == DST_RGBA) {
    unsigned long long u;
    if (io_parse_u64(tok.s, tok.len, &u) && u <= 0xffffffffULL) {
      *bits = (uint32_t)u;
      return BSURF_OK;
    }
    double d;
    if (!io_parse_double(tok.s, tok.len, &d))
      return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "colour '%s' is not a number",
                        io_token_repr(tok, a));
    float f = (float)d;
    memcpy(bits, &f, sizeof *bits);
    return BSURF_OK;
  }
  if (!io_parse_double(tok.s, tok.len, v))
    return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "'%s' (field '%s') is not a number",
                      io_token_repr(tok, a), io_token_repr(col->f->name, b));
  if (col->f->kind != 'F') {
    double lo = 0, hi = 0;
    int s = col->f->kind == 'I';
    switch (col->f->size) {
    case 1:
      lo = s ? -128 : 0;
      hi = s ? 127 : 255;
      break;
    case 2:
      lo = s ? -32768 : 0;
      hi = s ? 32767 : 65535;
      break;
    case 4:
      lo = s ? -2147483648.0 : 0;
      hi = s ? 2147483647.0 : 4294967295.0;
      break;
    default:
      lo = s ? -9007199254740992.0 : 0;
      hi = 9007199254740992.0;
      break;
    }
    if (!(*v == floor(*v)) || *v < lo || *v > hi)
      return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "'%s' is not a %c%zu integer (field '%s')",
                        io_token_repr(tok, a), col->f->kind, col->f->size,
                        io_token_repr(col->f->name, b));
  } else {
    *v = io_type_convert(*v, col->type);
  }
  return BSURF_OK;
}

static bsurf_status read_ascii(const pcd_header *h, const char *data, size_t size,
                               bsurf_cloud *cloud, const pcd_column *cols, size_t ncols,
                               bsurf_failure *err) {
  io_text t;
  io_text_init(&t, data + h->body, size - h->body);
  t.line = h->body_line - 1;
  size_t n = cloud->point_count, i = 0;
  /* every point needs at least two bytes ("0\n"): a count the file cannot
   * hold fails before the work */
  if (n && ncols && n > (size - h->body) / (2 * ncols) + 1)
    return bsurf_fail(
        err, BSURF_ERR_PARSE, h->body_line, -1,
        "POINTS %zu with %zu values each cannot fit in the %zu bytes after the header", n, ncols,
        size - h->body);
  const char *line;
  size_t len;
  while (io_text_next_line(&t, &line, &len)) {
    io_cursor c;
    io_token tok;
    len = io_strip_comment(line, len);
    io_cursor_init(&c, line, len, IO_SEP_SPACE);
    size_t k = io_count_tokens(&c);
    if (k == 0) continue;
    if (i == n)
      return bsurf_fail(err, BSURF_ERR_PARSE, t.line, -1, "more points than POINTS %zu", n);
    if (k != ncols)
      return bsurf_fail(err, BSURF_ERR_PARSE, t.line, -1,
                        "expected %zu values (the header's fields), found %zu", ncols, k);
    for (size_t q = 0; q < ncols; q++) {
      io_next_token(&c, &tok);
      const pcd_column *col = &cols[q];
      if (col->dst == DST_SKIP) continue;
      double v = 0;
      uint32_t bits = 0;
      bsurf_status st = ascii_value(tok, col, &v, &bits, t.line, err);
      if (st != BSURF_OK) return st;
      store(cloud, col, i, v, bits);
    }
    i++;
  }
  if (i < n)
    return bsurf_fail(err, BSURF_ERR_PARSE, t.line + 1, -1,
                      "POINTS %zu but the data end after %zu points", n, i);
  return BSURF_OK;
}

bsurf_status bsurf_io_read_pcd(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_failure *err) {
  pcd_header h;
  memset(&h, 0, sizeof h);
  pcd_column *cols = NULL;
  size_t ncols = 0;
  bsurf_status st = parse_header(data, size, &h, err);
  /* before anything is allocated: can the bytes after the header hold the
   * points? (binary: exactly; compressed: LZF expands at most 88-fold;
   * ascii: at least a byte a point) */
  size_t have = st == BSURF_OK ? size - h.body : 0;
  if (st == BSURF_OK && h.data == 1 && h.points > have / h.record)
    st = bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)h.body,
                    "POINTS %llu needs %llu bytes of binary data (%zu per point) but the file has "
                    "%zu after the header",
                    h.points, h.points * (unsigned long long)h.record, h.record, have);
  if (st == BSURF_OK && h.data == 2 && h.points > (have / h.record + 1) * 88)
    st = bsurf_fail(
        err, BSURF_ERR_PARSE, 0, (long long)h.body,
        "POINTS %llu (%zu bytes each) cannot be in the %zu compressed bytes after the header",
        h.points, h.record, have);
  if (st == BSURF_OK && h.data == 0 && h.points > have)
    st = bsurf_fail(err, BSURF_ERR_PARSE, h.body_line, -1,
                    "POINTS %llu is more than the %zu bytes after the header can hold", h.points,
                    have);
  if (st == BSURF_OK) st = setup(&h, cloud, &cols, &ncols, err);
  if (st == BSURF_OK) {
    if (h.data == 0)
      st = read_ascii(&h, data, size, cloud, cols, ncols, err);
    else if (h.data == 1)
      st = read_binary(&h, data, size, cloud, cols, ncols, err);
    else
      st = read_compressed(&h, data, size, cloud, cols, ncols, err);
  }
  if (st == BSURF_OK) memcpy(cloud->shape, h.shape, sizeof cloud->shape);
  free(cols);
  free(h.fields);
  return st;
}

/* ---- writer ---------------------------------------------------------------- */

typedef struct pcd_out {
  const char *name; /* header name */
  char kind;
  size_t size;
  size_t count;
  const double *src[PCD_MAX_COUNT_OUT]; /* element sources */
  size_t stride;
  bsurf_type type;
  int rgb; /* packed colour: src[0..2] red green blue, src[3] alpha or NULL */
} pcd_out;

static void type_code(bsurf_type t, char *kind, size_t *size) {
  switch (t) {
  case BSURF_INT8:
    *kind = 'I';
    *size = 1;
    break;
  case BSURF_UINT8:
    *kind = 'U';
    *size = 1;
    break;
  case BSURF_INT16:
    *kind = 'I';
    *size = 2;
    break;
  case BSURF_UINT16:
    *kind = 'U';
    *size = 2;
    break;
  case BSURF_INT32:
    *kind = 'I';
    *size = 4;
    break;
  case BSURF_UINT32:
    *kind = 'U';
    *size = 4;
    break;
  case BSURF_FLOAT32:
    *kind = 'F';
    *size = 4;
    break;
  default:
    *kind = 'F';
    *size = 8;
    break;
  }
}

/* 1 if the field holds integers 0..255 at every point. */
static int is_byte_field(const bsurf_field *f, size_t n) {
  if (!f) return 0;
  for (size_t i = 0; i < n; i++)
    if (!(f->values[i] >= 0 && f->values[i] <= 255 && f->values[i] == floor(f->values[i])))
      return 0;
  return 1;
}

/* Length of the name's base when it ends in "_<digits>" (else 0), and the number. */
static size_t split_index(const char *name, unsigned long *index) {
  size_t n = strlen(name), i = n;
  while (i > 0 && name[i - 1] >= '0' && name[i - 1] <= '9')
    i--;
  if (i == n || i < 2 || name[i - 1] != '_' || n - i > 6) return 0;
  if (name[i] == '0' && n - i > 1) return 0;
  *index = strtoul(name + i, NULL, 10);
  return i - 1;
}

bsurf_status bsurf_io_write_pcd(io_writer *w, const bsurf_cloud *cloud, int ascii,
                                bsurf_failure *err) {
  size_t n = cloud->point_count;
  size_t nf = cloud->field_count;
  pcd_out *outs = bsurf_alloc_array(nf + 7, sizeof *outs); /* x y z, normals, rgb, fields */
  char(*names)[BSURF_FIELD_NAME_MAX] = bsurf_alloc_array(nf + 1, sizeof *names);
  if (!outs || !names) {
    free(outs);
    free(names);
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  }
  size_t no = 0;
  static const char *const xyz[3] = {"x", "y", "z"}, *const nn[3] = {"normal_x", "normal_y",
                                                                     "normal_z"};
  for (int k = 0; k < 3; k++) {
    pcd_out *o = &outs[no++];
    memset(o, 0, sizeof *o);
    o->name = xyz[k];
    o->count = 1;
    o->src[0] = cloud->xyz ? cloud->xyz + k : NULL;
    o->stride = 3;
    o->type = cloud->xyz_type;
  }
  if (cloud->normals)
    for (int k = 0; k < 3; k++) {
      pcd_out *o = &outs[no++];
      memset(o, 0, sizeof *o);
      o->name = nn[k];
      o->count = 1;
      o->src[0] = cloud->normals + k;
      o->stride = 3;
      o->type = cloud->normal_type;
    }
  /* red green blue (alpha) holding bytes: PCL's packed colour */
  const bsurf_field *r = bsurf_cloud_field(cloud, "red"), *g = bsurf_cloud_field(cloud, "green"),
                    *b = bsurf_cloud_field(cloud, "blue"), *al = bsurf_cloud_field(cloud, "alpha");
  int packed = is_byte_field(r, n) && is_byte_field(g, n) && is_byte_field(b, n);
  if (packed && !is_byte_field(al, n)) al = NULL;
  if (packed) {
    pcd_out *o = &outs[no++];
    memset(o, 0, sizeof *o);
    o->name = al ? "rgba" : "rgb";
    o->count = 1;
    o->rgb = 1;
    o->src[0] = r->values;
    o->src[1] = g->values;
    o->src[2] = b->values;
    o->src[3] = al ? al->values : NULL;
    o->stride = 1;
    o->type = al ? BSURF_UINT32 : BSURF_FLOAT32;
  }
  for (size_t i = 0; i < nf; i++) {
    const bsurf_field *f = &cloud->fields[i];
    if (packed && (f == r || f == g || f == b || f == al)) continue;
    pcd_out *o = &outs[no++];
    memset(o, 0, sizeof *o);
    o->name = f->name;
    o->count = 1;
    o->src[0] = f->values;
    o->stride = 1;
    o->type = f->type;
    /* base_0 base_1 ... of one type in a row: one field with COUNT k */
    unsigned long idx;
    size_t bl = split_index(f->name, &idx);
    if (bl && idx == 0) {
      size_t k = 1;
      while (i + k < nf && k < PCD_MAX_COUNT_OUT) {
        const bsurf_field *q = &cloud->fields[i + k];
        unsigned long qi;
        size_t ql = split_index(q->name, &qi);
        if (ql != bl || memcmp(q->name, f->name, bl) != 0 || qi != k || q->type != f->type) break;
        if (packed && (q == r || q == g || q == b || q == al)) break;
        o->src[k] = q->values;
        k++;
      }
      if (k > 1) {
        memcpy(names[i], f->name, bl);
        names[i][bl] = 0;
        o->name = names[i];
        o->count = k;
        i += k - 1;
      }
    }
  }
  for (size_t j = 0; j < no; j++)
    type_code(outs[j].type, &outs[j].kind, &outs[j].size);

  io_write_str(w, "# .PCD v0.7 - Point Cloud Data file format (written by bootsurf)\n");
  const char *shape_end = memchr(cloud->shape, 0, sizeof cloud->shape);
  if (shape_end && shape_end != cloud->shape && !strpbrk(cloud->shape, " \t\r\n"))
    io_write_fmt(w, "# bootsurf shape %s\n", cloud->shape);
  io_write_str(w, "VERSION 0.7\nFIELDS");
  for (size_t j = 0; j < no; j++)
    io_write_fmt(w, " %s", outs[j].name);
  io_write_str(w, "\nSIZE");
  for (size_t j = 0; j < no; j++)
    io_write_fmt(w, " %zu", outs[j].size);
  io_write_str(w, "\nTYPE");
  for (size_t j = 0; j < no; j++)
    io_write_fmt(w, " %c", outs[j].kind);
  io_write_str(w, "\nCOUNT");
  for (size_t j = 0; j < no; j++)
    io_write_fmt(w, " %zu", outs[j].count);
  io_write_fmt(w, "\nWIDTH %zu\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %zu\nDATA %s\n", n, n,
               ascii ? "ascii" : "binary");

  size_t rec = 0;
  for (size_t j = 0; j < no; j++)
    rec += outs[j].size * outs[j].count;
  bsurf_status st = BSURF_OK;
  if (ascii) {
    io_obuf ob;
    if (io_obuf_init(&ob, w) != BSURF_OK) {
      st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
    } else {
      for (size_t i = 0; i < n && !w->failed; i++) {
        for (size_t j = 0; j < no; j++) {
          const pcd_out *o = &outs[j];
          for (size_t e = 0; e < o->count; e++) {
            if (j || e) io_obuf_char(&ob, ' ');
            if (o->rgb) {
              uint32_t u = (uint32_t)o->src[0][i] << 16 | (uint32_t)o->src[1][i] << 8 |
                           (uint32_t)o->src[2][i];
              if (o->src[3]) u |= (uint32_t)o->src[3][i] << 24;
              io_obuf_uint(&ob, u); /* PCL writes a packed colour as its uint32 */
            } else {
              io_obuf_value(&ob, o->src[e][i * o->stride], o->type);
            }
          }
        }
        io_obuf_char(&ob, '\n');
      }
      io_obuf_done(&ob);
    }
  } else if (n) {
    size_t cap = (size_t)1 << 20;
    if (cap < rec) cap = rec;
    unsigned char *buf = malloc(cap);
    if (!buf) {
      st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
    } else {
      size_t per = cap / rec;
      for (size_t i0 = 0; i0 < n && !w->failed; i0 += per) {
        size_t i1 = i0 + per < n ? i0 + per : n;
        unsigned char *p = buf;
        for (size_t i = i0; i < i1; i++)
          for (size_t j = 0; j < no; j++) {
            const pcd_out *o = &outs[j];
            if (o->rgb) {
              /* alpha 255 when there is none, as PCL's PointXYZRGB */
              uint32_t u = (uint32_t)o->src[0][i] << 16 | (uint32_t)o->src[1][i] << 8 |
                           (uint32_t)o->src[2][i];
              u |= o->src[3] ? (uint32_t)o->src[3][i] << 24 : 0xff000000u;
              for (int q = 0; q < 4; q++)
                *p++ = (unsigned char)(u >> (8 * q));
              continue;
            }
            for (size_t e = 0; e < o->count; e++)
              p = io_put_le(p, o->src[e][i * o->stride], o->type);
          }
        io_write_bytes(w, buf, (size_t)(p - buf));
      }
      free(buf);
    }
  }
  free(outs);
  free(names);
  return st;
}
