/* Little-endian values in unaligned bytes, for the binary readers and
 * writers of PCD and LAS (PLY keeps its own, which also reads big-endian). */
#include "io/io.h"

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

void io_unique_name(const bsurf_cloud *cloud, const char *name, char out[BSURF_FIELD_NAME_MAX]) {
  snprintf(out, BSURF_FIELD_NAME_MAX, "%s", name);
  for (unsigned k = 1; bsurf_cloud_field(cloud, out); k++) {
    char suffix[16];
    int n = snprintf(suffix, sizeof suffix, "_%u", k);
    size_t keep = strlen(name);
    if (keep > BSURF_FIELD_NAME_MAX - 1 - (size_t)n) keep = BSURF_FIELD_NAME_MAX - 1 - (size_t)n;
    memcpy(out, name, keep);
    memcpy(out + keep, suffix, (size_t)n + 1);
  }
}
