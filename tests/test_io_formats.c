/* Round trips through every format, the OFF / OBJ / XYZ readers, and the
 * atomic file writes. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "bootsurf.h"
#include "io/io.h" /* the number formatting and parsing helpers */

/* A writable directory of this test's own. */
static const char *tmp_dir(void) {
  static char dir[4096];
  if (!dir[0]) {
    const char *base = getenv("BSURF_TMP");
    snprintf(dir, sizeof dir, "%s/io_formats.tmp", base && *base ? base : ".");
    if (mkdir(dir, 0777) != 0 && errno != EEXIST) fail_msg("cannot create %s", dir);
  }
  return dir;
}

static void tmp_path(char *out, size_t cap, const char *name) {
  snprintf(out, cap, "%s/%s", tmp_dir(), name);
}

/* Files in the directory whose name contains `needle`. */
static int count_files(const char *dir, const char *needle) {
  DIR *d = opendir(dir);
  assert_non_null(d);
  int n = 0;
  struct dirent *ent;
  while ((ent = readdir(d)))
    if (strstr(ent->d_name, needle)) n++;
  closedir(d);
  return n;
}

/* 5 points with normals, a FLOAT32 and a UINT8 field, 3 triangles. */
static void make_cloud(bsurf_cloud *c) {
  static const double xyz[15] = {
      0.1, 0.2, 0.3, 1.0 / 3.0, -2.0 / 7.0, 1e-300,  -12345.678901234567, 6.02214076e23, 0.0,
      1.0, 2.0, 3.0, -0.5,      0.25,       1e17 + 1};
  assert_int_equal(bsurf_cloud_alloc(c, 5, 1), BSURF_OK);
  memcpy(c->xyz, xyz, sizeof xyz);
  for (size_t i = 0; i < 5; i++) {
    double a = 0.7 * (double)i;
    c->normals[3 * i] = cos(a) * 0.6;
    c->normals[3 * i + 1] = sin(a) * 0.6;
    c->normals[3 * i + 2] = 0.8;
  }
  c->normal_type = BSURF_FLOAT64;
  bsurf_field *f = bsurf_cloud_add_field(c, "intensity", BSURF_FLOAT32);
  assert_non_null(f);
  for (size_t i = 0; i < 5; i++)
    f->values[i] = (double)(float)(0.1 * (double)i);
  f = bsurf_cloud_add_field(c, "label", BSURF_UINT8);
  assert_non_null(f);
  for (size_t i = 0; i < 5; i++)
    f->values[i] = (double)(i * 60);
  static const uint32_t faces[9] = {0, 1, 2, 2, 3, 4, 4, 3, 0};
  c->faces = malloc(sizeof faces);
  assert_non_null(c->faces);
  memcpy(c->faces, faces, sizeof faces);
  c->face_count = 3;
}

static void assert_same_doubles(const double *a, const double *b, size_t n) {
  for (size_t i = 0; i < n; i++)
    if (memcmp(&a[i], &b[i], sizeof(double)) != 0)
      fail_msg("value %zu: %.17g != %.17g", i, a[i], b[i]);
}

static void roundtrip(const char *name, const bsurf_write_options *opts, int keeps_fields,
                      int keeps_faces) {
  bsurf_cloud c, r;
  bsurf_failure e;
  char path[4200];
  make_cloud(&c);
  tmp_path(path, sizeof path, name);
  if (bsurf_write(path, &c, opts, &e) != BSURF_OK) fail_msg("write %s: %s", name, e.message);
  if (bsurf_read(path, &r, &e) != BSURF_OK)
    fail_msg("read %s: %s (line %ld byte %lld)", name, e.message, e.line, e.byte);
  assert_int_equal(r.point_count, c.point_count);
  assert_same_doubles(r.xyz, c.xyz, 15);
  assert_non_null(r.normals);
  assert_same_doubles(r.normals, c.normals, 15);
  if (keeps_fields) {
    assert_int_equal(r.xyz_type, BSURF_FLOAT64);
    assert_int_equal(r.normal_type, BSURF_FLOAT64);
    assert_int_equal(r.field_count, 2);
    for (size_t k = 0; k < 2; k++) {
      assert_string_equal(r.fields[k].name, c.fields[k].name);
      assert_int_equal(r.fields[k].type, c.fields[k].type);
      assert_same_doubles(r.fields[k].values, c.fields[k].values, 5);
    }
  } else {
    assert_int_equal(r.field_count, 0);
  }
  if (keeps_faces) {
    assert_int_equal(r.face_count, 3);
    assert_memory_equal(r.faces, c.faces, 9 * sizeof(uint32_t));
  } else {
    assert_int_equal(r.face_count, 0);
  }
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&r);
  assert_int_equal(unlink(path), 0);
}

static void test_roundtrip_ply_binary(void **state) {
  (void)state;
  roundtrip("rt_binary.ply", NULL, 1, 1);
}

static void test_roundtrip_ply_ascii(void **state) {
  (void)state;
  bsurf_write_options o = {.ascii = 1};
  roundtrip("rt_ascii.PLY", &o, 1, 1);
}

static void test_roundtrip_off(void **state) {
  (void)state;
  roundtrip("rt.off", NULL, 0, 1);
}

static void test_roundtrip_obj(void **state) {
  (void)state;
  roundtrip("rt.obj", NULL, 0, 1);
}

static void test_roundtrip_xyz(void **state) {
  (void)state;
  roundtrip("rt.xyz", NULL, 0, 0);
  roundtrip("rt.txt", NULL, 0, 0);
}

/* Values are stored the way their type says: rounded, clamped, as float. */
static void test_ply_write_conversions(void **state) {
  (void)state;
  for (int ascii = 0; ascii < 2; ascii++) {
    bsurf_cloud c, r;
    bsurf_failure e;
    assert_int_equal(bsurf_cloud_alloc(&c, 6, 0), BSURF_OK);
    c.xyz_type = BSURF_FLOAT32;
    static const double v[6] = {2.5, -3.0, 300.7, 0.1, NAN, -0.4};
    static const double as_u8[6] = {3, 0, 255, 0, 0, 0};
    static const double as_i8[6] = {3, -3, 127, 0, 0, 0};
    static const double as_u32[6] = {3, 0, 301, 0, 0, 0};
    bsurf_field *u8 = bsurf_cloud_add_field(&c, "u8", BSURF_UINT8);
    bsurf_field *i8 = bsurf_cloud_add_field(&c, "i8", BSURF_INT8);
    bsurf_field *u32 = bsurf_cloud_add_field(&c, "u32", BSURF_UINT32);
    assert_true(u8 && i8 && u32);
    u8 = &c.fields[0];
    i8 = &c.fields[1];
    for (int i = 0; i < 6; i++) {
      c.xyz[3 * i] = v[i] == v[i] ? v[i] : 1.0;
      c.fields[0].values[i] = c.fields[1].values[i] = c.fields[2].values[i] = v[i];
    }
    c.fields[1].values[1] = -1000;
    char path[4200];
    tmp_path(path, sizeof path, ascii ? "conv_ascii.ply" : "conv_bin.ply");
    bsurf_write_options o = {.ascii = ascii};
    assert_int_equal(bsurf_write(path, &c, &o, &e), BSURF_OK);
    assert_int_equal(bsurf_read(path, &r, &e), BSURF_OK);
    assert_int_equal(r.xyz_type, BSURF_FLOAT32);
    for (int i = 0; i < 6; i++) {
      assert_true(r.xyz[3 * i] == (double)(float)c.xyz[3 * i]);
      assert_true(r.fields[0].values[i] == as_u8[i]);
      assert_true(r.fields[1].values[i] == (i == 1 ? -128 : as_i8[i]));
      assert_true(r.fields[2].values[i] == as_u32[i]);
    }
    bsurf_cloud_free(&c);
    bsurf_cloud_free(&r);
    unlink(path);
  }
}

/* ---- OFF ------------------------------------------------------------------ */

static bsurf_status read_fmt(const char *s, bsurf_format f, bsurf_cloud *c, bsurf_failure *e) {
  return bsurf_read_buffer(s, strlen(s), f, c, e);
}

static void expect_fail(const char *s, bsurf_format f, long line, const char *needle) {
  bsurf_cloud c;
  bsurf_failure e;
  bsurf_status st = read_fmt(s, f, &c, &e);
  if (st != BSURF_ERR_PARSE || (line >= 0 && e.line != line) ||
      (needle && !strstr(e.message, needle)))
    print_error("got status %d line %ld message '%s'\n", (int)st, e.line, e.message);
  assert_int_equal(st, BSURF_ERR_PARSE);
  if (line >= 0) assert_int_equal(e.line, line);
  if (needle) assert_non_null(strstr(e.message, needle));
  assert_int_equal(c.point_count, 0);
  assert_null(c.xyz);
  assert_null(c.faces);
  assert_null(c.fields);
}

static void test_off_read(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure e;
  const char *off = "# a comment before the keyword\n"
                    "OFF\n"
                    "\n"
                    "# counts follow\n"
                    "4 2 0\n"
                    "0 0 0\n"
                    "1 0 0 # inline comment\n"
                    "\n"
                    "1 1 0\n"
                    "0 1 0.5\n"
                    "4 0 1 2 3 255 0 0\n"
                    "3 3 2 1\n";
  assert_int_equal(read_fmt(off, BSURF_FORMAT_OFF, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 4);
  assert_null(c.normals);
  assert_true(c.xyz[11] == 0.5);
  assert_int_equal(c.face_count, 3);
  static const uint32_t tri[9] = {0, 1, 2, 0, 2, 3, 3, 2, 1};
  assert_memory_equal(c.faces, tri, sizeof tri);
  bsurf_cloud_free(&c);

  const char *noff = "NOFF 2 0 0\n1 2 3 0 0 1\n4 5 6 0 1 0\n";
  assert_int_equal(read_fmt(noff, BSURF_FORMAT_OFF, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 2);
  assert_non_null(c.normals);
  assert_true(c.normals[2] == 1 && c.normals[4] == 1 && c.xyz[5] == 6);
  bsurf_cloud_free(&c);

  const char *coff = "COFF\n2 0 0\n0 0 0 255 128 0 255\n1 1 1 0 0 10 200\n";
  assert_int_equal(read_fmt(coff, BSURF_FORMAT_OFF, &c, &e), BSURF_OK);
  assert_int_equal(c.field_count, 4);
  assert_string_equal(c.fields[3].name, "alpha");
  assert_int_equal(c.fields[0].type, BSURF_UINT8);
  assert_true(c.fields[1].values[0] == 128 && c.fields[3].values[1] == 200);
  bsurf_cloud_free(&c);

  const char *ncoff = "NCOFF\n1 0 0\n0 0 0 0 0 1 0.5 0.25 1.0\n";
  assert_int_equal(read_fmt(ncoff, BSURF_FORMAT_OFF, &c, &e), BSURF_OK);
  assert_non_null(c.normals);
  assert_int_equal(c.field_count, 3);
  assert_int_equal(c.fields[0].type, BSURF_FLOAT32);
  assert_true(c.fields[1].values[0] == 0.25);
  bsurf_cloud_free(&c);
}

static void test_off_errors(void **state) {
  (void)state;
  expect_fail("", BSURF_FORMAT_OFF, -1, "not an OFF file");
  expect_fail("PLY\n1 0 0\n0 0 0\n", BSURF_FORMAT_OFF, 1, "not an OFF file");
  expect_fail("OFF\n3 1 0\n0 0 0\n1 0 0\n", BSURF_FORMAT_OFF, 5,
              "vertex 2: unexpected end of file");
  expect_fail("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", BSURF_FORMAT_OFF, 7,
              "face 1: unexpected end of file");
  expect_fail("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", BSURF_FORMAT_OFF, 4,
              "vertex 1: expected 3 values, found 2");
  expect_fail("OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", BSURF_FORMAT_OFF, 4,
              "'x' is not a number");
  expect_fail("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", BSURF_FORMAT_OFF, 6,
              "face 0: vertex index '3' is out of range");
  expect_fail("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", BSURF_FORMAT_OFF, 6,
              "face 0: expected 4 vertex indices");
  expect_fail("OFF\n99999999999 1 0\n0 0 0\n", BSURF_FORMAT_OFF, 4,
              "vertex 1: unexpected end of file (header declares 99999999999 vertices)");
  expect_fail("OFF\n1 99999999999 0\n0 0 0\n", BSURF_FORMAT_OFF, 4,
              "face 0: unexpected end of file (header declares 99999999999 faces)");
  expect_fail("OFF\n1 0 0\n0 0 0\n5 5 5\n", BSURF_FORMAT_OFF, 4, "after the last face");
  expect_fail("OFF\nx y z\n", BSURF_FORMAT_OFF, 2, "counts");
}

/* ---- OBJ ------------------------------------------------------------------- */

static void test_obj_read(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure e;
  const char *obj = "# comment\n"
                    "mtllib a.mtl\n"
                    "o thing\n"
                    "v 0 0 0\n"
                    "v 1 0 0 1.0\n"
                    "v 1 1 0\n"
                    "vn 0 0 1\n"
                    "vn 0 0 -1\n"
                    "vn 1 0 0\n"
                    "vt 0.5 0.5\n"
                    "g group\n"
                    "usemtl red\n"
                    "s off\n"
                    "f 1//1 2//2 3//3\n"
                    "v 0 1 0\n"
                    "vn 0 1 0\n"
                    "f -4/1/-4 -2/1/-2 -1/1/-1\n"
                    "l 1 2\n"
                    "p 3\n";
  assert_int_equal(read_fmt(obj, BSURF_FORMAT_OBJ, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 4);
  assert_int_equal(c.face_count, 2);
  static const uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
  assert_memory_equal(c.faces, tri, sizeof tri);
  /* as many vn as v, and faces agree: vn[i] is v[i]'s */
  assert_non_null(c.normals);
  assert_true(c.normals[5] == -1 && c.normals[6] == 1 && c.normals[10] == 1);
  assert_int_equal(c.field_count, 0);
  bsurf_cloud_free(&c);

  /* shared normals: each vertex takes the first corner's vn; polygons fan out */
  const char *flat = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n";
  assert_int_equal(read_fmt(flat, BSURF_FORMAT_OBJ, &c, &e), BSURF_OK);
  assert_int_equal(c.face_count, 2);
  assert_non_null(c.normals);
  for (int i = 0; i < 4; i++)
    assert_true(c.normals[3 * i + 2] == 1);
  bsurf_cloud_free(&c);

  /* a vertex no corner gives a normal: no normals at all */
  const char *part = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 5 5 5\nvn 0 0 1\nf 1//1 2//1 3//1\n";
  assert_int_equal(read_fmt(part, BSURF_FORMAT_OBJ, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 4);
  assert_null(c.normals);
  bsurf_cloud_free(&c);

  /* same counts but faces pair v and vn differently */
  const char *perm = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvn 1 0 0\nvn 0 1 0\nvn 0 0 1\n"
                     "f 1//3 2//1 3//2\n";
  assert_int_equal(read_fmt(perm, BSURF_FORMAT_OBJ, &c, &e), BSURF_OK);
  assert_true(c.normals[2] == 1 && c.normals[3] == 1 && c.normals[7] == 1);
  bsurf_cloud_free(&c);

  /* vertex colours */
  const char *col = "v 0 0 0 1 0.5 0\nv 1 0 0 0 0 1\nv 0 1 0 0.25 0.25 0.25\n";
  assert_int_equal(read_fmt(col, BSURF_FORMAT_OBJ, &c, &e), BSURF_OK);
  assert_int_equal(c.field_count, 3);
  assert_string_equal(c.fields[1].name, "green");
  assert_int_equal(c.fields[1].type, BSURF_FLOAT32);
  assert_true(c.fields[1].values[0] == 0.5 && c.fields[2].values[1] == 1);
  assert_null(c.normals);
  bsurf_cloud_free(&c);
}

static void test_obj_errors(void **state) {
  (void)state;
  expect_fail("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", BSURF_FORMAT_OBJ, 4,
              "vertex index 4 is out of range");
  expect_fail("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", BSURF_FORMAT_OBJ, 4,
              "vertex index -4 is out of range");
  expect_fail("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", BSURF_FORMAT_OBJ, 4, "vertex index 0");
  expect_fail("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n", BSURF_FORMAT_OBJ, 5,
              "normal index 2 is out of range");
  expect_fail("v 0 0 0\nv 1 0 zero\n", BSURF_FORMAT_OBJ, 2, "'zero' in a 'v' line is not a number");
  expect_fail("v 0 0\n", BSURF_FORMAT_OBJ, 1, "found 2");
  expect_fail("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/a 2 3\n", BSURF_FORMAT_OBJ, 4, "'1/a'");
  expect_fail("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/ 2 3\n", BSURF_FORMAT_OBJ, 4, "'1/'");
}

/* ---- XYZ ------------------------------------------------------------------- */

static void test_xyz_read(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure e;
  const char *six = "// X,Y,Z,Nx,Ny,Nz\n# another comment\n\n"
                    "1.5,2,3,0,0,1\r\n4;5;6;0;1;0\n  7, 8 ,9\t1 0 0\n";
  assert_int_equal(read_fmt(six, BSURF_FORMAT_XYZ, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 3);
  assert_non_null(c.normals);
  assert_true(c.xyz[0] == 1.5 && c.xyz[8] == 9 && c.normals[2] == 1 && c.normals[6] == 1);
  assert_int_equal(c.field_count, 0);
  bsurf_cloud_free(&c);

  const char *five = "1 2 3 10 20\n4 5 6 11 21\n";
  assert_int_equal(read_fmt(five, BSURF_FORMAT_XYZ, &c, &e), BSURF_OK);
  assert_null(c.normals);
  assert_int_equal(c.field_count, 2);
  assert_string_equal(c.fields[0].name, "scalar_3");
  assert_string_equal(c.fields[1].name, "scalar_4");
  assert_int_equal(c.fields[1].type, BSURF_FLOAT64);
  assert_true(c.fields[1].values[1] == 21);
  bsurf_cloud_free(&c);

  /* a UTF-8 byte order mark is skipped */
  assert_int_equal(read_fmt("\xEF\xBB\xBF"
                            "1 2 3\n",
                            BSURF_FORMAT_XYZ, &c, &e),
                   BSURF_OK);
  assert_int_equal(c.point_count, 1);
  bsurf_cloud_free(&c);

  /* .pts: a point count first */
  assert_int_equal(read_fmt("2\n0 0 0\n1 1 1\n", BSURF_FORMAT_XYZ, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 2);
  bsurf_cloud_free(&c);

  assert_int_equal(read_fmt("", BSURF_FORMAT_XYZ, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 0);
  bsurf_cloud_free(&c);

  expect_fail("1 2 3\n4 5 6\n7 8\n", BSURF_FORMAT_XYZ, 3,
              "expected 3 values like the first point (line 1), found 2");
  expect_fail("# c\n1 2 3 4\n4 5 6 7 8\n", BSURF_FORMAT_XYZ, 3, "found 5");
  expect_fail("1 2\n", BSURF_FORMAT_XYZ, 1, "at least 3");
  expect_fail("1 2 3\n4 five 6\n", BSURF_FORMAT_XYZ, 2, "'five' is not a number");
}

/* Numbers at the very end of an unterminated buffer are parsed without
 * reading past it (ASan checks with an exact-size copy). */
static void test_unterminated_buffers(void **state) {
  (void)state;
  static const char *texts[4] = {"1 2 3\n4 5 6.25", "OFF\n1 0 0\n1 2 3.5", "v 1 2 3\nv 4 5 6.75",
                                 "ply\nformat ascii 1.0\nelement vertex 1\n"
                                 "property double x\nproperty double y\nproperty double z\n"
                                 "end_header\n1 2 3.125"};
  static const bsurf_format fmts[4] = {BSURF_FORMAT_XYZ, BSURF_FORMAT_OFF, BSURF_FORMAT_OBJ,
                                       BSURF_FORMAT_PLY};
  for (int k = 0; k < 4; k++) {
    size_t n = strlen(texts[k]);
    char *copy = malloc(n);
    memcpy(copy, texts[k], n);
    bsurf_cloud c;
    bsurf_failure e;
    assert_int_equal(bsurf_read_buffer(copy, n, fmts[k], &c, &e), BSURF_OK);
    assert_true(c.point_count >= 1);
    assert_true(c.xyz[3 * c.point_count - 1] > 3);
    bsurf_cloud_free(&c);
    /* and every prefix fails or succeeds without overreading */
    for (size_t m = 0; m < n; m++) {
      memcpy(copy, texts[k], m);
      bsurf_status st = bsurf_read_buffer(copy, m, fmts[k], &c, &e);
      if (st == BSURF_OK) bsurf_cloud_free(&c);
    }
    free(copy);
  }
}

/* ---- numbers ----------------------------------------------------------------- */

static uint64_t xorshift(uint64_t *s) {
  *s ^= *s << 13;
  *s ^= *s >> 7;
  *s ^= *s << 17;
  return *s;
}

/* The writer's own %.17g / %.9g and the reader's own strtod agree with the C
 * library bit for bit (they exist for speed and locale independence). */
static void test_number_conversions(void **state) {
  (void)state;
  uint64_t s = 88172645463325252ULL;
  char mine[64], ref[64];
  long mismatches = 0;
  for (long i = 0; i < 400000; i++) {
    double v;
    switch (i % 5) {
    case 0: {
      uint64_t u = xorshift(&s);
      memcpy(&v, &u, sizeof v);
      break;
    }
    case 1: v = ldexp((double)(xorshift(&s) >> 11), (int)(xorshift(&s) % 200) - 150); break;
    case 2: v = (double)(xorshift(&s) % 2000000) / pow(10, (double)(xorshift(&s) % 12)); break;
    case 3:
      v = nextafter(pow(10, (double)((int)(xorshift(&s) % 60) - 30)), i % 2 ? 0 : 1e300);
      break;
    default: v = (double)(float)ldexp((double)(xorshift(&s) >> 40), (int)(xorshift(&s) % 80) - 60);
    }
    if (isnan(v)) continue;
    if (i % 3 == 0) v = -v;
    io_format_value(mine, sizeof mine, v, BSURF_FLOAT64);
    snprintf(ref, sizeof ref, "%.17g", v);
    if (strcmp(mine, ref) && mismatches++ < 5) print_error("%s != %s\n", mine, ref);
    io_format_value(mine, sizeof mine, v, BSURF_FLOAT32);
    snprintf(ref, sizeof ref, "%.9g", io_type_convert(v, BSURF_FLOAT32));
    if (strcmp(mine, ref) && mismatches++ < 5) print_error("%s != %s\n", mine, ref);
    /* parse what printf wrote, and random digit strings */
    const char *fmts[3] = {"%.17g", "%.15g", "%.9g"};
    snprintf(ref, sizeof ref, fmts[i % 3], v);
    if (i % 4 == 0) {
      int o = 0, nd = 1 + (int)(xorshift(&s) % 21), dot = (int)(xorshift(&s) % 22);
      for (int k = 0; k < nd; k++) {
        if (k == dot) ref[o++] = '.';
        ref[o++] = (char)('0' + xorshift(&s) % 10);
      }
      snprintf(ref + o, sizeof ref - (size_t)o, "e%d", (int)(xorshift(&s) % 70) - 35);
    }
    double a = 0, b;
    char *end;
    b = strtod(ref, &end);
    if ((!io_parse_double(ref, strlen(ref), &a) || memcmp(&a, &b, sizeof a)) && mismatches++ < 5)
      print_error("parse %s: %.17g != %.17g\n", ref, a, b);
  }
  assert_int_equal(mismatches, 0);
  static const char *bad[] = {"", "-", ".", "e5", "1e", "1.2.3", "1e+", "0x", "--1", "1 2", "abc"};
  double v;
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
    assert_false(io_parse_double(bad[i], strlen(bad[i]), &v));
  assert_true(io_parse_double("-0", 2, &v) && v == 0 && signbit(v));
  assert_true(io_parse_double("inf", 3, &v) && isinf(v));
  assert_true(io_parse_double("1e400", 5, &v) && isinf(v));
  io_format_value(mine, sizeof mine, -0.0, BSURF_FLOAT64);
  assert_string_equal(mine, "-0");
  io_format_value(mine, sizeof mine, 300.5, BSURF_UINT8);
  assert_string_equal(mine, "255");
  io_format_value(mine, sizeof mine, -2.5, BSURF_INT16);
  assert_string_equal(mine, "-3");
}

/* ---- files ----------------------------------------------------------------- */

static void test_formats_from_path(void **state) {
  (void)state;
  assert_int_equal(bsurf_format_from_path("a/b.c/model.PlY"), BSURF_FORMAT_PLY);
  assert_int_equal(bsurf_format_from_path("x.off"), BSURF_FORMAT_OFF);
  assert_int_equal(bsurf_format_from_path("x.Obj"), BSURF_FORMAT_OBJ);
  assert_int_equal(bsurf_format_from_path("x.xyz"), BSURF_FORMAT_XYZ);
  assert_int_equal(bsurf_format_from_path("x.txt"), BSURF_FORMAT_XYZ);
  assert_int_equal(bsurf_format_from_path("x.pts"), BSURF_FORMAT_XYZ);
  assert_int_equal(bsurf_format_from_path("x.stl"), BSURF_FORMAT_UNKNOWN);
  assert_int_equal(bsurf_format_from_path("dir.ply/x"), BSURF_FORMAT_UNKNOWN);
  assert_int_equal(bsurf_format_from_path(".ply"), BSURF_FORMAT_UNKNOWN);
  assert_int_equal(bsurf_format_keeps_fields(BSURF_FORMAT_PLY), 1);
  assert_int_equal(bsurf_format_keeps_fields(BSURF_FORMAT_OFF), 0);
  assert_int_equal(bsurf_format_keeps_fields(BSURF_FORMAT_OBJ), 0);
  assert_int_equal(bsurf_format_keeps_fields(BSURF_FORMAT_XYZ), 0);
}

static void test_read_file_errors(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure e;
  char path[4200];
  tmp_path(path, sizeof path, "does_not_exist.ply");
  assert_int_equal(bsurf_read(path, &c, &e), BSURF_ERR_IO);
  assert_non_null(strstr(e.message, "No such file"));
  assert_null(c.xyz);
  tmp_path(path, sizeof path, "a_directory.ply");
  mkdir(path, 0777);
  assert_int_equal(bsurf_read(path, &c, &e), BSURF_ERR_IO);
  assert_non_null(strstr(e.message, "directory"));
  rmdir(path);
  /* an unknown extension: the content decides; without a signature the
   * extension is the error (a missing file is one first) */
  assert_int_equal(bsurf_read("model.stl", &c, &e), BSURF_ERR_IO);
  tmp_path(path, sizeof path, "model.stl");
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  fputs("solid x\nendsolid x\n", f);
  fclose(f);
  assert_int_equal(bsurf_read(path, &c, &e), BSURF_ERR_UNSUPPORTED);
  assert_non_null(strstr(e.message, "extension"));
}

static void test_atomic_write(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure e;
  make_cloud(&c);
  char path[4200];
  static const char *names[5] = {"atomic.ply", "atomic.off", "atomic.obj", "atomic.xyz",
                                 "atomic.txt"};
  for (int k = 0; k < 5; k++) {
    tmp_path(path, sizeof path, names[k]);
    assert_int_equal(bsurf_write(path, &c, NULL, &e), BSURF_OK);
    /* overwriting works too */
    assert_int_equal(bsurf_write(path, &c, NULL, &e), BSURF_OK);
    struct stat sb;
    assert_int_equal(stat(path, &sb), 0);
    assert_true(sb.st_size > 0);
    /* permissions as for any new file (umask), not mkstemp's 0600 */
    mode_t mask = umask(022);
    umask(mask);
    assert_int_equal(sb.st_mode & 0777, 0666 & ~mask);
    unlink(path);
  }
  assert_int_equal(count_files(tmp_dir(), ".tmp."), 0);

  /* a missing directory: BSURF_ERR_IO and no file */
  tmp_path(path, sizeof path, "no_such_dir/out.ply");
  assert_int_equal(bsurf_write(path, &c, NULL, &e), BSURF_ERR_IO);
  assert_non_null(strstr(e.message, "cannot create a file in directory"));
  assert_non_null(strstr(e.message, "no_such_dir"));
  assert_int_equal(access(path, F_OK), -1);

  /* an unknown extension */
  tmp_path(path, sizeof path, "out.stl");
  assert_int_equal(bsurf_write(path, &c, NULL, &e), BSURF_ERR_UNSUPPORTED);
  assert_int_equal(access(path, F_OK), -1);

  /* a cloud that cannot be written: nothing is left behind */
  c.faces[4] = 99;
  tmp_path(path, sizeof path, "bad_faces.ply");
  assert_int_equal(bsurf_write(path, &c, NULL, &e), BSURF_ERR_INVALID_ARG);
  assert_int_equal(access(path, F_OK), -1);
  c.faces[4] = 3;
  bsurf_field *f = bsurf_cloud_add_field(&c, "bad name", BSURF_FLOAT32);
  assert_non_null(f);
  assert_int_equal(bsurf_write(path, &c, NULL, &e), BSURF_ERR_INVALID_ARG);
  assert_int_equal(access(path, F_OK), -1);
  assert_int_equal(count_files(tmp_dir(), ".tmp."), 0);
  bsurf_cloud_free(&c);

  /* a write that fails half-way (file size limit): BSURF_ERR_IO, no
   * temporary left, and the existing target untouched */
  bsurf_cloud big;
  assert_int_equal(bsurf_cloud_alloc(&big, 200000, 1), BSURF_OK);
  tmp_path(path, sizeof path, "limited.ply");
  FILE *old = fopen(path, "w");
  assert_non_null(old);
  fputs("old content\n", old);
  fclose(old);
  struct rlimit saved, lim;
  assert_int_equal(getrlimit(RLIMIT_FSIZE, &saved), 0);
  lim = saved;
  lim.rlim_cur = 100000;
  void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
  assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
  bsurf_status st = bsurf_write(path, &big, NULL, &e);
  setrlimit(RLIMIT_FSIZE, &saved);
  signal(SIGXFSZ, prev);
  assert_int_equal(st, BSURF_ERR_IO);
  assert_non_null(strstr(e.message, "write failed"));
  struct stat sb;
  assert_int_equal(stat(path, &sb), 0);
  assert_int_equal(sb.st_size, 12);
  assert_int_equal(count_files(tmp_dir(), ".tmp."), 0);
  unlink(path);
  bsurf_cloud_free(&big);
}

/* An empty cloud round-trips through every format. */
static void test_empty_cloud(void **state) {
  (void)state;
  static const char *names[4] = {"empty.ply", "empty.off", "empty.obj", "empty.xyz"};
  for (int k = 0; k < 4; k++) {
    bsurf_cloud c, r;
    bsurf_failure e;
    char path[4200];
    bsurf_cloud_init(&c);
    tmp_path(path, sizeof path, names[k]);
    assert_int_equal(bsurf_write(path, &c, NULL, &e), BSURF_OK);
    assert_int_equal(bsurf_read(path, &r, &e), BSURF_OK);
    assert_int_equal(r.point_count, 0);
    bsurf_cloud_free(&r);
    unlink(path);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_roundtrip_ply_binary),
      cmocka_unit_test(test_roundtrip_ply_ascii),
      cmocka_unit_test(test_roundtrip_off),
      cmocka_unit_test(test_roundtrip_obj),
      cmocka_unit_test(test_roundtrip_xyz),
      cmocka_unit_test(test_ply_write_conversions),
      cmocka_unit_test(test_off_read),
      cmocka_unit_test(test_off_errors),
      cmocka_unit_test(test_obj_read),
      cmocka_unit_test(test_obj_errors),
      cmocka_unit_test(test_xyz_read),
      cmocka_unit_test(test_unterminated_buffers),
      cmocka_unit_test(test_number_conversions),
      cmocka_unit_test(test_formats_from_path),
      cmocka_unit_test(test_read_file_errors),
      cmocka_unit_test(test_atomic_write),
      cmocka_unit_test(test_empty_cloud),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
