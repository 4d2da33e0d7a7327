/* LAS writing: LAS 1.4 with point format 6, 7 or 8 (or LAS 1.2 with point
 * format 1 or 3), standard attributes in their slots when they hold the
 * values exactly, every other field as extra bytes (the top of las_read.c
 * has the whole picture). */
#include "io/las.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- writing ---------------------------------------------------------------------- */

/* The standard slot a field called `name` would go to: in point formats
 * 6-8, or (legacy) 1 and 3. */
static int slot_of(const char *name, int legacy) {
  for (int a = 0; a < A_COUNT; a++)
    if (!strcmp(name, io_las_attr[a].name)) {
      if (a >= A_WP_INDEX) return -1;
      if (legacy ? (a == A_OVERLAP || a == A_CHANNEL || a == A_ANGLE || a == A_NIR)
                 : a == A_ANGLE_RANK)
        return -1;
      return a;
    }
  return -1;
}

/* 1 if the slot of attribute a holds every value exactly and some is not 0. */
static int slot_holds(int a, const double *v, size_t n, int legacy) {
  double hi;
  switch (a) {
  case A_GPS: {
    for (size_t i = 0; i < n; i++)
      if (v[i] != 0 || signbit(v[i])) return 1;
    return 0;
  }
  case A_RETURN:
  case A_NRETURNS: hi = legacy ? 7 : 15; break;
  case A_SYNTHETIC:
  case A_KEYPOINT:
  case A_WITHHELD:
  case A_OVERLAP:
  case A_SCANDIR:
  case A_EDGE: hi = 1; break;
  case A_CHANNEL: hi = 3; break;
  case A_CLASS: hi = legacy ? 31 : 255; break;
  case A_USERDATA: hi = 255; break;
  case A_ANGLE: hi = 32767; break;
  case A_ANGLE_RANK: hi = 127; break;
  default: hi = 65535; break;
  }
  double lo = a == A_ANGLE ? -32768 : a == A_ANGLE_RANK ? -128 : 0;
  int nonzero = 0;
  for (size_t i = 0; i < n; i++) {
    if (!(v[i] >= lo && v[i] <= hi && v[i] == floor(v[i])) || (v[i] == 0 && signbit(v[i])))
      return 0;
    nonzero |= v[i] != 0;
  }
  return nonzero;
}

static int eb_type_code(bsurf_type t) {
  switch (t) {
  case BSURF_UINT8: return 1;
  case BSURF_INT8: return 2;
  case BSURF_UINT16: return 3;
  case BSURF_INT16: return 4;
  case BSURF_UINT32: return 5;
  case BSURF_INT32: return 6;
  case BSURF_FLOAT32: return 9;
  default: return 10;
  }
}

/* The header's file creation day of year and year (LAS 1.4 R15, 2.4): 0 and
 * 0 (no date: January 1 is day 1), so that a run gives the same bytes
 * whenever it runs (results are deterministic for a seed), or the UTC date
 * of the SOURCE_DATE_EPOCH environment variable (reproducible-builds.org:
 * seconds since 1970) when it is set. A malformed value is refused, as that
 * specification asks, rather than silently replaced. docs/formats.md. */
static bsurf_status creation_date(unsigned *day, unsigned *year, bsurf_failure *err) {
  *day = *year = 0;
  const char *e = getenv("SOURCE_DATE_EPOCH");
  if (!e || !*e) return BSURF_OK;
  unsigned long long v = 0;
  const char *p = e;
  for (; *p >= '0' && *p <= '9' && v <= 253402300799ull; p++) /* up to 9999-12-31 */
    v = v * 10 + (unsigned)(*p - '0');
  if (*p || v > 253402300799ull)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "SOURCE_DATE_EPOCH='%.40s' is not a number of seconds since 1970 "
                      "(up to the year 9999); unset it to write the date as 0",
                      e);
  time_t t = (time_t)v;
  struct tm tm;
  if (!gmtime_r(&t, &tm))
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "SOURCE_DATE_EPOCH='%.40s': no date", e);
  *day = (unsigned)tm.tm_yday + 1;
  *year = (unsigned)tm.tm_year + 1900;
  return BSURF_OK;
}

bsurf_status bsurf_io_las_check(const bsurf_cloud *cloud, bsurf_failure *err) {
  unsigned day, year;
  bsurf_status st = creation_date(&day, &year, err);
  if (st != BSURF_OK) return st;
  size_t bytes = 38;
  for (size_t i = 0; i < 3 * cloud->point_count; i++)
    if (!isfinite(cloud->xyz[i]))
      return bsurf_fail(err, BSURF_ERR_INVALID_VALUE, 0, -1,
                        "point %zu has a NaN or infinite coordinate, which LAS cannot store",
                        i / 3);
  /* the extra-bytes VLR's record length is 16 bits: at most 65535 / 192
   * descriptors (LAS 1.4 R15, 2.5). Counted before the standard attributes
   * take their slots (so a little strict), since the slots depend on the
   * values */
  size_t extra = cloud->field_count + (cloud->normals ? 3 : 0);
  if (extra > 65535 / LAS_EB_SIZE)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "%zu fields: LAS holds at most %d extra-bytes fields (write PLY, PCD or CSV)",
                      extra, 65535 / LAS_EB_SIZE);
  for (size_t i = 0; i < cloud->field_count; i++) {
    if (strlen(cloud->fields[i].name) > LAS_NAME_MAX)
      return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                        "field '%s': LAS extra bytes names have at most %d characters",
                        cloud->fields[i].name, LAS_NAME_MAX);
    bytes += io_type_size(cloud->fields[i].type);
  }
  if (cloud->normals) bytes += 3 * io_type_size(cloud->normal_type);
  if (bytes > 65535)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "the fields need %zu bytes per point, more than a LAS record's 65535", bytes);
  return BSURF_OK;
}

/* Scale and offset: the same scale s for x y z, the smallest power of ten
 * with which every coordinate's distance to the offset (the middle of the
 * bounding box) is at most 2^31 - 2 steps; a coordinate is then stored within
 * s/2 (plus the rounding of one division). */
static void choose_scale(const bsurf_cloud *cloud, double *scale, double offset[3], double lo[3],
                         double hi[3]) {
  size_t n = cloud->point_count;
  double half = 0;
  for (int k = 0; k < 3; k++) {
    lo[k] = n ? INFINITY : 0;
    hi[k] = n ? -INFINITY : 0;
    for (size_t i = 0; i < n; i++) {
      double v = cloud->xyz[3 * i + (size_t)k];
      if (v < lo[k]) lo[k] = v;
      if (v > hi[k]) hi[k] = v;
    }
    offset[k] = lo[k] / 2 + hi[k] / 2;
    double h = fmax(hi[k] - offset[k], offset[k] - lo[k]);
    if (h > half) half = h;
  }
  const double steps = 2147483646.0;
  if (!(half > 0)) {
    *scale = 0.001;
    return;
  }
  int e = (int)ceil(log10(half / steps));
  if (e < -300) e = -300;
  if (e > 300) e = 300;
  while (e < 300 && half / pow(10, e) > steps)
    e++;
  while (e > -300 && half / pow(10, e - 1) <= steps)
    e--;
  *scale = pow(10, e);
}

/* the header's numbers (io_put_le_bytes, io_put_le: binary.c) */
#define put_u16(p, v) io_put_le_bytes((p), (uint16_t)(v), 2)
#define put_u32(p, v) io_put_le_bytes((p), (uint32_t)(v), 4)
#define put_u64(p, v) io_put_le_bytes((p), (uint64_t)(v), 8)
#define put_f64(p, v) io_put_le((p), (v), BSURF_FLOAT64)

typedef struct las_col {
  const double *src;
  size_t stride;
  bsurf_type type;
  const char *name;
} las_col;

bsurf_status bsurf_io_write_las(io_writer *w, const bsurf_cloud *cloud, int legacy,
                                bsurf_failure *err) {
  size_t n = cloud->point_count, nf = cloud->field_count;
  unsigned day, year;
  bsurf_status date_st = creation_date(&day, &year, err);
  if (date_st != BSURF_OK) return date_st;
  if (legacy && n > 0xffffffffu)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "LAS 1.2 counts at most 2^32 - 1 points; write LAS 1.4");
  const double *slot[A_COUNT] = {0};
  las_col *eb = bsurf_alloc_array(nf + 3, sizeof *eb);
  if (!eb) return io_nomem(err);
  size_t neb = 0;
  for (size_t i = 0; i < nf; i++) {
    const bsurf_field *f = &cloud->fields[i];
    int a = slot_of(f->name, legacy);
    if (a >= 0 && !slot[a] && slot_holds(a, f->values, n, legacy)) {
      slot[a] = f->values;
      continue;
    }
    eb[neb++] = (las_col){f->values, 1, f->type, f->name};
  }
  int rgb = slot[A_RED] && slot[A_GREEN] && slot[A_BLUE];
  int fmt = legacy ? (rgb ? 3 : 1) : rgb ? (slot[A_NIR] ? 8 : 7) : 6;
  /* colour components that do not make a full RGB go to extra bytes too */
  static const int colour[4] = {A_RED, A_GREEN, A_BLUE, A_NIR};
  for (int q = 0; q < 4; q++) {
    int a = colour[q];
    if (slot[a] && !io_las_has_attr(fmt, a)) {
      eb[neb++] = (las_col){slot[a], 1, io_las_attr[a].type, io_las_attr[a].name};
      slot[a] = NULL;
    }
  }
  /* keep the extra bytes in the fields' order */
  for (size_t i = 0; i < neb; i++)
    for (size_t j = i + 1; j < neb; j++) {
      const bsurf_field *fi = bsurf_cloud_field(cloud, eb[i].name),
                        *fj = bsurf_cloud_field(cloud, eb[j].name);
      if (fj < fi) {
        las_col t = eb[i];
        eb[i] = eb[j];
        eb[j] = t;
      }
    }
  if (cloud->normals) {
    static const char *const nn[3] = {"nx", "ny", "nz"};
    for (int k = 0; k < 3; k++)
      eb[neb++] = (las_col){cloud->normals + k, 3, cloud->normal_type, nn[k]};
  }
  size_t record = io_las_record_size[fmt];
  for (size_t i = 0; i < neb; i++)
    record += io_type_size(eb[i].type);

  double scale, offset[3], lo[3], hi[3];
  choose_scale(cloud, &scale, offset, lo, hi);
  size_t shape_len = strnlen(cloud->shape, sizeof cloud->shape);
  for (size_t k = 0; k < shape_len; k++)
    if ((unsigned char)cloud->shape[k] <= 0x20 || (unsigned char)cloud->shape[k] >= 0x7f)
      shape_len = 0;
  size_t vlr_bytes =
      (neb ? LAS_VLR_HEADER + neb * LAS_EB_SIZE : 0) + (shape_len ? LAS_VLR_HEADER + shape_len : 0);
  unsigned nvlr = (neb ? 1u : 0u) + (shape_len ? 1u : 0u);

  /* the coordinates as stored, for the bounds and the returns */
  uint64_t by_return[15] = {0};
  double blo[3] = {0, 0, 0}, bhi[3] = {0, 0, 0};
  for (size_t i = 0; i < n; i++) {
    for (int k = 0; k < 3; k++) {
      double raw = nearbyint((cloud->xyz[3 * i + (size_t)k] - offset[k]) / scale);
      double v = fma(raw, scale, offset[k]);
      if (i == 0 || v < blo[k]) blo[k] = v;
      if (i == 0 || v > bhi[k]) bhi[k] = v;
    }
    if (slot[A_RETURN]) {
      int r = (int)slot[A_RETURN][i];
      if (r >= 1 && r <= (legacy ? 5 : 15)) by_return[r - 1]++;
    } else {
      by_return[0]++;
    }
  }

  unsigned char hdr[LAS_HEADER_14];
  size_t hsize = legacy ? LAS_HEADER_12 : LAS_HEADER_14;
  memset(hdr, 0, sizeof hdr);
  memcpy(hdr, "LASF", 4);
  if (!legacy) put_u16(hdr + 6, 0x10); /* global encoding: WKT (required for formats 6-10) */
  hdr[24] = 1;
  hdr[25] = legacy ? 2 : 4;
  memcpy(hdr + 26, "bootsurf", 8);
  snprintf((char *)hdr + 58, 32, "bootsurf %s", BSURF_VERSION_STRING);
  put_u16(hdr + 90, day);
  put_u16(hdr + 92, year);
  put_u16(hdr + 94, (unsigned)hsize);
  put_u32(hdr + 96, (uint32_t)(hsize + vlr_bytes));
  put_u32(hdr + 100, nvlr);
  hdr[104] = (unsigned char)fmt;
  put_u16(hdr + 105, (unsigned)record);
  for (int k = 0; k < 3; k++) {
    put_f64(hdr + 131 + 8 * k, scale);
    put_f64(hdr + 155 + 8 * k, offset[k]);
    put_f64(hdr + 179 + 16 * k, bhi[k]);
    put_f64(hdr + 187 + 16 * k, blo[k]);
  }
  if (legacy) {
    put_u32(hdr + 107, (uint32_t)n);
    for (int r = 0; r < 5; r++)
      put_u32(hdr + 111 + 4 * r, (uint32_t)by_return[r]);
  } else {
    put_u64(hdr + 247, n);
    for (int r = 0; r < 15; r++)
      put_u64(hdr + 255 + 8 * r, by_return[r]);
  }
  io_write_bytes(w, hdr, hsize);

  if (neb) {
    unsigned char vh[LAS_VLR_HEADER];
    memset(vh, 0, sizeof vh);
    memcpy(vh + 2, "LASF_Spec", 9);
    put_u16(vh + 18, 4);
    put_u16(vh + 20, (unsigned)(neb * LAS_EB_SIZE));
    memcpy(vh + 22, "bootsurf fields", 15);
    io_write_bytes(w, vh, sizeof vh);
    for (size_t i = 0; i < neb; i++) {
      unsigned char dsc[LAS_EB_SIZE];
      memset(dsc, 0, sizeof dsc);
      dsc[2] = (unsigned char)eb_type_code(eb[i].type);
      memcpy(dsc + 4, eb[i].name, strlen(eb[i].name)); /* at most 32: checked */
      memcpy(dsc + 160, "bootsurf field", 14);
      io_write_bytes(w, dsc, sizeof dsc);
    }
  }
  if (shape_len) {
    unsigned char vh[LAS_VLR_HEADER];
    memset(vh, 0, sizeof vh);
    memcpy(vh + 2, "bootsurf", 8);
    put_u16(vh + 18, 1);
    put_u16(vh + 20, (unsigned)shape_len);
    memcpy(vh + 22, "generated shape", 15);
    io_write_bytes(w, vh, sizeof vh);
    io_write_bytes(w, cloud->shape, shape_len);
  }

  size_t cap = (size_t)1 << 20;
  if (cap < record) cap = record;
  unsigned char *buf = malloc(cap);
  if (!buf) {
    free(eb);
    return io_nomem(err);
  }
  size_t per = cap / record;
  for (size_t i0 = 0; i0 < n && !w->failed; i0 += per) {
    size_t i1 = i0 + per < n ? i0 + per : n;
    unsigned char *p = buf;
    for (size_t i = i0; i < i1; i++) {
      unsigned char *r = p;
      memset(r, 0, record);
      for (int k = 0; k < 3; k++) {
        double raw = nearbyint((cloud->xyz[3 * i + (size_t)k] - offset[k]) / scale);
        put_u32(r + 4 * k, (uint32_t)(int32_t)raw);
      }
#define SV(a) (slot[a] ? slot[a][i] : 0.0)
      put_u16(r + 12, (unsigned)SV(A_INTENSITY));
      if (legacy) {
        r[14] = (unsigned char)((unsigned)SV(A_RETURN) | (unsigned)SV(A_NRETURNS) << 3 |
                                (unsigned)SV(A_SCANDIR) << 6 | (unsigned)SV(A_EDGE) << 7);
        r[15] = (unsigned char)((unsigned)SV(A_CLASS) | (unsigned)SV(A_SYNTHETIC) << 5 |
                                (unsigned)SV(A_KEYPOINT) << 6 | (unsigned)SV(A_WITHHELD) << 7);
        r[16] = (unsigned char)(int8_t)SV(A_ANGLE_RANK);
        r[17] = (unsigned char)SV(A_USERDATA);
        put_u16(r + 18, (unsigned)SV(A_SOURCE));
        put_f64(r + 20, SV(A_GPS));
        if (fmt == 3) {
          put_u16(r + 28, (unsigned)SV(A_RED));
          put_u16(r + 30, (unsigned)SV(A_GREEN));
          put_u16(r + 32, (unsigned)SV(A_BLUE));
        }
        goto extra_bytes;
      }
      r[14] = (unsigned char)((unsigned)SV(A_RETURN) | (unsigned)SV(A_NRETURNS) << 4);
      r[15] = (unsigned char)((unsigned)SV(A_SYNTHETIC) | (unsigned)SV(A_KEYPOINT) << 1 |
                              (unsigned)SV(A_WITHHELD) << 2 | (unsigned)SV(A_OVERLAP) << 3 |
                              (unsigned)SV(A_CHANNEL) << 4 | (unsigned)SV(A_SCANDIR) << 6 |
                              (unsigned)SV(A_EDGE) << 7);
      r[16] = (unsigned char)SV(A_CLASS);
      r[17] = (unsigned char)SV(A_USERDATA);
      put_u16(r + 18, (unsigned)(uint16_t)(int16_t)SV(A_ANGLE));
      put_u16(r + 20, (unsigned)SV(A_SOURCE));
      put_f64(r + 22, SV(A_GPS));
      if (fmt >= 7) {
        put_u16(r + 30, (unsigned)SV(A_RED));
        put_u16(r + 32, (unsigned)SV(A_GREEN));
        put_u16(r + 34, (unsigned)SV(A_BLUE));
      }
      if (fmt == 8) put_u16(r + 36, (unsigned)SV(A_NIR));
#undef SV
    extra_bytes:;
      unsigned char *q = r + io_las_record_size[fmt];
      for (size_t e = 0; e < neb; e++)
        q = io_put_le(q, eb[e].src[i * eb[e].stride], eb[e].type);
      p += record;
    }
    io_write_bytes(w, buf, (size_t)(p - buf));
  }
  free(buf);
  free(eb);
  return BSURF_OK;
}
