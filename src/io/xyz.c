/* Plain-text point lists (.xyz, .txt, .pts): one point a line, values
 * separated by whitespace, ',' or ';'. 3 columns are x y z, 6 are x y z nx
 * ny nz, any other count >= 4 keeps the extra columns as FLOAT64 fields
 * scalar_3, scalar_4, ... (named by column). '#' and '//' lines and blank
 * lines are skipped, as is a single leading point-count line (.pts). */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

#define XYZ_MAX_COLUMNS 1024

/* Starts a comment or is blank. */
static int skip_line(const char *s, size_t len) {
  size_t i = 0;
  while (i < len && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\v' || s[i] == '\f'))
    i++;
  if (i == len || s[i] == '#') return 1;
  return len - i >= 2 && s[i] == '/' && s[i + 1] == '/';
}

bsurf_status bsurf_io_read_xyz(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_error *err) {
  io_text t;
  io_text_init(&t, data, size);
  io_dvec rows = {NULL, 0, 0};
  double *row = NULL;
  size_t ncols = 0;
  long first_line = 0;
  int seen_line = 0;
  const char *line;
  size_t len;
  char a[48];
  bsurf_status st = BSURF_OK;

  while (io_text_next_line(&t, &line, &len)) {
    if (skip_line(line, len)) continue;
    io_cursor c;
    io_token tok;
    io_cursor_init(&c, line, len, IO_SEP_XYZ);
    size_t k = io_count_tokens(&c);
    if (ncols == 0) {
      unsigned long long count;
      if (!seen_line && k == 1) {
        io_cursor probe = c;
        io_next_token(&probe, &tok);
        seen_line = 1;
        if (io_parse_u64(tok.s, tok.len, &count)) continue; /* .pts point count */
      }
      seen_line = 1;
      if (k < 3) {
        st = bsurf_fail(err, BSURF_ERR_PARSE, t.line, -1,
                        "expected at least 3 values (x y z), found %zu", k);
        break;
      }
      if (k > XYZ_MAX_COLUMNS) {
        st = bsurf_fail(err, BSURF_ERR_UNSUPPORTED, t.line, -1,
                        "%zu columns is more than the %d supported", k, XYZ_MAX_COLUMNS);
        break;
      }
      ncols = k;
      first_line = t.line;
      row = malloc(ncols * sizeof *row);
      if (!row) {
        st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
        break;
      }
    } else if (k != ncols) {
      st = bsurf_fail(err, BSURF_ERR_PARSE, t.line, -1,
                      "expected %zu values like the first point (line %ld), found %zu", ncols,
                      first_line, k);
      break;
    }
    for (size_t j = 0; j < ncols; j++) {
      io_next_token(&c, &tok);
      if (!io_parse_double(tok.s, tok.len, &row[j])) {
        st = bsurf_fail(err, BSURF_ERR_PARSE, t.line, -1, "'%s' is not a number%s",
                        io_token_repr(tok, a),
                        rows.n == 0 ? " (a header line must start with '#' or '//')" : "");
        break;
      }
    }
    if (st != BSURF_OK) break;
    if (io_dvec_push(&rows, row, ncols) != BSURF_OK) {
      st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
      break;
    }
  }
  free(row);

  size_t n = ncols ? rows.n / ncols : 0;
  if (st == BSURF_OK && n) {
    if (ncols == 3) {
      cloud->point_count = n;
      cloud->xyz = io_dvec_take(&rows);
    } else if (bsurf_cloud_alloc(cloud, n, ncols == 6) != BSURF_OK) {
      st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
    } else {
      for (size_t i = 0; i < n; i++) {
        const double *r = rows.v + i * ncols;
        memcpy(cloud->xyz + 3 * i, r, 3 * sizeof(double));
        if (ncols == 6) memcpy(cloud->normals + 3 * i, r + 3, 3 * sizeof(double));
      }
      for (size_t j = 3; ncols != 6 && j < ncols && st == BSURF_OK; j++) {
        char name[BSURF_FIELD_NAME_MAX];
        snprintf(name, sizeof name, "scalar_%zu", j);
        bsurf_field *f = bsurf_cloud_add_field(cloud, name, BSURF_FLOAT64);
        if (!f) {
          st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
          break;
        }
        for (size_t i = 0; i < n; i++) f->values[i] = rows.v[i * ncols + j];
      }
    }
  }
  free(rows.v);
  return st;
}

bsurf_status bsurf_io_write_xyz(io_writer *w, const bsurf_cloud *cloud, bsurf_error *err) {
  io_obuf ob;
  if (io_obuf_init(&ob, w) != BSURF_OK)
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  for (size_t i = 0; i < cloud->point_count && !w->failed; i++) {
    for (int k = 0; k < 3; k++) {
      if (k) io_obuf_char(&ob, ' ');
      io_obuf_value(&ob, cloud->xyz[3 * i + (size_t)k], BSURF_FLOAT64);
    }
    if (cloud->normals)
      for (int k = 0; k < 3; k++) {
        io_obuf_char(&ob, ' ');
        io_obuf_value(&ob, cloud->normals[3 * i + (size_t)k], BSURF_FLOAT64);
      }
    io_obuf_char(&ob, '\n');
  }
  io_obuf_done(&ob);
  return BSURF_OK;
}
