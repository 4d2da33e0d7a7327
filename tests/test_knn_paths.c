/* Tests of the all-kNN's paths (src/search/knn_all.c): the batches' gathered
 * candidates scanned in AVX-512 (where the processor has it) and by the
 * portable scan, and the tree search alone, each bit for bit against the
 * brute force (indices and squared distances, ties by index included; the
 * AVX2 scan too where the processor has it), on
 * clouds chosen so that every path is taken (bsurf_knn_path_counts): the
 * candidates' answers, the tree search after the candidates fell short
 * (density jumps), batches whose candidates do not fit (coincident
 * points), exact ties (integer grids), and the same rows for 1 and 2
 * threads. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "search/search.h"

typedef struct paths_case {
  const char *name;
  double *xyz;
  size_t n;
} paths_case;

static double *alloc_xyz(size_t n) {
  double *xyz = malloc(n * 3 * sizeof *xyz);
  assert_non_null(xyz);
  return xyz;
}

/* The benchmark's cloud, small: a regularly sampled sphere (coherent order)
 * with uniform noise along the normals of about half the spacing. */
static double *gen_sphere(size_t *n_out) {
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 6000, BSURF_SAMPLING_REGULAR, 1, 0.0),
                   BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_UNIFORM, 0.5, 0.045, 1),
      BSURF_OK);
  double *xyz = alloc_xyz(c.point_count);
  memcpy(xyz, c.xyz, c.point_count * 3 * sizeof *xyz);
  *n_out = c.point_count;
  bsurf_cloud_free(&c);
  return xyz;
}

/* Clusters of scales 1e-4 .. 1 beside sparse outliers: a batch's guess (the
 * previous batch's largest distance) is often far too small or too large. */
static double *gen_clusters(size_t n, uint64_t seed) {
  double *xyz = alloc_xyz(n);
  bsurf_rng r;
  bsurf_rng_init(&r, seed, 2, 0);
  for (size_t i = 0; i < n; i++) {
    const uint32_t c = bsurf_rng_below(&r, 5);
    const double scale = c == 4 ? 30.0 : pow(10.0, -(double)c);
    for (int d = 0; d < 3; d++)
      xyz[3 * i + d] = 3.0 * (double)c + scale * bsurf_rng_normal(&r);
  }
  return xyz;
}

/* An integer grid (exactly equal distances everywhere), with runs of
 * coincident points: 600 copies of one point (more than a batch's
 * candidates hold) and pairs of copies. */
static double *gen_grid_copies(size_t *n_out) {
  const int g = 16;
  const size_t n = (size_t)g * g * g + 600 + 200;
  double *xyz = alloc_xyz(n);
  size_t p = 0;
  for (int x = 0; x < g; x++)
    for (int y = 0; y < g; y++)
      for (int z = 0; z < g; z++) {
        xyz[3 * p] = x;
        xyz[3 * p + 1] = y;
        xyz[3 * p + 2] = z;
        p++;
      }
  for (int c = 0; c < 600; c++, p++) {
    xyz[3 * p] = 7.0;
    xyz[3 * p + 1] = 8.0;
    xyz[3 * p + 2] = 9.0;
  }
  for (int c = 0; c < 200; c++, p++)
    memcpy(xyz + 3 * p, xyz + 3 * (size_t)(c * 13), 3 * sizeof(double));
  *n_out = n;
  return xyz;
}

/* The rows of one path setting (and the path counts). */
static void run_path(const double *xyz, size_t n, int k, int threads, int batches, int simd,
                     uint32_t *idx, double *d2, size_t counts[4]) {
  bsurf_knn_index *index = NULL;
  bsurf_knn_set_paths(batches, simd);
  if (simd == 0) assert_int_equal(bsurf_knn_simd(), 0);
  assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
  assert_int_equal(bsurf_knn_all(index, k, threads, idx, d2, NULL, NULL), BSURF_OK);
  bsurf_knn_path_counts(counts);
  bsurf_knn_free(index);
  bsurf_knn_set_paths(1, 2);
}

static void expect_rows(const uint32_t *ia, const double *da, const uint32_t *ib, const double *db,
                        size_t len, const char *what, const char *name, int k) {
  for (size_t t = 0; t < len; t++)
    if (ia[t] != ib[t] || memcmp(&da[t], &db[t], sizeof(double)) != 0) {
      print_error("%s (%s, k = %d): row %zu col %zu: idx %u vs %u, dist2 %.17g vs %.17g\n", what,
                  name, k, t / (size_t)k, t % (size_t)k, ia[t], ib[t], da[t], db[t]);
      fail();
    }
}

/* Every path and thread count against the brute force; adds the path
 * counts of the default path (batches, AVX-512 where present) and of the
 * portable scan to sum_simd and sum_plain. */
static void check_paths(const paths_case *c, int k, size_t sum_simd[4], size_t sum_plain[4]) {
  const size_t len = c->n * (size_t)k;
  uint32_t *ib = malloc(len * sizeof *ib), *it = malloc(len * sizeof *it);
  double *db = malloc(len * sizeof *db), *dt = malloc(len * sizeof *dt);
  size_t counts[4];
  assert_true(ib && it && db && dt);
  assert_int_equal(bsurf_knn_all_brute(c->xyz, c->n, k, ib, db), BSURF_OK);
  static const struct {
    int batches, simd, threads;
    const char *what;
  } paths[] = {{1, 2, 1, "batches, AVX-512 scan (or the best), 1 thread"},
               {1, 2, 2, "batches, AVX-512 scan (or the best), 2 threads"},
               {1, 1, 2, "batches, AVX2 scan (or portable), 2 threads"},
               {1, 0, 1, "batches, portable scan, 1 thread"},
               {1, 0, 2, "batches, portable scan, 2 threads"},
               {0, 2, 2, "tree search only, 2 threads"}};
  for (size_t p = 0; p < sizeof paths / sizeof paths[0]; p++) {
    memset(it, 0xff, len * sizeof *it);
    memset(dt, 0xff, len * sizeof *dt);
    run_path(c->xyz, c->n, k, paths[p].threads, paths[p].batches, paths[p].simd, it, dt, counts);
    expect_rows(it, dt, ib, db, len, paths[p].what, c->name, k);
    if (!paths[p].batches) assert_true(counts[0] == 0 && counts[2] == 0 && counts[3] == 0);
    for (int q = 0; q < 4 && paths[p].batches && paths[p].threads == 1; q++)
      (paths[p].simd ? sum_simd : sum_plain)[q] += counts[q];
  }
  free(ib);
  free(it);
  free(db);
  free(dt);
}

static void test_knn_paths_against_brute(void **state) {
  (void)state;
  paths_case cases[3];
  size_t sn = 0;
  cases[0].xyz = gen_sphere(&sn);
  cases[0].n = sn;
  cases[0].name = "noisy sphere";
  cases[1] = (paths_case){"clusters", gen_clusters(5000, 2), 5000};
  size_t gn = 0;
  cases[2].xyz = gen_grid_copies(&gn);
  cases[2].n = gn;
  cases[2].name = "grid with copies";
  static const int ks[] = {2, 7, 30, 64};
  size_t sum_simd[4] = {0}, sum_plain[4] = {0};
  for (size_t c = 0; c < 3; c++)
    for (size_t t = 0; t < sizeof ks / sizeof ks[0]; t++)
      check_paths(&cases[c], ks[t], sum_simd, sum_plain);
  /* every path was taken: batches through their candidates and through the
   * tree, queries answered from the candidates and, after they fell short,
   * by the tree search; the same choices in both scans */
  for (int q = 0; q < 4; q++) {
    assert_true(sum_simd[q] > 0);
    assert_true(sum_simd[q] == sum_plain[q]);
  }
  /* most queries answered from the candidates */
  assert_true(sum_simd[2] > 10 * sum_simd[3]);
  for (size_t c = 0; c < 3; c++)
    free(cases[c].xyz);
}

/* The batches' bound near overflow: squared distances beyond the largest
 * double (the candidates' bound is then infinite) and subnormal ones. */
static void test_knn_paths_extreme_scales(void **state) {
  (void)state;
  const size_t n = 3000;
  double *xyz = alloc_xyz(n);
  bsurf_rng r;
  bsurf_rng_init(&r, 5, 5, 0);
  for (size_t i = 0; i < n; i++) {
    static const double scale[] = {1e-160, 1.0, 1e160};
    const size_t c = i % 3;
    for (int d = 0; d < 3; d++)
      xyz[3 * i + d] = scale[c] * (bsurf_rng_uniform(&r) + (double)c * 10.0);
  }
  paths_case pc = {"extreme scales", xyz, n};
  size_t sum_simd[4] = {0}, sum_plain[4] = {0};
  check_paths(&pc, 20, sum_simd, sum_plain);
  free(xyz);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_knn_paths_against_brute),
      cmocka_unit_test(test_knn_paths_extreme_scales),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
