/* Field value types: sizes, names, conversion into a type's range; and the
 * buffered text output of the writers. */
#include "io/io.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Value types                                                               */
/* ------------------------------------------------------------------------ */

size_t io_type_size(bsurf_type type) {
  switch (type) {
  case BSURF_INT8:
  case BSURF_UINT8: return 1;
  case BSURF_INT16:
  case BSURF_UINT16: return 2;
  case BSURF_INT32:
  case BSURF_UINT32:
  case BSURF_FLOAT32: return 4;
  case BSURF_FLOAT64: return 8;
  }
  return 8;
}

const char *io_type_name(bsurf_type type) {
  switch (type) {
  case BSURF_INT8: return "char";
  case BSURF_UINT8: return "uchar";
  case BSURF_INT16: return "short";
  case BSURF_UINT16: return "ushort";
  case BSURF_INT32: return "int";
  case BSURF_UINT32: return "uint";
  case BSURF_FLOAT32: return "float";
  case BSURF_FLOAT64: return "double";
  }
  return "double";
}

int io_type_parse(const char *s, size_t len, bsurf_type *type) {
  static const struct {
    const char *name;
    bsurf_type type;
  } names[] = {{"char", BSURF_INT8},      {"uchar", BSURF_UINT8},    {"short", BSURF_INT16},
               {"ushort", BSURF_UINT16},  {"int", BSURF_INT32},      {"uint", BSURF_UINT32},
               {"float", BSURF_FLOAT32},  {"double", BSURF_FLOAT64}, {"int8", BSURF_INT8},
               {"uint8", BSURF_UINT8},    {"int16", BSURF_INT16},    {"uint16", BSURF_UINT16},
               {"int32", BSURF_INT32},    {"uint32", BSURF_UINT32},  {"float32", BSURF_FLOAT32},
               {"float64", BSURF_FLOAT64}};
  io_token tok = {s, len};
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
    if (io_token_is(tok, names[i].name)) {
      *type = names[i].type;
      return 1;
    }
  }
  return 0;
}

int io_type_is_integer(bsurf_type type) {
  return type != BSURF_FLOAT32 && type != BSURF_FLOAT64;
}

double io_type_convert(double v, bsurf_type type) {
  double lo, hi;
  switch (type) {
  case BSURF_INT8:
    lo = -128.0;
    hi = 127.0;
    break;
  case BSURF_UINT8:
    lo = 0.0;
    hi = 255.0;
    break;
  case BSURF_INT16:
    lo = -32768.0;
    hi = 32767.0;
    break;
  case BSURF_UINT16:
    lo = 0.0;
    hi = 65535.0;
    break;
  case BSURF_INT32:
    lo = -2147483648.0;
    hi = 2147483647.0;
    break;
  case BSURF_UINT32:
    lo = 0.0;
    hi = 4294967295.0;
    break;
  case BSURF_FLOAT32:
    /* Beyond FLT_MAX the conversion is undefined in ISO C: do IEEE's rounding
     * by hand (up to FLT_MAX + half an ulp rounds down to FLT_MAX). */
    if (v > FLT_MAX) return v < 0x1.ffffffp127 ? (double)FLT_MAX : (double)INFINITY;
    if (v < -FLT_MAX) return v > -0x1.ffffffp127 ? -(double)FLT_MAX : -(double)INFINITY;
    return (double)(float)v;
  case BSURF_FLOAT64:
  default: return v;
  }
  if (isnan(v)) return 0.0;
  v = round(v);
  if (v < lo) v = lo;
  if (v > hi) v = hi;
  return v + 0.0; /* no negative zero */
}

/* ------------------------------------------------------------------------ */
/* Buffered text output                                                      */
/* ------------------------------------------------------------------------ */

#define IO_OBUF_CAP ((size_t)1 << 16)
#define IO_VALUE_MAX 64 /* longest formatted value, with room to spare */

bsurf_status io_obuf_init(io_obuf *b, io_writer *w) {
  b->w = w;
  b->n = 0;
  b->cap = IO_OBUF_CAP;
  b->buf = malloc(b->cap);
  return b->buf ? BSURF_OK : BSURF_ERR_NOMEM;
}

void io_obuf_flush(io_obuf *b) {
  io_write_bytes(b->w, b->buf, b->n);
  b->n = 0;
}

void io_obuf_done(io_obuf *b) {
  if (b->buf) io_obuf_flush(b);
  free(b->buf);
  b->buf = NULL;
}

static void obuf_room(io_obuf *b, size_t n) {
  if (b->cap - b->n < n) io_obuf_flush(b);
}

void io_obuf_str(io_obuf *b, const char *s) {
  size_t n = strlen(s);
  if (n > b->cap / 2) {
    io_obuf_flush(b);
    io_write_bytes(b->w, s, n);
    return;
  }
  obuf_room(b, n);
  memcpy(b->buf + b->n, s, n);
  b->n += n;
}

void io_obuf_char(io_obuf *b, char c) {
  obuf_room(b, 1);
  b->buf[b->n++] = c;
}

void io_obuf_value(io_obuf *b, double v, bsurf_type type) {
  obuf_room(b, IO_VALUE_MAX);
  b->n += io_format_value(b->buf + b->n, IO_VALUE_MAX, v, type);
}

void io_obuf_point(io_obuf *b, const bsurf_cloud *cloud, size_t i, char sep) {
  for (int k = 0; k < 3; k++) {
    if (k) io_obuf_char(b, sep);
    io_obuf_value(b, cloud->xyz[3 * i + (size_t)k], BSURF_FLOAT64);
  }
  if (cloud->normals)
    for (int k = 0; k < 3; k++) {
      io_obuf_char(b, sep);
      io_obuf_value(b, cloud->normals[3 * i + (size_t)k], BSURF_FLOAT64);
    }
}

void io_obuf_uint(io_obuf *b, unsigned long long v) {
  char tmp[24];
  size_t n = 0;
  do {
    tmp[n++] = (char)('0' + v % 10);
    v /= 10;
  } while (v);
  obuf_room(b, n);
  while (n)
    b->buf[b->n++] = tmp[--n];
}
