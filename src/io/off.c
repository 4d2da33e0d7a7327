/* OFF (Geomview object file format): OFF, NOFF, COFF, NCOFF/CNOFF and STOFF
 * variants; '#' comments and blank lines anywhere; polygons are
 * fan-triangulated. Writes OFF or NOFF with %.17g coordinates. */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

/* The next line with content: comment stripped, cursor at its start. */
static int next_data_line(io_text *t, io_cursor *c) {
  const char *line;
  size_t len;
  while (io_text_next_line(t, &line, &len)) {
    len = io_strip_comment(line, len);
    io_cursor_init(c, line, len, IO_SEP_SPACE);
    io_cursor probe = *c;
    io_token tok;
    if (io_next_token(&probe, &tok)) return 1;
  }
  return 0;
}

/* A colour component read as an integer literal in 0..255. */
static int is_byte_literal(io_token tok) {
  unsigned long long v;
  return io_parse_u64(tok.s, tok.len, &v) && v <= 255;
}

/* The reader's state between the header, the vertices and the faces. */
typedef struct off_reader {
  io_text t;
  bsurf_failure *err;
  int has_st, has_c, has_n;  /* the keyword's ST, C, N prefixes */
  unsigned long long nv, nf; /* declared counts */
  long counts_ln;            /* the line of the counts */
  int dry;                   /* the counts cannot fit: validate only */
  bsurf_failure dry_err;     /* the error to report if validation finds nothing */
} off_reader;

/* The keyword (optional: [ST][C][N]OFF) and the counts line. */
static bsurf_status read_header(off_reader *r) {
  io_cursor c;
  io_token tok;
  char a[48];
  if (!next_data_line(&r->t, &c))
    return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line ? r->t.line : 1, -1,
                      "not an OFF file: it has no header");
  io_cursor counts_line = c;
  io_next_token(&c, &tok);
  if (tok.len >= 3 && memcmp(tok.s + tok.len - 3, "OFF", 3) == 0) {
    size_t plen = tok.len - 3, i = 0;
    int has_4 = 0, has_dim = 0, bad = 0;
    if (plen >= 2 && tok.s[0] == 'S' && tok.s[1] == 'T') {
      r->has_st = 1;
      i = 2;
    }
    for (; i < plen; i++) {
      int *flag = tok.s[i] == 'C'   ? &r->has_c
                  : tok.s[i] == 'N' ? &r->has_n
                  : tok.s[i] == '4' ? &has_4
                  : tok.s[i] == 'n' ? &has_dim
                                    : NULL;
      if (!flag || *flag)
        bad = 1;
      else
        *flag = 1;
    }
    if (bad)
      return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1, "unknown OFF keyword '%s'",
                        io_token_repr(tok, a));
    if (has_4 || has_dim)
      return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, r->t.line, -1,
                        "'%s' files (4-dimensional or n-dimensional) are not supported",
                        io_token_repr(tok, a));
    counts_line = c;
    io_cursor probe = c;
    if (!io_next_token(&probe, &tok)) {
      /* the counts are on the next line */
      if (!next_data_line(&r->t, &counts_line))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line + 1, -1,
                          "the file ends before the counts line 'vertices faces edges'");
    }
  } else {
    /* the keyword is optional: then this line holds the counts */
    unsigned long long dummy;
    if (!io_parse_u64(tok.s, tok.len, &dummy))
      return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1,
                        "not an OFF file: it does not start with 'OFF'");
  }

  r->counts_ln = r->t.line;
  unsigned long long counts[3] = {0, 0, 0};
  size_t ncounts = 0;
  while (io_next_token(&counts_line, &tok)) {
    if (ncounts == 3 || !io_parse_u64(tok.s, tok.len, &counts[ncounts]))
      return bsurf_fail(r->err, BSURF_ERR_PARSE, r->counts_ln, -1,
                        "expected the counts 'vertices faces edges', found '%s'",
                        io_token_repr(tok, a));
    ncounts++;
  }
  if (ncounts < 2)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, r->counts_ln, -1,
                      "expected the counts 'vertices faces edges'");
  r->nv = counts[0];
  r->nf = counts[1];
  return BSURF_OK;
}

/* Never trust the counts: a vertex line takes at least 6 bytes ("0 0 0\n"),
 * a face line 2 ("0\n"). If they cannot fit, the data are only validated
 * (nothing is stored), which finds the line where they go wrong. */
static bsurf_status check_counts(off_reader *r, size_t size) {
  unsigned long long left = size - r->t.pos + 1, nv = r->nv, nf = r->nf;
  if (nv > left / 6) {
    r->dry = 1;
    bsurf_fail(&r->dry_err, BSURF_ERR_PARSE, r->counts_ln, -1,
               "header declares %llu vertices but only %llu bytes follow", nv, left - 1);
  } else if (nf > (left - nv * 6) / 2) {
    r->dry = 1;
    bsurf_fail(&r->dry_err, BSURF_ERR_PARSE, r->counts_ln, -1,
               "header declares %llu faces but only %llu bytes follow the vertices", nf,
               left - nv * 6 > 0 ? left - nv * 6 - 1 : 0);
  }
  if (!r->dry && nf > 0 && nv > 0xffffffffULL)
    return bsurf_fail(r->err, BSURF_ERR_UNSUPPORTED, r->counts_ln, -1,
                      "meshes with more than 4294967295 vertices are not supported");
  return BSURF_OK;
}

/* The vertex lines: x y z [nx ny nz] [r g b [a]] [s t]; colours become the
 * fields red green blue (alpha), uint8 when every value is a byte literal. */
static bsurf_status read_vertices(off_reader *r, bsurf_cloud *cloud) {
  io_cursor c;
  io_token tok;
  char a[48];
  size_t base = 3 + (r->has_n ? 3 : 0);
  size_t ncolour = 0, ncols = base + (r->has_st ? 2 : 0);
  double *colour[4] = {NULL, NULL, NULL, NULL};
  int colour_bytes = 1, dry = r->dry;
  static const char *const colour_name[4] = {"red", "green", "blue", "alpha"};
  for (unsigned long long i = 0; i < r->nv; i++) {
    if (!next_data_line(&r->t, &c))
      return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line + 1, -1,
                        "vertex %llu: unexpected end of file (header declares %llu vertices)", i,
                        r->nv);
    size_t found = io_count_tokens(&c);
    if (i == 0 && r->has_c) {
      /* the first vertex tells whether the colours have an alpha */
      if (found != ncols + 3 && found != ncols + 4)
        return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1,
                          "vertex 0: expected %zu or %zu values, found %zu", ncols + 3, ncols + 4,
                          found);
      ncolour = found - ncols;
      ncols = found;
      for (size_t k = 0; k < ncolour && !dry; k++)
        if (!bsurf_cloud_add_field(cloud, colour_name[k], BSURF_FLOAT32)) return io_nomem(r->err);
      for (size_t k = 0; k < ncolour && !dry; k++)
        colour[k] = cloud->fields[k].values;
    }
    if (found != ncols)
      return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1,
                        "vertex %llu: expected %zu values, found %zu", i, ncols, found);
    for (size_t k = 0; k < ncols; k++) {
      double v;
      io_next_token(&c, &tok);
      if (!io_parse_double(tok.s, tok.len, &v))
        return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1,
                          "vertex %llu: '%s' is not a number", i, io_token_repr(tok, a));
      if (dry)
        continue;
      else if (k < 3)
        cloud->xyz[3 * i + k] = v;
      else if (k < base)
        cloud->normals[3 * i + k - 3] = v;
      else if (k < base + ncolour) {
        colour[k - base][i] = v;
        if (colour_bytes && !is_byte_literal(tok)) colour_bytes = 0;
      }
      /* texture coordinates (ST) are dropped */
    }
  }
  if (ncolour && colour_bytes && !dry)
    for (size_t k = 0; k < ncolour; k++)
      cloud->fields[k].type = BSURF_UINT8;
  return BSURF_OK;
}

/* One face line: n i_1 .. i_n [colour]; polygons are fanned into triangles. */
static bsurf_status read_face(off_reader *r, io_faces *faces, unsigned long long fi) {
  io_cursor c;
  io_token tok;
  char a[48];
  if (!next_data_line(&r->t, &c))
    return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line + 1, -1,
                      "face %llu: unexpected end of file (header declares %llu faces)", fi, r->nf);
  size_t found = io_count_tokens(&c);
  unsigned long long corners;
  io_next_token(&c, &tok);
  if (!io_parse_u64(tok.s, tok.len, &corners))
    return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1,
                      "face %llu: '%s' is not a number of vertices", fi, io_token_repr(tok, a));
  if (found - 1 < corners || found - 1 - corners > 4)
    return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1,
                      "face %llu: expected %llu vertex indices (and at most 4 colour values), "
                      "found %zu values",
                      fi, corners, found - 1);
  io_faces_begin(faces);
  for (unsigned long long k = 0; k < corners; k++) {
    unsigned long long idx;
    io_next_token(&c, &tok);
    if (!io_parse_u64(tok.s, tok.len, &idx) || idx >= r->nv)
      return bsurf_fail(r->err, BSURF_ERR_PARSE, r->t.line, -1,
                        "face %llu: vertex index '%s' is out of range (the file has %llu "
                        "vertices)",
                        fi, io_token_repr(tok, a), r->nv);
    if (io_faces_corner(faces, (uint32_t)idx) != BSURF_OK) return io_nomem(r->err);
  }
  /* a face colour, if any, is dropped */
  return BSURF_OK;
}

bsurf_status bsurf_io_read_off(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_failure *err) {
  off_reader r;
  memset(&r, 0, sizeof r);
  io_text_init(&r.t, data, size);
  r.err = err;
  bsurf_status st = read_header(&r);
  if (st == BSURF_OK) st = check_counts(&r, size);
  if (st != BSURF_OK) return st;
  if (!r.dry && bsurf_cloud_alloc(cloud, (size_t)r.nv, r.has_n) != BSURF_OK) return io_nomem(err);
  st = read_vertices(&r, cloud);
  if (st != BSURF_OK) return st;

  io_faces faces;
  io_faces_init(&faces);
  for (unsigned long long fi = 0; fi < r.nf && st == BSURF_OK; fi++)
    st = read_face(&r, &faces, fi);
  if (st == BSURF_OK && r.dry) {
    if (err) *err = r.dry_err;
    st = BSURF_ERR_PARSE;
  }
  if (st != BSURF_OK) {
    io_faces_free(&faces);
    return st;
  }
  io_faces_move(&faces, cloud);

  io_cursor c;
  io_token tok;
  char a[48];
  if (next_data_line(&r.t, &c)) {
    io_next_token(&c, &tok);
    return bsurf_fail(err, BSURF_ERR_PARSE, r.t.line, -1,
                      "unexpected data after the last face declared in the header: '%s'",
                      io_token_repr(tok, a));
  }
  return BSURF_OK;
}

bsurf_status bsurf_io_write_off(io_writer *w, const bsurf_cloud *cloud, bsurf_failure *err) {
  io_obuf ob;
  if (io_obuf_init(&ob, w) != BSURF_OK)
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  io_obuf_str(&ob, cloud->normals ? "NOFF\n" : "OFF\n");
  io_obuf_uint(&ob, cloud->point_count);
  io_obuf_char(&ob, ' ');
  io_obuf_uint(&ob, cloud->face_count);
  io_obuf_str(&ob, " 0\n");
  for (size_t i = 0; i < cloud->point_count && !w->failed; i++) {
    io_obuf_point(&ob, cloud, i, ' ');
    io_obuf_char(&ob, '\n');
  }
  for (size_t i = 0; i < cloud->face_count && !w->failed; i++) {
    io_obuf_str(&ob, "3");
    for (int k = 0; k < 3; k++) {
      io_obuf_char(&ob, ' ');
      io_obuf_uint(&ob, cloud->faces[3 * i + (size_t)k]);
    }
    io_obuf_char(&ob, '\n');
  }
  io_obuf_done(&ob);
  return BSURF_OK;
}
