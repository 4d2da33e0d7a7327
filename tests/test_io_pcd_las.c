/* PCD, LAS and CSV: round trips PLY -> PCD -> LAS -> CSV -> PLY keep every
 * field with the same values (LAS coordinates within their scale), exact
 * cases of the readers (PCD COUNT > 1, packed rgb, binary_compressed LZF;
 * LAS formats 1 and 3 with scale and offset, extra bytes), detection by
 * content, and bad input with its message. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bootsurf.h"

static void tmp_path(char *out, size_t cap, const char *name) {
  const char *base = getenv("BSURF_TMP");
  char dir[2048];
  snprintf(dir, sizeof dir, "%.1000s/io_pcd_las.tmp", base && *base ? base : ".");
  if (mkdir(dir, 0777) != 0 && errno != EEXIST) fail_msg("cannot create %s", dir);
  snprintf(out, cap, "%.2000s/%.1000s", dir, name);
}

static void add(bsurf_cloud *c, const char *name, bsurf_type type, double (*f)(size_t)) {
  bsurf_field *fl = bsurf_cloud_add_field(c, name, type);
  assert_non_null(fl);
  for (size_t i = 0; i < c->point_count; i++)
    fl->values[i] = f(i);
}

static double v_u8(size_t i) {
  return (double)((i * 37) % 256);
}
static double v_i8(size_t i) {
  return (double)((int)(i % 200) - 100);
}
static double v_u16(size_t i) {
  return (double)((i * 977) % 65536);
}
static double v_i32(size_t i) {
  return (double)((long)(i * 104729) - 5000000);
}
static double v_f32(size_t i) {
  return (double)(float)(0.1 * (double)i - 3.3);
}
static double v_f64(size_t i) {
  return sin((double)i) * 1e-3 + 1.0 / 3.0;
}
static double v_gps(size_t i) {
  return 4.5e8 + (double)i / 7.0;
}
static double v_class(size_t i) {
  return (double)(i % 19);
}
static double v_ret(size_t i) {
  return (double)(1 + i % 3);
}

/* A cloud with every kind of field. */
static void make_cloud(bsurf_cloud *c, size_t n) {
  assert_int_equal(bsurf_cloud_alloc(c, n, 1), BSURF_OK);
  for (size_t i = 0; i < n; i++) {
    c->xyz[3 * i] = 1234.5 + cos((double)i) * 10.0;
    c->xyz[3 * i + 1] = -20.25 + sin(0.3 * (double)i);
    c->xyz[3 * i + 2] = 0.001 * (double)i;
    double t = (double)i * 0.1;
    c->normals[3 * i] = cos(t);
    c->normals[3 * i + 1] = sin(t);
    c->normals[3 * i + 2] = 0;
  }
  c->normal_type = BSURF_FLOAT32;
  add(c, "err_632", BSURF_FLOAT64, v_f64);
  add(c, "normal_var", BSURF_FLOAT32, v_f32);
  add(c, "fpfh_0", BSURF_FLOAT32, v_f32);
  add(c, "fpfh_1", BSURF_FLOAT32, v_f32);
  add(c, "fpfh_2", BSURF_FLOAT32, v_f32);
  add(c, "label", BSURF_INT8, v_i8);
  add(c, "red", BSURF_UINT8, v_u8);
  add(c, "green", BSURF_UINT8, v_class);
  add(c, "blue", BSURF_UINT8, v_u8);
  add(c, "intensity", BSURF_UINT16, v_u16);
  add(c, "classification", BSURF_UINT8, v_class);
  add(c, "return_number", BSURF_UINT8, v_ret);
  add(c, "gps_time", BSURF_FLOAT64, v_gps);
  add(c, "index", BSURF_INT32, v_i32);
  add(c, "zero", BSURF_UINT8, v_class);
  for (size_t i = 0; i < n; i++)
    bsurf_cloud_field(c, "zero")->values[i] = 0;
  snprintf(c->shape, sizeof c->shape, "cube");
}

/* b has every field of a with the same values; coordinates within tol. */
static void same_fields(const bsurf_cloud *a, const bsurf_cloud *b, double tol, const char *what) {
  assert_int_equal(a->point_count, b->point_count);
  assert_int_equal(a->field_count, b->field_count);
  assert_non_null(b->normals);
  for (size_t i = 0; i < 3 * a->point_count; i++) {
    if (fabs(a->xyz[i] - b->xyz[i]) > tol)
      fail_msg("%s: coordinate %zu: %.17g vs %.17g", what, i, a->xyz[i], b->xyz[i]);
    double want = (double)(float)a->normals[i];
    if (b->normals[i] != want)
      fail_msg("%s: normal %zu: %.17g vs %.17g", what, i, want, b->normals[i]);
  }
  for (size_t k = 0; k < a->field_count; k++) {
    const bsurf_field *fa = &a->fields[k], *fb = bsurf_cloud_field(b, fa->name);
    if (!fb) fail_msg("%s: field %s is missing", what, fa->name);
    for (size_t i = 0; i < a->point_count; i++)
      if (memcmp(&fa->values[i], &fb->values[i], sizeof(double)) != 0)
        fail_msg("%s: field %s point %zu: %.17g vs %.17g", what, fa->name, i, fa->values[i],
                 fb->values[i]);
  }
}

static void roundtrip(const bsurf_cloud *in, const char *name, const bsurf_write_options *o,
                      bsurf_cloud *out) {
  char path[4096];
  bsurf_failure err;
  tmp_path(path, sizeof path, name);
  if (bsurf_write(path, in, o, &err) != BSURF_OK) fail_msg("write %s: %s", name, err.message);
  if (bsurf_read(path, out, &err) != BSURF_OK) fail_msg("read %s: %s", name, err.message);
}

static void test_roundtrip_chain(void **state) {
  (void)state;
  bsurf_cloud a, pcd, pcd_ascii, las, csv, ply;
  make_cloud(&a, 300);
  bsurf_write_options bin = {.ascii = 0}, asc = {.ascii = 1};
  roundtrip(&a, "chain.pcd", &bin, &pcd);
  same_fields(&a, &pcd, 0, "pcd");
  assert_string_equal(pcd.shape, "cube");
  roundtrip(&a, "chain_ascii.pcd", &asc, &pcd_ascii);
  same_fields(&a, &pcd_ascii, 0, "ascii pcd");
  roundtrip(&pcd, "chain.las", NULL, &las);
  /* scale: the smallest power of ten with the half-extent in 2^31 - 2 steps */
  same_fields(&a, &las, 0.5e-8 * 1.000001, "las");
  assert_string_equal(las.shape, "cube");
  bsurf_cloud las12;
  bsurf_write_options legacy = {.las_legacy = 1};
  roundtrip(&pcd, "chain12.las", &legacy, &las12);
  same_fields(&a, &las12, 0.5e-8 * 1.000001, "las 1.2");
  bsurf_cloud_free(&las12);
  roundtrip(&las, "chain.csv", NULL, &csv);
  same_fields(&las, &csv, 0, "csv");
  roundtrip(&csv, "chain.ply", &bin, &ply);
  same_fields(&las, &ply, 0, "ply");
  /* the types a field had come back where the format keeps them */
  assert_int_equal(bsurf_cloud_field(&pcd, "label")->type, BSURF_INT8);
  assert_int_equal(bsurf_cloud_field(&las, "index")->type, BSURF_INT32);
  assert_int_equal(bsurf_cloud_field(&las, "intensity")->type, BSURF_UINT16);
  assert_int_equal(bsurf_cloud_field(&csv, "err_632")->type, BSURF_FLOAT64);
  assert_int_equal(bsurf_cloud_field(&csv, "normal_var")->type, BSURF_FLOAT32);
  bsurf_cloud *all[] = {&a, &pcd, &pcd_ascii, &las, &csv, &ply};
  for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
    bsurf_cloud_free(all[i]);
}

/* Writes bytes to a file and reads it (format from the content). */
static bsurf_status read_bytes(const char *name, const void *data, size_t n, bsurf_cloud *c,
                               bsurf_failure *err) {
  char path[4096];
  tmp_path(path, sizeof path, name);
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  assert_int_equal(fwrite(data, 1, n, f), n);
  fclose(f);
  return bsurf_read(path, c, err);
}

static void test_pcd_cases(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure err;
  /* COUNT 3 becomes h_0 h_1 h_2; rgb is PCL's packed colour (as uint32 text);
   * no extension: the content says PCD */
  const char *txt =
      "# .PCD v0.7\nVERSION .7\nFIELDS x y z h rgb _\nSIZE 4 4 4 2 4 1\nTYPE F F F I F U\n"
      "COUNT 1 1 1 3 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
      "1 2 3 -1 0 7 16711935 9\n4 5 6 1 2 3 65280 9\n";
  assert_int_equal(read_bytes("count3", txt, strlen(txt), &c, &err), BSURF_OK);
  assert_int_equal(c.point_count, 2);
  assert_int_equal(c.xyz_type, BSURF_FLOAT32);
  assert_non_null(bsurf_cloud_field(&c, "h_2"));
  assert_true(bsurf_cloud_field(&c, "h_0")->values[0] == -1 &&
              bsurf_cloud_field(&c, "h_2")->values[1] == 3);
  assert_int_equal(bsurf_cloud_field(&c, "h_1")->type, BSURF_INT16);
  assert_true(bsurf_cloud_field(&c, "red")->values[0] == 255 &&
              bsurf_cloud_field(&c, "blue")->values[0] == 255);
  assert_true(bsurf_cloud_field(&c, "green")->values[1] == 255 &&
              bsurf_cloud_field(&c, "red")->values[1] == 0);
  assert_null(bsurf_cloud_field(&c, "_"));
  assert_int_equal(c.field_count, 6);
  bsurf_cloud_free(&c);

  /* binary_compressed: 2 points x (x y z float) = 24 bytes, field by field;
   * LZF: 12 literal bytes (x of both points = 1.0f, y = 2.0f) then a
   * back-reference copying the 4 bytes of 2.0f twice (z = 2.0f) */
  unsigned char body[64];
  size_t k = 0;
  const unsigned char one[4] = {0, 0, 0x80, 0x3f}, two[4] = {0, 0, 0, 0x40};
  unsigned char lzf[32];
  size_t m = 0;
  lzf[m++] = 11; /* 12 literals */
  memcpy(lzf + m, one, 4), m += 4;
  memcpy(lzf + m, one, 4), m += 4;
  memcpy(lzf + m, two, 4), m += 4;
  lzf[m++] = 3; /* 4 more literals: the second y */
  memcpy(lzf + m, two, 4), m += 4;
  lzf[m++] = (unsigned char)((6 << 5) | 0); /* length 6 + 2 = 8, offset 3 + 1 = 4 */
  lzf[m++] = 3;
  const char *hdr =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
      "POINTS 2\nDATA binary_compressed\n";
  unsigned char file[256];
  size_t hl = strlen(hdr);
  memcpy(file, hdr, hl);
  k = hl;
  uint32_t cs = (uint32_t)m, us = 24;
  for (int q = 0; q < 4; q++)
    file[k++] = (unsigned char)(cs >> (8 * q));
  for (int q = 0; q < 4; q++)
    file[k++] = (unsigned char)(us >> (8 * q));
  memcpy(file + k, lzf, m);
  k += m;
  (void)body;
  assert_int_equal(read_bytes("lzf.pcd", file, k, &c, &err), BSURF_OK);
  assert_int_equal(c.point_count, 2);
  for (int i = 0; i < 2; i++) {
    assert_true(c.xyz[3 * i] == 1.0);
    assert_true(c.xyz[3 * i + 1] == 2.0);
    assert_true(c.xyz[3 * i + 2] == 2.0);
  }
  bsurf_cloud_free(&c);
  /* the same with a reference before the start of the output */
  file[k - 1] = 40;
  assert_int_equal(read_bytes("lzf_bad.pcd", file, k, &c, &err), BSURF_ERR_PARSE);
  assert_non_null(strstr(err.message, "corrupt LZF"));
}

static void put16(unsigned char *p, unsigned v) {
  p[0] = (unsigned char)v;
  p[1] = (unsigned char)(v >> 8);
}
static void put32(unsigned char *p, uint32_t v) {
  for (int i = 0; i < 4; i++)
    p[i] = (unsigned char)(v >> (8 * i));
}
static void putd(unsigned char *p, double d) {
  uint64_t u;
  memcpy(&u, &d, 8);
  for (int i = 0; i < 8; i++)
    p[i] = (unsigned char)(u >> (8 * i));
}

/* A LAS 1.2 file of point format `fmt` (1 or 3) with 2 points and one extra
 * bytes record (a scaled int16 "height" and a float triple "v"). */
static size_t make_las12(unsigned char *f, int fmt, int extra) {
  memset(f, 0, 1024);
  memcpy(f, "LASF", 4);
  f[24] = 1;
  f[25] = 2;
  put16(f + 94, 227);
  size_t vlr = extra ? 54 + 2 * 192 : 0;
  put32(f + 96, (uint32_t)(227 + vlr));
  put32(f + 100, extra ? 1 : 0);
  f[104] = (unsigned char)fmt;
  size_t rec = (fmt == 1 ? 28 : 34) + (extra ? 2 + 12 : 0);
  put16(f + 105, (unsigned)rec);
  put32(f + 107, 2);
  putd(f + 131, 0.01);
  putd(f + 139, 0.01);
  putd(f + 147, 0.001);
  putd(f + 155, 1000);
  putd(f + 163, 2000);
  putd(f + 171, 0);
  unsigned char *v = f + 227;
  if (extra) {
    memcpy(v + 2, "LASF_Spec", 9);
    put16(v + 18, 4);
    put16(v + 20, 2 * 192);
    unsigned char *d = v + 54;
    d[2] = 4;      /* int16 */
    d[3] = 8 | 16; /* scale and offset */
    memcpy(d + 4, "height", 6);
    putd(d + 112, 0.5);
    putd(d + 136, 100);
    d += 192;
    d[2] = 29; /* 3 x float */
    memcpy(d + 4, "v", 1);
  }
  unsigned char *p = f + 227 + vlr;
  for (int i = 0; i < 2; i++, p += rec) {
    put32(p, (uint32_t)(int32_t)(i ? -150 : 12345));
    put32(p + 4, 77);
    put32(p + 8, (uint32_t)(int32_t)-5);
    put16(p + 12, 300 + (unsigned)i);
    p[14] = (unsigned char)(1 | 2 << 3 | 1 << 7); /* return 1 of 2, edge */
    p[15] = (unsigned char)(6 | 1 << 5);          /* building, synthetic */
    p[16] = (unsigned char)(int8_t)-12;
    putd(p + 20, 1.5 + i);
    if (fmt == 3) {
      put16(p + 28, 65535);
      put16(p + 30, 0);
      put16(p + 32, 256);
    }
    if (extra) {
      unsigned char *e = p + (fmt == 1 ? 28 : 34);
      put16(e, (unsigned)(uint16_t)(int16_t)(i ? -4 : 6));
      float fl[3] = {0.25f, -1.0f, 3.5f};
      memcpy(e + 2, fl, 12);
    }
  }
  return (size_t)(p - f);
}

static void test_las_cases(void **state) {
  (void)state;
  unsigned char f[1024];
  bsurf_cloud c;
  bsurf_failure err;
  size_t n = make_las12(f, 3, 1);
  if (read_bytes("fmt3.las", f, n, &c, &err) != BSURF_OK)
    fail_msg("%s (byte %lld)", err.message, err.byte);
  assert_int_equal(c.point_count, 2);
  assert_true(c.xyz[0] == fma(12345.0, 0.01, 1000.0)); /* 1123.45 as one rounding */
  assert_true(c.xyz[3] == fma(-150.0, 0.01, 1000.0));
  assert_true(c.xyz[1] == fma(77.0, 0.01, 2000.0));
  assert_true(c.xyz[2] == fma(-5.0, 0.001, 0.0));
  assert_true(bsurf_cloud_field(&c, "intensity")->values[1] == 301);
  assert_true(bsurf_cloud_field(&c, "return_number")->values[0] == 1);
  assert_true(bsurf_cloud_field(&c, "number_of_returns")->values[0] == 2);
  assert_true(bsurf_cloud_field(&c, "edge_of_flight_line")->values[0] == 1);
  assert_true(bsurf_cloud_field(&c, "classification")->values[0] == 6);
  assert_true(bsurf_cloud_field(&c, "synthetic")->values[0] == 1);
  assert_true(bsurf_cloud_field(&c, "scan_angle_rank")->values[0] == -12);
  assert_true(bsurf_cloud_field(&c, "gps_time")->values[1] == 2.5);
  assert_true(bsurf_cloud_field(&c, "red")->values[0] == 65535);
  assert_true(bsurf_cloud_field(&c, "blue")->values[0] == 256);
  assert_null(bsurf_cloud_field(&c, "green"));     /* zero at every point */
  assert_null(bsurf_cloud_field(&c, "key_point")); /* likewise */
  assert_true(bsurf_cloud_field(&c, "height")->values[0] == 103);
  assert_true(bsurf_cloud_field(&c, "height")->values[1] == 98);
  assert_true(bsurf_cloud_field(&c, "v_2")->values[1] == 3.5);
  assert_int_equal(bsurf_cloud_field(&c, "v_0")->type, BSURF_FLOAT32);
  bsurf_cloud_free(&c);

  /* bad input: the message says what and where */
  struct {
    const char *what;
    size_t at;
    int value;
    const char *msg;
  } bad[] = {
      {"laz", 104, 0x83, "LAZ"},
      {"format", 104, 11, "unknown point data record format 11"},
      {"version", 25, 9, "version 1.9"},
      {"count", 107, 200, "point count beyond the file"},
      {"vlr", 227 + 20, 0xff, "wrong VLR length"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    n = make_las12(f, 1, 1);
    f[bad[i].at] = (unsigned char)bad[i].value;
    assert_int_not_equal(read_bytes("bad.las", f, n, &c, &err), BSURF_OK);
    if (!strstr(err.message, bad[i].msg))
      fail_msg("%s: '%s' lacks '%s'", bad[i].what, err.message, bad[i].msg);
    assert_true(err.byte >= 0);
  }
  n = make_las12(f, 1, 0);
  assert_int_not_equal(read_bytes("short.las", f, 100, &c, &err), BSURF_OK);
  assert_non_null(strstr(err.message, "truncated header"));
}

/* CloudCompare's ASCII export and a plain header: names, order, aliases. */
static void test_csv_header(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure err;
  const char *cc =
      "//X,Y,Z,R,G,B,Nx,Ny,Nz,Scalar field\n1,2,3,255,0,9,0,0,1,0.5\n4,5,6,1,2,3,1,0,0,-2\n";
  assert_int_equal(read_bytes("cc.asc", cc, strlen(cc), &c, &err), BSURF_OK);
  assert_int_equal(c.point_count, 2);
  assert_non_null(c.normals);
  assert_true(c.normals[2] == 1 && c.xyz[5] == 6);
  assert_non_null(bsurf_cloud_field(&c, "red"));
  assert_int_equal(bsurf_cloud_field(&c, "red")->type, BSURF_UINT8);
  assert_true(bsurf_cloud_field(&c, "Scalar_field")->values[1] == -2);
  bsurf_cloud_free(&c);
  const char *plain = "intensity z y x\n7 3 2 1\n";
  assert_int_equal(read_bytes("plain.txt", plain, strlen(plain), &c, &err), BSURF_OK);
  assert_true(c.xyz[0] == 1 && c.xyz[2] == 3);
  assert_true(bsurf_cloud_field(&c, "intensity")->values[0] == 7);
  bsurf_cloud_free(&c);
  const char *wrong = "a b c d\n1 2 3\n";
  assert_int_equal(read_bytes("wrong.csv", wrong, strlen(wrong), &c, &err), BSURF_ERR_PARSE);
  assert_non_null(strstr(err.message, "header names"));
}

static void test_detect(void **state) {
  (void)state;
  assert_int_equal(bsurf_format_detect("ply\nformat", 10), BSURF_FORMAT_PLY);
  assert_int_equal(bsurf_format_detect("# .PCD v0.7", 11), BSURF_FORMAT_PCD);
  assert_int_equal(bsurf_format_detect("VERSION 0.7\n", 12), BSURF_FORMAT_PCD);
  assert_int_equal(bsurf_format_detect("LASF\x00\x00", 6), BSURF_FORMAT_LAS);
  assert_int_equal(bsurf_format_detect("# c\nNOFF\n", 10), BSURF_FORMAT_OFF);
  assert_int_equal(bsurf_format_detect("1 2 3\n", 6), BSURF_FORMAT_UNKNOWN);
  assert_int_equal(bsurf_format_detect("plyx", 4), BSURF_FORMAT_UNKNOWN);
  assert_int_equal(bsurf_format_from_name("LAS"), BSURF_FORMAT_LAS);
  assert_int_equal(bsurf_format_from_path("a/b.laz"), BSURF_FORMAT_LAS);
  assert_int_equal(bsurf_format_from_path("b.asc"), BSURF_FORMAT_CSV);
  assert_string_equal(bsurf_format_name(BSURF_FORMAT_PCD), "pcd");
  /* a PLY file called .xyz reads as PLY */
  bsurf_cloud c;
  bsurf_failure err;
  const char *ply = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n1 2 3\n";
  assert_int_equal(read_bytes("really_ply.xyz", ply, strlen(ply), &c, &err), BSURF_OK);
  assert_int_equal(c.xyz_type, BSURF_FLOAT32);
  bsurf_cloud_free(&c);
}

/* The first `cap` - 1 bytes of a file written by roundtrip(), as a string. */
static const char *file_head(const char *name, char *buf, size_t cap) {
  char path[4096];
  tmp_path(path, sizeof path, name);
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  size_t n = fread(buf, 1, cap - 1, f);
  fclose(f);
  buf[n] = 0;
  return buf;
}

/* Reads an ascii PLY of one vertex: x y z (0 0 0) and `props` (property
 * lines) with `values`, the header comment `comment` ("" or a line). */
static void read_one_vertex(const char *comment, const char *props, const char *values,
                            bsurf_cloud *b) {
  char text[1024];
  bsurf_failure err;
  snprintf(text, sizeof text,
           "ply\nformat ascii 1.0\n%selement vertex 1\nproperty float x\nproperty float y\n"
           "property float z\n%send_header\n0 0 0 %s\n",
           comment, props, values);
  if (read_bytes("one_vertex.ply", text, strlen(text), b, &err) != BSURF_OK)
    fail_msg("one vertex: %s", err.message);
}

/* --float32 and --ply-names change only the PLY header's types and names, and
 * bootsurf reads the names it wrote for a viewer back as they were
 * (docs/formats.md): scalar_NAME is NAME again, MeshLab's quality copy is
 * dropped, so PLY -> viewer names -> PLY keeps every field. */
static void test_write_views(void **state) {
  (void)state;
  bsurf_cloud a, b;
  char head[4096];
  make_cloud(&a, 10);
  bsurf_write_options o = {.float32 = 1, .ply_names = BSURF_PLY_NAMES_CLOUDCOMPARE};
  roundtrip(&a, "views.ply", &o, &b);
  assert_non_null(strstr(file_head("views.ply", head, sizeof head),
                         "comment bootsurf ply-names cloudcompare\n"));
  assert_non_null(strstr(head, "property float scalar_err_632\n"));
  assert_non_null(strstr(head, "property char scalar_label\n"));
  assert_int_equal(b.xyz_type, BSURF_FLOAT32);
  assert_int_equal(b.field_count, a.field_count);
  assert_null(bsurf_cloud_field(&b, "scalar_err_632"));
  assert_int_equal(bsurf_cloud_field(&b, "err_632")->type, BSURF_FLOAT32);
  assert_int_equal(bsurf_cloud_field(&b, "label")->type, BSURF_INT8);
  assert_int_equal(a.xyz_type, BSURF_FLOAT64); /* the cloud itself is unchanged */
  bsurf_cloud_free(&b);
  /* without --float32 the round trip is exact, names and values */
  bsurf_write_options cc = {.ply_names = BSURF_PLY_NAMES_CLOUDCOMPARE};
  roundtrip(&a, "cc.ply", &cc, &b);
  same_fields(&a, &b, 0, "cloudcompare names");
  bsurf_cloud_free(&b);
  bsurf_write_options m = {.ply_names = BSURF_PLY_NAMES_MESHLAB};
  roundtrip(&a, "meshlab.ply", &m, &b);
  assert_non_null(
      strstr(file_head("meshlab.ply", head, sizeof head), "comment bootsurf ply-names meshlab\n"));
  assert_non_null(strstr(head, "property float quality\nend_header"));
  same_fields(&a, &b, 0, "meshlab names");
  assert_null(bsurf_cloud_field(&b, "quality"));
  bsurf_cloud_free(&b);
  /* a field of the cloud called quality: no copy, no comment, kept */
  assert_non_null(bsurf_cloud_add_field(&a, "quality", BSURF_FLOAT32));
  roundtrip(&a, "meshlab_q.ply", &m, &b);
  assert_null(strstr(file_head("meshlab_q.ply", head, sizeof head), "ply-names"));
  same_fields(&a, &b, 0, "meshlab names, own quality");
  bsurf_cloud_free(&b);
  bsurf_cloud_free(&a);

  /* names are taken back only from files that say bootsurf wrote them so:
   * CloudCompare's own scalar_ names stay, as does a marked file in which
   * some field lacks the prefix or would become a coordinate */
  const char *ccmark = "comment bootsurf ply-names cloudcompare\n";
  read_one_vertex("", "property float scalar_a\nproperty float quality\n", "1 2", &b);
  assert_non_null(bsurf_cloud_field(&b, "scalar_a"));
  assert_non_null(bsurf_cloud_field(&b, "quality"));
  bsurf_cloud_free(&b);
  read_one_vertex(ccmark, "property float scalar_a\nproperty float a\n", "1 2", &b);
  assert_true(bsurf_cloud_field(&b, "scalar_a")->values[0] == 1.0);
  assert_true(bsurf_cloud_field(&b, "a")->values[0] == 2.0);
  bsurf_cloud_free(&b);
  read_one_vertex(ccmark, "property float scalar_x\n", "1", &b);
  assert_non_null(bsurf_cloud_field(&b, "scalar_x"));
  bsurf_cloud_free(&b);
  read_one_vertex("comment bootsurf ply-names meshlab\n",
                  "property double w\nproperty float quality\n", "0.1 0.1", &b);
  assert_int_equal(b.field_count, 1);
  assert_true(b.fields[0].values[0] == 0.1);
  bsurf_cloud_free(&b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_roundtrip_chain), cmocka_unit_test(test_pcd_cases),
      cmocka_unit_test(test_las_cases),       cmocka_unit_test(test_csv_header),
      cmocka_unit_test(test_detect),          cmocka_unit_test(test_write_views),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
