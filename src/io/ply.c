/* PLY (Stanford polygon file format 1.0): ascii, binary little- and
 * big-endian reading; binary little-endian and ascii writing.
 *
 * Reading never trusts the header: before anything is allocated, every
 * element's declared count times its smallest possible record size is checked
 * against the bytes that follow, and every variable-length record is checked
 * again as it is read. */
#include "io/io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { PLY_ASCII, PLY_LE, PLY_BE };
enum { ELEM_OTHER, ELEM_VERTEX, ELEM_FACE };

typedef struct ply_prop {
  io_token name;
  int is_list;
  bsurf_type type;       /* scalar type, or the type of a list's items */
  bsurf_type count_type; /* list only */
  long line;
  size_t offset; /* binary: offset inside a fixed-size record */
  double *dst;   /* vertex element: where the values go */
  size_t stride;
  int is_index; /* face element: the vertex index list */
  size_t field; /* vertex element: its field in the cloud, or (size_t)-1 */
} ply_prop;

typedef struct ply_elem {
  io_token name;
  unsigned long long count;
  long line;
  int kind;
  ply_prop *props;
  size_t nprops, cap;
  int has_list;
  size_t min_record; /* smallest record: binary bytes, or ascii values */
} ply_elem;

typedef struct ply_reader {
  const char *data;
  size_t size;
  int format;
  ply_elem *elems;
  size_t nelems, cap;
  size_t body;    /* offset of the first byte after the header */
  long body_line; /* number of the first line after the header */
  unsigned long long nv;
  io_faces faces;
  bsurf_failure *err;
  int dry;                          /* ascii data too short for the header: validate only */
  bsurf_failure dry_err;            /* the error to report if validation finds nothing */
  char shape[BSURF_FIELD_NAME_MAX]; /* from "comment bootsurf shape NAME" */
  io_ply_layout *layout;            /* io_ply_map: vertices are located, not stored */
  int probe;                        /* io_ply_probe: the header only, checked */
} ply_reader;

/* A shape name a header line can carry: one printable word that fits. */
static int shape_name_ok(const char *s, size_t len) {
  if (len == 0 || len >= BSURF_FIELD_NAME_MAX) return 0;
  for (size_t i = 0; i < len; i++)
    if ((unsigned char)s[i] < 0x21 || (unsigned char)s[i] > 0x7e) return 0;
  return 1;
}

/* ------------------------------------------------------------------------ */
/* Messages                                                                  */
/* ------------------------------------------------------------------------ */

/* "vertex", "face" or the element's own name, printable. */
static const char *elem_word(const ply_elem *e, char out[48]) {
  return io_token_repr(e->name, out);
}

/* "vertices", "faces", "elements 'material'" */
static const char *elem_plural(const ply_elem *e, char out[64]) {
  char name[48];
  if (e->kind == ELEM_VERTEX) return "vertices";
  if (e->kind == ELEM_FACE) return "faces";
  snprintf(out, 64, "'%s' elements", io_token_repr(e->name, name));
  return out;
}

static bsurf_status nomem(ply_reader *r) {
  return bsurf_fail(r->err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
}

/* ------------------------------------------------------------------------ */
/* Header                                                                    */
/* ------------------------------------------------------------------------ */

static bsurf_status add_elem(ply_reader *r, io_token name, unsigned long long count, long line) {
  if (r->nelems == r->cap) {
    size_t cap = r->cap ? 2 * r->cap : 8;
    ply_elem *e = realloc(r->elems, cap * sizeof *e);
    if (!e) return nomem(r);
    r->elems = e;
    r->cap = cap;
  }
  ply_elem *e = &r->elems[r->nelems++];
  memset(e, 0, sizeof *e);
  e->name = name;
  e->count = count;
  e->line = line;
  return BSURF_OK;
}

static bsurf_status add_prop(ply_reader *r, ply_elem *e, const ply_prop *p) {
  if (e->nprops == e->cap) {
    size_t cap = e->cap ? 2 * e->cap : 8;
    ply_prop *props = realloc(e->props, cap * sizeof *props);
    if (!props) return nomem(r);
    e->props = props;
    e->cap = cap;
  }
  e->props[e->nprops++] = *p;
  return BSURF_OK;
}

static bsurf_status parse_header(ply_reader *r) {
  io_text t;
  io_text_init(&t, r->data, r->size);
  const char *line;
  size_t len;
  io_cursor c;
  io_token tok, extra;
  char a[48];

  int ok = io_text_next_line(&t, &line, &len);
  if (ok) {
    io_cursor_init(&c, line, len, IO_SEP_SPACE);
    ok = io_next_token(&c, &tok) && io_token_is(tok, "ply") && !io_next_token(&c, &extra);
  }
  if (!ok && r->size == 0)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, 1, -1, "not a PLY file: the file is empty");
  if (!ok)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, 1, -1,
                      "not a PLY file: the first line is not 'ply'");
  /* The header's line breaks, from its first line: with lone CRs (classic
   * Mac OS), "end_header\r" ends the header of a binary file even when the
   * first data byte is 0x0A (it is not the LF of a CR LF). */
  int cr_only = t.pos >= 1 && r->data[t.pos - 1] == '\r';

  int have_format = 0;
  while (io_text_next_line(&t, &line, &len)) {
    long ln = t.line;
    io_cursor_init(&c, line, len, IO_SEP_SPACE);
    if (!io_next_token(&c, &tok)) continue;
    if (io_token_is(tok, "comment")) {
      /* "comment bootsurf shape NAME": the generated shape the points sample
       * (bsurf_cloud.shape); any other comment is ignored */
      io_token w1, w2, name;
      if (io_next_token(&c, &w1) && io_token_is(w1, "bootsurf") && io_next_token(&c, &w2) &&
          io_token_is(w2, "shape") && io_next_token(&c, &name) && !io_next_token(&c, &extra) &&
          shape_name_ok(name.s, name.len)) {
        memcpy(r->shape, name.s, name.len);
        r->shape[name.len] = 0;
      }
      continue;
    }
    if (io_token_is(tok, "obj_info")) continue;

    if (io_token_is(tok, "format")) {
      io_token enc, ver;
      if (!io_next_token(&c, &enc) || !io_next_token(&c, &ver) || io_next_token(&c, &extra))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                          "the format line must read 'format <encoding> 1.0'");
      if (have_format)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "the header has two format lines");
      if (io_token_is(enc, "ascii"))
        r->format = PLY_ASCII;
      else if (io_token_is(enc, "binary_little_endian"))
        r->format = PLY_LE;
      else if (io_token_is(enc, "binary_big_endian"))
        r->format = PLY_BE;
      else
        return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, ln, -1,
                          "unknown PLY encoding '%s' (expected ascii, binary_little_endian "
                          "or binary_big_endian)",
                          io_token_repr(enc, a));
      double v;
      if (!io_parse_double(ver.s, ver.len, &v) || v != 1.0)
        return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, ln, -1,
                          "PLY version '%s' is not supported (expected 1.0)",
                          io_token_repr(ver, a));
      have_format = 1;
      continue;
    }

    if (io_token_is(tok, "element")) {
      io_token name, count;
      unsigned long long n;
      if (!io_next_token(&c, &name) || !io_next_token(&c, &count) || io_next_token(&c, &extra))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                          "an element line must read 'element <name> <count>'");
      if (!io_parse_u64(count.s, count.len, &n)) {
        size_t digits = 0;
        while (digits < count.len && count.s[digits] >= '0' && count.s[digits] <= '9')
          digits++;
        if (digits == count.len)
          return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                            "element count '%s' is too large (more than 2^64 - 1)",
                            io_token_repr(count, a));
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                          "element count '%s' is not a non-negative integer",
                          io_token_repr(count, a));
      }
      bsurf_status st = add_elem(r, name, n, ln);
      if (st != BSURF_OK) return st;
      continue;
    }

    if (io_token_is(tok, "property")) {
      if (r->nelems == 0)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                          "a property is declared before any element");
      ply_prop p;
      memset(&p, 0, sizeof p);
      p.line = ln;
      io_token ty;
      if (!io_next_token(&c, &ty))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "a property needs a type and a name");
      if (io_token_is(ty, "list")) {
        io_token ct, it;
        p.is_list = 1;
        if (!io_next_token(&c, &ct) || !io_next_token(&c, &it) || !io_next_token(&c, &p.name))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                            "a list property must read 'property list <count type> "
                            "<item type> <name>'");
        if (!io_type_parse(ct.s, ct.len, &p.count_type))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "unknown property type '%s'",
                            io_token_repr(ct, a));
        if (!io_type_parse(it.s, it.len, &p.type))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "unknown property type '%s'",
                            io_token_repr(it, a));
        if (!io_type_is_integer(p.count_type))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                            "the length of a list must have an integer type, not '%s'",
                            io_token_repr(ct, a));
      } else {
        if (!io_type_parse(ty.s, ty.len, &p.type))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "unknown property type '%s'",
                            io_token_repr(ty, a));
        if (!io_next_token(&c, &p.name))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "the property has no name");
      }
      if (io_next_token(&c, &extra))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                          "unexpected '%s' after the property name", io_token_repr(extra, a));
      bsurf_status st = add_prop(r, &r->elems[r->nelems - 1], &p);
      if (st != BSURF_OK) return st;
      continue;
    }

    if (io_token_is(tok, "end_header")) {
      if (io_next_token(&c, &extra))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "unexpected '%s' after end_header",
                          io_token_repr(extra, a));
      if (!have_format)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1, "the header has no format line");
      r->body = t.pos;
      if (cr_only && r->format != PLY_ASCII && t.pos >= 2 &&
          (size_t)(line - r->data) + len + 2 == t.pos && r->data[t.pos - 2] == '\r' &&
          r->data[t.pos - 1] == '\n')
        r->body = t.pos - 1; /* the '\n' is data */
      r->body_line = t.line + 1;
      return BSURF_OK;
    }

    return bsurf_fail(r->err, BSURF_ERR_PARSE, ln, -1,
                      "unknown header keyword '%s' (or a missing end_header line)",
                      io_token_repr(tok, a));
  }
  return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1,
                    "the header does not end (no end_header line)");
}

/* ------------------------------------------------------------------------ */
/* Vertex layout and the cloud                                               */
/* ------------------------------------------------------------------------ */

static ply_prop *find_prop(ply_elem *e, const char *name) {
  for (size_t i = 0; i < e->nprops; i++)
    if (io_token_is(e->props[i].name, name)) return &e->props[i];
  return NULL;
}

/* Binary: the records of `e` starting at `offset` need more than the `left`
 * bytes that follow. */
static bsurf_status too_short(ply_reader *r, const ply_elem *e, unsigned long long offset,
                              unsigned long long left) {
  char a[48], b[64];
  unsigned long long per = e->min_record, whole = left / per;
  if (e->count > ~0ULL / per)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)offset,
                      "header declares %llu %s (more bytes than any file holds) but only %llu "
                      "bytes follow",
                      e->count, elem_plural(e, b), left);
  return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)(offset + whole * per),
                    "header declares %llu %s (%llu bytes) but only %llu bytes follow: the data "
                    "ends inside %s %llu",
                    e->count, elem_plural(e, b), e->count * per, left, elem_word(e, a), whole);
}

/* Checks the layout, checks the declared counts against the data size and
 * allocates the cloud. */
static bsurf_status setup(ply_reader *r, bsurf_cloud *cloud) {
  char a[48], b[64];
  ply_elem *vertex = NULL;
  int have_faces = 0;
  for (size_t i = 0; i < r->nelems; i++) {
    ply_elem *e = &r->elems[i];
    if (io_token_is(e->name, "vertex")) {
      if (vertex)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, e->line, -1,
                          "the header declares a second vertex element");
      vertex = e;
      e->kind = ELEM_VERTEX;
    } else if (io_token_is(e->name, "face")) {
      e->kind = ELEM_FACE;
      for (size_t j = 0; j < e->nprops; j++) {
        ply_prop *p = &e->props[j];
        if (p->is_list &&
            (io_token_is(p->name, "vertex_indices") || io_token_is(p->name, "vertex_index"))) {
          p->is_index = 1;
          if (e->count) have_faces = 1;
          break;
        }
      }
    }
    /* sizes: binary bytes of the smallest record, or values on an ascii line */
    for (size_t j = 0; j < e->nprops; j++) {
      ply_prop *p = &e->props[j];
      p->offset = e->min_record;
      if (r->format == PLY_ASCII)
        e->min_record += 1;
      else
        e->min_record += io_type_size(p->is_list ? p->count_type : p->type);
      if (p->is_list) e->has_list = 1;
    }
  }
  if (!vertex)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, r->body_line - 1, -1,
                      "the file has no vertex element");

  for (size_t j = 0; j < vertex->nprops; j++) {
    ply_prop *p = &vertex->props[j];
    if (p->is_list)
      return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, p->line, -1,
                        "the vertex element has a list property '%s'; only single values "
                        "per vertex are supported",
                        io_token_repr(p->name, a));
    if (p->name.len >= BSURF_FIELD_NAME_MAX)
      return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, p->line, -1,
                        "property name '%s' is too long (at most %d characters)",
                        io_token_repr(p->name, a), BSURF_FIELD_NAME_MAX - 1);
    for (size_t k = 0; k < p->name.len; k++) {
      unsigned char ch = (unsigned char)p->name.s[k];
      if (ch < 0x21 || ch == 0x7f)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, p->line, -1,
                          "property name '%s' contains control characters",
                          io_token_repr(p->name, a));
    }
  }
  /* names declared twice: a hash set, linear in the number of properties
   * (a pairwise check took 80 s on a 100,000-property header) */
  {
    bsurf_nameset names;
    if (bsurf_nameset_init(&names, vertex->nprops) != BSURF_OK) return nomem(r);
    for (size_t j = 0; j < vertex->nprops; j++) {
      ply_prop *p = &vertex->props[j];
      if (bsurf_nameset_insert(&names, p->name.s, p->name.len, j) != BSURF_NAMESET_NONE) {
        bsurf_nameset_free(&names);
        return bsurf_fail(r->err, BSURF_ERR_PARSE, p->line, -1,
                          "vertex property '%s' is declared twice", io_token_repr(p->name, a));
      }
    }
    bsurf_nameset_free(&names);
  }
  static const char *const coord[3] = {"x", "y", "z"};
  static const char *const ncoord[3] = {"nx", "ny", "nz"};
  ply_prop *pc[3], *pn[3];
  for (int k = 0; k < 3; k++) {
    pc[k] = find_prop(vertex, coord[k]);
    if (!pc[k])
      return bsurf_fail(r->err, BSURF_ERR_PARSE, vertex->line, -1,
                        "the vertex element has no '%s' property", coord[k]);
  }
  int with_normals = 1;
  for (int k = 0; k < 3; k++) {
    pn[k] = find_prop(vertex, ncoord[k]);
    if (!pn[k]) with_normals = 0;
  }

  /* Never trust the header: the smallest possible data must fit. */
  unsigned long long left = r->size - r->body, offset = r->body;
  for (size_t i = 0; i < r->nelems; i++) {
    ply_elem *e = &r->elems[i];
    if (e->count == 0 || e->min_record == 0) continue;
    unsigned long long per = e->min_record;
    if (r->format == PLY_ASCII) per *= 2; /* a value and a separator */
    if (e->count > (left + (r->format == PLY_ASCII)) / per) {
      if (r->format == PLY_ASCII) {
        /* The data cannot be complete, but reading it (without storing
         * anything) tells the line where it goes wrong. */
        bsurf_fail(&r->dry_err, BSURF_ERR_PARSE, r->body_line, -1,
                   "header declares %llu %s but only %llu bytes of data follow "
                   "(each needs at least %llu)",
                   e->count, elem_plural(e, b), left, per);
        r->dry = 1;
        break;
      }
      return too_short(r, e, offset, left);
    }
    unsigned long long used = e->count * per;
    left = used > left ? 0 : left - used;
    offset += used;
  }
  if (have_faces && vertex->count > 0xffffffffULL)
    return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, vertex->line, -1,
                      "meshes with more than 4294967295 vertices are not supported");

  r->nv = vertex->count;
  if (r->probe) {
    /* io_ply_probe: the header alone, checked; ascii data too short for it
     * is the error itself (there is no data here to find the line) */
    if (r->dry) {
      if (r->err) *r->err = r->dry_err;
      return BSURF_ERR_PARSE;
    }
    return BSURF_OK;
  }
  if (r->dry) {
    for (size_t j = 0; j < vertex->nprops; j++)
      vertex->props[j].dst = NULL;
    return BSURF_OK;
  }
  /* io_ply_map: a one-point cloud with the file's properties (the schema) */
  size_t n = r->layout ? 1 : (size_t)vertex->count;
  if (bsurf_cloud_alloc(cloud, n, with_normals) != BSURF_OK) return nomem(r);
  cloud->xyz_type = pc[0]->type;
  if (with_normals) cloud->normal_type = pn[0]->type;

  {
    /* the other properties become fields, all at once (one allocation, no
     * name lookups: the names are distinct) */
    size_t nf = 0;
    char *names = bsurf_alloc_array(vertex->nprops ? vertex->nprops : 1, BSURF_FIELD_NAME_MAX);
    const char **np = bsurf_alloc_array(vertex->nprops ? vertex->nprops : 1, sizeof *np);
    bsurf_type *types = bsurf_alloc_array(vertex->nprops ? vertex->nprops : 1, sizeof *types);
    bsurf_status st = names && np && types ? BSURF_OK : BSURF_ERR_NOMEM;
    for (size_t j = 0; j < vertex->nprops && st == BSURF_OK; j++) {
      ply_prop *p = &vertex->props[j];
      int special = 0;
      for (int k = 0; k < 3; k++)
        if (p == pc[k] || (with_normals && p == pn[k])) special = 1;
      if (special) continue;
      char *name = names + nf * BSURF_FIELD_NAME_MAX;
      memcpy(name, p->name.s, p->name.len);
      name[p->name.len] = '\0';
      np[nf] = name;
      types[nf++] = p->type;
    }
    if (st == BSURF_OK) st = bsurf_cloud_add_fields(cloud, nf, np, types);
    free(names);
    free(np);
    free(types);
    if (st != BSURF_OK) return nomem(r);
  }
  /* Destinations, now that the field array no longer moves. */
  size_t f = 0;
  for (size_t j = 0; j < vertex->nprops; j++) {
    ply_prop *p = &vertex->props[j];
    p->dst = NULL;
    p->stride = 1;
    int special = 0;
    for (int k = 0; k < 3; k++) {
      if (p == pc[k]) {
        special = 1;
        p->dst = n ? cloud->xyz + k : NULL; /* no offsets from NULL */
        p->stride = 3;
      } else if (with_normals && p == pn[k]) {
        special = 1;
        p->dst = n ? cloud->normals + k : NULL;
        p->stride = 3;
      }
    }
    p->field = special ? (size_t)-1 : f;
    if (!special) p->dst = cloud->fields[f++].values;
  }
  if (r->layout) {
    io_ply_layout *L = r->layout;
    L->count = (size_t)vertex->count;
    L->record = vertex->min_record;
    L->big_endian = r->format == PLY_BE;
    L->nprops = vertex->nprops;
    L->props = bsurf_alloc_array(vertex->nprops ? vertex->nprops : 1, sizeof *L->props);
    if (!L->props) return nomem(r);
    for (size_t j = 0; j < vertex->nprops; j++) {
      const ply_prop *p = &vertex->props[j];
      io_ply_column *col = &L->props[j];
      col->offset = p->offset;
      col->type = p->type;
      col->stride = p->stride;
      /* where the value goes in a cloud with the schema's arrays */
      col->array = 0;
      col->at = 0;
      for (int k = 0; k < 3; k++) {
        if (p == pc[k]) col->at = (size_t)k;
        if (with_normals && p == pn[k]) col->array = 1, col->at = (size_t)k;
      }
      if (p->field != (size_t)-1) col->array = 2, col->at = p->field;
    }
  }
  return BSURF_OK;
}

/* ------------------------------------------------------------------------ */
/* Binary data                                                               */
/* ------------------------------------------------------------------------ */

static double get_value(const unsigned char *p, bsurf_type type, int be) {
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
                      elem_word(e, a), rec, v, r->nv);
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
      /* fixed-size records (setup() checked their minimum, but a list
       * element before them may have taken more than its minimum) */
      size_t rec = e->min_record;
      if (e->count > (r->size - pos) / rec) return too_short(r, e, pos, r->size - pos);
      if (e->kind == ELEM_VERTEX && r->layout) {
        r->layout->body = pos;
      } else if (e->kind == ELEM_VERTEX) {
        size_t n = (size_t)e->count;
        const unsigned char *p = d + pos;
        for (size_t i = 0; i < n; i++, p += rec)
          for (size_t j = 0; j < e->nprops; j++) {
            const ply_prop *q = &e->props[j];
            q->dst[i * q->stride] = get_value(p + q->offset, q->type, be);
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
                            "%s %llu: the file ends in the middle of the record", elem_word(e, a),
                            ri);
        if (!q->is_list) {
          pos += s;
          continue;
        }
        double cnt = get_value(d + pos, q->count_type, be);
        pos += s;
        if (cnt < 0)
          return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)start,
                            "%s %llu: negative list length %.0f", elem_word(e, a), ri, cnt);
        unsigned long long n = (unsigned long long)cnt;
        size_t is = io_type_size(q->type);
        if (n > (r->size - pos) / is)
          return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)pos,
                            "%s %llu: a list of %llu values needs %llu bytes but only %zu "
                            "bytes follow",
                            elem_word(e, a), ri, n, n * is, r->size - pos);
        if (q->is_index) {
          io_faces_begin(&r->faces);
          for (unsigned long long k = 0; k < n; k++) {
            uint32_t idx = 0;
            bsurf_status st = check_index(r, e, ri, get_value(d + pos + k * is, q->type, be), 0,
                                          (long long)start, &idx);
            if (st != BSURF_OK) return st;
            if (io_faces_corner(&r->faces, idx) != BSURF_OK) return nomem(r);
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
                    elem_word(e, a), ri, at_least ? "at least " : "", need,
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
                            elem_word(e, a), ri, e->count, elem_plural(e, b));
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
                            elem_word(e, a), ri, io_token_repr(tok, b));
        if (!q->is_list) {
          /* the value the declared type holds, as binary data would give */
          if (q->dst) q->dst[ri * q->stride] = io_type_convert(v, q->type);
          continue;
        }
        if (!(v >= 0 && v == floor(v) && v <= 4294967295.0))
          return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1,
                            "%s %llu: list length '%s' is not a non-negative integer",
                            elem_word(e, a), ri, io_token_repr(tok, b));
        unsigned long long n = (unsigned long long)v;
        if (q->is_index) io_faces_begin(&r->faces);
        for (unsigned long long k = 0; k < n; k++) {
          if (!io_next_token(&c, &tok))
            return short_record(r, e, ri, used + (size_t)(n - k) + (e->nprops - j - 1), later_list,
                                &c0, t.line);
          used++;
          if (!io_parse_double(tok.s, tok.len, &v))
            return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1, "%s %llu: '%s' is not a number",
                              elem_word(e, a), ri, io_token_repr(tok, b));
          if (q->is_index) {
            uint32_t idx = 0;
            bsurf_status st = check_index(r, e, ri, v, t.line, -1, &idx);
            if (st != BSURF_OK) return st;
            if (io_faces_corner(&r->faces, idx) != BSURF_OK) return nomem(r);
          }
        }
      }
      if (io_next_token(&c, &tok))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, t.line, -1,
                          "%s %llu: expected %zu values, found %zu", elem_word(e, a), ri, used,
                          io_count_tokens(&c0));
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
  bsurf_status st = parse_header(&r);
  if (st == BSURF_OK) st = setup(&r, cloud);
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
  bsurf_status st = parse_header(&r);
  if (st == BSURF_OK) {
    bsurf_cloud unused;
    bsurf_cloud_init(&unused);
    r.size = file_size > size ? (size_t)file_size : size; /* the checks count the whole file */
    st = setup(&r, &unused);
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
  bsurf_status st = parse_header(&r);
  if (st == BSURF_OK && r.format == PLY_ASCII)
    st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, 0, -1,
                    "an ascii PLY file; tiled runs read binary PLY (convert it first)");
  for (size_t i = 0; st == BSURF_OK && i < r.nelems; i++)
    if (io_token_is(r.elems[i].name, "face") && r.elems[i].count)
      st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, r.elems[i].line, -1,
                      "the file is a mesh (it has faces); tiled runs take point clouds");
  if (st == BSURF_OK) st = setup(&r, schema);
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
    double v = get_value(p + col->offset, col->type, L->big_endian);
    double *dst = col->array == 0   ? c->xyz + 3 * j + col->at
                  : col->array == 1 ? c->normals + 3 * j + col->at
                                    : c->fields[col->at].values + j;
    *dst = v;
  }
}

/* ------------------------------------------------------------------------ */
/* Writer                                                                    */
/* ------------------------------------------------------------------------ */

bsurf_status bsurf_io_ply_check(const bsurf_cloud *cloud, bsurf_failure *err) {
  for (size_t i = 0; i < cloud->field_count; i++) {
    const char *name = cloud->fields[i].name;
    if (!name[0]) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "a field has an empty name");
    for (const char *p = name; *p; p++)
      if ((unsigned char)*p < 0x21 || *p == 0x7f)
        return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                          "field name '%s' contains spaces or control characters", name);
    int reserved = !strcmp(name, "x") || !strcmp(name, "y") || !strcmp(name, "z");
    if (cloud->normals)
      reserved |= !strcmp(name, "nx") || !strcmp(name, "ny") || !strcmp(name, "nz");
    if (reserved)
      return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                        "field '%s' has the name of a coordinate", name);
    for (size_t k = 0; k < i; k++)
      if (!strcmp(cloud->fields[k].name, name))
        return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "two fields are called '%s'", name);
  }
  return BSURF_OK;
}

/* One column of the vertex record. */
typedef struct out_prop {
  const double *src;
  size_t stride;
  bsurf_type type;
} out_prop;

static unsigned char *put_value(unsigned char *o, double v, bsurf_type type) {
  switch (type) {
  case BSURF_FLOAT64: {
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    for (int i = 0; i < 8; i++)
      o[i] = (unsigned char)(u >> (8 * i));
    return o + 8;
  }
  case BSURF_FLOAT32: {
    float f = (float)io_type_convert(v, BSURF_FLOAT32);
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    for (int i = 0; i < 4; i++)
      o[i] = (unsigned char)(u >> (8 * i));
    return o + 4;
  }
  default: {
    /* two's complement of the rounded, clamped value */
    uint64_t u = (uint64_t)(long long)io_type_convert(v, type);
    size_t n = io_type_size(type);
    for (size_t i = 0; i < n; i++)
      o[i] = (unsigned char)(u >> (8 * i));
    return o + n;
  }
  }
}

static size_t vertex_layout(const bsurf_cloud *cloud, out_prop *props) {
  size_t n = 0;
  /* an empty cloud may have NULL arrays: no offsets from NULL */
  for (int k = 0; k < 3; k++)
    props[n++] = (out_prop){cloud->xyz ? cloud->xyz + k : NULL, 3, cloud->xyz_type};
  if (cloud->normals)
    for (int k = 0; k < 3; k++)
      props[n++] = (out_prop){cloud->normals + k, 3, cloud->normal_type};
  for (size_t i = 0; i < cloud->field_count; i++)
    props[n++] = (out_prop){cloud->fields[i].values, 1, cloud->fields[i].type};
  return n;
}

static void write_header(io_writer *w, const bsurf_cloud *cloud, const out_prop *props, size_t np,
                         size_t point_count, int ascii) {
  static const char *const coord[6] = {"x", "y", "z", "nx", "ny", "nz"};
  /* Face indices as int (what every reader expects) unless they do not fit. */
  int wide = point_count > 0x7fffffffu;

  io_write_fmt(w, "ply\nformat %s 1.0\ncomment generated by bootsurf %s\n",
               ascii ? "ascii" : "binary_little_endian", BSURF_VERSION_STRING);
  const char *shape_end = memchr(cloud->shape, 0, sizeof cloud->shape);
  if (shape_end && shape_name_ok(cloud->shape, (size_t)(shape_end - cloud->shape)))
    io_write_fmt(w, "comment bootsurf shape %s\n", cloud->shape);
  io_write_fmt(w, "element vertex %zu\n", point_count);
  size_t nfixed = cloud->normals ? 6 : 3;
  for (size_t j = 0; j < np; j++)
    io_write_fmt(w, "property %s %s\n", io_type_name(props[j].type),
                 j < nfixed ? coord[j] : cloud->fields[j - nfixed].name);
  if (cloud->face_count)
    io_write_fmt(w, "element face %zu\nproperty list uchar %s vertex_indices\n", cloud->face_count,
                 wide ? "uint" : "int");
  io_write_str(w, "end_header\n");
}

bsurf_status io_ply_write_header(io_writer *w, const bsurf_cloud *schema, size_t point_count,
                                 size_t *record) {
  size_t np = 3 + (schema->normals ? 3u : 0u) + schema->field_count;
  out_prop *props = bsurf_alloc_array(np, sizeof *props);
  if (!props) return BSURF_ERR_NOMEM;
  vertex_layout(schema, props);
  write_header(w, schema, props, np, point_count, 0);
  *record = 0;
  for (size_t j = 0; j < np; j++)
    *record += io_type_size(props[j].type);
  free(props);
  return BSURF_OK;
}

bsurf_status io_ply_encode(const bsurf_cloud *cloud, unsigned char *out) {
  size_t np = 3 + (cloud->normals ? 3u : 0u) + cloud->field_count;
  out_prop *props = bsurf_alloc_array(np, sizeof *props);
  if (!props) return BSURF_ERR_NOMEM;
  vertex_layout(cloud, props);
  for (size_t i = 0; i < cloud->point_count; i++)
    for (size_t j = 0; j < np; j++)
      out = put_value(out, props[j].src[i * props[j].stride], props[j].type);
  free(props);
  return BSURF_OK;
}

bsurf_status bsurf_io_write_ply(io_writer *w, const bsurf_cloud *cloud, int ascii,
                                bsurf_failure *err) {
  size_t np = 3 + (cloud->normals ? 3u : 0u) + cloud->field_count;
  out_prop *props = bsurf_alloc_array(np, sizeof *props);
  if (!props) return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  vertex_layout(cloud, props);
  write_header(w, cloud, props, np, cloud->point_count, ascii);

  bsurf_status st = BSURF_OK;
  if (ascii) {
    io_obuf ob;
    if (io_obuf_init(&ob, w) != BSURF_OK) {
      free(props);
      return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
    }
    for (size_t i = 0; i < cloud->point_count && !w->failed; i++) {
      for (size_t j = 0; j < np; j++) {
        if (j) io_obuf_char(&ob, ' ');
        io_obuf_value(&ob, props[j].src[i * props[j].stride], props[j].type);
      }
      io_obuf_char(&ob, '\n');
    }
    for (size_t i = 0; i < cloud->face_count && !w->failed; i++) {
      const uint32_t *f = cloud->faces + 3 * i;
      io_obuf_str(&ob, "3 ");
      io_obuf_uint(&ob, f[0]);
      io_obuf_char(&ob, ' ');
      io_obuf_uint(&ob, f[1]);
      io_obuf_char(&ob, ' ');
      io_obuf_uint(&ob, f[2]);
      io_obuf_char(&ob, '\n');
    }
    io_obuf_done(&ob);
    free(props);
    return st;
  }

  size_t rec = 0;
  for (size_t j = 0; j < np; j++)
    rec += io_type_size(props[j].type);
  size_t cap = (size_t)1 << 20;
  if (cap < rec) cap = rec;
  unsigned char *buf = malloc(cap);
  if (!buf) {
    free(props);
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  }
  size_t per_chunk = cap / rec;
  for (size_t i0 = 0; i0 < cloud->point_count && !w->failed; i0 += per_chunk) {
    size_t i1 = i0 + per_chunk < cloud->point_count ? i0 + per_chunk : cloud->point_count;
    unsigned char *o = buf;
    for (size_t i = i0; i < i1; i++)
      for (size_t j = 0; j < np; j++)
        o = put_value(o, props[j].src[i * props[j].stride], props[j].type);
    io_write_bytes(w, buf, (size_t)(o - buf));
  }
  per_chunk = cap / 13;
  for (size_t i0 = 0; i0 < cloud->face_count && !w->failed; i0 += per_chunk) {
    size_t i1 = i0 + per_chunk < cloud->face_count ? i0 + per_chunk : cloud->face_count;
    unsigned char *o = buf;
    for (size_t i = i0; i < i1; i++) {
      *o++ = 3;
      for (int k = 0; k < 3; k++) {
        uint32_t u = cloud->faces[3 * i + (size_t)k];
        for (int b = 0; b < 4; b++)
          *o++ = (unsigned char)(u >> (8 * b));
      }
    }
    io_write_bytes(w, buf, (size_t)(o - buf));
  }
  free(buf);
  free(props);
  return st;
}
