/* The body of every reader fuzz target: FUZZ_FORMAT (a bsurf_format) is
 * defined by the including fuzz_<format>.c before it includes this file.
 *
 * The input goes unchanged to bsurf_read_buffer (whose readers must never
 * read past data + size: libFuzzer's buffer is exactly `size` bytes long, so
 * ASan catches any over-read). Beyond memory errors, leaks and undefined
 * behaviour, the target checks the reader's contract and abort()s when it is
 * broken:
 *   - failure: the cloud is left empty and the error message is a non-empty,
 *     terminated string;
 *   - success: every array the counts promise is there and readable, field
 *     names are terminated, non-empty and distinct, every face index is a
 *     point of the cloud, the shape name is terminated.
 *
 * Optional round trip (BSURF_FUZZ_ROUNDTRIP=DIR, e.g. /dev/shm): every cloud
 * read is also written to DIR as binary and as ascii PLY and read back; the
 * write must succeed and the cloud read back must equal the first (values as
 * their declared type stores them). Slower (two files per input). */
#ifndef BSURF_FUZZ_READER_H
#define BSURF_FUZZ_READER_H

#include "bootsurf.h"
#include "io/io.h" /* io_type_convert */

#include <math.h>
#include <unistd.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FUZZ_CHECK(cond)                                                                           \
  do {                                                                                             \
    if (!(cond)) {                                                                                 \
      fprintf(stderr, "%s:%d: reader contract broken: %s\n", __FILE__, __LINE__, #cond);           \
      abort();                                                                                     \
    }                                                                                              \
  } while (0)

/* Reads every value so that a short allocation is an ASan report; the sum is
 * kept so that the compiler cannot drop the loads. */
static volatile double fuzz_sink;

static void fuzz_touch(const double *v, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++)
    s += v[i];
  fuzz_sink = s;
}

static void fuzz_check_cloud(bsurf_status st, const bsurf_cloud *c, const bsurf_failure *err) {
  FUZZ_CHECK(memchr(err->message, '\0', sizeof err->message) != NULL);
  FUZZ_CHECK(err->line >= 0);
  if (st != BSURF_OK) {
    FUZZ_CHECK(err->message[0] != '\0');
    FUZZ_CHECK(c->point_count == 0 && c->xyz == NULL && c->normals == NULL);
    FUZZ_CHECK(c->field_count == 0 && c->fields == NULL);
    FUZZ_CHECK(c->face_count == 0 && c->faces == NULL);
    return;
  }
  FUZZ_CHECK(c->point_count == 0 || c->xyz != NULL);
  if (c->point_count) fuzz_touch(c->xyz, 3 * c->point_count);
  if (c->normals && c->point_count) fuzz_touch(c->normals, 3 * c->point_count);
  FUZZ_CHECK(c->field_count == 0 || c->fields != NULL);
  for (size_t i = 0; i < c->field_count; i++) {
    const bsurf_field *f = &c->fields[i];
    FUZZ_CHECK(memchr(f->name, '\0', sizeof f->name) != NULL);
    FUZZ_CHECK(f->name[0] != '\0');
    FUZZ_CHECK((unsigned)f->type <= (unsigned)BSURF_FLOAT64);
    FUZZ_CHECK(c->point_count == 0 || f->values != NULL);
    if (c->point_count) fuzz_touch(f->values, c->point_count);
    for (size_t k = 0; k < i; k++)
      FUZZ_CHECK(strcmp(c->fields[k].name, f->name) != 0);
  }
  FUZZ_CHECK(c->face_count == 0 || c->faces != NULL);
  for (size_t i = 0; i < 3 * c->face_count; i++)
    FUZZ_CHECK(c->faces[i] < c->point_count);
  FUZZ_CHECK(memchr(c->shape, '\0', sizeof c->shape) != NULL);
  FUZZ_CHECK((unsigned)c->xyz_type <= (unsigned)BSURF_FLOAT64);
  FUZZ_CHECK((unsigned)c->normal_type <= (unsigned)BSURF_FLOAT64);
}

/* The same value once stored as `type` (NaN equals NaN). */
static int fuzz_same(double first, double again, bsurf_type type) {
  double want = io_type_convert(first, type);
  return (isnan(want) && isnan(again)) || want == again;
}

static const char *g_roundtrip_dir;

static void fuzz_roundtrip(const bsurf_cloud *c, int ascii) {
  char path[4096];
  snprintf(path, sizeof path, "%s/bsurf-fuzz-%ld.ply", g_roundtrip_dir, (long)getpid());
  bsurf_write_options o = {.ascii = ascii};
  bsurf_failure err;
  bsurf_status st = bsurf_write(path, c, &o, &err);
  if (st != BSURF_OK) fprintf(stderr, "write: %s\n", err.message);
  FUZZ_CHECK(st == BSURF_OK);
  bsurf_cloud b;
  st = bsurf_read(path, &b, &err);
  if (st != BSURF_OK) fprintf(stderr, "read back: line %ld: %s\n", err.line, err.message);
  FUZZ_CHECK(st == BSURF_OK);
  unlink(path);
  FUZZ_CHECK(b.point_count == c->point_count && b.face_count == c->face_count);
  FUZZ_CHECK(b.field_count == c->field_count && !b.normals == !c->normals);
  FUZZ_CHECK(b.xyz_type == c->xyz_type && (!c->normals || b.normal_type == c->normal_type));
  FUZZ_CHECK(strcmp(b.shape, c->shape) == 0);
  for (size_t i = 0; i < 3 * c->point_count; i++) {
    FUZZ_CHECK(fuzz_same(c->xyz[i], b.xyz[i], c->xyz_type));
    if (c->normals) FUZZ_CHECK(fuzz_same(c->normals[i], b.normals[i], c->normal_type));
  }
  for (size_t k = 0; k < c->field_count; k++) {
    FUZZ_CHECK(strcmp(b.fields[k].name, c->fields[k].name) == 0);
    FUZZ_CHECK(b.fields[k].type == c->fields[k].type);
    for (size_t i = 0; i < c->point_count; i++)
      FUZZ_CHECK(fuzz_same(c->fields[k].values[i], b.fields[k].values[i], c->fields[k].type));
  }
  if (c->face_count)
    FUZZ_CHECK(memcmp(b.faces, c->faces, 3 * c->face_count * sizeof *c->faces) == 0);
  bsurf_cloud_free(&b);
}

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc;
  (void)argv;
  const char *dir = getenv("BSURF_FUZZ_ROUNDTRIP");
  if (dir && dir[0]) g_roundtrip_dir = dir;
  return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  bsurf_cloud cloud;
  bsurf_failure err;
  bsurf_status st = bsurf_read_buffer(data, size, FUZZ_FORMAT, &cloud, &err);
  fuzz_check_cloud(st, &cloud, &err);
  if (st == BSURF_OK) {
    /* the copy walks every array once more with the counts it trusts */
    bsurf_cloud copy;
    if (bsurf_cloud_copy(&copy, &cloud) == BSURF_OK) bsurf_cloud_free(&copy);
    if (g_roundtrip_dir) {
      fuzz_roundtrip(&cloud, 0);
      fuzz_roundtrip(&cloud, 1);
    }
  }
  bsurf_cloud_free(&cloud);
  return 0;
}

#endif
