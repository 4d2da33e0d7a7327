/* LAS (ASPRS LiDAR data exchange format) 1.0-1.4, point data record formats
 * 0-10, uncompressed. Debian has no LAS library (docs/formats.md), so this is
 * written from the specification (LAS 1.4 R15), with the header never
 * trusted: every offset, length and count is checked against the file before
 * it is used or anything is allocated.
 *
 * Reading: coordinates are X * scale + offset as one correctly rounded
 * fma(); every standard attribute of the record format becomes a field
 * (intensity, return_number, number_of_returns, classification, the flags,
 * scan_angle_rank or scan_angle, user_data, point_source_id, gps_time, red
 * green blue, nir, the wave packet descriptors) unless it is zero at every
 * point (most files never set most flags); the "extra bytes" a LASF_Spec
 * record 4 VLR (or EVLR) describes become fields with their names (arrays:
 * name_0 name_1 name_2; scale and offset applied when declared). LAZ is
 * refused with a message.
 *
 * Writing: LAS 1.4, point format 6, or 7 with red green blue, or 8 with nir
 * too (or, asked for, LAS 1.2 with point format 1 or 3 for readers that stop
 * at 1.3; overlap, scanner_channel, scan_angle and nir are then extra bytes). A field named as a
 * standard attribute goes into its slot when the slot holds every value exactly (and some value is
 * not zero); any other field, and the normals (nx ny nz), go into extra bytes of the field's type,
 * so that reading the file back gives every field with the same values. Scale and offset: see
 * choose_scale(). */
#include "io/io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LAS_HEADER_12 227
#define LAS_HEADER_13 235
#define LAS_HEADER_14 375
#define LAS_VLR_HEADER 54
#define LAS_EVLR_HEADER 60
#define LAS_EB_SIZE 192
#define LAS_NAME_MAX 32

static const size_t k_record_size[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

static bsurf_status nomem(bsurf_failure *err) {
  return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
}

/* ---- the standard attributes ------------------------------------------------ */

enum {
  A_INTENSITY,
  A_RETURN,
  A_NRETURNS,
  A_SYNTHETIC,
  A_KEYPOINT,
  A_WITHHELD,
  A_OVERLAP,
  A_CHANNEL,
  A_SCANDIR,
  A_EDGE,
  A_CLASS,
  A_USERDATA,
  A_ANGLE_RANK,
  A_ANGLE,
  A_SOURCE,
  A_GPS,
  A_RED,
  A_GREEN,
  A_BLUE,
  A_NIR,
  A_WP_INDEX,
  A_WP_OFFSET,
  A_WP_SIZE,
  A_WP_LOCATION,
  A_WP_XT,
  A_WP_YT,
  A_WP_ZT,
  A_COUNT
};

static const struct {
  const char *name;
  bsurf_type type;
} k_attr[A_COUNT] = {{"intensity", BSURF_UINT16},
                     {"return_number", BSURF_UINT8},
                     {"number_of_returns", BSURF_UINT8},
                     {"synthetic", BSURF_UINT8},
                     {"key_point", BSURF_UINT8},
                     {"withheld", BSURF_UINT8},
                     {"overlap", BSURF_UINT8},
                     {"scanner_channel", BSURF_UINT8},
                     {"scan_direction_flag", BSURF_UINT8},
                     {"edge_of_flight_line", BSURF_UINT8},
                     {"classification", BSURF_UINT8},
                     {"user_data", BSURF_UINT8},
                     {"scan_angle_rank", BSURF_INT8},
                     {"scan_angle", BSURF_INT16},
                     {"point_source_id", BSURF_UINT16},
                     {"gps_time", BSURF_FLOAT64},
                     {"red", BSURF_UINT16},
                     {"green", BSURF_UINT16},
                     {"blue", BSURF_UINT16},
                     {"nir", BSURF_UINT16},
                     {"wave_packet_index", BSURF_UINT8},
                     {"wave_offset", BSURF_FLOAT64},
                     {"wave_size", BSURF_UINT32},
                     {"wave_location", BSURF_FLOAT32},
                     {"wave_xt", BSURF_FLOAT32},
                     {"wave_yt", BSURF_FLOAT32},
                     {"wave_zt", BSURF_FLOAT32}};

/* Which attributes format f has. */
static int has_attr(int f, int a) {
  int modern = f >= 6;
  switch (a) {
  case A_OVERLAP:
  case A_CHANNEL:
  case A_ANGLE: return modern;
  case A_ANGLE_RANK: return !modern;
  case A_GPS: return f != 0 && f != 2;
  case A_RED:
  case A_GREEN:
  case A_BLUE: return f == 2 || f == 3 || f == 5 || f == 7 || f == 8 || f == 10;
  case A_NIR: return f == 8 || f == 10;
  case A_WP_INDEX:
  case A_WP_OFFSET:
  case A_WP_SIZE:
  case A_WP_LOCATION:
  case A_WP_XT:
  case A_WP_YT:
  case A_WP_ZT: return f == 4 || f == 5 || f == 9 || f == 10;
  default: return 1;
  }
}

/* The 29 bytes of a wave packet descriptor (formats 4, 5, 9, 10); an offset
 * beyond 2^53 becomes NaN, which the reader refuses. */
static void decode_wave(const unsigned char *p, double *v) {
  v[A_WP_INDEX] = p[0];
  int ok = 1;
  v[A_WP_OFFSET] = io_u64_exact(io_le64(p + 1), &ok);
  if (!ok) v[A_WP_OFFSET] = NAN;
  v[A_WP_SIZE] = io_le32(p + 9);
  v[A_WP_LOCATION] = io_le_f32(p + 13);
  v[A_WP_XT] = io_le_f32(p + 17);
  v[A_WP_YT] = io_le_f32(p + 21);
  v[A_WP_ZT] = io_le_f32(p + 25);
}

/* The attributes of record p (format f) into v[A_COUNT]. */
static void decode_attrs(const unsigned char *p, int f, double *v) {
  v[A_INTENSITY] = io_le16(p + 12);
  if (f < 6) {
    unsigned b = p[14], c = p[15];
    v[A_RETURN] = b & 7;
    v[A_NRETURNS] = (b >> 3) & 7;
    v[A_SCANDIR] = (b >> 6) & 1;
    v[A_EDGE] = (b >> 7) & 1;
    v[A_CLASS] = c & 31;
    v[A_SYNTHETIC] = (c >> 5) & 1;
    v[A_KEYPOINT] = (c >> 6) & 1;
    v[A_WITHHELD] = (c >> 7) & 1;
    v[A_ANGLE_RANK] = (int8_t)p[16];
    v[A_USERDATA] = p[17];
    v[A_SOURCE] = io_le16(p + 18);
    size_t at = 20;
    if (has_attr(f, A_GPS)) {
      v[A_GPS] = io_le_f64(p + at);
      at += 8;
    }
    if (has_attr(f, A_RED)) {
      v[A_RED] = io_le16(p + at);
      v[A_GREEN] = io_le16(p + at + 2);
      v[A_BLUE] = io_le16(p + at + 4);
      at += 6;
    }
    if (has_attr(f, A_WP_INDEX)) decode_wave(p + at, v);
    return;
  }
  unsigned b = p[14], c = p[15];
  v[A_RETURN] = b & 15;
  v[A_NRETURNS] = b >> 4;
  v[A_SYNTHETIC] = c & 1;
  v[A_KEYPOINT] = (c >> 1) & 1;
  v[A_WITHHELD] = (c >> 2) & 1;
  v[A_OVERLAP] = (c >> 3) & 1;
  v[A_CHANNEL] = (c >> 4) & 3;
  v[A_SCANDIR] = (c >> 6) & 1;
  v[A_EDGE] = (c >> 7) & 1;
  v[A_CLASS] = p[16];
  v[A_USERDATA] = p[17];
  v[A_ANGLE] = (int16_t)io_le16(p + 18);
  v[A_SOURCE] = io_le16(p + 20);
  v[A_GPS] = io_le_f64(p + 22);
  size_t at = 30;
  if (has_attr(f, A_RED)) {
    v[A_RED] = io_le16(p + 30);
    v[A_GREEN] = io_le16(p + 32);
    v[A_BLUE] = io_le16(p + 34);
    at = 36;
  }
  if (has_attr(f, A_NIR)) {
    v[A_NIR] = io_le16(p + 36);
    at = 38;
  }
  if (has_attr(f, A_WP_INDEX)) decode_wave(p + at, v);
}

/* ---- extra bytes ------------------------------------------------------------- */

static const size_t k_eb_size[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
static const bsurf_type k_eb_type[11] = {BSURF_UINT8,   BSURF_UINT8,   BSURF_INT8,   BSURF_UINT16,
                                         BSURF_INT16,   BSURF_UINT32,  BSURF_INT32,  BSURF_FLOAT64,
                                         BSURF_FLOAT64, BSURF_FLOAT32, BSURF_FLOAT64};

typedef struct las_extra {
  char name[LAS_NAME_MAX + 1];
  int base;      /* 1..10, 0: undocumented bytes */
  int dim;       /* 1, 2 or 3 elements */
  size_t bytes;  /* all elements */
  size_t offset; /* in the record */
  int scaled;    /* options bit 3 or 4: raw * scale + offset */
  double scale[3], offset_v[3];
  size_t field[3]; /* the cloud's fields */
} las_extra;

/* Reads the descriptors of one extra bytes record. */
static bsurf_status parse_extra(const unsigned char *p, size_t len, long long at, las_extra **out,
                                size_t *count, bsurf_failure *err) {
  if (len % LAS_EB_SIZE != 0)
    return bsurf_fail(
        err, BSURF_ERR_PARSE, 0, at,
        "wrong VLR length: the extra bytes record has %zu bytes, not a multiple of %d", len,
        LAS_EB_SIZE);
  size_t n = len / LAS_EB_SIZE;
  las_extra *e = realloc(*out, (*count + n + 1) * sizeof *e);
  if (!e) return nomem(err);
  *out = e;
  for (size_t i = 0; i < n; i++) {
    const unsigned char *d = p + i * LAS_EB_SIZE;
    las_extra *x = &e[*count];
    memset(x, 0, sizeof *x);
    unsigned type = d[2], options = d[3];
    if (type > 30)
      return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, at + (long long)(i * LAS_EB_SIZE) + 2,
                        "extra bytes descriptor %zu has the unknown data type %u", i + 1, type);
    if (type == 0) {
      x->base = 0;
      x->dim = 1;
      x->bytes = options; /* options holds the size of undocumented bytes */
      if (x->bytes == 0)
        return bsurf_fail(err, BSURF_ERR_PARSE, 0, at + (long long)(i * LAS_EB_SIZE) + 3,
                          "extra bytes descriptor %zu: undocumented bytes of size 0", i + 1);
    } else {
      x->base = (int)((type - 1) % 10 + 1);
      x->dim = (int)((type - 1) / 10 + 1);
      x->bytes = k_eb_size[x->base] * (size_t)x->dim;
    }
    x->scaled = (options & 0x18) != 0;
    for (int k = 0; k < 3; k++) {
      x->scale[k] = (options & 0x08) ? io_le_f64(d + 112 + 8 * k) : 1.0;
      x->offset_v[k] = (options & 0x10) ? io_le_f64(d + 136 + 8 * k) : 0.0;
      if (x->scaled && k < x->dim &&
          !(isfinite(x->scale[k]) && isfinite(x->offset_v[k]) && x->scale[k] != 0))
        return bsurf_fail(err, BSURF_ERR_PARSE, 0, at + (long long)(i * LAS_EB_SIZE) + 112,
                          "extra bytes descriptor %zu: scale or offset is zero or not finite",
                          i + 1);
    }
    size_t nl = 0;
    while (nl < LAS_NAME_MAX && d[4 + nl])
      nl++;
    for (size_t k = 0; k < nl; k++) {
      unsigned char ch = d[4 + k];
      x->name[k] = (ch > 0x20 && ch < 0x7f) ? (char)ch : '_';
    }
    x->name[nl] = 0;
    if (nl == 0) snprintf(x->name, sizeof x->name, "extra_%zu", *count + 1);
    (*count)++;
  }
  return BSURF_OK;
}

/* ---- reading -------------------------------------------------------------------- */

static int user_is(const unsigned char *user16, const char *id) {
  size_t n = strlen(id);
  if (memcmp(user16, id, n) != 0) return 0;
  for (size_t i = n; i < 16; i++)
    if (user16[i]) return 0;
  return 1;
}

static bsurf_status laz_refused(bsurf_failure *err, long long at) {
  return bsurf_fail(
      err, BSURF_ERR_UNSUPPORTED, 0, at,
      "LAZ (compressed LAS) is not supported: decompress it first, e.g. 'laszip -i IN.laz -o "
      "OUT.las' or 'pdal translate IN.laz OUT.las'");
}

bsurf_status bsurf_io_read_las(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_failure *err) {
  const unsigned char *d = (const unsigned char *)data;
  if (size < 4 || memcmp(d, "LASF", 4) != 0)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, 0, "not a LAS file: it does not start with 'LASF'");
  if (size < LAS_HEADER_12)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)size,
                      "truncated header: the file has %zu bytes, a LAS header at least %d", size,
                      LAS_HEADER_12);
  unsigned major = d[24], minor = d[25];
  if (major != 1 || minor > 4)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, 24,
                      "LAS version %u.%u is not supported (1.0 to 1.4)", major, minor);
  size_t header_size = io_le16(d + 94);
  size_t need = minor >= 4 ? LAS_HEADER_14 : minor == 3 ? LAS_HEADER_13 : LAS_HEADER_12;
  if (header_size < need)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, 94,
                      "the header size %zu is less than LAS 1.%u's %zu bytes", header_size, minor,
                      need);
  if (header_size > size)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, 94,
                      "truncated header: it declares %zu bytes, the file has %zu", header_size,
                      size);
  size_t point_offset = io_le32(d + 96);
  size_t nvlr = io_le32(d + 100);
  unsigned fmt_byte = d[104];
  if (fmt_byte & 0xc0) return laz_refused(err, 104);
  int fmt = (int)fmt_byte;
  if (fmt > 10)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, 104,
                      "unknown point data record format %d (LAS has 0 to 10)", fmt);
  size_t record = io_le16(d + 105);
  if (record < k_record_size[fmt])
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, 105,
                      "the point record length %zu is less than point format %d's %zu bytes",
                      record, fmt, k_record_size[fmt]);
  uint64_t count = io_le32(d + 107);
  if (minor >= 4) {
    uint64_t c64 = io_le64(d + 247);
    if (c64 || !count) count = c64;
  }
  double scale[3], offset[3];
  for (int k = 0; k < 3; k++) {
    scale[k] = io_le_f64(d + 131 + 8 * k);
    offset[k] = io_le_f64(d + 155 + 8 * k);
    if (!isfinite(scale[k]) || scale[k] == 0 || !isfinite(offset[k]))
      return bsurf_fail(err, BSURF_ERR_PARSE, 0, 131 + 8 * k,
                        "the %c scale factor or offset is zero or not finite", "xyz"[k]);
  }
  if (point_offset < header_size || point_offset > size)
    return bsurf_fail(
        err, BSURF_ERR_PARSE, 0, 96, "the offset to the point data (%zu) is %s", point_offset,
        point_offset < header_size ? "inside the header" : "beyond the end of the file");

  las_extra *extra = NULL;
  size_t nextra = 0;
  char shape[BSURF_FIELD_NAME_MAX] = "";
  bsurf_status st = BSURF_OK;
  size_t at = header_size;
  /* variable length records between the header and the points */
  for (size_t v = 0; v < nvlr && st == BSURF_OK; v++) {
    if (point_offset - at < LAS_VLR_HEADER) {
      st = bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)at,
                      "VLR %zu of %zu: its header runs past the point data offset %zu", v + 1, nvlr,
                      point_offset);
      break;
    }
    const unsigned char *h = d + at;
    unsigned rid = io_le16(h + 18);
    size_t len = io_le16(h + 20);
    if (len > point_offset - at - LAS_VLR_HEADER) {
      st = bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)at + 20,
                      "wrong VLR length: VLR %zu (record %u) has %zu bytes, which run past the "
                      "point data offset %zu",
                      v + 1, rid, len, point_offset);
      break;
    }
    if (user_is(h + 2, "laszip encoded")) {
      st = laz_refused(err, (long long)at);
      break;
    }
    if (user_is(h + 2, "LASF_Spec") && rid == 4)
      st = parse_extra(h + LAS_VLR_HEADER, len, (long long)(at + LAS_VLR_HEADER), &extra, &nextra,
                       err);
    if (user_is(h + 2, "bootsurf") && rid == 1 && len < BSURF_FIELD_NAME_MAX) {
      size_t k = 0;
      while (k < len && h[LAS_VLR_HEADER + k] > 0x20 && h[LAS_VLR_HEADER + k] < 0x7f)
        k++;
      if (k == len) {
        memcpy(shape, h + LAS_VLR_HEADER, len);
        shape[len] = 0;
      }
    }
    at += LAS_VLR_HEADER + len;
  }
  /* extended VLRs after the points (1.4) */
  if (st == BSURF_OK && minor >= 4) {
    uint64_t eat = io_le64(d + 235);
    size_t nevlr = io_le32(d + 243);
    for (size_t v = 0; v < nevlr && eat && st == BSURF_OK; v++) {
      if (eat > size || size - eat < LAS_EVLR_HEADER) {
        st = bsurf_fail(err, BSURF_ERR_PARSE, 0, 235,
                        "EVLR %zu of %zu starts beyond the end of the file", v + 1, nevlr);
        break;
      }
      const unsigned char *h = d + eat;
      unsigned rid = io_le16(h + 18);
      uint64_t len = io_le64(h + 20);
      if (len > size - eat - LAS_EVLR_HEADER) {
        st = bsurf_fail(
            err, BSURF_ERR_PARSE, 0, (long long)eat + 20,
            "wrong EVLR length: EVLR %zu (record %u) has %llu bytes, beyond the end of the file",
            v + 1, rid, (unsigned long long)len);
        break;
      }
      if (user_is(h + 2, "LASF_Spec") && rid == 4)
        st = parse_extra(h + LAS_EVLR_HEADER, (size_t)len, (long long)(eat + LAS_EVLR_HEADER),
                         &extra, &nextra, err);
      eat += LAS_EVLR_HEADER + len;
    }
  }
  size_t avail = size - point_offset;
  if (st == BSURF_OK && count > avail / record)
    st = bsurf_fail(err, BSURF_ERR_PARSE, 0, (long long)point_offset,
                    "point count beyond the file: %llu points of %zu bytes need %llu bytes, the "
                    "file has %zu after "
                    "offset %zu",
                    (unsigned long long)count, record, (unsigned long long)count * record, avail,
                    point_offset);
  size_t eb_total = 0;
  for (size_t i = 0; st == BSURF_OK && i < nextra; i++) {
    extra[i].offset = k_record_size[fmt] + eb_total;
    eb_total += extra[i].bytes;
  }
  if (st == BSURF_OK && eb_total > record - k_record_size[fmt])
    st = bsurf_fail(
        err, BSURF_ERR_PARSE, 0, 105,
        "the extra bytes records describe %zu bytes, the point records have %zu after format %d's "
        "attributes",
        eb_total, record - k_record_size[fmt], fmt);
  size_t n = (size_t)count;
  if (st == BSURF_OK && bsurf_cloud_alloc(cloud, n, 0) != BSURF_OK) st = nomem(err);

  /* the standard attributes, all first; removed afterwards where zero */
  size_t attr_field[A_COUNT];
  for (int a = 0; a < A_COUNT && st == BSURF_OK; a++) {
    attr_field[a] = (size_t)-1;
    if (!has_attr(fmt, a)) continue;
    if (!bsurf_cloud_add_field(cloud, k_attr[a].name, k_attr[a].type)) st = nomem(err);
    attr_field[a] = cloud->field_count - 1;
  }
  /* extra bytes: named fields (a name taken by a standard attribute is
   * the extra bytes' own: bootsurf writes a field that its slot cannot hold
   * exactly there) */
  for (size_t i = 0; i < nextra && st == BSURF_OK; i++) {
    las_extra *x = &extra[i];
    if (x->base == 0) continue; /* undocumented bytes: no name, no type */
    for (int k = 0; k < x->dim && st == BSURF_OK; k++) {
      char want[LAS_NAME_MAX + 16], name[BSURF_FIELD_NAME_MAX];
      if (x->dim > 1)
        snprintf(want, sizeof want, "%s_%d", x->name, k);
      else
        snprintf(want, sizeof want, "%s", x->name);
      bsurf_type type = x->scaled ? BSURF_FLOAT64 : k_eb_type[x->base];
      bsurf_field *same = bsurf_cloud_field(cloud, want);
      if (same) {
        size_t idx = (size_t)(same - cloud->fields);
        int standard = 0;
        for (int a = 0; a < A_COUNT; a++)
          standard |= attr_field[a] == idx;
        if (standard) {
          same->type = type; /* take over the standard attribute's field */
          for (int a = 0; a < A_COUNT; a++)
            if (attr_field[a] == idx) attr_field[a] = (size_t)-2; /* not decoded, not dropped */
          x->field[k] = idx;
          continue;
        }
      }
      io_unique_name(cloud, want, name);
      if (!bsurf_cloud_add_field(cloud, name, type)) {
        st = nomem(err);
        break;
      }
      x->field[k] = cloud->field_count - 1;
    }
  }
  /* the points */
  double v[A_COUNT];
  for (size_t i = 0; i < n && st == BSURF_OK; i++) {
    const unsigned char *p = d + point_offset + i * record;
    for (int k = 0; k < 3; k++)
      cloud->xyz[3 * i + (size_t)k] = fma((double)(int32_t)io_le32(p + 4 * k), scale[k], offset[k]);
    decode_attrs(p, fmt, v);
    for (int a = 0; a < A_COUNT; a++)
      if (attr_field[a] < (size_t)-2) {
        if (isnan(v[a]) && a == A_WP_OFFSET) {
          st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, (long long)(point_offset + i * record),
                          "point %zu: the wave packet offset is beyond 2^53, which a double cannot "
                          "hold exactly",
                          i);
          break;
        }
        cloud->fields[attr_field[a]].values[i] = v[a];
      }
    for (size_t e = 0; e < nextra && st == BSURF_OK; e++) {
      const las_extra *x = &extra[e];
      if (x->base == 0) continue;
      size_t es = k_eb_size[x->base];
      for (int k = 0; k < x->dim; k++) {
        const unsigned char *q = p + x->offset + (size_t)k * es;
        double val;
        int ok = 1;
        if (x->base == 7)
          val = io_u64_exact(io_le64(q), &ok);
        else if (x->base == 8)
          val = io_i64_exact((int64_t)io_le64(q), &ok);
        else
          val = io_le_value(q, k_eb_type[x->base]);
        if (!ok) {
          st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0,
                          (long long)(point_offset + i * record + x->offset),
                          "point %zu: the 8-byte integer of extra bytes '%s' is beyond 2^53, which "
                          "a double cannot "
                          "hold exactly",
                          i, x->name);
          break;
        }
        if (x->scaled) val = fma(val, x->scale[k], x->offset_v[k]);
        cloud->fields[x->field[k]].values[i] = val;
      }
    }
  }
  /* standard attributes that are zero everywhere carry nothing */
  for (int a = A_COUNT - 1; a >= 0 && st == BSURF_OK; a--) {
    if (attr_field[a] >= (size_t)-2) continue;
    const double *vals = cloud->fields[attr_field[a]].values;
    size_t i = 0;
    while (i < n && vals[i] == 0 && !signbit(vals[i]))
      i++;
    if (i == n) {
      size_t idx = attr_field[a];
      bsurf_cloud_remove_field(cloud, k_attr[a].name);
      for (size_t e = 0; e < nextra; e++)
        for (int k = 0; k < 3; k++)
          if (extra[e].field[k] > idx) extra[e].field[k]--;
    }
  }
  /* extra bytes nx ny nz: the normals */
  if (st == BSURF_OK) {
    bsurf_field *nx = bsurf_cloud_field(cloud, "nx"), *ny = bsurf_cloud_field(cloud, "ny"),
                *nz = bsurf_cloud_field(cloud, "nz");
    if (nx && ny && nz) {
      cloud->normals = bsurf_alloc_array(n ? 3 * n : 1, sizeof(double));
      if (!cloud->normals) {
        st = nomem(err);
      } else {
        for (size_t i = 0; i < n; i++) {
          cloud->normals[3 * i] = nx->values[i];
          cloud->normals[3 * i + 1] = ny->values[i];
          cloud->normals[3 * i + 2] = nz->values[i];
        }
        cloud->normal_type = nx->type;
        bsurf_cloud_remove_field(cloud, "nx");
        bsurf_cloud_remove_field(cloud, "ny");
        bsurf_cloud_remove_field(cloud, "nz");
      }
    }
  }
  if (st == BSURF_OK) memcpy(cloud->shape, shape, sizeof shape);
  free(extra);
  return st;
}

/* ---- writing ---------------------------------------------------------------------- */

/* The standard slot a field called `name` would go to: in point formats
 * 6-8, or (legacy) 1 and 3. */
static int slot_of(const char *name, int legacy) {
  for (int a = 0; a < A_COUNT; a++)
    if (!strcmp(name, k_attr[a].name)) {
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

bsurf_status bsurf_io_las_check(const bsurf_cloud *cloud, bsurf_failure *err) {
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

static unsigned char *put_u16(unsigned char *p, unsigned v) {
  p[0] = (unsigned char)v;
  p[1] = (unsigned char)(v >> 8);
  return p + 2;
}
static unsigned char *put_u32(unsigned char *p, uint32_t v) {
  for (int i = 0; i < 4; i++)
    p[i] = (unsigned char)(v >> (8 * i));
  return p + 4;
}
static unsigned char *put_u64(unsigned char *p, uint64_t v) {
  for (int i = 0; i < 8; i++)
    p[i] = (unsigned char)(v >> (8 * i));
  return p + 8;
}
static unsigned char *put_f64(unsigned char *p, double v) {
  uint64_t u;
  memcpy(&u, &v, sizeof u);
  return put_u64(p, u);
}

typedef struct las_col {
  const double *src;
  size_t stride;
  bsurf_type type;
  const char *name;
} las_col;

bsurf_status bsurf_io_write_las(io_writer *w, const bsurf_cloud *cloud, int legacy,
                                bsurf_failure *err) {
  size_t n = cloud->point_count, nf = cloud->field_count;
  if (legacy && n > 0xffffffffu)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "LAS 1.2 counts at most 2^32 - 1 points; write LAS 1.4");
  const double *slot[A_COUNT] = {0};
  las_col *eb = bsurf_alloc_array(nf + 3, sizeof *eb);
  if (!eb) return nomem(err);
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
    if (slot[a] && !has_attr(fmt, a)) {
      eb[neb++] = (las_col){slot[a], 1, k_attr[a].type, k_attr[a].name};
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
  size_t record = k_record_size[fmt];
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
    return nomem(err);
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
      unsigned char *q = r + k_record_size[fmt];
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
