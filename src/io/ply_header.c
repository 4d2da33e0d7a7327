/* PLY (Stanford polygon file format 1.0), reading, part 1: the header (its
 * elements and properties) and the vertex layout it declares.
 *
 * Reading never trusts the header: before anything is allocated, every
 * element's declared count times its smallest possible record size is checked
 * against the bytes that follow, and every variable-length record is checked
 * again as it is read (ply_read.c). */
#include "io/ply_reader.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A shape name a header line can carry: one printable word that fits. */
int io_ply_shape_name_ok(const char *s, size_t len) {
  if (len == 0 || len >= BSURF_FIELD_NAME_MAX) return 0;
  for (size_t i = 0; i < len; i++)
    if ((unsigned char)s[i] < 0x21 || (unsigned char)s[i] > 0x7e) return 0;
  return 1;
}

/* ------------------------------------------------------------------------ */
/* Messages                                                                  */
/* ------------------------------------------------------------------------ */

/* "vertex", "face" or the element's own name, printable. */
const char *io_ply_elem_word(const ply_elem *e, char out[48]) {
  return io_token_repr(e->name, out);
}

/* "vertices", "faces", "elements 'material'" */
const char *io_ply_elem_plural(const ply_elem *e, char out[64]) {
  char name[48];
  if (e->kind == ELEM_VERTEX) return "vertices";
  if (e->kind == ELEM_FACE) return "faces";
  snprintf(out, 64, "'%s' elements", io_token_repr(e->name, name));
  return out;
}

bsurf_status io_ply_nomem(ply_reader *r) {
  return bsurf_fail(r->err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
}

/* ------------------------------------------------------------------------ */
/* Header                                                                    */
/* ------------------------------------------------------------------------ */

static bsurf_status add_elem(ply_reader *r, io_token name, unsigned long long count, long line) {
  if (r->nelems == r->cap) {
    size_t cap = r->cap ? 2 * r->cap : 8;
    ply_elem *e = realloc(r->elems, cap * sizeof *e);
    if (!e) return io_ply_nomem(r);
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
    if (!props) return io_ply_nomem(r);
    e->props = props;
    e->cap = cap;
  }
  e->props[e->nprops++] = *p;
  return BSURF_OK;
}

/* "comment bootsurf shape NAME": the generated shape the points sample
 * (bsurf_cloud.shape); "comment bootsurf ply-names cloudcompare|meshlab": the
 * names were written for a viewer (--ply-names) and are read back as they
 * were (io_ply_setup). Any other comment is ignored. */
static void bootsurf_comment(ply_reader *r, io_cursor *c) {
  io_token w1, w2, name, extra;
  if (!io_next_token(c, &w1) || !io_token_is(w1, "bootsurf") || !io_next_token(c, &w2) ||
      !io_next_token(c, &name) || io_next_token(c, &extra))
    return;
  if (io_token_is(w2, "shape") && io_ply_shape_name_ok(name.s, name.len)) {
    memcpy(r->shape, name.s, name.len);
    r->shape[name.len] = 0;
  } else if (io_token_is(w2, "ply-names")) {
    if (io_token_is(name, "cloudcompare")) r->names = BSURF_PLY_NAMES_CLOUDCOMPARE;
    if (io_token_is(name, "meshlab")) r->names = BSURF_PLY_NAMES_MESHLAB;
  }
}

bsurf_status io_ply_parse_header(ply_reader *r) {
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
      bootsurf_comment(r, &c);
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
bsurf_status io_ply_too_short(ply_reader *r, const ply_elem *e, unsigned long long offset,
                              unsigned long long left) {
  char a[48], b[64];
  unsigned long long per = e->min_record, whole = left / per;
  if (e->count > ~0ULL / per)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)offset,
                      "header declares %llu %s (more bytes than any file holds) but only %llu "
                      "bytes follow",
                      e->count, io_ply_elem_plural(e, b), left);
  return bsurf_fail(r->err, BSURF_ERR_PARSE, 0, (long long)(offset + whole * per),
                    "header declares %llu %s (%llu bytes) but only %llu bytes follow: the data "
                    "ends inside %s %llu",
                    e->count, io_ply_elem_plural(e, b), e->count * per, left,
                    io_ply_elem_word(e, a), whole);
}

/* A file bootsurf wrote with --ply-names cloudcompare ("comment bootsurf
 * ply-names cloudcompare") has every field as scalar_NAME: its fields are read
 * as NAME again. Returns the length of the prefix to drop from every field's
 * name: 7, or 0 when some field lacks the prefix or would become a
 * coordinate's name (a file edited since: the names stay as they are). */
static size_t strip_prefix(const ply_reader *r, const ply_elem *vertex, ply_prop *const pc[3],
                           ply_prop *const pn[3]) {
  static const char *const reserved[6] = {"x", "y", "z", "nx", "ny", "nz"};
  const size_t k = 7; /* strlen("scalar_") */
  if (r->names != BSURF_PLY_NAMES_CLOUDCOMPARE) return 0;
  for (size_t j = 0; j < vertex->nprops; j++) {
    const ply_prop *p = &vertex->props[j];
    if (p == pc[0] || p == pc[1] || p == pc[2]) continue;
    if (pn && (p == pn[0] || p == pn[1] || p == pn[2])) continue;
    if (p->name.len <= k || memcmp(p->name.s, "scalar_", k) != 0) return 0;
    io_token rest = {p->name.s + k, p->name.len - k};
    for (int q = 0; q < (pn ? 6 : 3); q++)
      if (io_token_is(rest, reserved[q])) return 0;
  }
  return k;
}

/* A file bootsurf wrote with --ply-names meshlab ("comment bootsurf ply-names
 * meshlab") ends its vertex with a float copy of the first field called
 * quality: that property is not read. NULL when there is none. */
static const ply_prop *quality_copy(const ply_reader *r, const ply_elem *vertex) {
  if (r->names != BSURF_PLY_NAMES_MESHLAB || vertex->nprops == 0) return NULL;
  const ply_prop *last = &vertex->props[vertex->nprops - 1];
  return io_token_is(last->name, "quality") && last->type == BSURF_FLOAT32 ? last : NULL;
}

/* Element kinds (vertex, face with its index list) and each element's
 * smallest record: binary bytes, or values on an ascii line. */
static bsurf_status classify_elements(ply_reader *r, ply_elem **vertex, int *have_faces) {
  *vertex = NULL;
  *have_faces = 0;
  for (size_t i = 0; i < r->nelems; i++) {
    ply_elem *e = &r->elems[i];
    if (io_token_is(e->name, "vertex")) {
      if (*vertex)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, e->line, -1,
                          "the header declares a second vertex element");
      *vertex = e;
      e->kind = ELEM_VERTEX;
    } else if (io_token_is(e->name, "face")) {
      e->kind = ELEM_FACE;
      for (size_t j = 0; j < e->nprops; j++) {
        ply_prop *p = &e->props[j];
        if (p->is_list &&
            (io_token_is(p->name, "vertex_indices") || io_token_is(p->name, "vertex_index"))) {
          p->is_index = 1;
          if (e->count) *have_faces = 1;
          break;
        }
      }
    }
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
  if (!*vertex)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, r->body_line - 1, -1,
                      "the file has no vertex element");
  return BSURF_OK;
}

/* The vertex properties: single values, printable names of a field's
 * length, each declared once. */
static bsurf_status check_vertex_props(ply_reader *r, const ply_elem *vertex) {
  char a[48];
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
    if (bsurf_nameset_init(&names, vertex->nprops) != BSURF_OK) return io_ply_nomem(r);
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
  return BSURF_OK;
}

/* Never trust the header: the smallest possible data of every element must
 * fit in the bytes after it (ascii: too little data is only validated, in a
 * dry run that finds the line where it ends). */
static bsurf_status check_sizes(ply_reader *r) {
  char b[64];
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
                   e->count, io_ply_elem_plural(e, b), left, per);
        r->dry = 1;
        break;
      }
      return io_ply_too_short(r, e, offset, left);
    }
    unsigned long long used = e->count * per;
    left = used > left ? 0 : left - used;
    offset += used;
  }
  return BSURF_OK;
}

/* The other properties become fields, all at once (one allocation, no name
 * lookups: the names are distinct); then every property's destination, now
 * that the field array no longer moves. pn: NULL without normals. */
static bsurf_status make_fields(ply_reader *r, ply_elem *vertex, bsurf_cloud *cloud, size_t n,
                                ply_prop *const pc[3], ply_prop *const pn[3]) {
  /* --ply-names read back: the names bootsurf wrote for a viewer */
  size_t strip = strip_prefix(r, vertex, pc, pn);
  const ply_prop *copy = quality_copy(r, vertex);
  size_t nf = 0, cap = vertex->nprops ? vertex->nprops : 1;
  char *names = bsurf_alloc_array(cap, BSURF_FIELD_NAME_MAX);
  const char **np = bsurf_alloc_array(cap, sizeof *np);
  bsurf_type *types = bsurf_alloc_array(cap, sizeof *types);
  bsurf_status st = names && np && types ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t j = 0; j < vertex->nprops && st == BSURF_OK; j++) {
    ply_prop *p = &vertex->props[j];
    int special = 0;
    for (int k = 0; k < 3; k++)
      if (p == pc[k] || (pn && p == pn[k])) special = 1;
    if (special || p == copy) continue;
    char *name = names + nf * BSURF_FIELD_NAME_MAX;
    memcpy(name, p->name.s + strip, p->name.len - strip);
    name[p->name.len - strip] = '\0';
    np[nf] = name;
    types[nf++] = p->type;
  }
  if (st == BSURF_OK) st = bsurf_cloud_add_fields(cloud, nf, np, types);
  free(names);
  free(np);
  free(types);
  if (st != BSURF_OK) return io_ply_nomem(r);
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
      } else if (pn && p == pn[k]) {
        special = 1;
        p->dst = n ? cloud->normals + k : NULL;
        p->stride = 3;
      }
    }
    p->field = special || p == copy ? (size_t)-1 : f;
    if (p->field != (size_t)-1) p->dst = cloud->fields[f++].values;
  }
  return BSURF_OK;
}

/* io_ply_map: where each vertex property is in a record and where it goes
 * in a cloud with the schema's arrays. */
static bsurf_status fill_layout(ply_reader *r, const ply_elem *vertex, ply_prop *const pc[3],
                                ply_prop *const pn[3]) {
  const ply_prop *copy = quality_copy(r, vertex);
  io_ply_layout *L = r->layout;
  L->count = (size_t)vertex->count;
  L->record = vertex->min_record;
  L->big_endian = r->format == PLY_BE;
  L->nprops = vertex->nprops;
  L->props = bsurf_alloc_array(vertex->nprops ? vertex->nprops : 1, sizeof *L->props);
  if (!L->props) return io_ply_nomem(r);
  for (size_t j = 0; j < vertex->nprops; j++) {
    const ply_prop *p = &vertex->props[j];
    io_ply_column *col = &L->props[j];
    col->offset = p->offset;
    col->type = p->type;
    col->stride = p->stride;
    col->array = 0;
    col->at = 0;
    for (int k = 0; k < 3; k++) {
      if (p == pc[k]) col->at = (size_t)k;
      if (pn && p == pn[k]) col->array = 1, col->at = (size_t)k;
    }
    if (p->field != (size_t)-1) col->array = 2, col->at = p->field;
    if (p == copy) col->array = 3;
  }
  return BSURF_OK;
}

/* Checks the layout, checks the declared counts against the data size and
 * allocates the cloud. */
bsurf_status io_ply_setup(ply_reader *r, bsurf_cloud *cloud) {
  ply_elem *vertex;
  int have_faces;
  bsurf_status st = classify_elements(r, &vertex, &have_faces);
  if (st == BSURF_OK) st = check_vertex_props(r, vertex);
  if (st != BSURF_OK) return st;
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
  st = check_sizes(r);
  if (st != BSURF_OK) return st;
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
  if (bsurf_cloud_alloc(cloud, n, with_normals) != BSURF_OK) return io_ply_nomem(r);
  cloud->xyz_type = pc[0]->type;
  if (with_normals) cloud->normal_type = pn[0]->type;
  st = make_fields(r, vertex, cloud, n, pc, with_normals ? pn : NULL);
  if (st == BSURF_OK && r->layout) st = fill_layout(r, vertex, pc, with_normals ? pn : NULL);
  return st;
}

/* ------------------------------------------------------------------------ */
/* Binary data                                                               */
