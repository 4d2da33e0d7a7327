/* Helpers shared by the cmocka tests (include after cmocka.h and
 * bootsurf.h): scratch paths under $BSURF_TMP and the check of a refused
 * call's status and message. */
#ifndef BSURF_TEST_UTIL_H
#define BSURF_TEST_UTIL_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The scratch directory: tmp_dir_init() at the start of main. */
static char tmp_dir[1024];

static inline void tmp_dir_init(void) {
  const char *t = getenv("BSURF_TMP");
  snprintf(tmp_dir, sizeof tmp_dir, "%s", t ? t : "/tmp");
}

/* tmp_dir/name; the last four results stay valid. */
static inline const char *tmp_path(const char *name) {
  static char buf[4][1200];
  static int slot = 0;
  slot = (slot + 1) % 4;
  snprintf(buf[slot], sizeof buf[slot], "%s/%s", tmp_dir, name);
  return buf[slot];
}

/* status BSURF_ERR_INVALID_ARG and a message that names the function
 * ("func:") and contains `needle` (the parameter and its value) */
#define assert_invalid(call, func, needle)                                                         \
  do {                                                                                             \
    bsurf_status st_ = (call);                                                                     \
    assert_int_equal(st_, BSURF_ERR_INVALID_ARG);                                                  \
    const char *m_ = bsurf_last_message();                                                         \
    if (!strstr(m_, func ":") || !strstr(m_, needle))                                              \
      fail_msg("message '%s' lacks '%s' / '%s'", m_, func, needle);                                \
  } while (0)

/* A cylinder of radius 1 sampled on rings, as a turned part's mesh
 * vertices are (test_smooth's test_noise_rings, test_jobs' rings input): 60
 * rings of 60 points at arc spacing s = 2 pi / 60, `gap` s apart, odd rings
 * turned half a spacing, with gaussian noise of 0.3 s (seed 41) along a
 * normal tilted 0.1 out of the ring's plane (a mesh's vertex normals are
 * not exactly radial), so the noise stays nearly within each ring's plane.
 * xyz, nrm: 3600 x 3 each. Returns the points, 3600. */
#define RING_PI 3.14159265358979323846
static inline size_t ring_cylinder(double gap, double *xyz, double *nrm) {
  const int rings = 60, per = 60;
  const double s = 2 * RING_PI / per, w = sqrt(1.01);
  size_t m = 0;
  for (int r = 0; r < rings; r++)
    for (int j = 0; j < per; j++, m++) {
      const double t = (j + 0.5 * (r % 2)) * s;
      xyz[3 * m] = cos(t), xyz[3 * m + 1] = sin(t), xyz[3 * m + 2] = r * gap * s;
      nrm[3 * m] = cos(t) / w, nrm[3 * m + 1] = sin(t) / w, nrm[3 * m + 2] = 0.1 / w;
    }
  if (bsurf_add_noise(xyz, nrm, m, BSURF_NOISE_GAUSSIAN, 0.3, s, 41) != BSURF_OK) return 0;
  return m;
}

#endif /* BSURF_TEST_UTIL_H */
