/* Plain-text point lists (.xyz, .txt, .pts, .csv, .asc): one point a line,
 * values separated by whitespace, ',' or ';'. Without a header line, 3
 * columns are x y z, 6 are x y z nx ny nz, any other count >= 4 keeps the
 * extra columns as FLOAT64 fields scalar_3, scalar_4, ... (named by column).
 * '#' and '//' lines and blank lines are skipped, as is a single leading
 * point-count line (.pts).
 *
 * A header line names the columns (CloudCompare's ASCII export "//X,Y,Z,..."
 * as the first line, or a first line of names such as "x y z intensity"):
 * x y z (any case) are the coordinates, nx ny nz (or normal_x ...) the
 * normals, R G B A CloudCompare's colours red green blue alpha, any other
 * name a field. With a header each column takes the smallest type that holds
 * every value exactly (integers: uint8 ... int32; else float32 when every
 * value is a float, else float64), so a file bsurf_io_write_csv wrote (every
 * value with 17 digits) reads back with the same values and types. */
#include "io/io.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define XYZ_MAX_COLUMNS 65536 /* the writer writes every field: a file it wrote must read back */

/* Starts a comment or is blank. */
static int skip_line(const char *s, size_t len) {
  size_t i = 0;
  while (i < len && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\v' || s[i] == '\f'))
    i++;
  if (i == len || s[i] == '#') return 1;
  return len - i >= 2 && s[i] == '/' && s[i + 1] == '/';
}

/* ---- the header line --------------------------------------------------- */

/* 1 if every token of the line is not a number (a line of names). */
static int all_names(const char *s, size_t len) {
  io_cursor c;
  io_token tok;
  double v;
  int any = 0;
  io_cursor_init(&c, s, len, IO_SEP_XYZ);
  while (io_next_token(&c, &tok)) {
    if (io_parse_double(tok.s, tok.len, &v)) return 0;
    any = 1;
  }
  return any;
}

/* Splits a header into at most `max` names (separator: ',' if there is
 * one, else ';', else tab, else blanks; leading '/' removed); returns the
 * count, or max + 1 when there are more. */
static size_t split_header(const char *s, size_t len, io_token *names, size_t max) {
  while (len && (*s == '/' || *s == ' ' || *s == '\t')) {
    s++;
    len--;
  }
  char sep = memchr(s, ',', len)    ? ','
             : memchr(s, ';', len)  ? ';'
             : memchr(s, '\t', len) ? '\t'
                                    : ' ';
  size_t n = 0, i = 0;
  while (i <= len) {
    size_t j = i;
    while (j < len && s[j] != sep)
      j++;
    size_t a = i, b = j;
    while (a < b && isspace((unsigned char)s[a]))
      a++;
    while (b > a && isspace((unsigned char)s[b - 1]))
      b--;
    if (b > a || sep != ' ') {
      if (n == max) return max + 1;
      names[n].s = s + a;
      names[n].len = b - a;
      n++;
    }
    i = j + 1;
  }
  return n;
}

static int name_ci(io_token t, const char *w) {
  size_t n = strlen(w);
  if (t.len != n) return 0;
  for (size_t i = 0; i < n; i++)
    if (tolower((unsigned char)t.s[i]) != w[i]) return 0;
  return 1;
}

/* The smallest type holding every value exactly. */
static bsurf_type infer_type(const double *v, size_t stride, size_t n, int allow_int) {
  int integral = allow_int, single = 1;
  double lo = 0, hi = 0;
  for (size_t i = 0; i < n; i++) {
    double x = v[i * stride];
    if (integral && !(x == floor(x) && fabs(x) <= 4294967295.0 && !(x == 0 && signbit(x))))
      integral = 0;
    if (single && !isnan(x) && (double)(float)x != x) single = 0;
    if (x < lo) lo = x;
    if (x > hi) hi = x;
  }
  if (integral && n) {
    if (lo >= 0) return hi <= 255 ? BSURF_UINT8 : hi <= 65535 ? BSURF_UINT16 : BSURF_UINT32;
    if (lo >= -128 && hi <= 127) return BSURF_INT8;
    if (lo >= -32768 && hi <= 32767) return BSURF_INT16;
    if (lo >= -2147483648.0 && hi <= 2147483647.0) return BSURF_INT32;
  }
  return single ? BSURF_FLOAT32 : BSURF_FLOAT64;
}

/* The cloud from rows named by a header. */
static bsurf_status named_columns(bsurf_cloud *cloud, const double *rows, size_t n, size_t ncols,
                                  const io_token *names, long hdr_line, bsurf_failure *err) {
  size_t xyz[3] = {0, 1, 2}, nrm[3] = {0, 0, 0};
  int found = 0, nfound = 0;
  static const char *const cx[3] = {"x", "y", "z"}, *const cn[3] = {"nx", "ny", "nz"},
                           *const cn2[3] = {"normal_x", "normal_y", "normal_z"};
  for (int k = 0; k < 3; k++)
    for (size_t j = 0; j < ncols; j++) {
      if (name_ci(names[j], cx[k]) && !(found & (1 << k))) {
        xyz[k] = j;
        found |= 1 << k;
      }
      if ((name_ci(names[j], cn[k]) || name_ci(names[j], cn2[k])) && !(nfound & (1 << k))) {
        nrm[k] = j;
        nfound |= 1 << k;
      }
    }
  /* some of x y z named, but not all: the first three columns, unless that
   * would put a named coordinate elsewhere ("i,x,y" would read i as x) */
  for (int k = 0; k < 3 && found != 7; k++)
    if ((found & (1 << k)) && xyz[k] != (size_t)k)
      return bsurf_fail(err, BSURF_ERR_PARSE, hdr_line, -1,
                        "the header names %s in column %zu but not all of x, y and z: the "
                        "coordinates would be the first three columns",
                        cx[k], xyz[k] + 1);
  if (found != 7) found = 0; /* no x y z names: the first three columns */
  if (!found) xyz[0] = 0, xyz[1] = 1, xyz[2] = 2;
  int with_normals = nfound == 7;
  for (int k = 0; with_normals && k < 3; k++)
    for (int q = 0; q < 3; q++)
      if (nrm[k] == xyz[q]) with_normals = 0;
  if (bsurf_cloud_alloc(cloud, n, with_normals) != BSURF_OK)
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) {
      cloud->xyz[3 * i + (size_t)k] = rows[i * ncols + xyz[k]];
      if (with_normals) cloud->normals[3 * i + (size_t)k] = rows[i * ncols + nrm[k]];
    }
  cloud->xyz_type =
      infer_type(cloud->xyz, 1, 3 * n, 0) == BSURF_FLOAT32 ? BSURF_FLOAT32 : BSURF_FLOAT64;
  if (with_normals)
    cloud->normal_type =
        infer_type(cloud->normals, 1, 3 * n, 0) == BSURF_FLOAT32 ? BSURF_FLOAT32 : BSURF_FLOAT64;
  /* the other columns' fields: named first, added at once, then filled */
  io_names fields;
  size_t *col = bsurf_alloc_array(ncols, sizeof *col);
  if (!col || io_names_init(&fields, cloud, ncols) != BSURF_OK) {
    free(col);
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  }
  for (size_t j = 0; j < ncols; j++) {
    int used = 0;
    for (int k = 0; k < 3; k++)
      used |= j == xyz[k] || (with_normals && j == nrm[k]);
    col[j] = (size_t)-1;
    if (used) continue;
    char want[BSURF_FIELD_NAME_MAX];
    size_t len = names[j].len < BSURF_FIELD_NAME_MAX - 1 ? names[j].len : BSURF_FIELD_NAME_MAX - 1;
    static const char *const cc[4][2] = {
        {"r", "red"}, {"g", "green"}, {"b", "blue"}, {"a", "alpha"}};
    const char *alias = NULL;
    for (int q = 0; q < 4; q++)
      if (name_ci(names[j], cc[q][0])) alias = cc[q][1];
    if (alias) {
      snprintf(want, sizeof want, "%s", alias);
    } else if (len == 0) {
      snprintf(want, sizeof want, "scalar_%zu", j);
    } else {
      for (size_t q = 0; q < len; q++) {
        unsigned char ch = (unsigned char)names[j].s[q];
        want[q] = (ch > 0x20 && ch < 0x7f && ch != ',' && ch != ';') ? (char)ch : '_';
      }
      want[len] = 0;
    }
    col[j] = io_names_add(&fields, want, BSURF_FLOAT64);
  }
  if (io_names_commit(&fields, cloud) != BSURF_OK) {
    free(col);
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  }
  for (size_t j = 0; j < ncols; j++) {
    if (col[j] == (size_t)-1) continue;
    bsurf_field *f = &cloud->fields[col[j]];
    for (size_t i = 0; i < n; i++)
      f->values[i] = rows[i * ncols + j];
    f->type = infer_type(f->values, 1, n, 1);
  }
  free(col);
  return BSURF_OK;
}

bsurf_status bsurf_io_read_xyz(const char *data, size_t size, bsurf_cloud *cloud,
                               bsurf_failure *err) {
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
  /* a header line: the first line if it is "//..." or all names */
  const char *hdr = NULL;
  size_t hdr_len = 0;
  long hdr_line = 0;
  io_token *names = NULL;
  int first = 1;

  while (io_text_next_line(&t, &line, &len)) {
    if (first) {
      first = 0;
      size_t i = 0;
      while (i < len && (line[i] == ' ' || line[i] == '\t'))
        i++;
      int cc = len - i >= 2 && line[i] == '/' && line[i + 1] == '/';
      if ((cc && len - i > 2) || (!skip_line(line, len) && all_names(line, len))) {
        hdr = line;
        hdr_len = len;
        hdr_line = t.line;
        seen_line = 1;
        continue;
      }
    }
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
      if (hdr) {
        names = malloc((ncols + 1) * sizeof *names);
        if (!names) {
          st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
          break;
        }
        size_t h = split_header(hdr, hdr_len, names, ncols);
        size_t q = 0;
        while (q < hdr_len && (hdr[q] == ' ' || hdr[q] == '\t'))
          q++;
        int comment = hdr_len - q >= 2 && hdr[q] == '/' && hdr[q + 1] == '/';
        if (h != ncols) {
          free(names);
          names = NULL;
          if (!comment) {
            st = bsurf_fail(err, BSURF_ERR_PARSE, hdr_line, -1,
                            "the header names %s%zu columns, the first point (line %ld) has %zu",
                            h > ncols ? "more than " : "", h > ncols ? ncols : h, t.line, ncols);
            break;
          }
        }
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
  if (st == BSURF_OK && n && names) {
    st = named_columns(cloud, rows.v, n, ncols, names, hdr_line, err);
  } else if (st == BSURF_OK && n) {
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
      /* the other columns: scalar_3, scalar_4, ... */
      const size_t nf = ncols == 6 || ncols < 3 ? 0 : ncols - 3;
      io_names fields;
      st = io_names_init(&fields, cloud, nf);
      for (size_t j = 3; j < 3 + nf && st == BSURF_OK; j++) {
        char name[BSURF_FIELD_NAME_MAX];
        snprintf(name, sizeof name, "scalar_%zu", j);
        io_names_add(&fields, name, BSURF_FLOAT64);
      }
      if (st == BSURF_OK) st = io_names_commit(&fields, cloud);
      if (st != BSURF_OK) st = bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
      for (size_t j = 3; j < 3 + nf && st == BSURF_OK; j++) {
        double *v = cloud->fields[j - 3].values;
        for (size_t i = 0; i < n; i++)
          v[i] = rows.v[i * ncols + j];
      }
    }
  }
  free(rows.v);
  free(names);
  return st;
}

bsurf_status bsurf_io_write_xyz(io_writer *w, const bsurf_cloud *cloud, bsurf_failure *err) {
  io_obuf ob;
  if (io_obuf_init(&ob, w) != BSURF_OK)
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  for (size_t i = 0; i < cloud->point_count && !w->failed; i++) {
    io_obuf_point(&ob, cloud, i, ' ');
    io_obuf_char(&ob, '\n');
  }
  io_obuf_done(&ob);
  return BSURF_OK;
}

bsurf_status bsurf_io_write_csv(io_writer *w, const bsurf_cloud *cloud, int cloudcompare,
                                bsurf_failure *err) {
  io_obuf ob;
  if (io_obuf_init(&ob, w) != BSURF_OK)
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  io_obuf_str(&ob, cloudcompare ? "//X,Y,Z" : "x,y,z");
  if (cloud->normals) io_obuf_str(&ob, cloudcompare ? ",Nx,Ny,Nz" : ",nx,ny,nz");
  for (size_t j = 0; j < cloud->field_count; j++) {
    io_obuf_char(&ob, ',');
    io_obuf_str(&ob, cloud->fields[j].name);
  }
  io_obuf_char(&ob, '\n');
  /* every value with 17 significant digits: read back exactly */
  for (size_t i = 0; i < cloud->point_count && !w->failed; i++) {
    io_obuf_point(&ob, cloud, i, ',');
    for (size_t j = 0; j < cloud->field_count; j++) {
      io_obuf_char(&ob, ',');
      io_obuf_value(&ob, cloud->fields[j].values[i], BSURF_FLOAT64);
    }
    io_obuf_char(&ob, '\n');
  }
  io_obuf_done(&ob);
  return BSURF_OK;
}
