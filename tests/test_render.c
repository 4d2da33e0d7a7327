/* Pictures: colormaps, the point renderer, histograms, PNG output. */
// clang-format off: cmocka.h needs these first
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
// clang-format on

#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bootsurf.h"

static const char *tmp_dir(void) {
  const char *t = getenv("BSURF_TMP");
  return t ? t : ".";
}

static void tmp_path(char *buf, size_t size, const char *name) {
  snprintf(buf, size, "%s/%s", tmp_dir(), name);
}

/* Decodes an 8-bit RGB PNG with libpng; returns the pixels (malloc) or NULL. */
static uint8_t *read_png(const char *path, int *w, int *h) {
  png_image img;
  memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, path)) return NULL;
  img.format = PNG_FORMAT_RGB;
  uint8_t *buf = malloc(PNG_IMAGE_SIZE(img));
  if (!buf || !png_image_finish_read(&img, NULL, buf, 0, NULL)) {
    free(buf);
    png_image_free(&img);
    return NULL;
  }
  *w = (int)img.width;
  *h = (int)img.height;
  return buf;
}

static uint8_t *read_file(const char *path, size_t *size) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  uint8_t *b = malloc((size_t)n + 1);
  *size = fread(b, 1, (size_t)n, f);
  fclose(f);
  return b;
}

static int color_dist(const uint8_t *a, const uint8_t *b) {
  return abs(a[0] - b[0]) + abs(a[1] - b[1]) + abs(a[2] - b[2]);
}

static void test_colormap_endpoints(void **state) {
  (void)state;
  uint8_t c[3];
  bsurf_colormap_rgb(BSURF_COLORMAP_VIRIDIS, 0.0, c);
  assert_true(c[0] == 68 && c[1] == 1 && c[2] == 84); /* #440154 */
  bsurf_colormap_rgb(BSURF_COLORMAP_VIRIDIS, 1.0, c);
  assert_true(c[0] == 253 && c[1] == 231 && c[2] == 37); /* #fde725 */
  bsurf_colormap_rgb(BSURF_COLORMAP_VIRIDIS, 0.5, c);
  assert_true(abs(c[0] - 33) <= 1 && abs(c[1] - 145) <= 1 && abs(c[2] - 140) <= 1); /* #21918c */
  bsurf_colormap_rgb(BSURF_COLORMAP_MAGMA, 0.0, c);
  assert_true(c[0] == 0 && c[1] == 0 && c[2] == 4);
  bsurf_colormap_rgb(BSURF_COLORMAP_MAGMA, 1.0, c);
  assert_true(c[0] == 252 && c[1] == 253 && c[2] == 191);
  bsurf_colormap_rgb(BSURF_COLORMAP_GRAY, 0.0, c);
  assert_true(c[0] == 0 && c[1] == 0 && c[2] == 0);
  bsurf_colormap_rgb(BSURF_COLORMAP_GRAY, 1.0, c);
  assert_true(c[0] == 255 && c[1] == 255 && c[2] == 255);
  bsurf_colormap_rgb(BSURF_COLORMAP_COOLWARM, 0.0, c);
  assert_true(c[2] > c[0]); /* blue end */
  bsurf_colormap_rgb(BSURF_COLORMAP_COOLWARM, 1.0, c);
  assert_true(c[0] > c[2]); /* red end */
  uint8_t d[3];
  bsurf_colormap_rgb(BSURF_COLORMAP_VIRIDIS, -3.0, c); /* clamped */
  bsurf_colormap_rgb(BSURF_COLORMAP_VIRIDIS, 0.0, d);
  assert_memory_equal(c, d, 3);
  bsurf_colormap rc;
  assert_int_equal(bsurf_colormap_from_name("magma", &rc), 0);
  assert_int_equal(rc, BSURF_COLORMAP_MAGMA);
  assert_int_not_equal(bsurf_colormap_from_name("jet", &rc), 0);
  double az, el;
  assert_int_equal(bsurf_view_from_name("top", &az, &el), 0);
  assert_true(el == 90);
  assert_int_not_equal(bsurf_view_from_name("sideways", &az, &el), 0);
}

/* A unit sphere coloured by z, seen from the front: the top of the disc is at
 * the high end of the colormap, the bottom at the low end, the corners are
 * background. */
static void test_sphere_field_front(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 20000, BSURF_SAMPLING_REGULAR, 1, 2.0),
                   BSURF_OK);
  double *z = malloc(c.point_count * sizeof *z);
  for (size_t i = 0; i < c.point_count; i++)
    z[i] = c.xyz[3 * i + 2];
  bsurf_render_options o = bsurf_render_options_default();
  o.width = 320;
  o.height = 240;
  o.shade = 0;
  o.colorbar = 0;
  o.range_lo = -1;
  o.range_hi = 1;
  assert_int_equal(bsurf_view_from_name("front", &o.azimuth, &o.elevation), 0);
  uint8_t *rgb = malloc((size_t)o.width * o.height * 3);
  bsurf_render_info info;
  assert_int_equal(bsurf_render(rgb, c.xyz, c.normals, c.point_count, z, &o, &info), BSURF_OK);
  assert_true(info.covered_pixels >
              0.5 * 3.14159 * 100 * 100); /* the disc is about 200 px across */
  uint8_t lo[3], hi[3];
  bsurf_colormap_rgb(o.colormap, 0.0, lo);
  bsurf_colormap_rgb(o.colormap, 1.0, hi);
  int top = -1, bottom = -1;
  for (int y = 0; y < o.height; y++) {
    const uint8_t *p = rgb + ((size_t)y * o.width + o.width / 2) * 3;
    if (p[0] != 255 || p[1] != 255 || p[2] != 255) {
      if (top < 0) top = y;
      bottom = y;
    }
  }
  assert_true(top > 0 && bottom > top + 100 && bottom < o.height - 1);
  /* 4% of the diameter inside: |z| ~ 0.92, t ~ 0.04 from the ends */
  int in = (bottom - top) / 25;
  const uint8_t *pt = rgb + ((size_t)(top + in) * o.width + o.width / 2) * 3;
  const uint8_t *pb = rgb + ((size_t)(bottom - in) * o.width + o.width / 2) * 3;
  assert_true(color_dist(pt, hi) < 60 && color_dist(pt, lo) > 200);
  assert_true(color_dist(pb, lo) < 60 && color_dist(pb, hi) > 200);
  /* the middle row is in the middle of the map */
  uint8_t mid[3];
  bsurf_colormap_rgb(o.colormap, 0.5, mid);
  const uint8_t *pm = rgb + ((size_t)((top + bottom) / 2) * o.width + o.width / 2) * 3;
  assert_true(color_dist(pm, mid) < 40);
  /* empty corners */
  static const uint8_t white[3] = {255, 255, 255};
  assert_memory_equal(rgb, white, 3);
  assert_memory_equal(rgb + ((size_t)o.height * o.width - 1) * 3, white, 3);
  /* shaded by normals without a field: not background, and gray */
  assert_int_equal(bsurf_render(rgb, c.xyz, c.normals, c.point_count, NULL, &o, &info), BSURF_OK);
  const uint8_t *pc = rgb + ((size_t)(o.height / 2) * o.width + o.width / 2) * 3;
  assert_true(pc[0] < 250 && abs(pc[0] - pc[1]) < 30);
  free(rgb);
  free(z);
  bsurf_cloud_free(&c);
}

static void test_deterministic_png(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_TORUS, 30000, BSURF_SAMPLING_RANDOM, 3, 2.0),
                   BSURF_OK);
  double *v = malloc(c.point_count * sizeof *v);
  for (size_t i = 0; i < c.point_count; i++)
    v[i] = sin(7 * c.xyz[3 * i]) + c.xyz[3 * i + 1];
  bsurf_render_options o = bsurf_render_options_default();
  o.width = 400;
  o.height = 300;
  o.views = 4;
  o.label = "value";
  o.title = "torus";
  size_t sz = (size_t)o.width * o.height * 3;
  uint8_t *a = malloc(sz), *b = malloc(sz);
  o.threads = 1;
  assert_int_equal(bsurf_render(a, c.xyz, c.normals, c.point_count, v, &o, NULL), BSURF_OK);
  o.threads = 2;
  assert_int_equal(bsurf_render(b, c.xyz, c.normals, c.point_count, v, &o, NULL), BSURF_OK);
  assert_memory_equal(a, b, sz);
  assert_int_equal(bsurf_render(b, c.xyz, c.normals, c.point_count, v, &o, NULL), BSURF_OK);
  assert_memory_equal(a, b, sz);
  char p1[512], p2[512];
  tmp_path(p1, sizeof p1, "render_a.png");
  tmp_path(p2, sizeof p2, "render_b.png");
  assert_int_equal(bsurf_write_png(p1, a, o.width, o.height, NULL), BSURF_OK);
  assert_int_equal(bsurf_write_png(p2, b, o.width, o.height, NULL), BSURF_OK);
  size_t n1 = 0, n2 = 0;
  uint8_t *f1 = read_file(p1, &n1), *f2 = read_file(p2, &n2);
  assert_non_null(f1);
  assert_non_null(f2);
  assert_int_equal(n1, n2);
  assert_memory_equal(f1, f2, n1);
  assert_memory_equal(f1 + 1, "PNG", 3);
  int w = 0, h = 0;
  uint8_t *dec = read_png(p1, &w, &h);
  assert_non_null(dec);
  assert_int_equal(w, 400);
  assert_int_equal(h, 300);
  assert_memory_equal(dec, a, sz);
  free(dec);
  free(f1);
  free(f2);
  /* the thread count never changes the image without a field either */
  o.views = 1;
  o.threads = 1;
  assert_int_equal(bsurf_render(a, c.xyz, NULL, c.point_count, NULL, &o, NULL), BSURF_OK);
  o.threads = 2;
  assert_int_equal(bsurf_render(b, c.xyz, NULL, c.point_count, NULL, &o, NULL), BSURF_OK);
  assert_memory_equal(a, b, sz);
  /* per-point spacing equal to h everywhere gives the same image as h */
  double *ps = malloc(c.point_count * sizeof *ps);
  o.spacing = 0.02;
  for (size_t i = 0; i < c.point_count; i++)
    ps[i] = 0.02;
  assert_int_equal(bsurf_render(a, c.xyz, NULL, c.point_count, NULL, &o, NULL), BSURF_OK);
  o.point_spacing = ps;
  assert_int_equal(bsurf_render(b, c.xyz, NULL, c.point_count, NULL, &o, NULL), BSURF_OK);
  assert_memory_equal(a, b, sz);
  o.point_spacing = NULL;
  free(ps);
  /* the torus seen from the top with z up is a ring; with y up, "top" looks
   * along y and sees it edge-on: far fewer pixels */
  bsurf_render_info i1, i2;
  assert_int_equal(bsurf_view_from_name("top", &o.azimuth, &o.elevation), 0);
  assert_int_equal(bsurf_render(a, c.xyz, NULL, c.point_count, NULL, &o, &i1), BSURF_OK);
  o.up_axis = 1;
  assert_int_equal(bsurf_render(a, c.xyz, NULL, c.point_count, NULL, &o, &i2), BSURF_OK);
  assert_true(i2.covered_pixels < i1.covered_pixels);
  o.up_axis = 3;
  assert_int_equal(bsurf_render(a, c.xyz, NULL, c.point_count, NULL, &o, NULL),
                   BSURF_ERR_INVALID_ARG);
  o.up_axis = 2;
  /* bad arguments */
  o.width = 3;
  assert_int_equal(bsurf_render(a, c.xyz, NULL, c.point_count, NULL, &o, NULL),
                   BSURF_ERR_INVALID_ARG);
  o.width = 400;
  o.views = 2;
  assert_int_equal(bsurf_render(a, c.xyz, NULL, c.point_count, NULL, &o, NULL),
                   BSURF_ERR_INVALID_ARG);
  /* unwritable: an error, no file */
  char bad[512];
  tmp_path(bad, sizeof bad, "no_such_dir/x.png");
  bsurf_failure err;
  assert_int_equal(bsurf_write_png(bad, a, 400, 300, &err), BSURF_ERR_IO);
  assert_true(strlen(err.message) > 0);
  assert_int_not_equal(access(bad, F_OK), 0);
  remove(p1);
  remove(p2);
  free(a);
  free(b);
  free(v);
  bsurf_cloud_free(&c);
}

static void test_histogram(void **state) {
  (void)state;
  size_t n = 10000;
  double *v = malloc(n * sizeof *v);
  bsurf_rng rng;
  bsurf_rng_init(&rng, 5, 0, 0);
  for (size_t i = 0; i < n; i++)
    v[i] = bsurf_rng_normal(&rng);
  v[0] = NAN;
  bsurf_histogram_options o = bsurf_histogram_options_default();
  o.width = 640;
  o.height = 360;
  o.bins = 40;
  o.threshold = 1.0;
  o.label = "normal";
  uint8_t *rgb = malloc((size_t)o.width * o.height * 3);
  bsurf_histogram_info info;
  assert_int_equal(bsurf_render_histogram(rgb, v, n, &o, &info), BSURF_OK);
  assert_int_equal(info.counted, n - 1);
  size_t above = 0;
  for (size_t i = 1; i < n; i++)
    above += v[i] > 1.0;
  assert_int_equal(info.above_threshold, above);
  char p[512];
  tmp_path(p, sizeof p, "hist.png");
  assert_int_equal(bsurf_write_png(p, rgb, o.width, o.height, NULL), BSURF_OK);
  int w = 0, h = 0;
  uint8_t *dec = read_png(p, &w, &h);
  assert_non_null(dec);
  assert_int_equal(w, 640);
  assert_int_equal(h, 360);
  free(dec);
  o.log_counts = 1;
  assert_int_equal(bsurf_render_histogram(rgb, v, n, &o, &info), BSURF_OK);
  o.bins = 0;
  assert_int_equal(bsurf_render_histogram(rgb, v, n, &o, &info), BSURF_ERR_INVALID_ARG);
  remove(p);
  free(rgb);
  free(v);
}

static void test_range(void **state) {
  (void)state;
  double v[101];
  for (int i = 0; i <= 100; i++)
    v[i] = 100 - i;
  double lo, hi;
  assert_int_equal(bsurf_render_range(v, 101, 1, 99, &lo, &hi), BSURF_OK);
  assert_true(lo == 1 && hi == 99);
  assert_int_equal(bsurf_render_range(v, 101, 0, 100, &lo, &hi), BSURF_OK);
  assert_true(lo == 0 && hi == 100);
  double nan[2] = {NAN, INFINITY};
  assert_int_equal(bsurf_render_range(nan, 2, 1, 99, &lo, &hi), BSURF_ERR_INVALID_VALUE);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_colormap_endpoints),
      cmocka_unit_test(test_sphere_field_front),
      cmocka_unit_test(test_deterministic_png),
      cmocka_unit_test(test_histogram),
      cmocka_unit_test(test_range),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
