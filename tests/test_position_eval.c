/* bsurf_eval_position (the position section of `bootsurf eval`): the choice
 * of the true surface, exact distances on hand-made cases (plane z = 0 as a
 * shape, a mesh and tangent planes), the nearest-point correspondence, the
 * split and feature groups against sums made here, thread independence, and
 * refused input (no surface, a zero truth normal). */
/* cmocka.h needs these first */
/* clang-format off */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
/* clang-format on */

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "test_util.h"

/* A truth of 4 x 4 points on z = 0 in the generated plane's square [-1, 1]^2
 * (spacing 0.6), normals +z, feature = 1
 * for x = 0; result points at the same x, y, at height z_i = (i % 5) / 10. */
#define SIDE 4
#define N (SIDE * SIDE)

static void make_truth(bsurf_cloud *t, int with_normals, int with_feature) {
  bsurf_cloud_init(t);
  t->point_count = N;
  t->xyz = calloc(3 * N, sizeof(double));
  for (int i = 0; i < N; i++) {
    t->xyz[3 * i] = -0.9 + 0.6 * (i % SIDE);
    t->xyz[3 * i + 1] = -0.9 + 0.6 * (i / SIDE);
  }
  if (with_normals) {
    t->normals = calloc(3 * N, sizeof(double));
    for (int i = 0; i < N; i++)
      t->normals[3 * i + 2] = 2.0; /* not unit: divided by its length */
  }
  if (with_feature) {
    bsurf_field *f = bsurf_cloud_add_field(t, "feature", BSURF_UINT8);
    assert_non_null(f);
    for (int i = 0; i < N; i++)
      f->values[i] = i % SIDE == 0;
  }
}

static void make_result(double *xyz) {
  for (int i = 0; i < N; i++) {
    xyz[3 * i] = -0.9 + 0.6 * (i % SIDE);
    xyz[3 * i + 1] = -0.9 + 0.6 * (i / SIDE);
    xyz[3 * i + 2] = (i % 5) / 10.0 * (i % 2 ? 1 : -1);
  }
}

/* The expected statistics of |z| over the points selected by keep(i). */
static void expect(const bsurf_distance_stats *s, const double *xyz, int (*keep)(int)) {
  size_t n = 0;
  double sum = 0, sum2 = 0, max = 0;
  for (int i = 0; i < N; i++)
    if (!keep || keep(i)) {
      double d = fabs(xyz[3 * i + 2]);
      n++;
      sum += d;
      sum2 += d * d;
      if (d > max) max = d;
    }
  assert_int_equal(s->count, n);
  assert_true(fabs(s->mean - sum / (double)n) < 1e-15);
  assert_true(fabs(s->rms - sqrt(sum2 / (double)n)) < 1e-15);
  assert_true(s->max == max);
}

static int is_feature(int i) {
  return i % SIDE == 0;
}
static int is_plain(int i) {
  return i % SIDE != 0;
}
static int is_high(int i) {
  return i >= 10;
}
static int is_high_feature(int i) {
  return i >= 10 && i % SIDE == 0;
}

static void test_surface_choice(void **state) {
  (void)state;
  bsurf_cloud t;
  make_truth(&t, 0, 0);
  bsurf_surface_kind k;
  bsurf_shape sh;
  assert_int_equal(bsurf_eval_position_surface(&t, NULL, &k, &sh), 0);
  bsurf_position_eval r;
  double xyz[3 * N];
  make_result(xyz);
  assert_invalid(bsurf_eval_position(xyz, N, &t, NULL, &r, NULL), "bsurf_eval_position",
                 "no true surface");
  t.normals = calloc(3 * N, sizeof(double));
  assert_int_equal(bsurf_eval_position_surface(&t, NULL, &k, &sh), 1);
  assert_int_equal(k, BSURF_SURFACE_TANGENT_PLANE);
  snprintf(t.shape, sizeof t.shape, "plane");
  assert_int_equal(bsurf_eval_position_surface(&t, NULL, &k, &sh), 1);
  assert_int_equal(k, BSURF_SURFACE_SHAPE);
  assert_int_equal(sh, BSURF_SHAPE_PLANE);
  bsurf_cloud mesh;
  bsurf_cloud_init(&mesh);
  mesh.face_count = 1;
  assert_int_equal(bsurf_eval_position_surface(&t, &mesh, &k, &sh), 1);
  assert_int_equal(k, BSURF_SURFACE_MESH);
  /* the zero normals: a NaN distance, reported at the first point */
  t.shape[0] = 0;
  assert_int_equal(bsurf_eval_position(xyz, N, &t, NULL, &r, NULL), BSURF_ERR_INVALID_VALUE);
  assert_int_equal(r.stage, BSURF_POSITION_STAGE_DISTANCE);
  assert_int_equal(r.bad_point, 0);
  bsurf_cloud_free(&t);
}

/* Shape, tangent planes and a mesh of the square give |z| for every point. */
static void test_three_surfaces(void **state) {
  (void)state;
  double xyz[3 * N], dist[N];
  make_result(xyz);
  bsurf_cloud t;
  make_truth(&t, 1, 1);
  uint8_t high[N];
  for (int i = 0; i < N; i++)
    high[i] = (uint8_t)is_high(i);
  bsurf_position_eval_options o;
  memset(&o, 0, sizeof o);
  o.high = high;
  bsurf_cloud mesh;
  bsurf_cloud_init(&mesh);
  double v[12] = {-1, -1, 0, 9, -1, 0, 9, 9, 0, -1, 9, 0};
  uint32_t f[6] = {0, 1, 2, 0, 2, 3};
  mesh.point_count = 4;
  mesh.xyz = v;
  mesh.face_count = 2;
  mesh.faces = f;
  for (int kind = 0; kind < 3; kind++) {
    t.shape[0] = 0;
    o.surface = NULL;
    if (kind == 0) snprintf(t.shape, sizeof t.shape, "plane");
    if (kind == 2) o.surface = &mesh;
    for (int threads = 1; threads <= 2; threads++) {
      o.threads = threads;
      bsurf_position_eval r;
      assert_int_equal(bsurf_eval_position(xyz, N, &t, &o, &r, dist), BSURF_OK);
      assert_int_equal(r.surface, kind == 0   ? BSURF_SURFACE_SHAPE
                                  : kind == 1 ? BSURF_SURFACE_TANGENT_PLANE
                                              : BSURF_SURFACE_MESH);
      assert_int_equal(r.surface_is_truth, 0);
      assert_int_equal(r.nearest, 0);
      assert_true(fabs(r.h - 0.6) < 1e-12);
      assert_int_equal(r.has_feature, 1);
      assert_int_equal(r.groups, 3);
      assert_int_equal(r.stage, BSURF_POSITION_STAGE_NONE);
      for (int i = 0; i < N; i++)
        assert_true(fabs(dist[i] - fabs(xyz[3 * i + 2])) < 1e-15);
      expect(&r.stats[BSURF_POSITION_ALL][BSURF_POSITION_PART_ALL], xyz, NULL);
      expect(&r.stats[BSURF_POSITION_ALL][BSURF_POSITION_PART_FEATURE], xyz, is_feature);
      expect(&r.stats[BSURF_POSITION_ALL][BSURF_POSITION_PART_NON_FEATURE], xyz, is_plain);
      expect(&r.stats[BSURF_POSITION_HIGH][BSURF_POSITION_PART_ALL], xyz, is_high);
      expect(&r.stats[BSURF_POSITION_HIGH][BSURF_POSITION_PART_FEATURE], xyz, is_high_feature);
      assert_int_equal(r.stats[BSURF_POSITION_LOW][BSURF_POSITION_PART_ALL].count, 10);
    }
  }
  t.shape[0] = 0;
  bsurf_cloud_free(&t);
}

/* Fewer result points than truth points: the nearest truth point gives the
 * tangent plane and the feature label. */
static void test_nearest(void **state) {
  (void)state;
  double xyz[3 * N];
  make_result(xyz);
  bsurf_cloud t;
  make_truth(&t, 1, 1);
  /* result: the points 5.., shifted by 0.2 in x (still nearest to their own) */
  const int m = N - 5;
  double *sub = &xyz[3 * 5];
  for (int i = 0; i < m; i++)
    sub[3 * i] += 0.2;
  bsurf_position_eval r;
  assert_int_equal(bsurf_eval_position(sub, (size_t)m, &t, NULL, &r, NULL), BSURF_OK);
  assert_int_equal(r.nearest, 1);
  size_t feat = 0;
  for (int i = 5; i < N; i++)
    feat += i % SIDE == 0;
  assert_int_equal(r.stats[0][BSURF_POSITION_PART_FEATURE].count, feat);
  assert_int_equal(r.stats[0][BSURF_POSITION_PART_ALL].count, (size_t)m);
  bsurf_cloud_free(&t);
}

int main(void) {
  tmp_dir_init();
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_surface_choice),
      cmocka_unit_test(test_three_surfaces),
      cmocka_unit_test(test_nearest),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
