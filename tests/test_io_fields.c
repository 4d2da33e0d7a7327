/* Field names of the PCD, LAS and CSV readers (one mechanism: a name set
 * and bsurf_cloud_add_fields, src/io/binary.c): many extra fields come back
 * with their names and values; names written twice become name, name_1,
 * name_2 in file order (a name taken by then gets the next suffix); a PCD
 * ascii header whose POINTS the data cannot hold fails with the size
 * message before the cloud is allocated; CSV's types are as
 * docs/formats.md states them. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bootsurf.h"
#include "common/common.h"
#include "test_util.h"

static void write_file(const char *path, const void *data, size_t n) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  assert_int_equal(fwrite(data, 1, n, f), n);
  assert_int_equal(fclose(f), 0);
}

#define NFIELDS 1500
#define NPOINTS 7

/* A value exact in float32, int16 and every text format. */
static double value(size_t f, size_t i) {
  return (double)((int)(f * 7 + i * 13) % 2001 - 1000) / 4.0;
}

/* Fields f0 .. f{count-1} are in b with their values. */
static void same_named(const bsurf_cloud *b, size_t count, const char *what) {
  assert_int_equal(b->point_count, NPOINTS);
  for (size_t f = 0; f < count; f++) {
    char name[32];
    snprintf(name, sizeof name, "f%zu", f);
    const bsurf_field *fb = bsurf_cloud_field(b, name);
    if (!fb) fail_msg("%s: field %s is missing", what, name);
    for (size_t i = 0; i < NPOINTS; i++)
      if (fb->values[i] != value(f, i))
        fail_msg("%s: %s point %zu: %.17g, not %.17g", what, name, i, fb->values[i], value(f, i));
  }
}

static void test_many_fields_round_trip(void **state) {
  (void)state;
  bsurf_cloud a;
  bsurf_cloud_init(&a);
  assert_int_equal(bsurf_cloud_alloc(&a, NPOINTS, 0), BSURF_OK);
  for (size_t i = 0; i < 3 * NPOINTS; i++)
    a.xyz[i] = (double)i * 0.5;
  const char **names = malloc(NFIELDS * sizeof *names);
  bsurf_type *types = malloc(NFIELDS * sizeof *types);
  char(*buf)[32] = malloc(NFIELDS * sizeof *buf);
  assert_true(names && types && buf);
  for (size_t f = 0; f < NFIELDS; f++) {
    snprintf(buf[f], sizeof buf[f], "f%zu", f);
    names[f] = buf[f];
    types[f] = BSURF_FLOAT32;
  }
  for (size_t f = 0; f < NFIELDS; f++) {
    bsurf_field *fl = bsurf_cloud_add_field(&a, names[f], types[f]);
    assert_non_null(fl);
    for (size_t i = 0; i < NPOINTS; i++)
      fl->values[i] = value(f, i);
  }
  /* LAS holds at most 341 extra-bytes fields: its file gets the first 340;
   * PCD and CSV take all of them (the CSV reader's limit is 65536 columns) */
  static const char *const files[] = {"io_fields_many.pcd", "io_fields_many_ascii.pcd",
                                      "io_fields_many.csv", "io_fields_many.las"};
  static const size_t keep[] = {NFIELDS, NFIELDS, NFIELDS, 340};
  for (size_t k = 0; k < sizeof files / sizeof files[0]; k++) {
    while (a.field_count > keep[k])
      bsurf_cloud_remove_field(&a, a.fields[a.field_count - 1].name);
    char path[4096];
    bsurf_failure err;
    bsurf_write_options o = {.ascii = k == 1};
    snprintf(path, sizeof path, "%s", tmp_path(files[k]));
    if (bsurf_write(path, &a, &o, &err) != BSURF_OK) fail_msg("write %s: %s", path, err.message);
    bsurf_cloud b;
    if (bsurf_read(path, &b, &err) != BSURF_OK) fail_msg("read %s: %s", path, err.message);
    same_named(&b, a.field_count, files[k]);
    bsurf_cloud_free(&b);
  }
  free(names);
  free(types);
  free(buf);
  bsurf_cloud_free(&a);
}

/* Names written twice (and a name that a suffix would make) in a PCD and a
 * CSV header: the first keeps the name, the next get _1, _2. */
/* bsurf_cloud_add_fields on a cloud that has fields already (LAS: the
 * standard attributes, then the extra bytes): the old names stay, a name
 * given again is the same field (its type replaced), the new ones follow in
 * order. Under ASan this also checks that no old name is read after the
 * field array moved. */
static void test_add_fields_to_existing(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  assert_int_equal(bsurf_cloud_alloc(&c, 4, 0), BSURF_OK);
  static const char *const first[3] = {"intensity", "classification", "gps_time"};
  for (int k = 0; k < 3; k++) {
    bsurf_field *f = bsurf_cloud_add_field(&c, first[k], BSURF_UINT16);
    assert_non_null(f);
    f->values[0] = 10 + k;
  }
  static const char *const more[4] = {"err", "classification", "label", "hits"};
  static const bsurf_type types[4] = {BSURF_FLOAT32, BSURF_UINT8, BSURF_INT8, BSURF_UINT32};
  assert_int_equal(bsurf_cloud_add_fields(&c, 4, more, types), BSURF_OK);
  static const char *const want[6] = {"intensity", "classification", "gps_time",
                                      "err",       "label",          "hits"};
  assert_int_equal(c.field_count, 6);
  for (int k = 0; k < 6; k++)
    assert_string_equal(c.fields[k].name, want[k]);
  assert_int_equal(c.fields[1].type, BSURF_UINT8);
  assert_true(c.fields[1].values[0] == 11);
  assert_true(c.fields[3].values[3] == 0);
  bsurf_cloud_free(&c);
}

static void test_repeated_names(void **state) {
  (void)state;
  char path[4096];
  bsurf_failure err;
  bsurf_cloud c;
  const char *pcd = "VERSION .7\nFIELDS x y z q q q_1 q\nSIZE 4 4 4 4 4 4 4\nTYPE F F F F F F F\n"
                    "COUNT 1 1 1 1 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n"
                    "1 2 3 10 11 12 13\n";
  snprintf(path, sizeof path, "%s", tmp_path("io_fields_repeated.pcd"));
  write_file(path, pcd, strlen(pcd));
  if (bsurf_read(path, &c, &err) != BSURF_OK) fail_msg("%s: %s", path, err.message);
  static const char *const want[4] = {"q", "q_1", "q_1_1", "q_2"};
  assert_int_equal(c.field_count, 4);
  for (int k = 0; k < 4; k++) {
    assert_string_equal(c.fields[k].name, want[k]);
    assert_true(c.fields[k].values[0] == 10 + k);
  }
  bsurf_cloud_free(&c);

  const char *csv = "x,y,z,q,q,q_1,q\n1,2,3,10,11,12,13\n";
  snprintf(path, sizeof path, "%s", tmp_path("io_fields_repeated.csv"));
  write_file(path, csv, strlen(csv));
  if (bsurf_read(path, &c, &err) != BSURF_OK) fail_msg("%s: %s", path, err.message);
  assert_int_equal(c.field_count, 4);
  for (int k = 0; k < 4; k++) {
    assert_string_equal(c.fields[k].name, want[k]);
    assert_true(c.fields[k].values[0] == 10 + k);
  }
  bsurf_cloud_free(&c);
}

/* POINTS 40,000 of 1,003 values each (x y z and h with COUNT 1000) over a
 * few kilobytes of ascii data: at least two bytes a value, so the data
 * cannot hold them; the reader says so before allocating the cloud (about
 * 320 MB). A child process limited to 128 MB of data shows the order: it
 * gets the parse error, not out of memory. */
static void test_pcd_ascii_count_before_allocation(void **state) {
  (void)state;
  char head[512], path[4096];
  snprintf(head, sizeof head,
           "VERSION .7\nFIELDS x y z h\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1000\n"
           "WIDTH 40000\nHEIGHT 1\nPOINTS 40000\nDATA ascii\n");
  const size_t hl = strlen(head), body = 60000; /* above POINTS: one byte a point fits */
  char *file = malloc(hl + body);
  assert_non_null(file);
  memcpy(file, head, hl);
  for (size_t i = 0; i < body; i++)
    file[hl + i] = (i % 2) ? '\n' : '0';
  snprintf(path, sizeof path, "%s", tmp_path("io_fields_huge_count.pcd"));
  write_file(path, file, hl + body);
  free(file);

  bsurf_cloud c;
  bsurf_failure err;
  assert_int_equal(bsurf_read(path, &c, &err), BSURF_ERR_PARSE);
  if (!strstr(err.message, "POINTS 40000 with 1003 values each cannot fit"))
    fail_msg("unexpected message: %s", err.message);
  assert_int_equal(err.line, 10); /* the first line of data */

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  printf("SKIP (part): the 128 MB child is left out under a sanitizer (its runtime maps far "
         "more)\n");
#else
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    struct rlimit lim = {128u << 20, 128u << 20};
    if (setrlimit(RLIMIT_DATA, &lim) != 0) _exit(100);
    bsurf_cloud cc;
    bsurf_failure e;
    _exit((int)bsurf_read(path, &cc, &e));
  }
  int status = 0;
  assert_int_equal(waitpid(pid, &status, 0), pid);
  assert_true(WIFEXITED(status));
  assert_int_equal(WEXITSTATUS(status), BSURF_ERR_PARSE);
#endif
}

/* docs/formats.md: CSV keeps the values, and a field's type only where it
 * is the smallest one holding them. */
static void test_csv_types(void **state) {
  (void)state;
  static const struct {
    const char *name;
    bsurf_type type, back;
    double scale, offset; /* value i: offset + scale i */
  } cases[] = {
      {"u16_wide", BSURF_UINT16, BSURF_UINT16, 100, 0}, /* up to 400: uint16 */
      {"u16_small", BSURF_UINT16, BSURF_UINT8, 50, 0},  /* below 256: uint8 */
      {"i16", BSURF_INT16, BSURF_INT16, 100, -300},
      {"i32", BSURF_INT32, BSURF_INT32, 1e6, -1e6},
      {"f32", BSURF_FLOAT32, BSURF_FLOAT32, 0.25, 0.5},
      {"f32_whole", BSURF_FLOAT32, BSURF_INT8, 1, -2},      /* whole numbers: an integer */
      {"f64_single", BSURF_FLOAT64, BSURF_FLOAT32, 0.5, 0}, /* floats hold them: float32 */
      {"f64", BSURF_FLOAT64, BSURF_FLOAT64, 0.1, 0},
  };
  const size_t nc = sizeof cases / sizeof cases[0];
  bsurf_cloud a, b;
  bsurf_cloud_init(&a);
  assert_int_equal(bsurf_cloud_alloc(&a, 5, 0), BSURF_OK);
  for (size_t i = 0; i < 15; i++)
    a.xyz[i] = (double)i;
  for (size_t k = 0; k < nc; k++) {
    bsurf_field *f = bsurf_cloud_add_field(&a, cases[k].name, cases[k].type);
    assert_non_null(f);
    for (size_t i = 0; i < 5; i++)
      f->values[i] = cases[k].offset + cases[k].scale * (double)i;
  }
  char path[4096];
  bsurf_failure err;
  snprintf(path, sizeof path, "%s", tmp_path("io_fields_types.csv"));
  if (bsurf_write(path, &a, NULL, &err) != BSURF_OK) fail_msg("write: %s", err.message);
  if (bsurf_read(path, &b, &err) != BSURF_OK) fail_msg("read: %s", err.message);
  for (size_t k = 0; k < nc; k++) {
    const bsurf_field *fa = bsurf_cloud_field(&a, cases[k].name);
    const bsurf_field *fb = bsurf_cloud_field(&b, cases[k].name);
    assert_non_null(fb);
    for (size_t i = 0; i < 5; i++)
      if (fa->values[i] != fb->values[i])
        fail_msg("%s point %zu: %.17g, not %.17g", cases[k].name, i, fb->values[i], fa->values[i]);
    if (fb->type != cases[k].back)
      fail_msg("%s: type %d, not %d", cases[k].name, (int)fb->type, (int)cases[k].back);
  }
  bsurf_cloud_free(&a);
  bsurf_cloud_free(&b);
}

int main(void) {
  tmp_dir_init();
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_many_fields_round_trip),
      cmocka_unit_test(test_add_fields_to_existing),
      cmocka_unit_test(test_repeated_names),
      cmocka_unit_test(test_pcd_ascii_count_before_allocation),
      cmocka_unit_test(test_csv_types),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
