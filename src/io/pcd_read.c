/* PCD reading: the data of the header pcd_header.c parsed (ascii, binary,
 * binary_compressed) into the cloud's coordinates, normals and fields. */
#include "io/pcd.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
  if (!cols) return io_nomem(err);
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
  if (h->points > (size_t)-1 / 24) return io_nomem(err);
  if (bsurf_cloud_alloc(cloud, (size_t)h->points, with_normals) != BSURF_OK) return io_nomem(err);
  io_names fields; /* a field per column, 3 more for an rgb, rgba column */
  if (io_names_init(&fields, cloud, n + 3 * h->nfields) != BSURF_OK) return io_nomem(err);
  size_t c = 0;
  for (size_t i = 0; i < h->nfields; i++) {
    const pcd_field *f = &h->fields[i];
    int wide;
    bsurf_type type = field_type(f, &wide);
    /* the name as written (a name bsurf writes has at most 63 characters;
     * io_names_add shortens a COUNT > 1 element's name to fit its suffix) */
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
        for (int q = 0; q < (rgba ? 4 : 3); q++) {
          size_t at = io_names_add(&fields, comp[q], BSURF_UINT8);
          if (q == 0) col->at = at;
        }
        continue;
      }
      char want[BSURF_FIELD_NAME_MAX + 24];
      if (f->count > 1)
        snprintf(want, sizeof want, "%s_%zu", base, e);
      else
        snprintf(want, sizeof want, "%s", base);
      for (char *p = want; *p; p++)
        if ((unsigned char)*p < 0x21 || *p == 0x7f) *p = '_';
      col->dst = DST_FIELD;
      col->at = io_names_add(&fields, want, type);
    }
  }
  return io_names_commit(&fields, cloud) == BSURF_OK ? BSURF_OK : io_nomem(err);
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
  if (h->record && n > (size_t)-1 / h->record) return io_nomem(err);
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
  if (!raw) return io_nomem(err);
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
  bsurf_status st = io_pcd_parse_header(data, size, &h, err);
  /* before anything is allocated: can the bytes after the header hold the
   * points? (binary: exactly; compressed: LZF expands at most 88-fold;
   * ascii: every value at least two bytes, "0\n") */
  size_t have = st == BSURF_OK ? size - h.body : 0, values = 0;
  for (size_t i = 0; st == BSURF_OK && i < h.nfields; i++)
    values += h.fields[i].count; /* at most PCD_MAX_COLUMNS each */
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
  if (st == BSURF_OK && h.data == 0 && h.points && values && h.points > have / (2 * values) + 1)
    st = bsurf_fail(err, BSURF_ERR_PARSE, h.body_line, -1,
                    "POINTS %llu with %zu values each cannot fit in the %zu bytes after the header",
                    h.points, values, have);
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
