/* Position error: exact point-to-triangle distance (every Voronoi region,
 * degenerate triangles), the mesh hierarchy against brute force (bit for
 * bit), per-point errors for any thread count, the nearest-point
 * correspondence, distance statistics, and the generated shape kept by PLY
 * files (comment bootsurf shape NAME). */
/* cmocka.h needs these first */
/* clang-format off */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
/* clang-format on */

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bootsurf.h"

#define PI 3.14159265358979323846

static double dot3(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double dist3(const double *a, const double *b) {
  double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
  return sqrt(dot3(d, d));
}

/* ---- a reference point-triangle distance by another method ---- */

enum { REG_FACE = 0, REG_EDGE, REG_VERTEX };

/* Point-segment: projection onto the line, clamped. *t out. */
static double ref_seg(const double *p, const double *a, const double *b, double *t) {
  double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
         w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  double dd = dot3(d, d), s = dd > 0 ? dot3(w, d) / dd : 0;
  s = s < 0 ? 0 : s > 1 ? 1 : s;
  double e[3] = {w[0] - s * d[0], w[1] - s * d[1], w[2] - s * d[2]};
  *t = s;
  return sqrt(dot3(e, e));
}

/* Projection onto the plane; inside (barycentric coordinates from a 2x2
 * Gram system, all > 0) -> the height; else the nearest edge. *region out. */
static double ref_tri(const double *p, const double *a, const double *b, const double *c,
                      int *region) {
  double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
         v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]},
         w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  double uu = dot3(u, u), uv = dot3(u, v), vv = dot3(v, v), wu = dot3(w, u), wv = dot3(w, v);
  double det = uu * vv - uv * uv;
  if (det > 1e-12 * uu * vv) {
    double s = (vv * wu - uv * wv) / det, t = (uu * wv - uv * wu) / det;
    if (s > 0 && t > 0 && s + t < 1) {
      double q[3];
      for (int k = 0; k < 3; k++)
        q[k] = a[k] + s * u[k] + t * v[k];
      *region = REG_FACE;
      return dist3(p, q);
    }
  }
  const double *e[3][2] = {{a, b}, {b, c}, {c, a}};
  double best = INFINITY, bt = 0;
  for (int i = 0; i < 3; i++) {
    double t, d = ref_seg(p, e[i][0], e[i][1], &t);
    if (d < best) best = d, bt = t;
  }
  *region = bt > 0 && bt < 1 ? REG_EDGE : REG_VERTEX;
  return best;
}

static void rand_vec(bsurf_rng *r, double scale, double *out) {
  for (int k = 0; k < 3; k++)
    out[k] = scale * (2 * bsurf_rng_uniform(r) - 1);
}

/* ---- point to triangle ---- */

/* A known triangle: one point in each of the seven regions, with its
 * closest point, in every vertex order and after a rigid motion. */
static void test_triangle_regions(void **state) {
  (void)state;
  const double T[3][3] = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}};
  const double P[7][3] = {{-1, -1, 0.5}, {3, -1, 0.3},    {-0.5, 3, -0.2}, {1, -1, 0.5},
                          {-1, 1, 0.5},  {1.5, 1.5, 0.7}, {0.5, 0.5, 2}};
  const double Q[7][3] = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0},    {1, 0, 0},
                          {0, 1, 0}, {1, 1, 0}, {0.5, 0.5, 0}};
  const int perm[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  bsurf_rng rng;
  bsurf_rng_init(&rng, 5, 0, 0);
  for (int trial = 0; trial < 20; trial++) {
    /* rotation from a random unit quaternion, translation up to 100 */
    double q[4], n = 0;
    for (int k = 0; k < 4; k++)
      q[k] = bsurf_rng_normal(&rng), n += q[k] * q[k];
    n = sqrt(n);
    for (int k = 0; k < 4; k++)
      q[k] /= n;
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                      {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                      {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
    double t[3];
    rand_vec(&rng, trial ? 100 : 0, t);
    if (trial == 0) memset(R, 0, sizeof R), R[0][0] = R[1][1] = R[2][2] = 1;
    double tv[3][3], pv[7][3], qv[7][3];
#define MOVE(src, dst)                                                                             \
  for (int k = 0; k < 3; k++)                                                                      \
    (dst)[k] = t[k] + dot3(R[k], (src));
    for (int i = 0; i < 3; i++) {
      MOVE(T[i], tv[i])
    }
    for (int i = 0; i < 7; i++) {
      MOVE(P[i], pv[i])
      MOVE(Q[i], qv[i])
    }
#undef MOVE
    for (int pm = 0; pm < 6; pm++)
      for (int i = 0; i < 7; i++) {
        double cl[3];
        double d =
            bsurf_triangle_distance(pv[i], tv[perm[pm][0]], tv[perm[pm][1]], tv[perm[pm][2]], cl);
        double expect = dist3(P[i], Q[i]);
        assert_true(fabs(d - expect) < 1e-12 * 100);
        assert_true(dist3(cl, qv[i]) < 1e-12 * 100);
      }
  }
}

/* Random triangles and points at several scales and offsets against the
 * reference; every region type is met many times. */
static void test_triangle_random(void **state) {
  (void)state;
  bsurf_rng rng;
  bsurf_rng_init(&rng, 11, 0, 0);
  size_t seen[3] = {0, 0, 0};
  for (int trial = 0; trial < 20000; trial++) {
    double scale = pow(10.0, (double)(trial % 7) - 3), off[3];
    int offset = trial % 3 == 0;
    rand_vec(&rng, offset ? 1e3 : 0, off);
    double a[3], b[3], c[3], p[3];
    rand_vec(&rng, scale, a);
    rand_vec(&rng, scale, b);
    rand_vec(&rng, scale, c);
    if (trial % 2) {
      rand_vec(&rng, 2 * scale, p);
    } else { /* around the triangle: barycentric in [-0.5, 1.5] plus a random offset */
      double s = 2 * bsurf_rng_uniform(&rng) - 0.5, t = 2 * bsurf_rng_uniform(&rng) - 0.5, e[3];
      rand_vec(&rng, 0.5 * scale, e);
      for (int k = 0; k < 3; k++)
        p[k] = a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]) + e[k];
    }
    for (int k = 0; k < 3; k++)
      a[k] += off[k], b[k] += off[k], c[k] += off[k], p[k] += off[k];
    int region;
    double ref = ref_tri(p, a, b, c, &region), cl[3];
    double d = bsurf_triangle_distance(p, a, b, c, cl);
    seen[region]++;
    /* the closest point is absolute: ulps of the offset coordinates */
    double tol = 1e-10 * scale + (offset ? 1e-12 : 0);
    assert_true(fabs(d - ref) <= tol);
    /* the closest point is at that distance */
    assert_true(fabs(dist3(p, cl) - d) <= tol);
  }
  for (int r = 0; r < 3; r++) {
    if (seen[r] <= 1000) print_error("region %d seen %zu times\n", r, seen[r]);
    assert_true(seen[r] > 1000);
  }
}

/* Zero-area triangles: never NaN, the distance to the nearest edge. */
static void test_triangle_degenerate(void **state) {
  (void)state;
  bsurf_rng rng;
  bsurf_rng_init(&rng, 3, 0, 0);
  for (int trial = 0; trial < 5000; trial++) {
    double a[3], d[3], p[3], b[3], c[3];
    rand_vec(&rng, 1, a);
    rand_vec(&rng, 1, d);
    rand_vec(&rng, 2, p);
    double s = 3 * bsurf_rng_uniform(&rng) - 1;
    switch (trial % 5) {
    case 0: /* collinear, c between or beyond */
      for (int k = 0; k < 3; k++)
        b[k] = a[k] + d[k], c[k] = a[k] + s * d[k];
      break;
    case 1: /* a == b */
      for (int k = 0; k < 3; k++)
        b[k] = a[k], c[k] = a[k] + d[k];
      break;
    case 2: /* b == c */
      for (int k = 0; k < 3; k++)
        b[k] = c[k] = a[k] + d[k];
      break;
    case 3: /* one point */
      memcpy(b, a, sizeof b);
      memcpy(c, a, sizeof c);
      break;
    default: /* collinear up to rounding: c on the line through a, b, scaled */
      for (int k = 0; k < 3; k++)
        b[k] = a[k] + d[k], c[k] = a[k] + 0.1 * (double)(trial % 17) * d[k];
      break;
    }
    double t, ref = INFINITY, e;
    if ((e = ref_seg(p, a, b, &t)) < ref) ref = e;
    if ((e = ref_seg(p, b, c, &t)) < ref) ref = e;
    if ((e = ref_seg(p, c, a, &t)) < ref) ref = e;
    const double *v[3] = {a, b, c};
    for (int r = 0; r < 3; r++) {
      double cl[3];
      double dd = bsurf_triangle_distance(p, v[r], v[(r + 1) % 3], v[(r + 2) % 3], cl);
      assert_false(isnan(dd));
      assert_false(isnan(cl[0]) || isnan(cl[1]) || isnan(cl[2]));
      assert_true(fabs(dd - ref) < 1e-12);
      assert_true(fabs(dist3(p, cl) - dd) < 1e-12);
    }
  }
  /* a sliver: thinner than rounding, still finite and right */
  double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0.5, 1e-300, 0}, p[3] = {0.5, 0.5, 0.5};
  double dd = bsurf_triangle_distance(p, a, b, c, NULL);
  assert_true(fabs(dd - sqrt(0.5)) < 1e-12);
}

/* ---- meshes ---- */

static void mesh_from(bsurf_cloud *m, const double *xyz, size_t nv, const uint32_t *tri,
                      size_t nf) {
  assert_int_equal(bsurf_cloud_alloc(m, nv, 0), BSURF_OK);
  memcpy(m->xyz, xyz, sizeof(double) * 3 * nv);
  m->faces = malloc(sizeof(uint32_t) * 3 * nf);
  assert_non_null(m->faces);
  memcpy(m->faces, tri, sizeof(uint32_t) * 3 * nf);
  m->face_count = nf;
}

/* A latitude-longitude sphere of radius 1: shared vertices, poles fanned. */
static void make_sphere(bsurf_cloud *m, int rings, int segs) {
  size_t nv = 2 + (size_t)(rings - 1) * (size_t)segs, nf = 2 * (size_t)segs * (size_t)(rings - 1);
  double *v = malloc(sizeof(double) * 3 * nv);
  uint32_t *f = malloc(sizeof(uint32_t) * 3 * nf);
  assert_non_null(v);
  assert_non_null(f);
  v[0] = 0, v[1] = 0, v[2] = 1;
  v[3] = 0, v[4] = 0, v[5] = -1;
  for (int i = 1; i < rings; i++)
    for (int j = 0; j < segs; j++) {
      double th = PI * i / rings, ph = 2 * PI * j / segs;
      double *x = &v[3 * (2 + (size_t)(i - 1) * segs + (size_t)j)];
      x[0] = sin(th) * cos(ph), x[1] = sin(th) * sin(ph), x[2] = cos(th);
    }
#define VID(i, j) ((uint32_t)(2 + (size_t)((i)-1) * segs + (size_t)(((j) % segs))))
  size_t k = 0;
  for (int j = 0; j < segs; j++) {
    f[k++] = 0, f[k++] = VID(1, j), f[k++] = VID(1, j + 1);
    f[k++] = 1, f[k++] = VID(rings - 1, j + 1), f[k++] = VID(rings - 1, j);
  }
  for (int i = 1; i < rings - 1; i++)
    for (int j = 0; j < segs; j++) {
      f[k++] = VID(i, j), f[k++] = VID(i + 1, j), f[k++] = VID(i + 1, j + 1);
      f[k++] = VID(i, j), f[k++] = VID(i + 1, j + 1), f[k++] = VID(i, j + 1);
    }
#undef VID
  assert_int_equal(k, 3 * nf);
  mesh_from(m, v, nv, f, nf);
  free(v);
  free(f);
}

/* A random triangle soup with some degenerate faces. */
static void make_soup(bsurf_cloud *m, size_t nf, uint64_t seed) {
  bsurf_rng rng;
  bsurf_rng_init(&rng, seed, 0, 0);
  size_t nv = 3 * nf;
  double *v = malloc(sizeof(double) * 3 * nv);
  uint32_t *f = malloc(sizeof(uint32_t) * 3 * nf);
  assert_non_null(v);
  assert_non_null(f);
  for (size_t i = 0; i < nf; i++) {
    double c[3], e1[3], e2[3];
    rand_vec(&rng, 5, c);
    rand_vec(&rng, 0.5, e1);
    rand_vec(&rng, 0.5, e2);
    if (i % 25 == 0) memcpy(e2, e1, sizeof e2);                          /* collinear: a segment */
    if (i % 25 == 1) memset(e1, 0, sizeof e1), memset(e2, 0, sizeof e2); /* a point */
    for (int k = 0; k < 3; k++) {
      v[9 * i + (size_t)k] = c[k];
      v[9 * i + 3 + (size_t)k] = c[k] + e1[k];
      v[9 * i + 6 + (size_t)k] = c[k] + (i % 25 == 0 ? 2 : 1) * e2[k];
    }
    for (int k = 0; k < 3; k++)
      f[3 * i + (size_t)k] = (uint32_t)(3 * i + (size_t)k);
  }
  /* a duplicated face: equal distances, the lower index wins */
  memcpy(&f[3 * (nf - 1)], &f[3 * 7], 3 * sizeof(uint32_t));
  mesh_from(m, v, nv, f, nf);
  free(v);
  free(f);
}

/* Brute force: min over all faces of bsurf_triangle_distance. */
static double brute(const bsurf_cloud *m, const double *p) {
  double best = INFINITY;
  for (size_t f = 0; f < m->face_count; f++) {
    const uint32_t *t = &m->faces[3 * f];
    double d = bsurf_triangle_distance(p, &m->xyz[3 * (size_t)t[0]], &m->xyz[3 * (size_t)t[1]],
                                       &m->xyz[3 * (size_t)t[2]], NULL);
    if (d < best) best = d;
  }
  return best;
}

static void check_against_brute(const bsurf_cloud *m, const double *pts, size_t n) {
  bsurf_mesh_index *ix = NULL;
  assert_int_equal(bsurf_mesh_index_build(&ix, m), BSURF_OK);
  for (size_t i = 0; i < n; i++) {
    const double *p = &pts[3 * i];
    size_t face = 99999999;
    double cl[3];
    double d = bsurf_mesh_distance(ix, p, &face, cl), ref = brute(m, p);
    assert_memory_equal(&d, &ref, sizeof d); /* bit for bit */
    assert_true(face < m->face_count);
    const uint32_t *t = &m->faces[3 * face];
    double cl2[3];
    double df = bsurf_triangle_distance(p, &m->xyz[3 * (size_t)t[0]], &m->xyz[3 * (size_t)t[1]],
                                        &m->xyz[3 * (size_t)t[2]], cl2);
    assert_memory_equal(&df, &d, sizeof d);
    assert_memory_equal(cl, cl2, sizeof cl);
  }
  bsurf_mesh_index_free(ix);
}

static void test_bvh_random_soup(void **state) {
  (void)state;
  bsurf_cloud m;
  make_soup(&m, 700, 21);
  bsurf_rng rng;
  bsurf_rng_init(&rng, 22, 0, 0);
  size_t n = 3000;
  double *pts = malloc(sizeof(double) * 3 * n);
  assert_non_null(pts);
  for (size_t i = 0; i < n; i++)
    rand_vec(&rng, i % 10 == 0 ? 30 : 6, &pts[3 * i]);
  /* points on faces and at vertices, including the duplicated face */
  for (size_t i = 0; i < 200; i++) {
    const uint32_t *t = &m.faces[3 * ((i * 37) % m.face_count)];
    double s = bsurf_rng_uniform(&rng), u = bsurf_rng_uniform(&rng) * (1 - s);
    for (int k = 0; k < 3; k++)
      pts[3 * i + (size_t)k] =
          m.xyz[3 * (size_t)t[0] + (size_t)k] +
          s * (m.xyz[3 * (size_t)t[1] + (size_t)k] - m.xyz[3 * (size_t)t[0] + (size_t)k]) +
          u * (m.xyz[3 * (size_t)t[2] + (size_t)k] - m.xyz[3 * (size_t)t[0] + (size_t)k]);
  }
  memcpy(&pts[3 * 200], &m.xyz[3 * (size_t)m.faces[3 * 7]], 3 * sizeof(double));
  check_against_brute(&m, pts, n);
  /* the duplicate of face 7 never wins over face 7 */
  bsurf_mesh_index *ix = NULL;
  assert_int_equal(bsurf_mesh_index_build(&ix, &m), BSURF_OK);
  size_t face;
  double c7[3] = {0, 0, 0};
  for (int v = 0; v < 3; v++)
    for (int k = 0; k < 3; k++)
      c7[k] += m.xyz[3 * (size_t)m.faces[3 * 7 + (size_t)v] + (size_t)k] / 3;
  assert_true(bsurf_mesh_distance(ix, c7, &face, NULL) < 1e-12);
  assert_int_equal(face, 7);
  bsurf_mesh_index_free(ix);
  free(pts);
  bsurf_cloud_free(&m);
}

static void test_bvh_sphere(void **state) {
  (void)state;
  bsurf_cloud m;
  make_sphere(&m, 40, 80);
  bsurf_rng rng;
  bsurf_rng_init(&rng, 31, 0, 0);
  size_t n = 4000;
  double *pts = malloc(sizeof(double) * 3 * n);
  assert_non_null(pts);
  for (size_t i = 0; i < n; i++) {
    double d[3];
    rand_vec(&rng, 1, d);
    double r = (i % 4 == 0) ? 0.2 + 3 * bsurf_rng_uniform(&rng) : 1 + 0.05 * bsurf_rng_normal(&rng);
    double l = sqrt(dot3(d, d));
    for (int k = 0; k < 3; k++)
      pts[3 * i + (size_t)k] = r * d[k] / l;
  }
  check_against_brute(&m, pts, n);

  /* points on the mesh: its vertices exactly 0, area samples ~0; the
   * polygonal sphere is within its sagitta of the unit sphere */
  bsurf_mesh_index *ix = NULL;
  assert_int_equal(bsurf_mesh_index_build(&ix, &m), BSURF_OK);
  for (size_t v = 0; v < m.point_count; v++)
    assert_true(bsurf_mesh_distance(ix, &m.xyz[3 * v], NULL, NULL) == 0.0);
  bsurf_sample_options so = bsurf_sample_options_default();
  so.points = 5000;
  bsurf_cloud s;
  assert_int_equal(bsurf_sample_mesh(&s, &m, &so, NULL), BSURF_OK);
  double *dist = malloc(sizeof(double) * s.point_count);
  assert_non_null(dist);
  bsurf_true_surface ts;
  memset(&ts, 0, sizeof ts);
  ts.kind = BSURF_SURFACE_MESH;
  ts.mesh = ix;
  assert_int_equal(bsurf_position_errors(s.xyz, s.point_count, &ts, 2, dist, NULL, NULL), BSURF_OK);
  for (size_t i = 0; i < s.point_count; i++)
    assert_true(dist[i] < 1e-14);
  for (size_t i = 0; i < n; i++) {
    double d = bsurf_mesh_distance(ix, &pts[3 * i], NULL, NULL);
    double exact = fabs(sqrt(dot3(&pts[3 * i], &pts[3 * i])) - 1);
    assert_true(fabs(d - exact) < 0.01); /* sagitta of a 4.5-degree arc: 0.0008 */
  }
  free(dist);
  bsurf_cloud_free(&s);
  bsurf_mesh_index_free(ix);
  free(pts);
  bsurf_cloud_free(&m);
}

static void test_mesh_index_errors(void **state) {
  (void)state;
  const double v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const uint32_t good[3] = {0, 1, 2}, bad[3] = {0, 1, 3};
  bsurf_cloud m;
  bsurf_mesh_index *ix = (bsurf_mesh_index *)&m; /* must be reset to NULL on failure */
  mesh_from(&m, v, 3, bad, 1);
  assert_int_equal(bsurf_mesh_index_build(&ix, &m), BSURF_ERR_INVALID_ARG);
  assert_null(ix);
  memcpy(m.faces, good, sizeof good);
  m.xyz[4] = NAN;
  assert_int_equal(bsurf_mesh_index_build(&ix, &m), BSURF_ERR_INVALID_VALUE);
  m.xyz[4] = 0;
  m.face_count = 0;
  assert_int_equal(bsurf_mesh_index_build(&ix, &m), BSURF_ERR_INVALID_ARG);
  m.face_count = 1;
  assert_int_equal(bsurf_mesh_index_build(&ix, &m), BSURF_OK);
  double p[3] = {NAN, 0, 0}, q[3] = {0.25, 0.25, -3};
  assert_true(isnan(bsurf_mesh_distance(ix, p, NULL, NULL)));
  assert_true(bsurf_mesh_distance(ix, q, NULL, NULL) == 3.0);
  bsurf_mesh_index_free(ix);
  bsurf_mesh_index_free(NULL);
  bsurf_cloud_free(&m);
}

/* ---- per-point errors and correspondence ---- */

static void test_position_threads(void **state) {
  (void)state;
  bsurf_cloud m;
  make_sphere(&m, 30, 60);
  bsurf_mesh_index *ix = NULL;
  assert_int_equal(bsurf_mesh_index_build(&ix, &m), BSURF_OK);
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_TORUS, 40000, BSURF_SAMPLING_RANDOM, 4, 2),
                   BSURF_OK);
  size_t n = c.point_count;
  double *d1 = malloc(sizeof(double) * n), *d2 = malloc(sizeof(double) * n);
  uint32_t *m1 = malloc(sizeof(uint32_t) * n), *m2 = malloc(sizeof(uint32_t) * n);
  assert_true(d1 && d2 && m1 && m2);
  bsurf_true_surface ts;
  memset(&ts, 0, sizeof ts);
  ts.kind = BSURF_SURFACE_MESH;
  ts.mesh = ix;
  assert_int_equal(bsurf_position_errors(c.xyz, n, &ts, 1, d1, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_position_errors(c.xyz, n, &ts, 2, d2, NULL, NULL), BSURF_OK);
  assert_memory_equal(d1, d2, sizeof(double) * n);
  assert_int_equal(bsurf_match_nearest(m.xyz, m.point_count, c.xyz, n, 1, m1), BSURF_OK);
  assert_int_equal(bsurf_match_nearest(m.xyz, m.point_count, c.xyz, n, 2, m2), BSURF_OK);
  assert_memory_equal(m1, m2, sizeof(uint32_t) * n);
  free(d1);
  free(d2);
  free(m1);
  free(m2);
  bsurf_cloud_free(&c);
  bsurf_mesh_index_free(ix);
  bsurf_cloud_free(&m);
}

/* Shape and tangent-plane surfaces: a point moved by t along its normal is
 * at |t| (away from edges), and a zero normal is reported. */
static void test_position_shape_and_plane(void **state) {
  (void)state;
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 2000, BSURF_SAMPLING_REGULAR, 1, 2),
                   BSURF_OK);
  size_t n = c.point_count;
  double *moved = malloc(sizeof(double) * 3 * n), *d = malloc(sizeof(double) * n);
  assert_true(moved && d);
  for (size_t i = 0; i < n; i++) {
    double t = 0.01 * (double)(i % 7) - 0.03;
    for (int k = 0; k < 3; k++)
      moved[3 * i + (size_t)k] = c.xyz[3 * i + (size_t)k] + t * c.normals[3 * i + (size_t)k];
  }
  bsurf_true_surface ts;
  memset(&ts, 0, sizeof ts);
  ts.kind = BSURF_SURFACE_SHAPE;
  ts.shape = BSURF_SHAPE_SPHERE;
  assert_int_equal(bsurf_position_errors(moved, n, &ts, 0, d, NULL, NULL), BSURF_OK);
  for (size_t i = 0; i < n; i++)
    assert_true(fabs(d[i] - fabs(0.01 * (double)(i % 7) - 0.03)) < 1e-12);
  ts.kind = BSURF_SURFACE_TANGENT_PLANE;
  ts.truth_xyz = c.xyz;
  ts.truth_normals = c.normals;
  ts.truth_count = n;
  assert_int_equal(bsurf_position_errors(moved, n, &ts, 0, d, NULL, NULL), BSURF_OK);
  for (size_t i = 0; i < n; i++)
    assert_true(fabs(d[i] - fabs(0.01 * (double)(i % 7) - 0.03)) < 1e-12);
  /* by a correspondence: every point against truth point 0's plane */
  uint32_t *match = calloc(n, sizeof(uint32_t));
  assert_non_null(match);
  ts.match = match;
  assert_int_equal(bsurf_position_errors(c.xyz, n, &ts, 0, d, NULL, NULL), BSURF_OK);
  for (size_t i = 0; i < n; i++) {
    double r[3] = {c.xyz[3 * i] - c.xyz[0], c.xyz[3 * i + 1] - c.xyz[1],
                   c.xyz[3 * i + 2] - c.xyz[2]};
    assert_true(fabs(d[i] - fabs(dot3(r, c.normals))) < 1e-12);
  }
  match[5] = (uint32_t)n; /* out of range */
  assert_int_equal(bsurf_position_errors(c.xyz, n, &ts, 0, d, NULL, NULL), BSURF_ERR_INVALID_ARG);
  ts.match = NULL;
  c.normals[3 * 9] = c.normals[3 * 9 + 1] = c.normals[3 * 9 + 2] = 0;
  assert_int_equal(bsurf_position_errors(c.xyz, n, &ts, 0, d, NULL, NULL), BSURF_ERR_INVALID_VALUE);
  assert_true(isnan(d[9]) && !isnan(d[8]));
  free(match);
  free(moved);
  free(d);
  bsurf_cloud_free(&c);
}

static void test_match_nearest(void **state) {
  (void)state;
  bsurf_rng rng;
  bsurf_rng_init(&rng, 41, 0, 0);
  size_t nt = 500, n = 2000;
  double *t = malloc(sizeof(double) * 3 * nt), *q = malloc(sizeof(double) * 3 * n);
  uint32_t *m = malloc(sizeof(uint32_t) * n);
  assert_true(t && q && m);
  for (size_t i = 0; i < nt; i++)
    rand_vec(&rng, 1, &t[3 * i]);
  memcpy(&t[3 * 100], &t[3 * 400], 3 * sizeof(double)); /* a duplicate: ties -> lower index */
  for (size_t i = 0; i < n; i++)
    rand_vec(&rng, 1.2, &q[3 * i]);
  memcpy(&q[0], &t[3 * 400], 3 * sizeof(double));
  assert_int_equal(bsurf_match_nearest(t, nt, q, n, 2, m), BSURF_OK);
  assert_int_equal(m[0], 100);
  for (size_t i = 0; i < n; i++) {
    size_t best = 0;
    double bd = INFINITY;
    for (size_t j = 0; j < nt; j++) {
      double d[3] = {q[3 * i] - t[3 * j], q[3 * i + 1] - t[3 * j + 1], q[3 * i + 2] - t[3 * j + 2]};
      double d2 = dot3(d, d);
      if (d2 < bd) bd = d2, best = j;
    }
    assert_int_equal(m[i], best);
  }
  assert_int_equal(bsurf_match_nearest(t, 0, q, n, 2, m), BSURF_ERR_INVALID_ARG);
  free(t);
  free(q);
  free(m);
}

static void test_distance_stats(void **state) {
  (void)state;
  const double d[5] = {1, 2, 3, 4, 10};
  const uint8_t mask[5] = {1, 0, 1, 0, 0};
  bsurf_distance_stats s;
  assert_int_equal(bsurf_distance_stats_compute(d, NULL, 0, 5, &s), BSURF_OK);
  assert_int_equal(s.count, 5);
  assert_true(fabs(s.mean - 4) < 1e-15);
  assert_true(fabs(s.rms - sqrt(130.0 / 5)) < 1e-14);
  assert_true(s.max == 10);
  assert_int_equal(bsurf_distance_stats_compute(d, mask, 1, 5, &s), BSURF_OK);
  assert_int_equal(s.count, 2);
  assert_true(s.mean == 2 && s.max == 3);
  assert_int_equal(bsurf_distance_stats_compute(d, mask, 2, 5, &s), BSURF_OK);
  assert_int_equal(s.count, 0);
  assert_true(isnan(s.mean) && isnan(s.rms) && isnan(s.max));
}

/* ---- the generated shape survives PLY files ---- */

static void tmp_path(char *out, size_t cap, const char *name) {
  const char *base = getenv("BSURF_TMP");
  char dir[4000];
  snprintf(dir, sizeof dir, "%s/surface_distance.tmp", base && *base ? base : ".");
  if (mkdir(dir, 0777) != 0 && errno != EEXIST) fail_msg("cannot create %s", dir);
  snprintf(out, cap, "%s/%s", dir, name);
}

static void test_shape_in_ply(void **state) {
  (void)state;
  bsurf_cloud c, r, copy;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 600, BSURF_SAMPLING_REGULAR, 1, 2),
                   BSURF_OK);
  assert_string_equal(c.shape, "cube");
  assert_int_equal(bsurf_cloud_copy(&copy, &c), BSURF_OK);
  assert_string_equal(copy.shape, "cube");
  bsurf_cloud_free(&copy);
  char path[4096];
  for (int ascii = 0; ascii < 2; ascii++) {
    tmp_path(path, sizeof path, ascii ? "cube_ascii.ply" : "cube.ply");
    bsurf_write_options wo = {.ascii = ascii};
    assert_int_equal(bsurf_write(path, &c, &wo, NULL), BSURF_OK);
    assert_int_equal(bsurf_read(path, &r, NULL), BSURF_OK);
    assert_string_equal(r.shape, "cube");
    assert_int_equal(r.point_count, c.point_count);
    bsurf_cloud_free(&r);
  }
  /* a cloud without a shape writes no such line; other formats drop it */
  c.shape[0] = 0;
  tmp_path(path, sizeof path, "plain.ply");
  assert_int_equal(bsurf_write(path, &c, NULL, NULL), BSURF_OK);
  assert_int_equal(bsurf_read(path, &r, NULL), BSURF_OK);
  assert_string_equal(r.shape, "");
  bsurf_cloud_free(&r);
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&c); /* free leaves an empty cloud: freeing again is fine */

  /* only the exact form is taken; other comments are ignored; the last wins */
  static const char *const heads[][2] = {
      {"comment bootsurf shape torus\n", "torus"},
      {"comment bootsurf shape\n", ""},
      {"comment bootsurf shape torus extra\n", ""},
      {"comment bootsurf  shape   sphere  \n", "sphere"},
      {"comment Bootsurf shape torus\n", ""},
      {"comment made by bootsurf shape cube\n", ""},
      {"comment bootsurf shape a234567890123456789012345678901234567890123456789012345678901234\n",
       ""},
      {"comment bootsurf shape cube\ncomment bootsurf shape plane\n", "plane"},
  };
  for (size_t h = 0; h < sizeof heads / sizeof heads[0]; h++) {
    char buf[512];
    snprintf(buf, sizeof buf,
             "ply\nformat ascii 1.0\n%selement vertex 1\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n1 2 3\n",
             heads[h][0]);
    assert_int_equal(bsurf_read_buffer(buf, strlen(buf), BSURF_FORMAT_PLY, &r, NULL), BSURF_OK);
    assert_string_equal(r.shape, heads[h][1]);
    bsurf_cloud_free(&r);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_triangle_regions),    cmocka_unit_test(test_triangle_random),
      cmocka_unit_test(test_triangle_degenerate), cmocka_unit_test(test_bvh_random_soup),
      cmocka_unit_test(test_bvh_sphere),          cmocka_unit_test(test_mesh_index_errors),
      cmocka_unit_test(test_position_threads),    cmocka_unit_test(test_position_shape_and_plane),
      cmocka_unit_test(test_match_nearest),       cmocka_unit_test(test_distance_stats),
      cmocka_unit_test(test_shape_in_ply),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
