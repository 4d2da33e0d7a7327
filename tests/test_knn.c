/* Tests of the exact K-nearest-neighbour search (src/search/): the k-d tree
 * against brute force (bit-identical indices and squared distances), the brute
 * force against an independent sort-based reference, determinism across thread
 * counts, h, cancellation, degenerate and non-finite input, arguments. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"

/* ------------------------------------------------------------------------ */
/* Point generators                                                           */
/* ------------------------------------------------------------------------ */

static double *alloc_xyz(size_t n) {
  double *xyz = malloc((n ? n : 1) * 3 * sizeof *xyz);
  assert_non_null(xyz);
  return xyz;
}

static double *gen_cube(size_t n, uint64_t seed) {
  double *xyz = alloc_xyz(n);
  bsurf_rng r;
  bsurf_rng_init(&r, seed, 1, 0);
  for (size_t i = 0; i < 3 * n; i++)
    xyz[i] = 2.0 * bsurf_rng_uniform(&r) - 1.0;
  return xyz;
}

static double *gen_sphere(size_t n, uint64_t seed) {
  double *xyz = alloc_xyz(n);
  bsurf_rng r;
  bsurf_rng_init(&r, seed, 2, 0);
  for (size_t i = 0; i < n; i++) {
    const double z = 2.0 * bsurf_rng_uniform(&r) - 1.0;
    const double phi = 6.283185307179586 * bsurf_rng_uniform(&r);
    const double s = sqrt(1.0 - z * z);
    xyz[3 * i] = s * cos(phi);
    xyz[3 * i + 1] = s * sin(phi);
    xyz[3 * i + 2] = z;
  }
  return xyz;
}

/* A few tight clusters of very different scales, a thin filament and sparse
 * outliers: strongly non-uniform density. */
static double *gen_clustered(size_t n, uint64_t seed) {
  double *xyz = alloc_xyz(n);
  double centre[6][3], scale[6];
  bsurf_rng r;
  bsurf_rng_init(&r, seed, 3, 0);
  for (int c = 0; c < 6; c++) {
    for (int d = 0; d < 3; d++)
      centre[c][d] = 10.0 * bsurf_rng_uniform(&r);
    scale[c] = pow(10.0, -4.0 + 4.0 * bsurf_rng_uniform(&r));
  }
  for (size_t i = 0; i < n; i++) {
    const uint32_t kind = bsurf_rng_below(&r, 20);
    double *p = xyz + 3 * i;
    if (kind == 0) { /* outlier */
      for (int d = 0; d < 3; d++)
        p[d] = 100.0 * bsurf_rng_uniform(&r) - 50.0;
    } else if (kind == 1) { /* filament along x */
      p[0] = 5.0 * bsurf_rng_uniform(&r);
      p[1] = 1e-6 * bsurf_rng_normal(&r);
      p[2] = 3.0;
    } else {
      const uint32_t c = bsurf_rng_below(&r, 6);
      for (int d = 0; d < 3; d++)
        p[d] = centre[c][d] + scale[c] * bsurf_rng_normal(&r);
    }
  }
  return xyz;
}

/* ------------------------------------------------------------------------ */
/* Checks                                                                     */
/* ------------------------------------------------------------------------ */

/* The library's distance expression (query minus point, x y z, left to right). */
static double ref_dist2(const double *q, const double *p) {
  const double dx = q[0] - p[0];
  const double dy = q[1] - p[1];
  const double dz = q[2] - p[2];
  return dx * dx + dy * dy + dz * dz;
}

typedef struct cand {
  double d;
  uint32_t i;
} cand;

/* (distance, index) with NaN after every number: the documented total order. */
static int cand_cmp(const void *a, const void *b) {
  const cand *x = a, *y = b;
  const int nx = isnan(x->d), ny = isnan(y->d);
  if (nx != ny) return nx - ny;
  if (!nx && x->d < y->d) return -1;
  if (!nx && x->d > y->d) return 1;
  return (x->i > y->i) - (x->i < y->i);
}

/* Independent reference by full sort: the k nearest indexed points of q,
 * leaving out `skip` (or none when skip >= n). */
static void sort_knn(const double *xyz, size_t n, const double *q, size_t skip, int k,
                     uint32_t *idx, double *dist2) {
  cand *c = malloc(n * sizeof *c);
  size_t m = 0;
  assert_non_null(c);
  for (size_t j = 0; j < n; j++) {
    if (j == skip) continue;
    c[m].d = ref_dist2(q, xyz + 3 * j);
    c[m].i = (uint32_t)j;
    m++;
  }
  qsort(c, m, sizeof *c, cand_cmp);
  assert_true((size_t)k <= m);
  for (int t = 0; t < k; t++) {
    idx[t] = c[t].i;
    dist2[t] = c[t].d;
  }
  free(c);
}

static void expect_same(const uint32_t *ia, const double *da, const uint32_t *ib, const double *db,
                        size_t n, int k, const char *what) {
  const size_t len = n * (size_t)k;
  for (size_t t = 0; t < len; t++) {
    if (ia[t] != ib[t] || memcmp(&da[t], &db[t], sizeof(double)) != 0) {
      print_error("%s: n=%zu k=%d first difference at row %zu col %zu: "
                  "idx %u vs %u, dist2 %.17g vs %.17g\n",
                  what, n, k, t / (size_t)k, t % (size_t)k, ia[t], ib[t], da[t], db[t]);
      fail();
    }
  }
}

/* Tree all-kNN (2 threads) == brute force, bit for bit; for small inputs the
 * brute force also equals the sort-based reference. */
static void check_all(const double *xyz, size_t n, int k) {
  const size_t len = n * (size_t)k;
  uint32_t *it = malloc(len * sizeof *it), *ib = malloc(len * sizeof *ib);
  double *dt = malloc(len * sizeof *dt), *db = malloc(len * sizeof *db);
  bsurf_knn_index *index = NULL;

  assert_non_null(it);
  assert_non_null(ib);
  assert_non_null(dt);
  assert_non_null(db);
  assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
  assert_int_equal(bsurf_knn_all(index, k, 2, it, dt, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_knn_all_brute(xyz, n, k, ib, db), BSURF_OK);
  expect_same(it, dt, ib, db, n, k, "tree vs brute");

  /* Without dist2 the indices are the same. */
  memset(it, 0xff, len * sizeof *it);
  assert_int_equal(bsurf_knn_all(index, k, 1, it, NULL, NULL, NULL), BSURF_OK);
  assert_memory_equal(it, ib, len * sizeof *it);

  if (n <= 400) {
    uint32_t *ri = malloc((size_t)k * sizeof *ri);
    double *rd = malloc((size_t)k * sizeof *rd);
    assert_non_null(ri);
    assert_non_null(rd);
    for (size_t i = 0; i < n; i++) {
      const size_t row = i * (size_t)k;
      assert_int_equal(ib[row], i);
      assert_true(db[row] == 0.0);
      if (k > 1) {
        sort_knn(xyz, n, xyz + 3 * i, i, k - 1, ri, rd);
        expect_same(ib + row + 1, db + row + 1, ri, rd, 1, k - 1, "brute vs sort");
      }
    }
    free(ri);
    free(rd);
  }
  bsurf_knn_free(index);
  free(it);
  free(ib);
  free(dt);
  free(db);
}

static const size_t sizes[] = {1, 2, 3, 5, 16, 17, 31, 64, 100, 257, 1000, 3000};
static const int ks[] = {1, 2, 5, 16, 50};

static void check_all_sizes(double *(*gen)(size_t, uint64_t)) {
  for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
    const size_t n = sizes[s];
    double *xyz = gen(n, 1000 + n);
    for (size_t t = 0; t < sizeof ks / sizeof ks[0]; t++)
      if ((size_t)ks[t] <= n) check_all(xyz, n, ks[t]);
    if (n <= 257) check_all(xyz, n, (int)n); /* k = N: everything */
    free(xyz);
  }
}

/* ------------------------------------------------------------------------ */
/* Tests                                                                      */
/* ------------------------------------------------------------------------ */

static void test_knn_all_uniform_cube(void **state) {
  (void)state;
  check_all_sizes(gen_cube);
}

static void test_knn_all_sphere_surface(void **state) {
  (void)state;
  check_all_sizes(gen_sphere);
}

static void test_knn_all_clustered(void **state) {
  (void)state;
  check_all_sizes(gen_clustered);
}

/* Exact duplicates, 1 to 4 copies of each point, scattered over the indices:
 * every row still starts with the point itself, its duplicates follow. */
static void test_knn_all_duplicates(void **state) {
  const size_t base = 400;
  double *src = gen_cube(base, 7);
  double *xyz = alloc_xyz(4 * base);
  size_t n = 0;
  bsurf_rng r;
  (void)state;
  bsurf_rng_init(&r, 7, 9, 0);
  for (size_t i = 0; i < base; i++) {
    const uint32_t copies = 1 + bsurf_rng_below(&r, 4);
    for (uint32_t c = 0; c < copies; c++)
      memcpy(xyz + 3 * n++, src + 3 * i, 3 * sizeof(double));
  }
  /* Shuffle (Fisher-Yates) so duplicates are not adjacent in index order. */
  for (size_t i = n - 1; i > 0; i--) {
    const size_t j = bsurf_rng_below(&r, (uint32_t)(i + 1));
    double t[3];
    memcpy(t, xyz + 3 * i, sizeof t);
    memcpy(xyz + 3 * i, xyz + 3 * j, sizeof t);
    memcpy(xyz + 3 * j, t, sizeof t);
  }
  for (size_t t = 0; t < sizeof ks / sizeof ks[0]; t++)
    check_all(xyz, n, ks[t]);
  check_all(xyz, n, 3);
  check_all(xyz, n, 4);
  check_all(xyz, n, (int)n);

  /* Explicitly: in row i, the zero-distance entries are i then the other
   * copies in increasing index order. */
  {
    const int k = 5;
    uint32_t *idx = malloc(n * k * sizeof *idx);
    double *d2 = malloc(n * k * sizeof *d2);
    bsurf_knn_index *index = NULL;
    assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
    assert_int_equal(bsurf_knn_all(index, k, 2, idx, d2, NULL, NULL), BSURF_OK);
    for (size_t i = 0; i < n; i++) {
      assert_int_equal(idx[i * k], i);
      for (int c = 2; c < k; c++)
        if (d2[i * k + c] == 0.0) assert_true(idx[i * k + c] > idx[i * k + c - 1]);
    }
    bsurf_knn_free(index);
    free(idx);
    free(d2);
  }
  free(src);
  free(xyz);
}

/* An integer grid: huge numbers of exactly equal distances. */
static void test_knn_all_integer_grid(void **state) {
  const int m = 14;
  const size_t n = (size_t)m * m * m;
  double *xyz = alloc_xyz(n);
  size_t p = 0;
  (void)state;
  for (int x = 0; x < m; x++)
    for (int y = 0; y < m; y++)
      for (int z = 0; z < m; z++) {
        xyz[3 * p] = x;
        xyz[3 * p + 1] = y;
        xyz[3 * p + 2] = z;
        p++;
      }
  for (size_t t = 0; t < sizeof ks / sizeof ks[0]; t++)
    check_all(xyz, n, ks[t]);
  check_all(xyz, n, 7);
  check_all(xyz, n, 27);
  check_all(xyz, n, 500);

  /* The same grid in a shuffled order, scaled by a non-power of two. */
  {
    bsurf_rng r;
    bsurf_rng_init(&r, 3, 3, 3);
    for (size_t i = n - 1; i > 0; i--) {
      const size_t j = bsurf_rng_below(&r, (uint32_t)(i + 1));
      double t[3];
      memcpy(t, xyz + 3 * i, sizeof t);
      memcpy(xyz + 3 * i, xyz + 3 * j, sizeof t);
      memcpy(xyz + 3 * j, t, sizeof t);
    }
    for (size_t i = 0; i < 3 * n; i++)
      xyz[i] *= 0.1;
    check_all(xyz, n, 7);
    check_all(xyz, n, 19);
    check_all(xyz, n, 50);
  }
  free(xyz);

  /* k = N on a smaller grid: every point, the whole order. */
  {
    const int g = 8;
    const size_t gn = (size_t)g * g * g;
    xyz = alloc_xyz(gn);
    p = 0;
    for (int x = 0; x < g; x++)
      for (int y = 0; y < g; y++)
        for (int z = 0; z < g; z++) {
          xyz[3 * p] = x;
          xyz[3 * p + 1] = y;
          xyz[3 * p + 2] = z;
          p++;
        }
    check_all(xyz, gn, (int)gn);
    free(xyz);
  }
}

static void test_knn_query_matches_brute(void **state) {
  const size_t n = 3000;
  double *clouds[3];
  (void)state;
  clouds[0] = gen_cube(n, 11);
  clouds[1] = gen_sphere(n, 12);
  clouds[2] = gen_clustered(n, 13);
  for (int c = 0; c < 3; c++) {
    bsurf_knn_index *index = NULL;
    bsurf_rng r;
    uint32_t *it = malloc(n * sizeof *it), *ir = malloc(n * sizeof *ir);
    double *dt = malloc(n * sizeof *dt), *dr = malloc(n * sizeof *dr);
    const int qk[] = {1, 2, 5, 16, 50, 300, (int)n};
    assert_int_equal(bsurf_knn_build(&index, clouds[c], n), BSURF_OK);
    bsurf_rng_init(&r, 77, (uint64_t)c, 0);
    for (int t = 0; t < 200; t++) {
      double q[3];
      const int k = qk[t % 7];
      if (t % 5 == 0) { /* exactly on an indexed point */
        memcpy(q, clouds[c] + 3 * bsurf_rng_below(&r, (uint32_t)n), sizeof q);
      } else if (t % 5 == 1) { /* far outside the bounding box */
        for (int d = 0; d < 3; d++)
          q[d] = 400.0 * bsurf_rng_uniform(&r) - 200.0;
      } else {
        for (int d = 0; d < 3; d++)
          q[d] = 3.0 * bsurf_rng_uniform(&r) - 1.5 + (c == 2 ? 5.0 : 0.0);
      }
      assert_int_equal(bsurf_knn_query(index, q, k, it, dt), BSURF_OK);
      sort_knn(clouds[c], n, q, SIZE_MAX, k, ir, dr);
      expect_same(it, dt, ir, dr, 1, k, "query vs sort");
      /* Without dist2 (internal buffer, on the stack or allocated). */
      memset(it, 0xff, n * sizeof *it);
      assert_int_equal(bsurf_knn_query(index, q, k, it, NULL), BSURF_OK);
      assert_memory_equal(it, ir, (size_t)k * sizeof *it);
    }
    bsurf_knn_free(index);
    free(it);
    free(ir);
    free(dt);
    free(dr);
    free(clouds[c]);
  }
}

static int count_progress(void *user, size_t done, size_t total) {
  size_t *last = user;
  assert_true(done > last[0]);
  assert_true(done <= total);
  last[0] = done;
  last[1]++;
  return 0;
}

/* Bit-identical for 1, 2 and 3 threads, with and without progress chunks. */
static void test_knn_all_threads_deterministic(void **state) {
  const size_t n = 100000;
  const int k = 16;
  double *xyz = gen_sphere(n, 5);
  bsurf_knn_index *index = NULL;
  uint32_t *i1 = malloc(n * k * sizeof *i1), *i2 = malloc(n * k * sizeof *i2);
  double *d1 = malloc(n * k * sizeof *d1), *d2 = malloc(n * k * sizeof *d2);
  size_t prog[2] = {0, 0};
  (void)state;
  assert_non_null(i1);
  assert_non_null(i2);
  assert_non_null(d1);
  assert_non_null(d2);
  assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
  assert_int_equal(bsurf_knn_all(index, k, 1, i1, d1, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_knn_all(index, k, 2, i2, d2, count_progress, prog), BSURF_OK);
  assert_memory_equal(i1, i2, n * k * sizeof *i1);
  assert_memory_equal(d1, d2, n * k * sizeof *d1);
  assert_int_equal(prog[0], n);
  assert_true(prog[1] >= n / 16384);
  memset(i2, 0, n * k * sizeof *i2);
  memset(d2, 0, n * k * sizeof *d2);
  assert_int_equal(bsurf_knn_all(index, k, 3, i2, d2, NULL, NULL), BSURF_OK);
  assert_memory_equal(i1, i2, n * k * sizeof *i1);
  assert_memory_equal(d1, d2, n * k * sizeof *d1);
  /* The index itself is deterministic: a second build gives the same rows. */
  bsurf_knn_free(index);
  index = NULL;
  assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
  assert_int_equal(bsurf_knn_all(index, k, 0, i2, d2, NULL, NULL), BSURF_OK);
  assert_memory_equal(i1, i2, n * k * sizeof *i1);
  assert_memory_equal(d1, d2, n * k * sizeof *d1);
  bsurf_knn_free(index);
  free(i1);
  free(i2);
  free(d1);
  free(d2);
  free(xyz);
}

/* bsurf_neighbors_build builds its tree with the threads it is given (the
 * top subtrees as tasks, their node places fixed in advance): 1 and 2
 * threads give the same rows on a cloud large enough for tasks, with runs of
 * coincident points (splits that stop early), and sampled rows equal a full
 * sort's. */
static void test_neighbors_build_threaded_tree(void **state) {
  const size_t n = 150000;
  const int k = 12;
  double *xyz = gen_sphere(n, 11);
  (void)state;
  for (size_t i = 0; i < n; i += 7) /* coincident runs of 40 points */
    if ((i / 40) % 50 == 3) memcpy(xyz + 3 * i, xyz + 3 * (i - i % 40), 3 * sizeof(double));
  bsurf_neighbors a, b;
  assert_int_equal(bsurf_neighbors_build(&a, xyz, n, k, 1, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_neighbors_build(&b, xyz, n, k, 2, NULL, NULL), BSURF_OK);
  assert_memory_equal(a.idx, b.idx, n * (size_t)k * sizeof *a.idx);
  assert_memory_equal(a.order, b.order, n * sizeof *a.order);
  assert_true(a.h == b.h);
  uint32_t ri[16];
  double rd[16];
  for (size_t i = 0; i < n; i += 997) {
    sort_knn(xyz, n, xyz + 3 * i, i, k - 1, ri, rd);
    assert_int_equal(b.idx[i * (size_t)k], i);
    for (int t = 0; t < k - 1; t++) /* ties by index: the same indices */
      assert_int_equal(b.idx[i * (size_t)k + 1 + (size_t)t], ri[t]);
  }
  bsurf_neighbors_free(&a);
  bsurf_neighbors_free(&b);
  free(xyz);
}

static double *square_grid(int nx, int ny, double s) {
  double *xyz = alloc_xyz((size_t)nx * ny);
  size_t p = 0;
  for (int y = 0; y < ny; y++)
    for (int x = 0; x < nx; x++) {
      xyz[3 * p] = x * s;
      xyz[3 * p + 1] = y * s;
      xyz[3 * p + 2] = 0.0;
      p++;
    }
  return xyz;
}

static void test_neighbors_build_grid_spacing(void **state) {
  const int nx = 60, ny = 45;
  const size_t n = (size_t)nx * ny;
  (void)state;
  {
    double *xyz = square_grid(nx, ny, 1.0);
    bsurf_neighbors nb, nb1;
    double h = -1.0;
    uint32_t *idx = malloc(n * 9 * sizeof *idx);
    bsurf_knn_index *index = NULL;
    assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 9, 2, NULL, NULL), BSURF_OK);
    assert_int_equal(nb.point_count, n);
    assert_int_equal(nb.k, 9);
    assert_non_null(nb.idx);
    assert_true(nb.h == 1.0);
    /* The rows are those of bsurf_knn_all. */
    assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
    assert_int_equal(bsurf_knn_all(index, 9, 1, idx, NULL, NULL, NULL), BSURF_OK);
    assert_memory_equal(idx, nb.idx, n * 9 * sizeof *idx);
    /* Same with 1 thread, and bsurf_mean_spacing agrees bit for bit. */
    assert_int_equal(bsurf_neighbors_build(&nb1, xyz, n, 9, 1, NULL, NULL), BSURF_OK);
    assert_memory_equal(&nb1.h, &nb.h, sizeof nb.h);
    assert_int_equal(bsurf_mean_spacing(xyz, n, 2, &h), BSURF_OK);
    assert_memory_equal(&h, &nb.h, sizeof h);
    bsurf_neighbors_free(&nb);
    bsurf_neighbors_free(&nb1);
    assert_null(nb.idx);
    bsurf_knn_free(index);
    free(idx);
    free(xyz);
  }
  {
    const double s = 0.1;
    double *xyz = square_grid(nx, ny, s);
    bsurf_neighbors nb;
    double h = -1.0;
    assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 2, 0, NULL, NULL), BSURF_OK);
    assert_true(fabs(nb.h - s) < 1e-12);
    assert_int_equal(bsurf_mean_spacing(xyz, n, 1, &h), BSURF_OK);
    assert_memory_equal(&h, &nb.h, sizeof h);
    bsurf_neighbors_free(&nb);
    free(xyz);
  }
  {
    /* Random cloud: h from a serial brute-force computation. */
    const size_t m = 2000;
    double *xyz = gen_clustered(m, 21), h = 0.0, ref = 0.0;
    uint32_t *idx = malloc(m * 2 * sizeof *idx);
    double *d2 = malloc(m * 2 * sizeof *d2);
    assert_int_equal(bsurf_knn_all_brute(xyz, m, 2, idx, d2), BSURF_OK);
    for (size_t i = 0; i < m; i++)
      ref += sqrt(d2[2 * i + 1]);
    ref /= (double)m;
    assert_int_equal(bsurf_mean_spacing(xyz, m, 2, &h), BSURF_OK);
    assert_true(fabs(h - ref) <= 1e-12 * ref);
    free(idx);
    free(d2);
    free(xyz);
  }
}

static void test_neighbors_build_errors(void **state) {
  double *xyz = gen_cube(10, 3);
  bsurf_neighbors nb;
  double h;
  (void)state;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, 10, 11, 1, NULL, NULL),
                   BSURF_ERR_TOO_FEW_POINTS);
  assert_null(nb.idx);
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, 10, 1, 1, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, 10, 0, 1, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, 0, 2, 1, NULL, NULL), BSURF_ERR_TOO_FEW_POINTS);
  assert_int_equal(bsurf_neighbors_build(&nb, NULL, 10, 2, 1, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_neighbors_build(NULL, xyz, 10, 2, 1, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, 10, 10, 1, NULL, NULL), BSURF_OK);
  bsurf_neighbors_free(&nb);
  bsurf_neighbors_free(NULL);
  assert_int_equal(bsurf_mean_spacing(xyz, 1, 1, &h), BSURF_ERR_TOO_FEW_POINTS);
  assert_int_equal(bsurf_mean_spacing(xyz, 0, 1, &h), BSURF_ERR_TOO_FEW_POINTS);
  assert_int_equal(bsurf_mean_spacing(xyz, 10, 1, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_mean_spacing(xyz, 2, 1, &h), BSURF_OK);
  free(xyz);
}

static void test_knn_argument_errors(void **state) {
  double *xyz = gen_cube(10, 4);
  bsurf_knn_index *index = (bsurf_knn_index *)&index; /* must be reset */
  uint32_t idx[20];
  double d2[20];
  const double q[3] = {0, 0, 0};
  (void)state;
  assert_int_equal(bsurf_knn_build(&index, xyz, 0), BSURF_ERR_TOO_FEW_POINTS);
  assert_null(index);
  assert_int_equal(bsurf_knn_build(&index, NULL, 10), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_build(NULL, xyz, 10), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_build(&index, xyz, 10), BSURF_OK);
  assert_int_equal(bsurf_knn_query(index, q, 0, idx, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_query(index, q, 11, idx, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_query(index, q, -3, idx, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_query(index, NULL, 1, idx, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_query(NULL, q, 1, idx, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_query(index, q, 1, NULL, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_query(index, q, 10, idx, d2), BSURF_OK);
  assert_int_equal(bsurf_knn_all(index, 0, 1, idx, d2, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_all(index, 11, 1, idx, d2, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_all(index, 2, 1, NULL, d2, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_all(NULL, 2, 1, idx, d2, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_all(index, 2, 1, idx, d2, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_knn_all_brute(xyz, 0, 1, idx, d2), BSURF_ERR_TOO_FEW_POINTS);
  assert_int_equal(bsurf_knn_all_brute(xyz, 10, 0, idx, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_all_brute(xyz, 10, 11, idx, d2), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_knn_all_brute(xyz, 10, 2, idx, NULL), BSURF_OK);
  bsurf_knn_free(index);
  bsurf_knn_free(NULL);
  free(xyz);
}

static int cancel_at_once(void *user, size_t done, size_t total) {
  int *calls = user;
  (void)done;
  (void)total;
  (*calls)++;
  return 1;
}

static int cancel_second(void *user, size_t done, size_t total) {
  int *calls = user;
  (void)done;
  (void)total;
  return ++(*calls) >= 2;
}

static void test_knn_all_cancellation(void **state) {
  const size_t n = 40000;
  double *xyz = gen_cube(n, 8);
  bsurf_knn_index *index = NULL;
  uint32_t *idx = malloc(n * 8 * sizeof *idx);
  bsurf_neighbors nb;
  int calls = 0;
  (void)state;
  assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
  assert_int_equal(bsurf_knn_all(index, 8, 2, idx, NULL, cancel_at_once, &calls),
                   BSURF_ERR_CANCELLED);
  assert_int_equal(calls, 1);
  calls = 0;
  assert_int_equal(bsurf_knn_all(index, 8, 1, idx, NULL, cancel_second, &calls),
                   BSURF_ERR_CANCELLED);
  assert_int_equal(calls, 2);
  calls = 0;
  assert_int_equal(bsurf_neighbors_build(&nb, xyz, n, 8, 2, cancel_at_once, &calls),
                   BSURF_ERR_CANCELLED);
  assert_int_equal(calls, 1);
  assert_null(nb.idx);
  bsurf_knn_free(index);
  free(idx);
  free(xyz);
}

static void test_knn_degenerate_identical(void **state) {
  const size_t n = 900;
  double *xyz = alloc_xyz(n);
  (void)state;
  for (size_t i = 0; i < n; i++) {
    xyz[3 * i] = 0.25;
    xyz[3 * i + 1] = -3.0;
    xyz[3 * i + 2] = 7.0;
  }
  check_all(xyz, n, 1);
  check_all(xyz, n, 2);
  check_all(xyz, n, 16);
  check_all(xyz, n, 50);
  check_all(xyz, n, (int)n);
  /* Two coincident clumps. */
  for (size_t i = 0; i < n; i += 3)
    xyz[3 * i] = 1.25;
  check_all(xyz, n, 16);
  check_all(xyz, n, 400);
  free(xyz);
}

static void test_knn_degenerate_collinear(void **state) {
  const size_t n = 2000;
  double *xyz = alloc_xyz(n);
  bsurf_rng r;
  (void)state;
  bsurf_rng_init(&r, 5, 5, 5);
  /* Random positions on a skew line. */
  for (size_t i = 0; i < n; i++) {
    const double t = bsurf_rng_uniform(&r);
    xyz[3 * i] = 1.0 + 2.0 * t;
    xyz[3 * i + 1] = -0.5 * t;
    xyz[3 * i + 2] = 3.0 * t;
  }
  check_all(xyz, n, 2);
  check_all(xyz, n, 16);
  check_all(xyz, n, 50);
  /* Evenly spaced integers on the x axis: every point has two equidistant
   * neighbours. Then a plane grid. */
  for (size_t i = 0; i < n; i++) {
    xyz[3 * i] = (double)((i * 7919) % n);
    xyz[3 * i + 1] = 0.0;
    xyz[3 * i + 2] = 0.0;
  }
  check_all(xyz, n, 2);
  check_all(xyz, n, 3);
  check_all(xyz, n, 16);
  check_all(xyz, n, 51);
  free(xyz);
  xyz = square_grid(40, 50, 0.5);
  check_all(xyz, 2000, 5);
  check_all(xyz, 2000, 9);
  check_all(xyz, 2000, 50);
  free(xyz);
}

/* Distances over hundreds of orders of magnitude, exact ties at every scale
 * and distances that overflow to infinity (no NaN): the all-kNN sorts its
 * candidates in buckets between the smallest and largest distance, with an
 * insertion sort alone where that range is zero or infinite; every path must
 * give the brute force's rows, order included. */
static void test_knn_all_wide_range(void **state) {
  const size_t n = 1500;
  double *xyz = alloc_xyz(n);
  bsurf_rng r;
  (void)state;
  bsurf_rng_init(&r, 11, 0, 0);
  for (size_t i = 0; i < n; i++) {
    /* Clusters of spacing 1e-150, 1, 1e150 on small integer grids (ties),
     * far apart, and a few points near 1e200 (squared distances to them
     * overflow). */
    static const double scale[] = {1e-150, 1.0, 1e150, 1e200};
    const size_t c = i % 10 < 4 ? 0 : i % 10 < 7 ? 1 : i % 10 < 9 ? 2 : 3;
    for (int d = 0; d < 3; d++)
      xyz[3 * i + d] = scale[c] * (double)bsurf_rng_below(&r, 6) + (double)c * 1e3 * (c < 3);
  }
  check_all(xyz, n, 16);
  check_all(xyz, n, 50);
  check_all(xyz, n, 200);
  free(xyz);
}

/* NaN and infinite coordinates are the caller's to reject, but the search must
 * terminate, and it still gives exactly the brute-force answer (NaN distances
 * sort last). */
static void test_knn_nonfinite_terminates(void **state) {
  const size_t n = 700;
  double *xyz = gen_cube(n, 9);
  (void)state;
  for (size_t i = 0; i < n; i += 7)
    xyz[3 * i + (i % 3)] = NAN;
  for (size_t i = 3; i < n; i += 50)
    xyz[3 * i + 1] = (i % 100 == 3) ? INFINITY : -INFINITY;
  check_all(xyz, n, 1);
  check_all(xyz, n, 2);
  check_all(xyz, n, 16);
  check_all(xyz, n, (int)n);
  for (size_t i = 0; i < 3 * n; i++)
    xyz[i] = NAN;
  check_all(xyz, n, 5);
  {
    bsurf_knn_index *index = NULL;
    uint32_t idx[4];
    double q[3] = {NAN, 0, 0};
    assert_int_equal(bsurf_knn_build(&index, xyz, n), BSURF_OK);
    assert_int_equal(bsurf_knn_query(index, q, 4, idx, NULL), BSURF_OK);
    for (int t = 0; t < 4; t++)
      assert_int_equal(idx[t], t);
    bsurf_knn_free(index);
  }
  free(xyz);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_knn_all_uniform_cube),
      cmocka_unit_test(test_neighbors_build_threaded_tree),
      cmocka_unit_test(test_knn_all_sphere_surface),
      cmocka_unit_test(test_knn_all_clustered),
      cmocka_unit_test(test_knn_all_duplicates),
      cmocka_unit_test(test_knn_all_integer_grid),
      cmocka_unit_test(test_knn_query_matches_brute),
      cmocka_unit_test(test_knn_all_threads_deterministic),
      cmocka_unit_test(test_neighbors_build_grid_spacing),
      cmocka_unit_test(test_neighbors_build_errors),
      cmocka_unit_test(test_knn_argument_errors),
      cmocka_unit_test(test_knn_all_cancellation),
      cmocka_unit_test(test_knn_degenerate_identical),
      cmocka_unit_test(test_knn_degenerate_collinear),
      cmocka_unit_test(test_knn_all_wide_range),
      cmocka_unit_test(test_knn_nonfinite_terminates),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
