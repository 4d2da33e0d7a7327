/* Fuzzing regressions (docs/fuzzing.md): every input in the fuzzers' seed
 * corpora (fuzz/corpus/fuzz_<reader>/, including the regress-* files kept
 * from crashes) goes through bsurf_read_buffer again, and the reader's
 * contract that fuzz/fuzz_reader.h checks is checked here too. Each input is
 * copied to an allocation of exactly its size, so a build with
 * -DBSURF_SANITIZE=ON catches reads past the end as the fuzzers do.
 *
 * Each seed is also cut at every length and has every byte replaced in turn
 * by a few bytes that matter to the parsers (NUL, line breaks, a space, a
 * digit, '-', 0xff): a small deterministic fuzz run on every build.
 *
 * The fuzzing campaigns in docs/fuzzing.md found no crash, leak, undefined
 * behaviour or broken contract; an input that ever does goes into the corpus
 * as fuzz/corpus/fuzz_<target>/regress-<what> (replayed here) and gets a test
 * of its own below, with the reason it failed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"

/* ---- the reader's contract (as in fuzz/fuzz_reader.h) ------------------------ */

static void check_cloud(bsurf_status st, const bsurf_cloud *c, const bsurf_failure *err) {
  assert_non_null(memchr(err->message, '\0', sizeof err->message));
  assert_true(err->line >= 0);
  if (st != BSURF_OK) {
    assert_true(err->message[0] != '\0');
    assert_true(c->point_count == 0 && c->xyz == NULL && c->normals == NULL);
    assert_true(c->field_count == 0 && c->fields == NULL);
    assert_true(c->face_count == 0 && c->faces == NULL);
    return;
  }
  assert_true(c->point_count == 0 || c->xyz != NULL);
  assert_true(c->field_count == 0 || c->fields != NULL);
  for (size_t i = 0; i < c->field_count; i++) {
    const bsurf_field *f = &c->fields[i];
    assert_non_null(memchr(f->name, '\0', sizeof f->name));
    assert_true(f->name[0] != '\0');
    assert_true(c->point_count == 0 || f->values != NULL);
    for (size_t k = 0; k < i; k++)
      assert_string_not_equal(c->fields[k].name, f->name);
  }
  assert_true(c->face_count == 0 || c->faces != NULL);
  for (size_t i = 0; i < 3 * c->face_count; i++)
    assert_true(c->faces[i] < c->point_count);
  assert_non_null(memchr(c->shape, '\0', sizeof c->shape));
}

/* Reads `size` bytes (copied to an exact-size allocation) and checks the
 * contract; returns the status. */
static bsurf_status read_exact(const void *data, size_t size, bsurf_format format,
                               bsurf_cloud *cloud, bsurf_failure *err) {
  void *copy = malloc(size ? size : 1);
  assert_non_null(copy);
  if (size) memcpy(copy, data, size);
  bsurf_status st = bsurf_read_buffer(size ? copy : NULL, size, format, cloud, err);
  free(copy);
  check_cloud(st, cloud, err);
  return st;
}

/* ---- the corpora ----------------------------------------------------------- */

static void corpus_dir(char *out, size_t cap, const char *target) {
  /* set by tests/CMakeLists.txt (tests/data is empty in a clone, so no path
   * through it) */
  const char *corpus = getenv("BSURF_FUZZ_CORPUS");
  snprintf(out, cap, "%s/%s", corpus && *corpus ? corpus : "fuzz/corpus", target);
}

/* Every prefix of the input, then every byte replaced by each of a few. */
static void read_variants(const char *buf, size_t size, bsurf_format format) {
  static const char subst[] = {'\0', '\n', '\r', ' ', '9', '-', (char)0xff};
  bsurf_cloud c;
  bsurf_failure err;
  for (size_t n = 0; n <= size; n++) {
    read_exact(buf, n, format, &c, &err);
    bsurf_cloud_free(&c);
  }
  char *m = malloc(size ? size : 1);
  assert_non_null(m);
  for (size_t i = 0; i < size; i++)
    for (size_t k = 0; k < sizeof subst; k++) {
      if (buf[i] == subst[k]) continue;
      memcpy(m, buf, size);
      m[i] = subst[k];
      read_exact(m, size, format, &c, &err);
      bsurf_cloud_free(&c);
    }
  free(m);
}

static int replay_dir(const char *target, bsurf_format format) {
  char dir[4096], path[4400];
  corpus_dir(dir, sizeof dir, target);
  DIR *d = opendir(dir);
  if (!d) fail_msg("cannot open the seed corpus %s", dir);
  int n = 0;
  struct dirent *ent;
  while ((ent = readdir(d))) {
    if (ent->d_name[0] == '.') continue;
    snprintf(path, sizeof path, "%s/%s", dir, ent->d_name);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    char *buf = NULL;
    size_t size = 0, cap = 0;
    for (;;) {
      if (size == cap) {
        cap = cap ? 2 * cap : 4096;
        buf = realloc(buf, cap);
        assert_non_null(buf);
      }
      size_t got = fread(buf + size, 1, cap - size, f);
      size += got;
      if (got == 0) break;
    }
    fclose(f);
    bsurf_cloud c;
    bsurf_failure err;
    read_exact(buf, size, format, &c, &err);
    bsurf_cloud_free(&c);
    if (size <= 4096) read_variants(buf, size, format);
    free(buf);
    n++;
  }
  closedir(d);
  return n;
}

static void test_replay_corpora(void **state) {
  (void)state;
  assert_true(replay_dir("fuzz_ply_ascii", BSURF_FORMAT_PLY) > 0);
  assert_true(replay_dir("fuzz_ply_binary", BSURF_FORMAT_PLY) > 0);
  assert_true(replay_dir("fuzz_off", BSURF_FORMAT_OFF) > 0);
  assert_true(replay_dir("fuzz_obj", BSURF_FORMAT_OBJ) > 0);
  assert_true(replay_dir("fuzz_xyz", BSURF_FORMAT_XYZ) > 0);
  assert_true(replay_dir("fuzz_pcd", BSURF_FORMAT_PCD) > 0);
  assert_true(replay_dir("fuzz_las", BSURF_FORMAT_LAS) > 0);
  assert_true(replay_dir("fuzz_csv", BSURF_FORMAT_CSV) > 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_replay_corpora),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
