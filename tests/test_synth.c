/* Generated shapes and synthetic noise. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"

static void test_shapes_on_surface(void **state) {
  (void)state;
  for (int s = 0; s < 4; s++) {
    for (int sampling = 0; sampling < 2; sampling++) {
      bsurf_cloud c;
      assert_int_equal(bsurf_generate(&c, (bsurf_shape)s, 5000, (bsurf_sampling)sampling, 4, 2.0),
                       BSURF_OK);
      assert_true(c.point_count > 4500 && c.point_count < 5500);
      assert_non_null(c.normals);
      for (size_t i = 0; i < c.point_count; i++) {
        const double *p = &c.xyz[3 * i], *n = &c.normals[3 * i];
        assert_true(bsurf_shape_distance((bsurf_shape)s, p) < 1e-12);
        assert_true(fabs(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1) < 1e-12);
        /* moving along the normal leaves the surface at unit rate */
        double q[3] = {p[0] + 1e-4 * n[0], p[1] + 1e-4 * n[1], p[2] + 1e-4 * n[2]};
        assert_true(fabs(bsurf_shape_distance((bsurf_shape)s, q) - 1e-4) < 1e-9);
      }
      bsurf_cloud_free(&c);
    }
  }
}

static void test_names(void **state) {
  (void)state;
  bsurf_shape s;
  assert_int_equal(bsurf_shape_from_name("torus", &s), 0);
  assert_int_equal(s, BSURF_SHAPE_TORUS);
  assert_string_equal(bsurf_shape_name(BSURF_SHAPE_CUBE), "cube");
  assert_int_equal(bsurf_shape_from_name("teapot", &s), -1);
}

static void test_cube_features(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(
      bsurf_generate(&c, BSURF_SHAPE_CUBE, 6 * 40 * 40, BSURF_SAMPLING_REGULAR, 1, 2.0), BSURF_OK);
  assert_int_equal(c.point_count, 6 * 40 * 40);
  bsurf_field *fd = bsurf_cloud_field(&c, "feature_dist"), *ff = bsurf_cloud_field(&c, "feature");
  assert_non_null(fd);
  assert_non_null(ff);
  /* grid step 2/40 = 0.05 = nominal spacing; width 2 spacings = 0.1: the two
   * outer rings of each face (distances 0.025 and 0.075) are features */
  size_t features = 0;
  for (size_t i = 0; i < c.point_count; i++) {
    const double *p = &c.xyz[3 * i];
    double m = 0;
    for (int t = 0; t < 3; t++)
      if (fabs(p[t]) < 1 - 1e-12 && fabs(p[t]) > m) m = fabs(p[t]);
    assert_true(fabs(fd->values[i] - (1 - m)) < 1e-12);
    features += ff->values[i] == 1.0;
  }
  assert_int_equal(features, 6 * (40 * 40 - 36 * 36));
  bsurf_cloud_free(&c);
}

static void test_random_determinism(void **state) {
  (void)state;
  bsurf_cloud a, b, c;
  assert_int_equal(bsurf_generate(&a, BSURF_SHAPE_SPHERE, 1000, BSURF_SAMPLING_RANDOM, 7, 0),
                   BSURF_OK);
  assert_int_equal(bsurf_generate(&b, BSURF_SHAPE_SPHERE, 1000, BSURF_SAMPLING_RANDOM, 7, 0),
                   BSURF_OK);
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 1000, BSURF_SAMPLING_RANDOM, 8, 0),
                   BSURF_OK);
  assert_memory_equal(a.xyz, b.xyz, 3000 * sizeof(double));
  assert_true(memcmp(a.xyz, c.xyz, 3000 * sizeof(double)) != 0);
  bsurf_cloud_free(&a);
  bsurf_cloud_free(&b);
  bsurf_cloud_free(&c);
}

/* Noise moves points along the normal with the asked distribution. */
static void test_noise_models(void **state) {
  (void)state;
  for (int model = 0; model < 2; model++) {
    bsurf_cloud c;
    assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 20000, BSURF_SAMPLING_REGULAR, 1, 0),
                     BSURF_OK);
    double *orig = malloc(sizeof(double) * 3 * c.point_count);
    memcpy(orig, c.xyz, sizeof(double) * 3 * c.point_count);
    const double level = 0.8, scale = 0.01;
    assert_int_equal(
        bsurf_add_noise(c.xyz, c.normals, c.point_count, (bsurf_noise_model)model, level, scale, 3),
        BSURF_OK);
    double s1 = 0, s2 = 0, maxabs = 0;
    for (size_t i = 0; i < c.point_count; i++) {
      double t = 0;
      for (int k = 0; k < 3; k++)
        t += (c.xyz[3 * i + k] - orig[3 * i + k]) * c.normals[3 * i + k];
      /* displacement is along the normal only */
      for (int k = 0; k < 3; k++)
        assert_true(fabs(c.xyz[3 * i + k] - orig[3 * i + k] - t * c.normals[3 * i + k]) < 1e-15);
      t /= scale;
      s1 += t;
      s2 += t * t;
      if (fabs(t) > maxabs) maxabs = fabs(t);
    }
    double n = (double)c.point_count, mean = s1 / n, sd = sqrt(s2 / n - mean * mean);
    assert_true(fabs(mean) < 0.02);
    if (model == BSURF_NOISE_GAUSSIAN) {
      assert_true(fabs(sd - level) < 0.02);
      assert_true(maxabs > 3 * level);
    } else {
      assert_true(fabs(sd - level / sqrt(3.0)) < 0.02);
      assert_true(maxabs <= level);
    }
    free(orig);
    bsurf_cloud_free(&c);
  }
}

static void test_noise_rejects_zero_normal(void **state) {
  (void)state;
  double xyz[6] = {0, 0, 0, 1, 0, 0}, n[6] = {0, 0, 1, 0, 0, 0};
  assert_int_equal(bsurf_add_noise(xyz, n, 2, BSURF_NOISE_GAUSSIAN, 1, 1, 1),
                   BSURF_ERR_INVALID_VALUE);
  assert_true(xyz[2] == 0); /* nothing moved */
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_shapes_on_surface), cmocka_unit_test(test_names),
      cmocka_unit_test(test_cube_features),     cmocka_unit_test(test_random_determinism),
      cmocka_unit_test(test_noise_models),      cmocka_unit_test(test_noise_rejects_zero_normal),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
