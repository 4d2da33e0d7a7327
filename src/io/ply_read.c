/* PLY reading, part 2: the binary and ascii data of the elements the header
 * declared (ply_header.c), the reader's entry points and the mapped vertex
 * layout of the tiled runs. */
#include "io/ply_reader.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define PLY_HOST_LE 1
#else
#define PLY_HOST_LE 0
#endif

static inline double get_value(const unsigned char *p, bsurf_type type, int be) {
  if (PLY_HOST_LE && !be && type == BSURF_FLOAT64) { /* the file's bytes are the host's double */
    double d;
    memcpy(&d, p, sizeof d);
    return d;
  }
  if (PLY_HOST_LE && !be && type == BSURF_FLOAT32) {
    float f;
    memcpy(&f, p, sizeof f);
    return f;
  }
  switch (type) {
  case BSURF_INT8: return p[0] >= 0x80 ? (double)p[0] - 256.0 : (double)p[0];
  case BSURF_UINT8: return p[0];
  case BSURF_INT16:
  case BSURF_UINT16: {
    unsigned u = be ? (unsigned)p[0] << 8 | p[1] : (unsigned)p[1] << 8 | p[0];
    if (type == BSURF_INT16 && u >= 0x8000u) return (double)u - 65536.0;
    return u;
  }
  case BSURF_INT32:
  case BSURF_UINT32:
  case BSURF_FLOAT32: {
    uint32_t u = be ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]
                    : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
    if (type == BSURF_UINT32) return u;
    if (type == BSURF_INT32) return u >= 0x80000000u ? (double)u - 4294967296.0 : (double)u;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
  }
  case BSURF_FLOAT64:
  default: {
    uint64_t u = 0;
    for (int i = 0; i < 8; i++)
      u = u << 8 | p[be ? i : 7 - i];
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
  }
  }
}

/* A face index must be an integer in [0, nv). */
static bsurf_status check_index(ply_reader *r, const ply_elem *e, unsigned long long rec, double v,
                                long line, long long byte, uint32_t *out) {
  char a[48];
  if (!(v >= 0 && v < (double)r->nv && v == floor(v)))
    return bsurf_fail(r->err, BSURF_ERR_PARSE, line, byte,
                      "%s %llu: vertex index %.17g is out of range (the file has %llu vertices)",
                      io_ply_elem_word(e, a), rec, v, r->nv);
  *out = (uint32_t)v;
  return BSURF_OK;
}

static bsurf_status read_binary(ply_reader *r) {
  const unsigned char *d = (const unsigned char *)r->data;
  size_t pos = r->body;
  int be = r->format == PLY_BE;
  char a[48];
  for (size_t ei = 0; ei < r->nelems; ei++) {
    ply_elem *e = &r->elems[ei];
    if (e->count == 0 || e->nprops == 0) continue;
    if (!e->has_list) {
      /* fixed-size records (io_ply_setup() checked their minimum, but a list
       * element before them may have taken more than its minimum) */
      size_t rec = e->min_record;
      if (e->count > (r->size - pos) / rec) return io_ply_too_short(r, e, pos, r->size - pos);
      if (e->kind == ELEM_VERTEX && r->layout) {
        r->layout->body = pos;
      } else if (e->kind == ELEM_VERTEX) {
        size_t n = (size_t)e->count;
        const unsigned char *p = d + pos;
        for (size_t i = 0; i < n; i++, p += rec)
          for (size_t j = 0; j < e->nprops; j++) {
            const ply_prop *q = &e->props[j];
            if (q->dst) q->dst[i * q->stride] = get_value(p + q->offset, q->type, be);
          }
      }
      pos += (size_t)e->count * rec;
      continue;
    }
    for (unsigned long long ri = 0; ri < e->count; ri++) {
      size_t start = pos;
      for (size_t j = 0; j < e->nprops; j++) {
        const ply_prop *q = &e->props[j];
        size_t s = io_type_size(q->is_list ? q->count_type : q->type);
        if (r->size - pos < s)
          return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)pos,
                            "%s %llu: the file ends in the middle of the record",
                            io_ply_elem_word(e, a), ri);
        if (!q->is_list) {
          pos += s;
          continue;
        }
        double cnt = get_value(d + pos, q->count_type, be);
        pos += s;
        if (cnt < 0)
          return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)start,
                            "%s %llu: negative list length %.0f", io_ply_elem_word(e, a), ri, cnt);
        unsigned long long n = (unsigned long long)cnt;
        size_t is = io_type_size(q->type);
        if (n > (r->size - pos) / is)
          return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)pos,
                            "%s %llu: a list of %llu values needs %llu bytes but only %zu "
                            "bytes follow",
                            io_ply_elem_word(e, a), ri, n, n * is, r->size - pos);
        if (q->is_index) {
          io_faces_begin(&r->faces);
          for (unsigned long long k = 0; k < n; k++) {
            uint32_t idx = 0;
            bsurf_status st = check_index(r, e, ri, get_value(d + pos + k * is, q->type, be), 0,
                                          (long long)start, &idx);
            if (st != BSURF_OK) return st;
            if (io_faces_corner(&r->faces, idx) != BSURF_OK) return io_ply_nomem(r);
          }
        }
        pos += (size_t)n * is;
      }
    }
  }
  /* Bytes after the last element mean the header does not describe the
   * data (e.g. a writer that declares uchar and writes float): only a
   * trailing line break or spaces are tolerated. */
  for (size_t i = pos; i < r->size; i++) {
    char ch = r->data[i];
    if (ch != '\n' && ch != '\r' && ch != ' ' && ch != '\t')
      return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)pos,
                        "%zu bytes of data follow the last element declared in the header: "
                        "the header does not describe the data",
                        r->size - pos);
  }
  return BSURF_OK;
}

/* ------------------------------------------------------------------------ */
/* ASCII data                                                                */
/* ------------------------------------------------------------------------ */

static int is_blank(const char *s, size_t len) {
  io_cursor c;
  io_token t;
  io_cursor_init(&c, s, len, IO_SEP_SPACE);
  return !io_next_token(&c, &t);
}

static bsurf_status short_record(ply_reader *r, const ply_elem *e, unsigned long long ri,
                                 size_t need, int at_least, const io_cursor *line_start,
                                 long line) {
  char a[48];
  return bsurf_fail(r->err, BSURF_ERR_PARSE, line, -1, "%s %llu: expected %s%zu values, found %zu",
                    io_ply_elem_word(e, a), ri, at_least ? "at least " : "", need,
                    io_count_tokens(line_start));
}

static bsurf_status read_ascii(ply_reader *r) {
  io_text t;
  io_text_init(&t, r->data, r->size);
  t.pos = r->body;
  t.line = r->body_line - 1;
  const char *line;
  size_t len;
  char a[48], b[64];

  for (size_t ei = 0; ei < r->nelems; ei++) {
    ply_elem *e = &r->elems[ei];
    if (e->nprops == 0) continue;
    /* the last list property (a record is short "at least" before it) */
    size_t last_list = 0;
    for (size_t k = 0; k < e->nprops; k++)
      if (e->props[k].is_list) last_list = k + 1;
    for (unsigned long long ri = 0; ri < e->count; ri++) {
      do {
        if (!io_text_next_line(&t, &line, &len))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line + 1, -1,
                            "%s %llu: unexpected end of file (header declares %llu %s)",
                            io_ply_elem_word(e, a), ri, e->count, io_ply_elem_plural(e, b));
      } while (is_blank(line, len));
      io_cursor c0, c;
      io_cursor_init(&c0, line, len, IO_SEP_SPACE);
      c = c0;
      io_token tok;
      size_t used = 0;
      for (size_t j = 0; j < e->nprops; j++) {
        const ply_prop *q = &e->props[j];
        int later_list = last_list > j + 1;
        double v;
        if (!io_next_token(&c, &tok))
          return short_record(r, e, ri, used + (e->nprops - j), later_list || q->is_list, &c0,
                              t.line);
        used++;
        if (!io_parse_double(tok.s, tok.len, &v))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1, "%s %llu: '%s' is not a number",
                            io_ply_elem_word(e, a), ri, io_token_repr(tok, b));
        if (!q->is_list) {
          /* the value the declared type holds, as binary data would give */
          if (q->dst) q->dst[ri * q->stride] = io_type_convert(v, q->type);
          continue;
        }
        if (!(v >= 0 && v == floor(v) && v <= 4294967295.0))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1,
                            "%s %llu: list length '%s' is not a non-negative integer",
                            io_ply_elem_word(e, a), ri, io_token_repr(tok, b));
        unsigned long long n = (unsigned long long)v;
        if (q->is_index) io_faces_begin(&r->faces);
        for (unsigned long long k = 0; k < n; k++) {
          if (!io_next_token(&c, &tok))
            return short_record(r, e, ri, used + (size_t)(n - k) + (e->nprops - j - 1), later_list,
                                &c0, t.line);
          used++;
          if (!io_parse_double(tok.s, tok.len, &v))
            return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1, "%s %llu: '%s' is not a number",
                              io_ply_elem_word(e, a), ri, io_token_repr(tok, b));
          if (q->is_index) {
            uint32_t idx = 0;
            bsurf_status st = check_index(r, e, ri, v, t.line, -1, &idx);
            if (st != BSURF_OK) return st;
            if (io_faces_corner(&r->faces, idx) != BSURF_OK) return io_ply_nomem(r);
          }
        }
      }
      if (io_next_token(&c, &tok))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1,
                          "%s %llu: expected %zu values, found %zu", io_ply_elem_word(e, a), ri,
                          used, io_count_tokens(&c0));
    }
  }
  while (io_text_next_line(&t, &line, &len)) {
    io_cursor c;
    io_token tok;
    io_cursor_init(&c, line, len, IO_SEP_SPACE);
    if (io_next_token(&c, &tok))
      return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1,
                        "unexpected data after the last element declared in the header: '%s'",
                        io_token_repr(tok, a));
  }
  return BSURF_OK;
}

/* ------------------------------------------------------------------------ */
/* Reader entry point                                                        */
/* ------------------------------------------------------------------------ */

bsurf_status bsurf_io_read_ply(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_failure *err) {
  ply_reader r;
  memset(&r, 0, sizeof r);
  r.data = data;
  r.size = size;
  r.err = err;
  io_faces_init(&r.faces);
  bsurf_status st = io_ply_parse_header(&r);
  if (st == BSURF_OK) st = io_ply_setup(&r, cloud);
  if (st == BSURF_OK) st = r.format == PLY_ASCII ? read_ascii(&r) : read_binary(&r);
  if (st == BSURF_OK && r.dry) {
    if (err) *err = r.dry_err;
    st = BSURF_ERR_PARSE;
  }
  if (st == BSURF_OK) {
    io_faces_move(&r.faces, cloud);
    memcpy(cloud->shape, r.shape, sizeof cloud->shape);
  }
  io_faces_free(&r.faces);
  for (size_t i = 0; i < r.nelems; i++)
    free(r.elems[i].props);
  free(r.elems);
  return st;
}

bsurf_status io_ply_probe(const char *data, size_t size, unsigned long long file_size,
                          unsigned long long *vertices, int *ascii_short, bsurf_failure *err) {
  ply_reader r;
  memset(&r, 0, sizeof r);
  r.data = data;
  r.size = size;
  r.err = err;
  r.probe = 1;
  *vertices = 0;
  *ascii_short = 0;
  bsurf_status st = io_ply_parse_header(&r);
  if (st == BSURF_OK) {
    bsurf_cloud unused;
    bsurf_cloud_init(&unused);
    r.size = file_size > size ? (size_t)file_size : size; /* the checks count the whole file */
    st = io_ply_setup(&r, &unused);
    if (st == BSURF_OK) *vertices = r.nv;
    *ascii_short = r.dry;
  }
  for (size_t i = 0; i < r.nelems; i++)
    free(r.elems[i].props);
  free(r.elems);
  return st;
}

bsurf_status io_ply_map(const char *data, size_t size, io_ply_layout *layout, bsurf_cloud *schema,
                        bsurf_failure *err) {
  ply_reader r;
  memset(&r, 0, sizeof r);
  memset(layout, 0, sizeof *layout);
  bsurf_cloud_init(schema);
  r.data = data;
  r.size = size;
  r.err = err;
  r.layout = layout;
  io_faces_init(&r.faces);
  bsurf_status st = io_ply_parse_header(&r);
  if (st == BSURF_OK && r.format == PLY_ASCII)
    st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1,
                    "an ascii PLY file; tiled runs read binary PLY (convert it first)");
  for (size_t i = 0; st == BSURF_OK && i < r.nelems; i++)
    if (io_token_is(r.elems[i].name, "face") && r.elems[i].count)
      st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, r.elems[i].line, -1,
                      "the file is a mesh (it has faces); tiled runs take point clouds");
  if (st == BSURF_OK) st = io_ply_setup(&r, schema);
  if (st == BSURF_OK) st = read_binary(&r);
  if (st == BSURF_OK) {
    memcpy(schema->shape, r.shape, sizeof schema->shape);
    if (layout->count) io_ply_decode(layout, data, 0, schema, 0);
  }
  io_faces_free(&r.faces);
  for (size_t i = 0; i < r.nelems; i++)
    free(r.elems[i].props);
  free(r.elems);
  if (st != BSURF_OK) {
    io_ply_layout_free(layout);
    bsurf_cloud_free(schema);
  }
  return st;
}

void io_ply_layout_free(io_ply_layout *layout) {
  free(layout->props);
  memset(layout, 0, sizeof *layout);
}

void io_ply_xyz(const io_ply_layout *L, const char *data, size_t i, double p[3]) {
  const unsigned char *rec = (const unsigned char *)data + L->body + i * L->record;
  for (size_t q = 0; q < L->nprops; q++)
    if (L->props[q].array == 0)
      p[L->props[q].at] = get_value(rec + L->props[q].offset, L->props[q].type, L->big_endian);
}

void io_ply_decode(const io_ply_layout *L, const char *data, size_t i, bsurf_cloud *c, size_t j) {
  const unsigned char *p = (const unsigned char *)data + L->body + i * L->record;
  for (size_t q = 0; q < L->nprops; q++) {
    const io_ply_column *col = &L->props[q];
    if (col->array == 3) continue; /* not read (MeshLab's quality copy) */
    double v = get_value(p + col->offset, col->type, L->big_endian);
    double *dst = col->array == 0   ? c->xyz + 3 * j + col->at
                  : col->array == 1 ? c->normals + 3 * j + col->at
                                    : c->fields[col->at].values + j;
    *dst = v;
  }
}
