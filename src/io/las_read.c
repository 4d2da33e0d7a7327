/* LAS reading (las_write.c: writing; las_attrs.c: the tables). LAS (ASPRS LiDAR data exchange
 * format) 1.0-1.4, point data record formats 0-10, uncompressed. Debian has no LAS library
 * (docs/formats.md), so this is written from the specification (LAS 1.4 R15), with the header never
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
 * choose_scale() in las_write.c. */
#include "io/las.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
    if (io_las_has_attr(f, A_GPS)) {
      v[A_GPS] = io_le_f64(p + at);
      at += 8;
    }
    if (io_las_has_attr(f, A_RED)) {
      v[A_RED] = io_le16(p + at);
      v[A_GREEN] = io_le16(p + at + 2);
      v[A_BLUE] = io_le16(p + at + 4);
      at += 6;
    }
    if (io_las_has_attr(f, A_WP_INDEX)) decode_wave(p + at, v);
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
  if (io_las_has_attr(f, A_RED)) {
    v[A_RED] = io_le16(p + 30);
    v[A_GREEN] = io_le16(p + 32);
    v[A_BLUE] = io_le16(p + 34);
    at = 36;
  }
  if (io_las_has_attr(f, A_NIR)) {
    v[A_NIR] = io_le16(p + 36);
    at = 38;
  }
  if (io_las_has_attr(f, A_WP_INDEX)) decode_wave(p + at, v);
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
  if (!e) return io_nomem(err);
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

/* The reader's state: the header's numbers, the extra bytes, where each
 * standard attribute goes. */
typedef struct las_reader {
  const unsigned char *d;
  size_t size;
  bsurf_failure *err;
  unsigned minor;
  size_t header_size, point_offset, nvlr, record;
  int fmt;
  uint64_t count;
  double scale[3], offset[3];
  las_extra *extra;
  size_t nextra;
  char shape[BSURF_FIELD_NAME_MAX];
  /* the field of each standard attribute; (size_t)-1: none, -2: taken over
   * by extra bytes of the same name */
  size_t attr_field[A_COUNT];
} las_reader;

/* The public header block, every number checked against the file. */
static bsurf_status read_header(las_reader *r) {
  const unsigned char *d = r->d;
  size_t size = r->size;
  bsurf_failure *err = r->err;
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
  r->minor = minor;
  r->header_size = io_le16(d + 94);
  size_t need = minor >= 4 ? LAS_HEADER_14 : minor == 3 ? LAS_HEADER_13 : LAS_HEADER_12;
  if (r->header_size < need)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, 94,
                      "the header size %zu is less than LAS 1.%u's %zu bytes", r->header_size,
                      minor, need);
  if (r->header_size > size)
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, 94,
                      "truncated header: it declares %zu bytes, the file has %zu", r->header_size,
                      size);
  r->point_offset = io_le32(d + 96);
  r->nvlr = io_le32(d + 100);
  unsigned fmt_byte = d[104];
  if (fmt_byte & 0xc0) return laz_refused(err, 104);
  r->fmt = (int)fmt_byte;
  if (r->fmt > 10)
    return bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, 104,
                      "unknown point data record format %d (LAS has 0 to 10)", r->fmt);
  r->record = io_le16(d + 105);
  if (r->record < io_las_record_size[r->fmt])
    return bsurf_fail(err, BSURF_ERR_PARSE, 0, 105,
                      "the point record length %zu is less than point format %d's %zu bytes",
                      r->record, r->fmt, io_las_record_size[r->fmt]);
  r->count = io_le32(d + 107);
  if (minor >= 4) {
    uint64_t c64 = io_le64(d + 247);
    if (c64 || !r->count) r->count = c64;
  }
  for (int k = 0; k < 3; k++) {
    r->scale[k] = io_le_f64(d + 131 + 8 * k);
    r->offset[k] = io_le_f64(d + 155 + 8 * k);
    if (!isfinite(r->scale[k]) || r->scale[k] == 0 || !isfinite(r->offset[k]))
      return bsurf_fail(err, BSURF_ERR_PARSE, 0, 131 + 8 * k,
                        "the %c scale factor or offset is zero or not finite", "xyz"[k]);
  }
  if (r->point_offset < r->header_size || r->point_offset > size)
    return bsurf_fail(
        err, BSURF_ERR_PARSE, 0, 96, "the offset to the point data (%zu) is %s", r->point_offset,
        r->point_offset < r->header_size ? "inside the header" : "beyond the end of the file");
  return BSURF_OK;
}

/* The variable length records between the header and the points: extra
 * bytes, bootsurf's shape, LAZ refused. */
static bsurf_status read_vlrs(las_reader *r) {
  size_t at = r->header_size, end = r->point_offset;
  for (size_t v = 0; v < r->nvlr; v++) {
    if (end - at < LAS_VLR_HEADER)
      return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)at,
                        "VLR %zu of %zu: its header runs past the point data offset %zu", v + 1,
                        r->nvlr, end);
    const unsigned char *h = r->d + at;
    unsigned rid = io_le16(h + 18);
    size_t len = io_le16(h + 20);
    if (len > end - at - LAS_VLR_HEADER)
      return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)at + 20,
                        "wrong VLR length: VLR %zu (record %u) has %zu bytes, which run past the "
                        "point data offset %zu",
                        v + 1, rid, len, end);
    if (user_is(h + 2, "laszip encoded")) return laz_refused(r->err, (long long)at);
    if (user_is(h + 2, "LASF_Spec") && rid == 4) {
      bsurf_status st = parse_extra(h + LAS_VLR_HEADER, len, (long long)(at + LAS_VLR_HEADER),
                                    &r->extra, &r->nextra, r->err);
      if (st != BSURF_OK) return st;
    }
    if (user_is(h + 2, "bootsurf") && rid == 1 && len < BSURF_FIELD_NAME_MAX) {
      size_t k = 0;
      while (k < len && h[LAS_VLR_HEADER + k] > 0x20 && h[LAS_VLR_HEADER + k] < 0x7f)
        k++;
      if (k == len) {
        memcpy(r->shape, h + LAS_VLR_HEADER, len);
        r->shape[len] = 0;
      }
    }
    at += LAS_VLR_HEADER + len;
  }
  return BSURF_OK;
}

/* The extended VLRs after the points (LAS 1.4): extra bytes. */
static bsurf_status read_evlrs(las_reader *r) {
  if (r->minor < 4) return BSURF_OK;
  size_t size = r->size;
  uint64_t eat = io_le64(r->d + 235);
  size_t nevlr = io_le32(r->d + 243);
  for (size_t v = 0; v < nevlr && eat; v++) {
    if (eat > size || size - eat < LAS_EVLR_HEADER)
      return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, 235,
                        "EVLR %zu of %zu starts beyond the end of the file", v + 1, nevlr);
    const unsigned char *h = r->d + eat;
    unsigned rid = io_le16(h + 18);
    uint64_t len = io_le64(h + 20);
    if (len > size - eat - LAS_EVLR_HEADER)
      return bsurf_fail(
          r->err, BSURF_ERR_PARSE, 0, (long long)eat + 20,
          "wrong EVLR length: EVLR %zu (record %u) has %llu bytes, beyond the end of the file",
          v + 1, rid, (unsigned long long)len);
    if (user_is(h + 2, "LASF_Spec") && rid == 4) {
      bsurf_status st =
          parse_extra(h + LAS_EVLR_HEADER, (size_t)len, (long long)(eat + LAS_EVLR_HEADER),
                      &r->extra, &r->nextra, r->err);
      if (st != BSURF_OK) return st;
    }
    eat += LAS_EVLR_HEADER + len;
  }
  return BSURF_OK;
}

/* The points fit the file, the extra bytes fit the records (their offsets
 * set). */
static bsurf_status check_records(las_reader *r) {
  size_t avail = r->size - r->point_offset, base = io_las_record_size[r->fmt];
  if (r->count > avail / r->record)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)r->point_offset,
                      "point count beyond the file: %llu points of %zu bytes need %llu bytes, the "
                      "file has %zu after "
                      "offset %zu",
                      (unsigned long long)r->count, r->record,
                      (unsigned long long)r->count * r->record, avail, r->point_offset);
  size_t eb_total = 0;
  for (size_t i = 0; i < r->nextra; i++) {
    r->extra[i].offset = base + eb_total;
    eb_total += r->extra[i].bytes;
  }
  if (eb_total > r->record - base)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, 105,
                      "the extra bytes records describe %zu bytes, the point records have %zu "
                      "after format %d's "
                      "attributes",
                      eb_total, r->record - base, r->fmt);
  return BSURF_OK;
}

/* The fields: every standard attribute of the format first (removed
 * afterwards where zero), then the extra bytes by name (a name taken by a
 * standard attribute is the extra bytes' own: bootsurf writes a field that
 * its slot cannot hold exactly there). */
static bsurf_status make_fields(las_reader *r, bsurf_cloud *cloud) {
  if (bsurf_cloud_alloc(cloud, (size_t)r->count, 0) != BSURF_OK) return io_nomem(r->err);
  for (int a = 0; a < A_COUNT; a++) {
    r->attr_field[a] = (size_t)-1;
    if (!io_las_has_attr(r->fmt, a)) continue;
    if (!bsurf_cloud_add_field(cloud, io_las_attr[a].name, io_las_attr[a].type))
      return io_nomem(r->err);
    r->attr_field[a] = cloud->field_count - 1;
  }
  size_t cap = 0;
  for (size_t i = 0; i < r->nextra; i++)
    cap += (size_t)r->extra[i].dim;
  io_names fields;
  if (io_names_init(&fields, cloud, cap) != BSURF_OK) return io_nomem(r->err);
  for (size_t i = 0; i < r->nextra; i++) {
    las_extra *x = &r->extra[i];
    if (x->base == 0) continue; /* undocumented bytes: no name, no type */
    for (int k = 0; k < x->dim; k++) {
      char want[LAS_NAME_MAX + 16];
      if (x->dim > 1)
        snprintf(want, sizeof want, "%s_%d", x->name, k);
      else
        snprintf(want, sizeof want, "%s", x->name);
      bsurf_type type = x->scaled ? BSURF_FLOAT64 : k_eb_type[x->base];
      const size_t idx = io_names_find(&fields, want);
      if (idx < fields.base) { /* a standard attribute's name */
        int standard = 0;
        for (int a = 0; a < A_COUNT; a++)
          standard |= r->attr_field[a] == idx;
        if (standard) {
          cloud->fields[idx].type = type; /* take over the standard attribute's field */
          for (int a = 0; a < A_COUNT; a++)
            if (r->attr_field[a] == idx) r->attr_field[a] = (size_t)-2; /* not decoded or dropped */
          x->field[k] = idx;
          continue;
        }
      }
      x->field[k] = io_names_add(&fields, want, type);
    }
  }
  return io_names_commit(&fields, cloud) == BSURF_OK ? BSURF_OK : io_nomem(r->err);
}

/* Point i's extra bytes (record p) into its fields. */
static bsurf_status decode_extra(const las_reader *r, const unsigned char *p, size_t i,
                                 bsurf_cloud *cloud) {
  for (size_t e = 0; e < r->nextra; e++) {
    const las_extra *x = &r->extra[e];
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
      if (!ok)
        return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, 0,
                          (long long)(r->point_offset + i * r->record + x->offset),
                          "point %zu: the 8-byte integer of extra bytes '%s' is beyond 2^53, which "
                          "a double cannot "
                          "hold exactly",
                          i, x->name);
      if (x->scaled) val = fma(val, x->scale[k], x->offset_v[k]);
      cloud->fields[x->field[k]].values[i] = val;
    }
  }
  return BSURF_OK;
}

/* The point records: coordinates as X * scale + offset (one fma, the double
 * nearest the exact value), standard attributes, extra bytes. */
static bsurf_status read_points(const las_reader *r, bsurf_cloud *cloud) {
  double v[A_COUNT];
  for (size_t i = 0; i < (size_t)r->count; i++) {
    const unsigned char *p = r->d + r->point_offset + i * r->record;
    for (int k = 0; k < 3; k++)
      cloud->xyz[3 * i + (size_t)k] =
          fma((double)(int32_t)io_le32(p + 4 * k), r->scale[k], r->offset[k]);
    decode_attrs(p, r->fmt, v);
    for (int a = 0; a < A_COUNT; a++) {
      if (r->attr_field[a] >= (size_t)-2) continue;
      if (isnan(v[a]) && a == A_WP_OFFSET)
        return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, 0,
                          (long long)(r->point_offset + i * r->record),
                          "point %zu: the wave packet offset is beyond 2^53, which a double cannot "
                          "hold exactly",
                          i);
      cloud->fields[r->attr_field[a]].values[i] = v[a];
    }
    bsurf_status st = decode_extra(r, p, i, cloud);
    if (st != BSURF_OK) return st;
  }
  return BSURF_OK;
}

/* Standard attributes that are zero everywhere carry nothing: removed. */
static void drop_zero_attributes(las_reader *r, bsurf_cloud *cloud) {
  size_t n = (size_t)r->count;
  for (int a = A_COUNT - 1; a >= 0; a--) {
    if (r->attr_field[a] >= (size_t)-2) continue;
    const double *vals = cloud->fields[r->attr_field[a]].values;
    size_t i = 0;
    while (i < n && vals[i] == 0 && !signbit(vals[i]))
      i++;
    if (i < n) continue;
    size_t idx = r->attr_field[a];
    bsurf_cloud_remove_field(cloud, io_las_attr[a].name);
    for (size_t e = 0; e < r->nextra; e++)
      for (int k = 0; k < 3; k++)
        if (r->extra[e].field[k] > idx) r->extra[e].field[k]--;
  }
}

/* Extra bytes nx ny nz are the normals. */
static bsurf_status take_normals(las_reader *r, bsurf_cloud *cloud) {
  size_t n = (size_t)r->count;
  bsurf_field *nx = bsurf_cloud_field(cloud, "nx"), *ny = bsurf_cloud_field(cloud, "ny"),
              *nz = bsurf_cloud_field(cloud, "nz");
  if (!nx || !ny || !nz) return BSURF_OK;
  cloud->normals = bsurf_alloc_array(n ? 3 * n : 1, sizeof(double));
  if (!cloud->normals) return io_nomem(r->err);
  for (size_t i = 0; i < n; i++) {
    cloud->normals[3 * i] = nx->values[i];
    cloud->normals[3 * i + 1] = ny->values[i];
    cloud->normals[3 * i + 2] = nz->values[i];
  }
  cloud->normal_type = nx->type;
  bsurf_cloud_remove_field(cloud, "nx");
  bsurf_cloud_remove_field(cloud, "ny");
  bsurf_cloud_remove_field(cloud, "nz");
  return BSURF_OK;
}

bsurf_status bsurf_io_read_las(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_failure *err) {
  las_reader r;
  memset(&r, 0, sizeof r);
  r.d = (const unsigned char *)data;
  r.size = size;
  r.err = err;
  bsurf_status st = read_header(&r);
  if (st == BSURF_OK) st = read_vlrs(&r);
  if (st == BSURF_OK) st = read_evlrs(&r);
  if (st == BSURF_OK) st = check_records(&r);
  if (st == BSURF_OK) st = make_fields(&r, cloud);
  if (st == BSURF_OK) st = read_points(&r, cloud);
  if (st == BSURF_OK) drop_zero_attributes(&r, cloud);
  if (st == BSURF_OK) st = take_normals(&r, cloud);
  if (st == BSURF_OK) memcpy(cloud->shape, r.shape, sizeof r.shape);
  free(r.extra);
  return st;
}
