/* Generated shapes with exact normals and sharp-feature ground truth, the
 * data of the thesis's synthetic experiments (sphere 4.2, cube 5.3.2, 7.x)
 * and of our tests.
 *
 * Regular sampling is deterministic and nearly even (a Fibonacci lattice on
 * the sphere, cell-centred grids on the cube's faces and the plane, rings of
 * equal spacing on the torus), like the vertices of the meshes the thesis
 * starts from; random sampling is uniform by area from the seed. */
#include "common/common.h"

#include <math.h>
#include <string.h>

#define PI 3.14159265358979323846
#define TORUS_R 1.0
#define TORUS_r 0.35

static const char *const shape_names[] = {"sphere", "cube", "torus", "plane"};

int bsurf_shape_from_name(const char *name, bsurf_shape *shape) {
  for (int i = 0; i < 4; i++)
    if (strcmp(name, shape_names[i]) == 0) {
      *shape = (bsurf_shape)i;
      return 0;
    }
  return -1;
}

const char *bsurf_shape_name(bsurf_shape shape) {
  return (unsigned)shape < 4 ? shape_names[shape] : "unknown";
}

static double shape_area(bsurf_shape shape) {
  switch (shape) {
  case BSURF_SHAPE_SPHERE: return 4 * PI;
  case BSURF_SHAPE_CUBE: return 24.0;
  case BSURF_SHAPE_TORUS: return 4 * PI * PI * TORUS_R * TORUS_r;
  case BSURF_SHAPE_PLANE: return 4.0;
  }
  return 1.0;
}

static void set_point(bsurf_cloud *c, size_t i, double x, double y, double z, double nx, double ny,
                      double nz) {
  c->xyz[3 * i] = x;
  c->xyz[3 * i + 1] = y;
  c->xyz[3 * i + 2] = z;
  c->normals[3 * i] = nx;
  c->normals[3 * i + 1] = ny;
  c->normals[3 * i + 2] = nz;
}

/* A cube face point from face f (0..5: +x -x +y -y +z -z) and (a, b) in [-1,1]^2. */
static void cube_point(bsurf_cloud *c, size_t i, int f, double a, double b) {
  double s = (f % 2 == 0) ? 1.0 : -1.0;
  switch (f / 2) {
  case 0: set_point(c, i, s, a, b, s, 0, 0); break;
  case 1: set_point(c, i, a, s, b, 0, s, 0); break;
  default: set_point(c, i, a, b, s, 0, 0, s); break;
  }
}

static size_t torus_regular_count(size_t n, int *rings) {
  double s = sqrt(shape_area(BSURF_SHAPE_TORUS) / (double)n);
  int nv = (int)lround(2 * PI * TORUS_r / s);
  if (nv < 3) nv = 3;
  size_t total = 0;
  for (int j = 0; j < nv; j++) {
    double v = 2 * PI * (j + 0.5) / nv;
    long nu = lround(2 * PI * (TORUS_R + TORUS_r * cos(v)) / s);
    total += (size_t)(nu < 3 ? 3 : nu);
  }
  *rings = nv;
  return total;
}

bsurf_status bsurf_generate(bsurf_cloud *cloud, bsurf_shape shape, size_t n,
                            bsurf_sampling sampling, uint64_t seed, double feature_width) {
  BSURF_REQUIRE(cloud, "cloud is NULL");
  bsurf_cloud_init(cloud);
  BSURF_REQUIRE(n >= 1, "n = 0: at least one point");
  BSURF_REQUIRE((unsigned)shape <= BSURF_SHAPE_PLANE, "shape = %d: not a bsurf_shape", (int)shape);
  BSURF_REQUIRE(sampling == BSURF_SAMPLING_REGULAR || sampling == BSURF_SAMPLING_RANDOM,
                "sampling = %d: must be BSURF_SAMPLING_REGULAR or BSURF_SAMPLING_RANDOM",
                (int)sampling);
  BSURF_REQUIRE(feature_width >= 0 && isfinite(feature_width),
                "feature_width = %g: must be finite and >= 0", feature_width);
  size_t count = n;
  int grid = 0, rings = 0;
  if (sampling == BSURF_SAMPLING_REGULAR) {
    if (shape == BSURF_SHAPE_CUBE) {
      grid = (int)lround(sqrt((double)n / 6.0));
      if (grid < 1) grid = 1;
      count = 6 * (size_t)grid * grid;
    } else if (shape == BSURF_SHAPE_PLANE) {
      grid = (int)lround(sqrt((double)n));
      if (grid < 1) grid = 1;
      count = (size_t)grid * grid;
    } else if (shape == BSURF_SHAPE_TORUS) {
      count = torus_regular_count(n, &rings);
    }
  }
  bsurf_status st = bsurf_cloud_alloc(cloud, count, 1);
  if (st != BSURF_OK) return st;
  cloud->normal_type = BSURF_FLOAT64;
  snprintf(cloud->shape, sizeof cloud->shape, "%s", bsurf_shape_name(shape));

  if (sampling == BSURF_SAMPLING_REGULAR) {
    switch (shape) {
    case BSURF_SHAPE_SPHERE: {
      const double golden = PI * (3.0 - sqrt(5.0));
      for (size_t i = 0; i < count; i++) {
        double z = 1.0 - (2.0 * i + 1.0) / count, r = sqrt(1.0 - z * z);
        double phi = golden * (double)i;
        double x = r * cos(phi), y = r * sin(phi);
        set_point(cloud, i, x, y, z, x, y, z);
      }
      break;
    }
    case BSURF_SHAPE_CUBE: {
      size_t i = 0;
      for (int f = 0; f < 6; f++)
        for (int a = 0; a < grid; a++)
          for (int b = 0; b < grid; b++)
            cube_point(cloud, i++, f, -1.0 + (2.0 * a + 1.0) / grid, -1.0 + (2.0 * b + 1.0) / grid);
      break;
    }
    case BSURF_SHAPE_PLANE: {
      size_t i = 0;
      for (int a = 0; a < grid; a++)
        for (int b = 0; b < grid; b++)
          set_point(cloud, i++, -1.0 + (2.0 * a + 1.0) / grid, -1.0 + (2.0 * b + 1.0) / grid, 0, 0,
                    0, 1);
      break;
    }
    case BSURF_SHAPE_TORUS: {
      double s = sqrt(shape_area(BSURF_SHAPE_TORUS) / (double)n);
      size_t i = 0;
      for (int j = 0; j < rings; j++) {
        double v = 2 * PI * (j + 0.5) / rings;
        long nu = lround(2 * PI * (TORUS_R + TORUS_r * cos(v)) / s);
        if (nu < 3) nu = 3;
        for (long t = 0; t < nu; t++) {
          double u = 2 * PI * (t + 0.5 * (j % 2)) / nu;
          double nx = cos(v) * cos(u), ny = cos(v) * sin(u), nz = sin(v);
          double rr = TORUS_R + TORUS_r * cos(v);
          set_point(cloud, i++, rr * cos(u), rr * sin(u), TORUS_r * nz, nx, ny, nz);
        }
      }
      break;
    }
    }
  } else {
    for (size_t i = 0; i < count; i++) {
      bsurf_rng rng;
      bsurf_rng_init(&rng, seed, i, 0x67656e65ull /* "gene" */);
      switch (shape) {
      case BSURF_SHAPE_SPHERE: {
        double z = 2.0 * bsurf_rng_uniform(&rng) - 1.0, phi = 2 * PI * bsurf_rng_uniform(&rng);
        double r = sqrt(1.0 - z * z), x = r * cos(phi), y = r * sin(phi);
        set_point(cloud, i, x, y, z, x, y, z);
        break;
      }
      case BSURF_SHAPE_CUBE: {
        int f = (int)bsurf_rng_below(&rng, 6);
        double a = 2.0 * bsurf_rng_uniform(&rng) - 1.0, b = 2.0 * bsurf_rng_uniform(&rng) - 1.0;
        cube_point(cloud, i, f, a, b);
        break;
      }
      case BSURF_SHAPE_PLANE:
        set_point(cloud, i, 2.0 * bsurf_rng_uniform(&rng) - 1.0,
                  2.0 * bsurf_rng_uniform(&rng) - 1.0, 0, 0, 0, 1);
        break;
      case BSURF_SHAPE_TORUS: {
        /* area element (R + r cos v): accept v with that probability */
        double u = 2 * PI * bsurf_rng_uniform(&rng), v;
        do {
          v = 2 * PI * bsurf_rng_uniform(&rng);
        } while (bsurf_rng_uniform(&rng) * (TORUS_R + TORUS_r) > TORUS_R + TORUS_r * cos(v));
        double nx = cos(v) * cos(u), ny = cos(v) * sin(u), nz = sin(v);
        double rr = TORUS_R + TORUS_r * cos(v);
        set_point(cloud, i, rr * cos(u), rr * sin(u), TORUS_r * nz, nx, ny, nz);
        break;
      }
      }
    }
  }

  if (shape == BSURF_SHAPE_CUBE) {
    const double spacing = sqrt(shape_area(shape) / (double)count);
    /* On a face point (a, b), the nearest sharp edge is on that face's
     * boundary: distance 1 - max(|a|, |b|). */
    bsurf_field *fd = bsurf_cloud_add_field(cloud, "feature_dist", BSURF_FLOAT32);
    bsurf_field *ff = fd ? bsurf_cloud_add_field(cloud, "feature", BSURF_UINT8) : NULL;
    if (!ff) {
      bsurf_cloud_free(cloud);
      return BSURF_ERR_NOMEM;
    }
    fd = bsurf_cloud_field(cloud, "feature_dist");
    for (size_t i = 0; i < count; i++) {
      const double *p = &cloud->xyz[3 * i], *nn = &cloud->normals[3 * i];
      double m = 0;
      for (int t = 0; t < 3; t++)
        if (nn[t] == 0 && fabs(p[t]) > m) m = fabs(p[t]);
      fd->values[i] = 1.0 - m;
      ff->values[i] = fd->values[i] <= feature_width * spacing ? 1.0 : 0.0;
    }
  }
  return BSURF_OK;
}

double bsurf_shape_distance(bsurf_shape shape, const double p[3]) {
  switch (shape) {
  case BSURF_SHAPE_SPHERE: return fabs(sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - 1.0);
  case BSURF_SHAPE_TORUS: {
    double q = sqrt(p[0] * p[0] + p[1] * p[1]) - TORUS_R;
    return fabs(sqrt(q * q + p[2] * p[2]) - TORUS_r);
  }
  case BSURF_SHAPE_PLANE: {
    double dx = fabs(p[0]) > 1 ? fabs(p[0]) - 1 : 0, dy = fabs(p[1]) > 1 ? fabs(p[1]) - 1 : 0;
    return sqrt(dx * dx + dy * dy + p[2] * p[2]);
  }
  case BSURF_SHAPE_CUBE: {
    double a[3] = {fabs(p[0]), fabs(p[1]), fabs(p[2])};
    if (a[0] <= 1 && a[1] <= 1 && a[2] <= 1) {
      double m = a[0] > a[1] ? a[0] : a[1];
      if (a[2] > m) m = a[2];
      return 1.0 - m;
    }
    double s = 0;
    for (int t = 0; t < 3; t++)
      if (a[t] > 1) s += (a[t] - 1) * (a[t] - 1);
    return sqrt(s);
  }
  }
  return NAN;
}
