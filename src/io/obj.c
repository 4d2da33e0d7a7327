/* Wavefront OBJ: vertices (with optional w or r g b), vertex normals and
 * faces (i, i/t, i//n, i/t/n, negative = relative indices); everything else
 * (vt, g, o, s, usemtl, mtllib, l, p, ...) is ignored.
 *
 * OBJ attaches normals to face corners, the cloud to points. If there are as
 * many vn as v and no face pairs a v with another vn, vn[i] is v[i]'s normal;
 * otherwise each vertex takes the vn of the first corner that uses it. If a
 * vertex is left without a normal the cloud gets none at all (a made-up zero
 * normal would poison every later computation). */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

#define NO_NORMAL 0xffffffffu

typedef struct obj_reader {
  io_dvec v;      /* nv x 3 */
  io_dvec colour; /* nv x 3 (zero where a vertex has none) */
  size_t ncoloured;
  io_dvec vn;        /* nvn x 3 */
  uint32_t *first_n; /* nv: the vn of the first corner using the vertex */
  size_t first_cap;
  int contradict; /* some corner pairs v[i] with vn[j], j != i */
  io_faces faces;
  bsurf_failure *err;
} obj_reader;

static bsurf_status nomem(obj_reader *r) {
  return bsurf_fail(r->err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
}

/* A signed decimal integer. */
static int parse_i64(const char *s, size_t len, long long *out) {
  int neg = 0;
  if (len && (s[0] == '-' || s[0] == '+')) {
    neg = s[0] == '-';
    s++;
    len--;
  }
  unsigned long long u;
  if (!io_parse_u64(s, len, &u) || u > 0x7fffffffffffffffULL) return 0;
  *out = neg ? -(long long)u : (long long)u;
  return 1;
}

/* OBJ index (1-based, or negative relative to the `count` defined so far) ->
 * 0-based; -1 if out of range. */
static long long resolve(long long i, size_t count) {
  long long r = i > 0 ? i - 1 : (long long)count + i;
  return (i != 0 && r >= 0 && (unsigned long long)r < count) ? r : -1;
}

static bsurf_status parse_values(obj_reader *r, io_cursor *c, const char *kw, long line,
                                 double *vals, size_t max, size_t *n) {
  io_token tok;
  char a[48];
  *n = 0;
  while (io_next_token(c, &tok)) {
    if (*n == max)
      return bsurf_fail(r->err, BSURF_ERR_PARSE, line, -1, "a '%s' line has more than %zu values",
                        kw, max);
    if (!io_parse_double(tok.s, tok.len, &vals[*n]))
      return bsurf_fail(r->err, BSURF_ERR_PARSE, line, -1, "'%s' in a '%s' line is not a number",
                        io_token_repr(tok, a), kw);
    (*n)++;
  }
  return BSURF_OK;
}

static bsurf_status add_vertex(obj_reader *r, const double *vals, size_t n, long line) {
  static const double none[3] = {0, 0, 0};
  if (n != 3 && n != 4 && n != 6)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, line, -1,
                      "a 'v' line needs 3, 4 or 6 values (x y z [w | r g b]), found %zu", n);
  if (r->v.n / 3 >= 0xffffffffu)
    return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, line, -1, "too many vertices");
  if (io_dvec_push(&r->v, vals, 3) != BSURF_OK) return nomem(r);
  if (io_dvec_push(&r->colour, n == 6 ? vals + 3 : none, 3) != BSURF_OK) return nomem(r);
  if (n == 6) r->ncoloured++;
  size_t nv = r->v.n / 3;
  if (nv > r->first_cap) {
    size_t cap = r->first_cap ? 2 * r->first_cap : 4096;
    uint32_t *p = realloc(r->first_n, cap * sizeof *p);
    if (!p) return nomem(r);
    r->first_n = p;
    r->first_cap = cap;
  }
  r->first_n[nv - 1] = NO_NORMAL;
  return BSURF_OK;
}

/* A face corner's vertex or normal index beyond those defined so far. */
static bsurf_status out_of_range(obj_reader *r, long line, io_token corner, const char *what,
                                 long long index, size_t defined) {
  char a[48];
  return bsurf_fail(r->err, BSURF_ERR_PARSE, line, -1,
                    "face corner '%s': %s index %lld is out of range (%zu defined so far)",
                    io_token_repr(corner, a), what, index, defined);
}

static bsurf_status add_face(obj_reader *r, io_cursor *c, long line) {
  io_token tok;
  char a[48];
  size_t nv = r->v.n / 3, nvn = r->vn.n / 3;
  io_faces_begin(&r->faces);
  while (io_next_token(c, &tok)) {
    /* i, i/t, i//n or i/t/n */
    io_token part[3] = {{NULL, 0}, {NULL, 0}, {NULL, 0}};
    size_t np = 0;
    const char *s = tok.s, *end = tok.s + tok.len;
    for (;;) {
      const char *slash = memchr(s, '/', (size_t)(end - s));
      const char *stop = slash ? slash : end;
      if (np == 3)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, line, -1, "face corner '%s' is malformed",
                          io_token_repr(tok, a));
      part[np++] = (io_token){s, (size_t)(stop - s)};
      if (!slash) break;
      s = slash + 1;
    }
    long long vi, ti, ni = -1;
    if (!parse_i64(part[0].s, part[0].len, &vi) ||
        (np > 1 && part[1].len && !parse_i64(part[1].s, part[1].len, &ti)) ||
        (np > 2 && part[2].len && !parse_i64(part[2].s, part[2].len, &ni)) ||
        (np == 2 && part[1].len == 0))
      return bsurf_fail(r->err, BSURF_ERR_PARSE, line, -1,
                        "face corner '%s' is not of the form i, i/t, i//n or i/t/n",
                        io_token_repr(tok, a));
    long long v = resolve(vi, nv);
    if (v < 0) return out_of_range(r, line, tok, "vertex", vi, nv);
    if (np > 2 && part[2].len) {
      long long n = resolve(ni, nvn);
      if (n < 0) return out_of_range(r, line, tok, "normal", ni, nvn);
      if (n != v) r->contradict = 1;
      if (r->first_n[v] == NO_NORMAL) r->first_n[v] = (uint32_t)n;
    }
    if (io_faces_corner(&r->faces, (uint32_t)v) != BSURF_OK) return nomem(r);
  }
  return BSURF_OK;
}

static bsurf_status parse(obj_reader *r, const char *data, size_t size) {
  io_text t;
  io_text_init(&t, data, size);
  const char *line;
  size_t len;
  double vals[7];
  size_t n;
  while (io_text_next_line(&t, &line, &len)) {
    io_cursor c;
    io_token kw;
    io_cursor_init(&c, line, io_strip_comment(line, len), IO_SEP_SPACE);
    if (!io_next_token(&c, &kw)) continue;
    bsurf_status st = BSURF_OK;
    if (io_token_is(kw, "v")) {
      st = parse_values(r, &c, "v", t.line, vals, 6, &n);
      if (st == BSURF_OK) st = add_vertex(r, vals, n, t.line);
    } else if (io_token_is(kw, "vn")) {
      st = parse_values(r, &c, "vn", t.line, vals, 3, &n);
      if (st == BSURF_OK && n != 3)
        st = bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1,
                        "a 'vn' line needs 3 values, found %zu", n);
      if (st == BSURF_OK && io_dvec_push(&r->vn, vals, 3) != BSURF_OK) st = nomem(r);
    } else if (io_token_is(kw, "f")) {
      st = add_face(r, &c, t.line);
    }
    if (st != BSURF_OK) return st;
  }
  return BSURF_OK;
}

bsurf_status bsurf_io_read_obj(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_failure *err) {
  obj_reader r;
  memset(&r, 0, sizeof r);
  r.err = err;
  io_faces_init(&r.faces);
  bsurf_status st = parse(&r, data, size);
  size_t nv = r.v.n / 3, nvn = r.vn.n / 3;
  if (st == BSURF_OK) {
    cloud->point_count = nv;
    cloud->xyz = io_dvec_take(&r.v);
    if (nv && nvn) {
      int identity = nvn == nv && !r.contradict;
      int complete = 1;
      for (size_t i = 0; i < nv && !identity; i++)
        if (r.first_n[i] == NO_NORMAL) complete = 0;
      if (identity || complete) {
        cloud->normals = bsurf_alloc_array(nv, 3 * sizeof(double));
        if (!cloud->normals) {
          st = nomem(&r);
        } else {
          for (size_t i = 0; i < nv; i++) {
            size_t j = identity ? i : r.first_n[i];
            memcpy(cloud->normals + 3 * i, r.vn.v + 3 * j, 3 * sizeof(double));
          }
        }
      }
    }
  }
  if (st == BSURF_OK && nv && r.ncoloured == nv) {
    static const char *const names[3] = {"red", "green", "blue"};
    for (int k = 0; k < 3 && st == BSURF_OK; k++) {
      bsurf_field *f = bsurf_cloud_add_field(cloud, names[k], BSURF_FLOAT32);
      if (!f) {
        st = nomem(&r);
        break;
      }
      for (size_t i = 0; i < nv; i++)
        f->values[i] = r.colour.v[3 * i + (size_t)k];
    }
  }
  if (st == BSURF_OK) io_faces_move(&r.faces, cloud);
  io_faces_free(&r.faces);
  free(r.v.v);
  free(r.vn.v);
  free(r.colour.v);
  free(r.first_n);
  return st;
}

bsurf_status bsurf_io_write_obj(io_writer *w, const bsurf_cloud *cloud, bsurf_failure *err) {
  io_obuf ob;
  if (io_obuf_init(&ob, w) != BSURF_OK)
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  io_obuf_str(&ob, "# generated by bootsurf " BSURF_VERSION_STRING "\n");
  for (int pass = 0; pass < (cloud->normals ? 2 : 1); pass++) {
    const double *src = pass ? cloud->normals : cloud->xyz;
    for (size_t i = 0; i < cloud->point_count && !w->failed; i++) {
      io_obuf_str(&ob, pass ? "vn" : "v");
      for (int k = 0; k < 3; k++) {
        io_obuf_char(&ob, ' ');
        io_obuf_value(&ob, src[3 * i + (size_t)k], BSURF_FLOAT64);
      }
      io_obuf_char(&ob, '\n');
    }
  }
  for (size_t i = 0; i < cloud->face_count && !w->failed; i++) {
    io_obuf_char(&ob, 'f');
    for (int k = 0; k < 3; k++) {
      unsigned long long idx = (unsigned long long)cloud->faces[3 * i + (size_t)k] + 1;
      io_obuf_char(&ob, ' ');
      io_obuf_uint(&ob, idx);
      if (cloud->normals) {
        io_obuf_str(&ob, "//");
        io_obuf_uint(&ob, idx);
      }
    }
    io_obuf_char(&ob, '\n');
  }
  io_obuf_done(&ob);
  return BSURF_OK;
}
