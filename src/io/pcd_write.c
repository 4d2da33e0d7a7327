/* PCD writing: ascii and binary, fields name_0 .. name_{n-1} of one type
 * grouped back into one field with a COUNT, red green blue packed as rgb. */
#include "io/pcd.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
  /* one line a keyword, one entry a field */
  static const char *const keyword[4] = {"\nFIELDS", "\nSIZE", "\nTYPE", "\nCOUNT"};
  io_write_str(w, "VERSION 0.7");
  for (int q = 0; q < 4; q++) {
    io_write_str(w, keyword[q]);
    for (size_t j = 0; j < no; j++) {
      if (q == 0) io_write_fmt(w, " %s", outs[j].name);
      if (q == 1) io_write_fmt(w, " %zu", outs[j].size);
      if (q == 2) io_write_fmt(w, " %c", outs[j].kind);
      if (q == 3) io_write_fmt(w, " %zu", outs[j].count);
    }
  }
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
