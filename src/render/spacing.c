/* The splat sizes of bsurf_render for a cloud: h and the local spacings. */
#include "common/common.h"

#include <math.h>
#include <stdlib.h>

/* Per-point spacing: h times the ratio of the point's distance to its 6th
 * nearest other point to the median of those distances, clamped to [1, 4]:
 * evenly sampled regions keep splats of h, sparse regions of a scan get
 * larger ones, so they look closed too. */
bsurf_status bsurf_render_spacing(const double *xyz, size_t point_count, int threads,
                                  bsurf_progress_fn progress, void *progress_user, double *h,
                                  double *point_spacing, int *filled) {
  const int k = 7;
  const size_t n = point_count;
  BSURF_REQUIRE(h, "h is NULL");
  BSURF_REQUIRE(n == 0 || xyz, "xyz is NULL");
  *h = 0;
  if (filled) *filled = 0;
  if (n < 2) return BSURF_OK;
  if (n < (size_t)k + 1)
    return bsurf_mean_spacing_progress(xyz, n, threads, h, progress, progress_user);
  /* one search: the nearest neighbour gives h (as bsurf_mean_spacing), the
   * 7th the local spacing */
  bsurf_neighbors nb;
  bsurf_status st = bsurf_neighbors_build(&nb, xyz, n, k, threads, progress, progress_user);
  if (st != BSURF_OK) return st;
  *h = nb.h;
  if (!point_spacing || !filled) {
    bsurf_neighbors_free(&nb);
    return BSURF_OK;
  }
  double *out = point_spacing;
  double med = 0, unused = 0;
  int okay = nb.h > 0;
  if (okay) {
    for (size_t i = 0; i < n; i++) {
      const double *p = &xyz[3 * i], *q = &xyz[3 * (size_t)nb.idx[i * k + k - 1]];
      out[i] = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                    (p[2] - q[2]) * (p[2] - q[2]));
    }
    okay = bsurf_render_range(out, n, 50, 50, &med, &unused) == BSURF_OK && med > 0;
  }
  if (okay)
    for (size_t i = 0; i < n; i++) {
      double r = out[i] / med;
      out[i] = nb.h * (r < 1 ? 1 : r > 4 ? 4 : r);
    }
  bsurf_neighbors_free(&nb);
  *filled = okay;
  return BSURF_OK;
}

/* --up auto: bootsurf's generated shapes (a "bootsurf shape" comment) are
 * z-up, like LiDAR and GIS data; scans and meshes from graphics (Stanford's
 * PLY scans, CGAL's OFF data, OBJ) are y-up, OpenGL's convention: the
 * Stanford bunny then stands upright (docs/gallery.md). */
int bsurf_render_auto_up(const char *shape) {
  return shape && shape[0] ? 2 : 1;
}
