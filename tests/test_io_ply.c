/* PLY reading from hand-written buffers: the three encodings, every property
 * type, skipped elements, faces, and files that lie or end early. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bootsurf.h"

/* ---- a byte buffer to build binary files ---------------------------------- */

typedef struct buf {
  unsigned char d[4096];
  size_t n;
} buf;

static void put_str(buf *b, const char *s) {
  size_t n = strlen(s);
  assert_true(b->n + n <= sizeof b->d);
  memcpy(b->d + b->n, s, n);
  b->n += n;
}

static void put_uint(buf *b, uint64_t u, int bytes, int be) {
  assert_true(b->n + (size_t)bytes <= sizeof b->d);
  for (int i = 0; i < bytes; i++) {
    int shift = 8 * (be ? bytes - 1 - i : i);
    b->d[b->n++] = (unsigned char)(u >> shift);
  }
}

static void put_f32(buf *b, float f, int be) {
  uint32_t u;
  memcpy(&u, &f, 4);
  put_uint(b, u, 4, be);
}

static void put_f64(buf *b, double f, int be) {
  uint64_t u;
  memcpy(&u, &f, 8);
  put_uint(b, u, 8, be);
}

static bsurf_status read_str(const char *s, bsurf_cloud *c, bsurf_failure *e) {
  return bsurf_read_buffer(s, strlen(s), BSURF_FORMAT_PLY, c, e);
}

/* The cloud is left empty after a failure. */
static void assert_empty(const bsurf_cloud *c) {
  assert_int_equal(c->point_count, 0);
  assert_null(c->xyz);
  assert_null(c->normals);
  assert_null(c->fields);
  assert_null(c->faces);
}

/* ---- the three encodings --------------------------------------------------- */

/* Every property type, big-endian, with an edge element (lists included) to
 * skip and a quad to triangulate. */
static void test_ply_binary_big_endian(void **state) {
  (void)state;
  buf b = {{0}, 0};
  put_str(&b, "ply\nformat binary_big_endian 1.0\ncomment built by hand\n"
              "element vertex 4\n"
              "property float x\nproperty float y\nproperty float z\n"
              "property double nx\nproperty double ny\nproperty double nz\n"
              "property uchar red\nproperty char c\nproperty short s\nproperty ushort us\n"
              "property int32 i\nproperty uint u\nproperty float64 d\n"
              "element edge 2\nproperty int vertex1\nproperty list uint8 int16 extra\n"
              "element face 1\nproperty uchar flags\nproperty list uchar uint vertex_indices\n"
              "property list short float texcoord\n"
              "end_header\n");
  for (int i = 0; i < 4; i++) {
    put_f32(&b, 1.5f + (float)i, 1);
    put_f32(&b, -2.25f * (float)i, 1);
    put_f32(&b, 0.125f, 1);
    put_f64(&b, 0.1 * i, 1);
    put_f64(&b, 1.0 / 3.0, 1);
    put_f64(&b, -1.0, 1);
    put_uint(&b, 200 + (uint64_t)i, 1, 1);
    put_uint(&b, (uint64_t)(uint8_t)(int8_t)(-100 - i), 1, 1);
    put_uint(&b, (uint64_t)(uint16_t)(int16_t)(-30000 + i), 2, 1);
    put_uint(&b, 65535 - (uint64_t)i, 2, 1);
    put_uint(&b, (uint64_t)(uint32_t)(int32_t)(-2000000000 - i), 4, 1);
    put_uint(&b, 4000000000u + (uint64_t)i, 4, 1);
    put_f64(&b, 1e-300 * (i + 1), 1);
  }
  /* edges: vertex1, then a list of 2 and a list of 0 int16 */
  put_uint(&b, 1, 4, 1);
  put_uint(&b, 2, 1, 1);
  put_uint(&b, 7, 2, 1);
  put_uint(&b, 8, 2, 1);
  put_uint(&b, 2, 4, 1);
  put_uint(&b, 0, 1, 1);
  /* the quad 0 1 2 3 with a texcoord list of 1 float */
  put_uint(&b, 9, 1, 1);
  put_uint(&b, 4, 1, 1);
  for (int i = 0; i < 4; i++)
    put_uint(&b, (uint64_t)i, 4, 1);
  put_uint(&b, 1, 2, 1);
  put_f32(&b, 0.5f, 1);

  bsurf_cloud c;
  bsurf_failure e;
  assert_int_equal(bsurf_read_buffer(b.d, b.n, BSURF_FORMAT_PLY, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 4);
  assert_int_equal(c.xyz_type, BSURF_FLOAT32);
  assert_int_equal(c.normal_type, BSURF_FLOAT64);
  assert_non_null(c.normals);
  assert_int_equal(c.field_count, 7);
  static const char *names[7] = {"red", "c", "s", "us", "i", "u", "d"};
  static const bsurf_type types[7] = {BSURF_UINT8, BSURF_INT8,   BSURF_INT16,  BSURF_UINT16,
                                      BSURF_INT32, BSURF_UINT32, BSURF_FLOAT64};
  for (int k = 0; k < 7; k++) {
    assert_string_equal(c.fields[k].name, names[k]);
    assert_int_equal(c.fields[k].type, types[k]);
  }
  for (int i = 0; i < 4; i++) {
    assert_true(c.xyz[3 * i] == 1.5 + i);
    assert_true(c.xyz[3 * i + 1] == -2.25 * i);
    assert_true(c.xyz[3 * i + 2] == 0.125);
    assert_true(c.normals[3 * i] == 0.1 * i);
    assert_true(c.normals[3 * i + 1] == 1.0 / 3.0);
    assert_true(c.normals[3 * i + 2] == -1.0);
    assert_true(c.fields[0].values[i] == 200 + i);
    assert_true(c.fields[1].values[i] == -100 - i);
    assert_true(c.fields[2].values[i] == -30000 + i);
    assert_true(c.fields[3].values[i] == 65535 - i);
    assert_true(c.fields[4].values[i] == -2000000000.0 - i);
    assert_true(c.fields[5].values[i] == 4000000000.0 + i);
    assert_true(c.fields[6].values[i] == 1e-300 * (i + 1));
  }
  assert_int_equal(c.face_count, 2);
  static const uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
  assert_memory_equal(c.faces, tri, sizeof tri);
  bsurf_cloud_free(&c);

  /* every truncation of the file fails cleanly; inside the data with
   * BSURF_ERR_PARSE and the offset */
  size_t header = (size_t)(strstr((const char *)b.d, "end_header\n") - (const char *)b.d) + 11;
  for (size_t n = 0; n < b.n; n++) {
    bsurf_status st = bsurf_read_buffer(b.d, n, BSURF_FORMAT_PLY, &c, &e);
    assert_int_not_equal(st, BSURF_OK);
    if (n >= header) {
      assert_int_equal(st, BSURF_ERR_PARSE);
      assert_true(e.byte >= (long long)header && e.byte <= (long long)n);
    }
    assert_true(e.message[0] != '\0');
    assert_empty(&c);
  }
}

static void test_ply_binary_little_endian(void **state) {
  (void)state;
  buf b = {{0}, 0};
  put_str(&b, "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 3\r\n"
              "property double x\r\nproperty double y\r\nproperty double z\r\n"
              "property float nx\r\nproperty float ny\r\n"
              "element face 1\r\nproperty list int32 int32 vertex_index\r\nend_header\r\n");
  for (int i = 0; i < 3; i++) {
    put_f64(&b, 0.1 + i, 0);
    put_f64(&b, 1e10 * i, 0);
    put_f64(&b, -0.0, 0);
    put_f32(&b, 0.5f, 0);
    put_f32(&b, -0.5f, 0);
  }
  put_uint(&b, 3, 4, 0);
  put_uint(&b, 2, 4, 0);
  put_uint(&b, 1, 4, 0);
  put_uint(&b, 0, 4, 0);
  bsurf_cloud c;
  bsurf_failure e;
  assert_int_equal(bsurf_read_buffer(b.d, b.n, BSURF_FORMAT_PLY, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 3);
  /* nx ny without nz are plain fields */
  assert_null(c.normals);
  assert_int_equal(c.field_count, 2);
  assert_string_equal(c.fields[0].name, "nx");
  assert_int_equal(c.fields[1].type, BSURF_FLOAT32);
  assert_true(c.fields[1].values[2] == -0.5);
  assert_true(c.xyz[3 * 2] == 0.1 + 2 && c.xyz[3 * 2 + 1] == 2e10);
  assert_true(signbit(c.xyz[2]));
  assert_int_equal(c.face_count, 1);
  assert_int_equal(c.faces[0], 2);
  assert_int_equal(c.faces[2], 0);
  bsurf_cloud_free(&c);
}

static void test_ply_ascii_crlf_comments(void **state) {
  (void)state;
  const char *s = "ply\r\n"
                  "format ascii 1.0\r\n"
                  "comment a comment\r\n"
                  "obj_info made by hand\r\n"
                  "element vertex 4\r\n"
                  "property float32 x\r\n"
                  "property float32 y\r\n"
                  "property float32 z\r\n"
                  "property uint8 red\r\n"
                  "element material 2\r\n"
                  "property uchar ambient_red\r\n"
                  "property list uchar float coefficients\r\n"
                  "element face 2\r\n"
                  "property list uchar int vertex_indices\r\n"
                  "property uchar flags\r\n"
                  "end_header\r\n"
                  "0 0 0 255\r\n"
                  "1 0 0 128\r\n"
                  "\r\n"
                  "1 1 0 0\r\n"
                  "0 1 1.5e-3 7\r\n"
                  "10 3 0.5 0.25 1\r\n"
                  "11 0\r\n"
                  "4 0 1 2 3 1\r\n"
                  "3 3 2 1 0\r\n"
                  "\r\n  \r\n";
  bsurf_cloud c;
  bsurf_failure e;
  assert_int_equal(read_str(s, &c, &e), BSURF_OK);
  assert_int_equal(c.point_count, 4);
  assert_int_equal(c.xyz_type, BSURF_FLOAT32);
  assert_int_equal(c.field_count, 1);
  assert_int_equal(c.fields[0].type, BSURF_UINT8);
  assert_true(c.fields[0].values[1] == 128);
  assert_true(c.xyz[3 * 3 + 2] == (double)1.5e-3f); /* a float property */
  assert_int_equal(c.face_count, 3);
  static const uint32_t tri[9] = {0, 1, 2, 0, 2, 3, 3, 2, 1};
  assert_memory_equal(c.faces, tri, sizeof tri);
  bsurf_cloud_free(&c);
}

static void test_ply_empty_and_minimal(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure e;
  assert_int_equal(read_str("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                            "property float y\nproperty float z\nend_header\n",
                            &c, &e),
                   BSURF_OK);
  assert_int_equal(c.point_count, 0);
  bsurf_cloud_free(&c);
  /* no newline after end_header, no data */
  assert_int_equal(read_str("ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
                            "property float x\nproperty float y\nproperty float z\nend_header",
                            &c, &e),
                   BSURF_OK);
  bsurf_cloud_free(&c);
}

/* ---- rejected files ---------------------------------------------------------- */

static void expect_fail(const char *s, bsurf_status want, long line, const char *needle) {
  bsurf_cloud c;
  bsurf_failure e;
  bsurf_status st = read_str(s, &c, &e);
  if (st != want || (line >= 0 && e.line != line) || (needle && !strstr(e.message, needle)))
    print_error("got status %d line %ld message '%s'\n", (int)st, e.line, e.message);
  assert_int_equal(st, want);
  if (line >= 0) assert_int_equal(e.line, line);
  if (needle) assert_non_null(strstr(e.message, needle));
  assert_empty(&c);
}

#define HDR3 "property float x\nproperty float y\nproperty float z\n"

static void test_ply_header_errors(void **state) {
  (void)state;
  expect_fail("", BSURF_ERR_PARSE, 1, "not a PLY file");
  expect_fail("plyx\nformat ascii 1.0\n", BSURF_ERR_PARSE, 1, "not a PLY file");
  expect_fail("OFF\n3 0 0\n", BSURF_ERR_PARSE, 1, "not a PLY file");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\n" HDR3 "0 0 0\n", BSURF_ERR_PARSE, -1,
              "end_header");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\n" HDR3, BSURF_ERR_PARSE, -1, "end_header");
  expect_fail("ply\nformat binary_middle_endian 1.0\nend_header\n", BSURF_ERR_UNSUPPORTED, 2,
              "binary_middle_endian");
  expect_fail("ply\nformat ascii 2.0\nend_header\n", BSURF_ERR_UNSUPPORTED, 2, "version");
  expect_fail("ply\nelement vertex 1\n" HDR3 "end_header\n0 0 0\n", BSURF_ERR_PARSE, 6,
              "no format");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "end_header\n0 0\n",
              BSURF_ERR_PARSE, 3, "'z'");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\nproperty float z\n"
              "end_header\n0 0\n",
              BSURF_ERR_PARSE, 3, "no 'x' property");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\n" HDR3
              "property list uchar float weights\nend_header\n0 0 0 1 1\n",
              BSURF_ERR_UNSUPPORTED, 7, "list property 'weights'");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\n" HDR3
              "property half h\nend_header\n0 0 0 1\n",
              BSURF_ERR_PARSE, 7, "unknown property type 'half'");
  expect_fail("ply\nformat ascii 1.0\nelement vertex -1\n" HDR3 "end_header\n", BSURF_ERR_PARSE, 3,
              "element count");
  expect_fail("ply\nformat ascii 1.0\nproperty float x\nend_header\n", BSURF_ERR_PARSE, 3,
              "before any element");
  expect_fail("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\n"
              "end_header\n",
              BSURF_ERR_PARSE, -1, "no vertex element");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\n" HDR3 "property float x\nend_header\n"
              "0 0 0 0\n",
              BSURF_ERR_PARSE, 7, "declared twice");
  expect_fail("ply\nformat ascii 1.0\nelement vertex 1\n" HDR3 "bogus line\nend_header\n",
              BSURF_ERR_PARSE, 7, "bogus");
}

static void test_ply_ascii_data_errors(void **state) {
  (void)state;
  const char *hdr =
      "ply\nformat ascii 1.0\nelement vertex 3\n" HDR3 "property uchar red\nproperty float s\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  char s[1024];
  /* header line count: 11, so data starts on line 12 */
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0\n3 0 1 2\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 14, "vertex 2: expected 5 values, found 3");
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1 9\n0 1 0 1 1\n3 0 1 2\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 13, "vertex 1: expected 5 values, found 6");
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 abc 1 1\n0 1 0 1 1\n3 0 1 2\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 13, "'abc' is not a number");
  /* the header lies: fewer vertices than declared */
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 14, "unexpected end of file");
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0 1 1\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 15, "face 0: unexpected end of file");
  /* bad faces */
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0 1 1\n3 0 1 3\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 15, "face 0: vertex index 3 is out of range");
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0 1 1\n3 0 -1 2\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 15, "face 0: vertex index -1");
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0 1 1\n4 0 1 2\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 15, "face 0: expected 5 values, found 4");
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0 1 1\n2.5 0 1 2\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 15, "list length");
  /* trailing data: whitespace is fine, anything else is reported */
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0 1 1\n3 0 1 2\n \n\t\n", hdr);
  bsurf_cloud c;
  bsurf_failure e;
  assert_int_equal(read_str(s, &c, &e), BSURF_OK);
  bsurf_cloud_free(&c);
  snprintf(s, sizeof s, "%s0 0 0 1 1\n1 0 0 1 1\n0 1 0 1 1\n3 0 1 2\n\n7 7 7\n", hdr);
  expect_fail(s, BSURF_ERR_PARSE, 17, "after the last element");
}

static void test_ply_binary_data_errors(void **state) {
  (void)state;
  /* the header lies: 10 vertices declared, 5 present */
  buf b = {{0}, 0};
  put_str(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 10\n" HDR3 "end_header\n");
  size_t body = b.n;
  for (int i = 0; i < 5 * 3; i++)
    put_f32(&b, (float)i, 0);
  put_uint(&b, 0, 2, 0); /* a partial sixth vertex */
  bsurf_cloud c;
  bsurf_failure e;
  assert_int_equal(bsurf_read_buffer(b.d, b.n, BSURF_FORMAT_PLY, &c, &e), BSURF_ERR_PARSE);
  assert_non_null(strstr(e.message, "header declares 10 vertices (120 bytes) but only 62 bytes"));
  assert_non_null(strstr(e.message, "vertex 5"));
  assert_int_equal(e.byte, (long long)(body + 5 * 12));
  assert_empty(&c);

  /* data after the last element: a line break is tolerated, anything else
   * means the header does not describe the data */
  for (int variant = 0; variant < 2; variant++) {
    buf t = {{0}, 0};
    put_str(&t, "ply\nformat binary_little_endian 1.0\nelement vertex 2\n" HDR3 "end_header\n");
    for (int i = 0; i < 6; i++)
      put_f32(&t, (float)i, 0);
    size_t end = t.n;
    put_str(&t, variant ? "\n" : "\x01\x02\x03");
    bsurf_status st = bsurf_read_buffer(t.d, t.n, BSURF_FORMAT_PLY, &c, &e);
    if (variant) {
      assert_int_equal(st, BSURF_OK);
      bsurf_cloud_free(&c);
    } else {
      assert_int_equal(st, BSURF_ERR_PARSE);
      assert_non_null(strstr(e.message, "3 bytes of data follow the last element"));
      assert_int_equal(e.byte, (long long)end);
      assert_empty(&c);
    }
  }

  /* a face index out of range, and a face list longer than the data */
  const char *fh = "ply\nformat binary_big_endian 1.0\nelement vertex 3\n" HDR3
                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (int variant = 0; variant < 2; variant++) {
    buf f = {{0}, 0};
    put_str(&f, fh);
    for (int i = 0; i < 9; i++)
      put_f32(&f, 1.0f, 1);
    size_t face_at = f.n;
    put_uint(&f, variant ? 200 : 3, 1, 1);
    put_uint(&f, 0, 4, 1);
    put_uint(&f, 1, 4, 1);
    put_uint(&f, variant ? 2 : 7, 4, 1);
    assert_int_equal(bsurf_read_buffer(f.d, f.n, BSURF_FORMAT_PLY, &c, &e), BSURF_ERR_PARSE);
    if (variant) {
      assert_non_null(strstr(e.message, "face 0: a list of 200 values"));
    } else {
      assert_non_null(strstr(e.message, "face 0: vertex index 7 is out of range"));
      assert_int_equal(e.byte, (long long)face_at);
    }
    assert_empty(&c);
  }
}

/* A header claiming 99999999999 vertices fails at once, without allocating. */
static void test_ply_huge_counts(void **state) {
  (void)state;
  static const char *fmts[3] = {"ascii", "binary_little_endian", "binary_big_endian"};
  clock_t t0 = clock();
  for (int k = 0; k < 3; k++) {
    char s[512];
    snprintf(s, sizeof s,
             "ply\nformat %s 1.0\nelement vertex 99999999999\n" HDR3 "end_header\n0 0 0\n1 1 1\n",
             fmts[k]);
    bsurf_cloud c;
    bsurf_failure e;
    assert_int_equal(read_str(s, &c, &e), BSURF_ERR_PARSE);
    assert_non_null(strstr(e.message, "header declares 99999999999 vertices"));
    if (k == 0)
      assert_int_equal(e.line, 10); /* where the data ends */
    else
      assert_non_null(strstr(e.message, "(1199999999988 bytes) but only 12 bytes follow"));
    assert_empty(&c);
    /* the same for a skipped element and for faces */
    snprintf(s, sizeof s,
             "ply\nformat %s 1.0\nelement vertex 1\n" HDR3
             "element junk 18446744073709551615\nproperty list uint int stuff\n"
             "element face 99999999999\nproperty list uchar int vertex_indices\n"
             "end_header\n0 0 0\n1 1 1\n",
             fmts[k]);
    assert_int_equal(read_str(s, &c, &e), BSURF_ERR_PARSE);
    if (k > 0) assert_non_null(strstr(e.message, "18446744073709551615 'junk' elements"));
    assert_empty(&c);
  }
  assert_true((double)(clock() - t0) / CLOCKS_PER_SEC < 0.5);
}

/* Random damage to a valid file never crashes or leaks (run under ASan). */
static void test_ply_damaged(void **state) {
  (void)state;
  const char *ascii =
      "ply\nformat ascii 1.0\nelement vertex 3\n" HDR3 "property uchar red\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n"
      "0 0 0 1\n1 0 0 2\n0 1 0 3\n3 0 1 2\n";
  buf b = {{0}, 0};
  put_str(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n" HDR3
              "property uchar red\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n");
  for (int i = 0; i < 3; i++) {
    for (int k = 0; k < 3; k++)
      put_f32(&b, (float)(i == k), 0);
    put_uint(&b, 9, 1, 0);
  }
  put_uint(&b, 3, 1, 0);
  for (int i = 0; i < 3; i++)
    put_uint(&b, (uint64_t)i, 4, 0);

  const unsigned char *src[2] = {(const unsigned char *)ascii, b.d};
  size_t len[2] = {strlen(ascii), b.n};
  uint32_t x = 12345;
  for (int f = 0; f < 2; f++) {
    for (int trial = 0; trial < 3000; trial++) {
      unsigned char *copy = malloc(len[f]); /* exact size: ASan sees overreads */
      memcpy(copy, src[f], len[f]);
      int flips = 1 + trial % 4;
      for (int k = 0; k < flips; k++) {
        x = x * 1103515245u + 12345u;
        size_t at = (x >> 8) % len[f];
        x = x * 1103515245u + 12345u;
        copy[at] = (unsigned char)(x >> 16);
      }
      x = x * 1103515245u + 12345u;
      size_t n = trial % 2 ? len[f] : (x >> 8) % (len[f] + 1);
      bsurf_cloud c;
      bsurf_failure e;
      bsurf_status st = bsurf_read_buffer(copy, n, BSURF_FORMAT_PLY, &c, &e);
      if (st == BSURF_OK) {
        for (size_t i = 0; i < 3 * c.face_count; i++)
          assert_true(c.faces[i] < c.point_count);
        bsurf_cloud_free(&c);
      } else {
        assert_true(e.message[0] != '\0');
        assert_empty(&c);
      }
      free(copy);
    }
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_ply_binary_big_endian),
      cmocka_unit_test(test_ply_binary_little_endian),
      cmocka_unit_test(test_ply_ascii_crlf_comments),
      cmocka_unit_test(test_ply_empty_and_minimal),
      cmocka_unit_test(test_ply_header_errors),
      cmocka_unit_test(test_ply_ascii_data_errors),
      cmocka_unit_test(test_ply_binary_data_errors),
      cmocka_unit_test(test_ply_huge_counts),
      cmocka_unit_test(test_ply_damaged),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
