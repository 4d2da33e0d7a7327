/* PCD (the Point Cloud Library's point cloud data format, v0.7): reads
 * DATA ascii, binary and binary_compressed (LZF, decompressed by lzf_decode
 * in pcd_read.c: docs/formats.md says why it is written here), every TYPE/SIZE/COUNT
 * (I U F of 1, 2, 4, 8 bytes; a field with COUNT n > 1 becomes the fields
 * name_0 .. name_{n-1}); writes ascii and binary.
 *
 * Names: x y z are the coordinates, normal_x normal_y normal_z the normals;
 * PCL's packed colour (`rgb`, 4 bytes, 0x00RRGGBB in the bits of a float, or
 * `rgba` with alpha in the top byte) becomes the uint8 fields red green blue
 * (and alpha), and is written back packed; `_` (PCL's padding) is skipped.
 * Like the PLY reader, the header is never trusted: counts times record
 * sizes are checked against the bytes there before anything is allocated. */
/* This file: the header (pcd_read.c reads the data, pcd_write.c writes). */
#include "io/pcd.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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

/* ---- header ---------------------------------------------------------------- */

/* "# bootsurf shape NAME" (bsurf_cloud.shape); other comments are ignored. */
static void comment_line(io_token kw, io_cursor *c, pcd_header *h) {
  io_token w1, w2, name, extra;
  if (io_token_is(kw, "#") && io_next_token(c, &w1) && io_token_is(w1, "bootsurf") &&
      io_next_token(c, &w2) && io_token_is(w2, "shape") && io_next_token(c, &name) &&
      !io_next_token(c, &extra) && name.len < BSURF_FIELD_NAME_MAX) {
    memcpy(h->shape, name.s, name.len);
    h->shape[name.len] = 0;
  }
}

static bsurf_status version_line(io_cursor *c, long ln, bsurf_failure *err) {
  io_token tok;
  char a[48];
  if (!io_next_token(c, &tok))
    return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "VERSION without a version");
  double v;
  if (!io_parse_double(tok.s, tok.len, &v) || v < 0.5 || v > 0.7 + 1e-9)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, ln, -1,
                      "PCD version '%s' is not supported (expected 0.7 or earlier)",
                      io_token_repr(tok, a));
  return BSURF_OK;
}

/* FIELDS (or COLUMNS, PCD 0.5): the names; SIZE 4, TYPE F, COUNT 1 until
 * those lines say otherwise. */
static bsurf_status fields_line(io_cursor *c, pcd_header *h, long ln, bsurf_failure *err) {
  char a[48];
  if (h->fields) return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "a second FIELDS line");
  size_t k = io_count_tokens(c);
  if (k == 0) return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "FIELDS names no field");
  if (k > PCD_MAX_FIELDS)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, ln, -1,
                      "%zu fields is more than the %d supported", k, PCD_MAX_FIELDS);
  h->fields = calloc(k, sizeof *h->fields);
  if (!h->fields) return io_nomem(err);
  h->nfields = k;
  for (size_t i = 0; i < k; i++) {
    pcd_field *f = &h->fields[i];
    io_next_token(c, &f->name);
    f->count = 1;
    f->size = 4;
    f->kind = 'F';
    if (f->name.len >= BSURF_FIELD_NAME_MAX)
      return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, ln, -1, "field name '%s' is too long",
                        io_token_repr(f->name, a));
  }
  return BSURF_OK;
}

/* SIZE, TYPE or COUNT: one entry per field (after FIELDS), each checked:
 * SIZE 1 2 4 8, TYPE I U F, COUNT 1 .. PCD_MAX_COLUMNS. */
static bsurf_status per_field_line(io_cursor *c, pcd_header *h, long ln, const char *kw,
                                   bsurf_failure *err) {
  char a[48], expected[32];
  if (!h->fields) return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "%s before FIELDS", kw);
  size_t k = io_count_tokens(c);
  if (k != h->nfields)
    return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "%s has %zu entries for %zu FIELDS", kw, k,
                      h->nfields);
  int which = kw[0] == 'S' ? 0 : kw[0] == 'T' ? 1 : 2;
  for (size_t i = 0; i < h->nfields; i++) {
    pcd_field *f = &h->fields[i];
    io_token tok;
    unsigned long long v = 0;
    io_next_token(c, &tok);
    int ok = which == 1 ? tok.len == 1 && (tok.s[0] == 'I' || tok.s[0] == 'U' || tok.s[0] == 'F')
                        : io_parse_u64(tok.s, tok.len, &v);
    if (which == 0) ok = ok && (v == 1 || v == 2 || v == 4 || v == 8);
    if (which == 2) ok = ok && v >= 1 && v <= PCD_MAX_COLUMNS;
    if (!ok) {
      if (which == 2) snprintf(expected, sizeof expected, "between 1 and %d", PCD_MAX_COLUMNS);
      return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "%s '%s' of field %zu is not %s", kw,
                        io_token_repr(tok, a), i + 1,
                        which == 0   ? "1, 2, 4 or 8"
                        : which == 1 ? "I, U or F"
                                     : expected);
    }
    if (which == 0) f->size = (size_t)v;
    if (which == 1) f->kind = tok.s[0];
    if (which == 2) f->count = (size_t)v;
  }
  if (which == 0) h->have_size = 1; /* COUNT may be left out: 1 each */
  if (which == 1) h->have_type = 1;
  return BSURF_OK;
}

/* WIDTH, HEIGHT or POINTS: one non-negative integer. */
static bsurf_status number_line(io_token kw, io_cursor *c, pcd_header *h, long ln,
                                bsurf_failure *err) {
  unsigned long long v;
  io_token tok, extra;
  if (!io_next_token(c, &tok) || io_next_token(c, &extra) || !io_parse_u64(tok.s, tok.len, &v))
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
  return BSURF_OK;
}

/* VIEWPOINT: the sensor pose, kept by PCL, not by bootsurf; 7 numbers. */
static bsurf_status viewpoint_line(io_cursor *c, long ln, bsurf_failure *err) {
  char a[48];
  size_t k = io_count_tokens(c);
  if (k != 7)
    return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "VIEWPOINT has %zu numbers, not 7", k);
  for (int i = 0; i < 7; i++) {
    double v;
    io_token tok;
    io_next_token(c, &tok);
    if (!io_parse_double(tok.s, tok.len, &v))
      return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "VIEWPOINT value '%s' is not a number",
                        io_token_repr(tok, a));
  }
  return BSURF_OK;
}

/* DATA ascii | binary | binary_compressed (any case): the last header line. */
static bsurf_status data_line(io_cursor *c, pcd_header *h, long ln, bsurf_failure *err) {
  char a[48];
  io_token tok, extra;
  if (!io_next_token(c, &tok) || io_next_token(c, &extra))
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
  return BSURF_OK;
}

/* The header read up to its DATA line (line `end`): every line it needs, the
 * counts consistent, the record's layout. */
static bsurf_status check_header(pcd_header *h, long end, bsurf_failure *err) {
  char a[48];
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

bsurf_status io_pcd_parse_header(const char *data, size_t size, pcd_header *h, bsurf_failure *err) {
  io_text t;
  io_text_init(&t, data, size);
  const char *line;
  size_t len;
  char a[48];
  if (size == 0)
    return bsurf_fail(err, BSURF_ERR_PARSE, 1, -1, "not a PCD file: the file is empty");
  while (io_text_next_line(&t, &line, &len)) {
    long ln = t.line;
    io_cursor c;
    io_token kw;
    io_cursor_init(&c, line, len, IO_SEP_SPACE);
    if (!io_next_token(&c, &kw)) continue;
    bsurf_status st = BSURF_OK;
    if (kw.s[0] == '#')
      comment_line(kw, &c, h);
    else if (io_token_is(kw, "VERSION"))
      st = version_line(&c, ln, err);
    else if (io_token_is(kw, "FIELDS") || io_token_is(kw, "COLUMNS"))
      st = fields_line(&c, h, ln, err);
    else if (io_token_is(kw, "SIZE") || io_token_is(kw, "TYPE") || io_token_is(kw, "COUNT"))
      st = per_field_line(&c, h, ln,
                          kw.s[0] == 'S'   ? "SIZE"
                          : kw.s[0] == 'T' ? "TYPE"
                                           : "COUNT",
                          err);
    else if (io_token_is(kw, "WIDTH") || io_token_is(kw, "HEIGHT") || io_token_is(kw, "POINTS"))
      st = number_line(kw, &c, h, ln, err);
    else if (io_token_is(kw, "VIEWPOINT"))
      st = viewpoint_line(&c, ln, err);
    else if (io_token_is(kw, "DATA")) {
      st = data_line(&c, h, ln, err);
      if (st != BSURF_OK) return st;
      h->body = t.pos;
      h->body_line = t.line + 1;
      return check_header(h, t.line, err);
    } else
      return bsurf_fail(err, BSURF_ERR_PARSE, ln, -1, "not a PCD header line: unknown keyword '%s'",
                        io_token_repr(kw, a));
    if (st != BSURF_OK) return st;
  }
  long end = t.line ? t.line : 1;
  if (!h->fields)
    return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "not a PCD file: no FIELDS and no DATA line");
  return bsurf_fail(err, BSURF_ERR_PARSE, end, -1, "the header ends without a DATA line");
}
