/* Little-endian values in unaligned bytes, for the binary readers of PCD
 * and LAS and the writers of PLY, PCD and LAS (PLY's reader keeps its own,
 * which also reads big-endian). */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

uint16_t io_le16(const unsigned char *p) {
  return (uint16_t)(p[0] | (unsigned)p[1] << 8);
}

uint32_t io_le32(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t io_le64(const unsigned char *p) {
  return (uint64_t)io_le32(p) | (uint64_t)io_le32(p + 4) << 32;
}

double io_le_f64(const unsigned char *p) {
  uint64_t u = io_le64(p);
  double d;
  memcpy(&d, &u, sizeof d);
  return d;
}

float io_le_f32(const unsigned char *p) {
  uint32_t u = io_le32(p);
  float f;
  memcpy(&f, &u, sizeof f);
  return f;
}

double io_le_value(const unsigned char *p, bsurf_type type) {
  switch (type) {
  case BSURF_INT8: return (double)(int8_t)p[0];
  case BSURF_UINT8: return (double)p[0];
  case BSURF_INT16: return (double)(int16_t)io_le16(p);
  case BSURF_UINT16: return (double)io_le16(p);
  case BSURF_INT32: return (double)(int32_t)io_le32(p);
  case BSURF_UINT32: return (double)io_le32(p);
  case BSURF_FLOAT32: return (double)io_le_f32(p);
  case BSURF_FLOAT64:
  default: return io_le_f64(p);
  }
}

unsigned char *io_put_le(unsigned char *p, double v, bsurf_type type) {
  uint64_t u;
  size_t n = io_type_size(type);
  if (type == BSURF_FLOAT64) {
    memcpy(&u, &v, sizeof u);
  } else if (type == BSURF_FLOAT32) {
    float f = (float)io_type_convert(v, BSURF_FLOAT32);
    uint32_t u32;
    memcpy(&u32, &f, sizeof u32);
    u = u32;
  } else {
    u = (uint64_t)(long long)io_type_convert(v, type); /* two's complement */
  }
  return io_put_le_bytes(p, u, n);
}

unsigned char *io_put_le_bytes(unsigned char *p, uint64_t u, size_t n) {
  for (size_t i = 0; i < n; i++)
    p[i] = (unsigned char)(u >> (8 * i));
  return p + n;
}

#define IO_EXACT_MAX 9007199254740992.0 /* 2^53 */

double io_i64_exact(int64_t v, int *ok) {
  double d = (double)v;
  if (d > IO_EXACT_MAX || d < -IO_EXACT_MAX) {
    *ok = 0;
    return 0;
  }
  return d;
}

double io_u64_exact(uint64_t v, int *ok) {
  if (v > (uint64_t)1 << 53) {
    *ok = 0;
    return 0;
  }
  return (double)v;
}

bsurf_status io_names_init(io_names *b, const bsurf_cloud *cloud, size_t cap) {
  memset(b, 0, sizeof *b);
  b->base = cloud->field_count;
  b->cap = cap;
  if (cap) {
    b->buf = bsurf_alloc_array(cap, BSURF_FIELD_NAME_MAX);
    b->names = bsurf_alloc_array(cap, sizeof *b->names);
    b->types = bsurf_alloc_array(cap, sizeof *b->types);
  }
  bsurf_status st = (!cap || (b->buf && b->names && b->types)) ? BSURF_OK : BSURF_ERR_NOMEM;
  if (st == BSURF_OK) st = bsurf_nameset_init(&b->set, b->base + cap);
  for (size_t f = 0; f < b->base && st == BSURF_OK; f++)
    bsurf_nameset_insert(&b->set, cloud->fields[f].name, strlen(cloud->fields[f].name), f);
  if (st != BSURF_OK) io_names_free(b);
  return st;
}

void io_names_free(io_names *b) {
  bsurf_nameset_free(&b->set);
  free(b->buf);
  free(b->names);
  free(b->types);
  memset(b, 0, sizeof *b);
}

size_t io_names_find(const io_names *b, const char *name) {
  return bsurf_nameset_find(&b->set, name, strlen(name));
}

size_t io_names_add(io_names *b, const char *name, bsurf_type type) {
  if (b->n == b->cap) return BSURF_NAMESET_FULL;
  char *out = b->buf + b->n * BSURF_FIELD_NAME_MAX;
  snprintf(out, BSURF_FIELD_NAME_MAX, "%s", name);
  for (unsigned k = 1; io_names_find(b, out) != BSURF_NAMESET_NONE; k++) {
    char suffix[16];
    int n = snprintf(suffix, sizeof suffix, "_%u", k);
    size_t keep = strlen(name);
    if (keep > BSURF_FIELD_NAME_MAX - 1 - (size_t)n) keep = BSURF_FIELD_NAME_MAX - 1 - (size_t)n;
    memcpy(out, name, keep);
    memcpy(out + keep, suffix, (size_t)n + 1);
  }
  const size_t at = b->base + b->n;
  bsurf_nameset_insert(&b->set, out, strlen(out), at);
  b->names[b->n] = out;
  b->types[b->n++] = type;
  return at;
}

bsurf_status io_names_commit(io_names *b, bsurf_cloud *cloud) {
  bsurf_status st = bsurf_cloud_add_fields(cloud, b->n, b->names, b->types);
  io_names_free(b);
  return st;
}
