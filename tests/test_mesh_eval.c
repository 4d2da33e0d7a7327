/* Mesh ground truth (vertex normals, sharp edges, area sampling, distance to
 * the nearest sharp edge) and the evaluation metrics (angles, summaries,
 * quantile split). */
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

#define PI 3.14159265358979323846
#define DEG (PI / 180.0)

/* A mesh from vertex and triangle arrays (copied). */
static void make_mesh(bsurf_cloud *m, const double *xyz, size_t nv, const uint32_t *tri,
                      size_t nf) {
  assert_int_equal(bsurf_cloud_alloc(m, nv, 0), BSURF_OK);
  memcpy(m->xyz, xyz, sizeof(double) * 3 * nv);
  m->faces = malloc(sizeof(uint32_t) * 3 * nf);
  assert_non_null(m->faces);
  memcpy(m->faces, tri, sizeof(uint32_t) * 3 * nf);
  m->face_count = nf;
}

/* Octahedron |x|+|y|+|z| = r around c, outward faces. */
static void make_octahedron(bsurf_cloud *m, double r, const double c[3]) {
  double v[18];
  for (int i = 0; i < 6; i++) {
    for (int k = 0; k < 3; k++)
      v[3 * i + k] = c[k];
    v[3 * i + i / 2] += (i % 2 ? -r : r); /* 0:+x 1:-x 2:+y 3:-y 4:+z 5:-z */
  }
  uint32_t t[24];
  int f = 0;
  for (int sx = 0; sx < 2; sx++)
    for (int sy = 0; sy < 2; sy++)
      for (int sz = 0; sz < 2; sz++) {
        uint32_t X = (uint32_t)sx, Y = (uint32_t)(2 + sy), Z = (uint32_t)(4 + sz);
        int positive = ((sx + sy + sz) % 2) == 0; /* sign product +1 */
        t[3 * f] = X;
        t[3 * f + 1] = positive ? Y : Z;
        t[3 * f + 2] = positive ? Z : Y;
        f++;
      }
  make_mesh(m, v, 6, t, 8);
}

/* Cube [-1,1]^3: 8 vertices, 12 outward triangles. */
static const double cube_v[24] = {-1, -1, -1, 1, -1, -1, 1, 1, -1, -1, 1, -1,
                                  -1, -1, 1,  1, -1, 1,  1, 1, 1,  -1, 1, 1};
static const uint32_t cube_t[36] = {0, 2, 1, 0, 3, 2, /* z = -1 */ 4, 5, 6, 4, 6, 7, /* z = +1 */
                                    0, 1, 5, 0, 5, 4, /* y = -1 */ 3, 7, 6, 3, 6, 2, /* y = +1 */
                                    0, 4, 7, 0, 7, 3, /* x = -1 */ 1, 2, 6, 1, 6, 5 /* x = +1 */};

static double dot3(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Reference point-segment distance (a different formula from the library's:
 * projection parameter from the closest point of the infinite line). */
static double ref_seg_dist(const double *p, const double *a, const double *b) {
  double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
         w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  double t = dot3(w, d) / dot3(d, d);
  t = t < 0 ? 0 : t > 1 ? 1 : t;
  double e[3] = {w[0] - t * d[0], w[1] - t * d[1], w[2] - t * d[2]};
  return sqrt(dot3(e, e));
}

/* Brute force: distance to the nearest of the cube's 12 edges. */
static double ref_cube_edge_dist(const double *p) {
  double best = INFINITY;
  for (int i = 0; i < 8; i++)
    for (int j = i + 1; j < 8; j++) {
      int diff = 0;
      for (int k = 0; k < 3; k++)
        diff += cube_v[3 * i + k] != cube_v[3 * j + k];
      if (diff != 1) continue;
      double d = ref_seg_dist(p, &cube_v[3 * i], &cube_v[3 * j]);
      if (d < best) best = d;
    }
  return best;
}

static void test_octahedron_vertex_normals(void **state) {
  (void)state;
  const double c[3] = {0.5, -2, 3};
  bsurf_cloud m;
  make_octahedron(&m, 1.7, c);
  double n[18];
  size_t without = 99;
  assert_int_equal(bsurf_mesh_vertex_normals(&m, n, &without), BSURF_OK);
  assert_int_equal(without, 0);
  for (int i = 0; i < 6; i++) {
    double expect[3] = {0, 0, 0};
    expect[i / 2] = i % 2 ? -1 : 1;
    for (int k = 0; k < 3; k++)
      assert_true(fabs(n[3 * i + k] - expect[k]) < 1e-14);
  }
  bsurf_cloud_free(&m);
}

/* An icosphere (subdivided icosahedron on the unit sphere): area-weighted
 * normals are within a fraction of a degree of the radial direction, and
 * exactly radial at the 12 symmetric original vertices. */
static void test_icosphere_vertex_normals(void **state) {
  (void)state;
  const double g = (1 + sqrt(5.0)) / 2;
  double v0[36] = {-1, g,  0,  1, g, 0,  -1, -g, 0,  1, -g, 0, 0,  -1, g,  0,  1, g,
                   0,  -1, -g, 0, 1, -g, g,  0,  -1, g, 0,  1, -g, 0,  -1, -g, 0, 1};
  uint32_t t0[60] = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                     4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                     6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
  /* one 4-to-1 subdivision with midpoints pushed to the sphere; midpoints
   * are found by a linear search (small mesh) */
  double v[3 * 42];
  uint32_t t[3 * 80];
  size_t nv = 12, nf = 0;
  for (int i = 0; i < 12; i++) {
    double l = sqrt(dot3(&v0[3 * i], &v0[3 * i]));
    for (int k = 0; k < 3; k++)
      v[3 * i + k] = v0[3 * i + k] / l;
  }
  for (int f = 0; f < 20; f++) {
    uint32_t mid[3];
    for (int e = 0; e < 3; e++) {
      uint32_t a = t0[3 * f + e], b = t0[3 * f + (e + 1) % 3];
      double p[3];
      for (int k = 0; k < 3; k++)
        p[k] = v[3 * a + k] + v[3 * b + k];
      double l = sqrt(dot3(p, p));
      for (int k = 0; k < 3; k++)
        p[k] /= l;
      size_t found = nv;
      for (size_t q = 12; q < nv; q++)
        if (fabs(v[3 * q] - p[0]) + fabs(v[3 * q + 1] - p[1]) + fabs(v[3 * q + 2] - p[2]) < 1e-12)
          found = q;
      if (found == nv) memcpy(&v[3 * nv++], p, sizeof p);
      mid[e] = (uint32_t)found;
    }
    uint32_t a = t0[3 * f], b = t0[3 * f + 1], c = t0[3 * f + 2];
    uint32_t nt[12] = {a, mid[0], mid[2], b,      mid[1], mid[0],
                       c, mid[2], mid[1], mid[0], mid[1], mid[2]};
    memcpy(&t[3 * nf], nt, sizeof nt);
    nf += 4;
  }
  assert_int_equal(nv, 42);
  bsurf_cloud m;
  make_mesh(&m, v, nv, t, nf);
  double n[3 * 42];
  assert_int_equal(bsurf_mesh_vertex_normals(&m, n, NULL), BSURF_OK);
  for (size_t i = 0; i < nv; i++) {
    double a = bsurf_normal_angle(&n[3 * i], &v[3 * i]);
    assert_true(dot3(&n[3 * i], &v[3 * i]) > 0); /* outward */
    assert_true(a < (i < 12 ? 1e-12 : 2 * DEG));
  }
  /* a sphere has no sharp edge at 30 degrees (icosphere-1 dihedral ~ 21 deg) */
  bsurf_cloud out;
  bsurf_sample_report rep;
  assert_int_equal(bsurf_sample_mesh(&out, &m, NULL, &rep), BSURF_OK);
  assert_int_equal(rep.edges, 120);
  assert_int_equal(rep.sharp_edges, 0);
  assert_int_equal(rep.boundary_edges, 0);
  bsurf_cloud_free(&out);
  bsurf_cloud_free(&m);
}

static void test_vertex_without_face(void **state) {
  (void)state;
  const double c[3] = {0, 0, 0};
  bsurf_cloud m;
  make_octahedron(&m, 1, c);
  /* add a 7th vertex used by no face */
  double *xyz = realloc(m.xyz, sizeof(double) * 21);
  assert_non_null(xyz);
  m.xyz = xyz;
  xyz[18] = 5;
  xyz[19] = 5;
  xyz[20] = 5;
  m.point_count = 7;
  double n[21];
  size_t without = 0;
  assert_int_equal(bsurf_mesh_vertex_normals(&m, n, &without), BSURF_OK);
  assert_int_equal(without, 1);
  assert_true(n[18] == 0 && n[19] == 0 && n[20] == 0);
  bsurf_cloud out;
  bsurf_sample_report rep;
  assert_int_equal(bsurf_sample_mesh(&out, &m, NULL, &rep), BSURF_OK);
  assert_int_equal(out.point_count, 6);
  assert_int_equal(rep.vertices_dropped, 1);
  bsurf_cloud_free(&out);
  /* a face index out of range, and a cloud without faces, are refused */
  m.faces[5] = 7;
  assert_int_equal(bsurf_mesh_vertex_normals(&m, n, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_sample_mesh(&out, &m, NULL, NULL), BSURF_ERR_INVALID_ARG);
  bsurf_cloud_free(&m);
  bsurf_cloud pts;
  assert_int_equal(bsurf_cloud_alloc(&pts, 3, 0), BSURF_OK);
  assert_int_equal(bsurf_sample_mesh(&out, &pts, NULL, NULL), BSURF_ERR_INVALID_ARG);
  assert_int_equal(out.point_count, 0);
  bsurf_cloud_free(&pts);
}

static void check_cube_sample(const bsurf_cloud *out, const bsurf_sample_report *rep) {
  const bsurf_field *fd = bsurf_cloud_field(out, "feature_dist"),
                    *ff = bsurf_cloud_field(out, "feature");
  assert_non_null(fd);
  assert_non_null(ff);
  assert_int_equal(ff->type, BSURF_UINT8);
  size_t features = 0;
  for (size_t i = 0; i < out->point_count; i++) {
    const double *p = &out->xyz[3 * i], *n = &out->normals[3 * i];
    /* the normal is a face normal, and the point lies on that face */
    int axis = -1;
    for (int k = 0; k < 3; k++)
      if (fabs(fabs(n[k]) - 1) < 1e-15) axis = k;
    assert_true(axis >= 0);
    assert_true(fabs(p[axis] - n[axis]) < 1e-15);
    double m = 0;
    for (int k = 0; k < 3; k++) {
      assert_true(fabs(p[k]) <= 1 + 1e-15);
      if (k != axis && fabs(p[k]) > m) m = fabs(p[k]);
    }
    /* exact distance to the nearest edge: brute force and analytic */
    assert_true(fabs(fd->values[i] - ref_cube_edge_dist(p)) < 1e-14);
    assert_true(fabs(fd->values[i] - (1 - m)) < 1e-14);
    assert_true(ff->values[i] == (fd->values[i] <= rep->feature_width ? 1.0 : 0.0));
    features += ff->values[i] != 0;
  }
  assert_int_equal(features, rep->feature_points);
}

static void test_cube_mesh(void **state) {
  (void)state;
  bsurf_cloud m, out, out2;
  make_mesh(&m, cube_v, 8, cube_t, 12);
  bsurf_sample_options o = bsurf_sample_options_default();
  assert_int_equal(o.points, 0);
  assert_true(o.sharp_angle_deg == 30 && o.feature_width == 2 && o.seed == 1);
  o.points = 3000;
  o.threads = 1;
  bsurf_sample_report rep;
  assert_int_equal(bsurf_sample_mesh(&out, &m, &o, &rep), BSURF_OK);
  assert_int_equal(out.point_count, 3000);
  assert_int_equal(out.face_count, 0);
  assert_int_equal(rep.edges, 18);
  assert_int_equal(rep.sharp_edges, 12); /* the face diagonals (0 deg) are not */
  assert_int_equal(rep.boundary_edges, 0);
  assert_int_equal(rep.inconsistent_edges, 0);
  assert_true(fabs(rep.area - 24) < 1e-12);
  assert_true(fabs(rep.spacing - sqrt(24.0 / 3000)) < 1e-15);
  assert_true(fabs(rep.feature_width - 2 * rep.spacing) < 1e-15);
  assert_true(rep.feature_points > 0 && rep.feature_points < 3000);
  check_cube_sample(&out, &rep);
  /* every face of the cube is sampled about equally (area 2 each) */
  size_t per_face[6] = {0};
  for (size_t i = 0; i < out.point_count; i++) {
    const double *n = &out.normals[3 * i];
    for (int k = 0; k < 3; k++)
      if (n[k] != 0) per_face[2 * k + (n[k] < 0)]++;
  }
  for (int f = 0; f < 6; f++)
    assert_true(per_face[f] > 400 && per_face[f] < 600);
  /* same seed, other thread count: identical; other seed: different */
  o.threads = 2;
  assert_int_equal(bsurf_sample_mesh(&out2, &m, &o, NULL), BSURF_OK);
  assert_memory_equal(out.xyz, out2.xyz, sizeof(double) * 3 * 3000);
  assert_memory_equal(bsurf_cloud_field(&out, "feature_dist")->values,
                      bsurf_cloud_field(&out2, "feature_dist")->values, sizeof(double) * 3000);
  bsurf_cloud_free(&out2);
  o.seed = 2;
  assert_int_equal(bsurf_sample_mesh(&out2, &m, &o, NULL), BSURF_OK);
  assert_true(memcmp(out.xyz, out2.xyz, sizeof(double) * 3 * 3000) != 0);
  bsurf_cloud_free(&out2);
  bsurf_cloud_free(&out);

  /* a larger angle threshold than 90 degrees: nothing is sharp */
  o.sharp_angle_deg = 91;
  assert_int_equal(bsurf_sample_mesh(&out, &m, &o, &rep), BSURF_OK);
  assert_int_equal(rep.sharp_edges, 0);
  bsurf_cloud_free(&out);

  /* vertices: all on sharp edges */
  o = bsurf_sample_options_default();
  assert_int_equal(bsurf_sample_mesh(&out, &m, &o, &rep), BSURF_OK);
  assert_int_equal(out.point_count, 8);
  assert_int_equal(rep.feature_points, 8);
  for (size_t i = 0; i < 8; i++) {
    assert_true(bsurf_cloud_field(&out, "feature_dist")->values[i] == 0);
    assert_true(dot3(&out.normals[3 * i], &cube_v[3 * i]) > 0); /* outward */
  }
  bsurf_cloud_free(&out);

  /* one face flipped: the orientation is inconsistent along its 3 edges,
   * yet the same 12 edges are found sharp */
  uint32_t tmp = m.faces[1];
  m.faces[1] = m.faces[2];
  m.faces[2] = tmp;
  assert_int_equal(bsurf_sample_mesh(&out, &m, &o, &rep), BSURF_OK);
  assert_int_equal(rep.inconsistent_edges, 3);
  assert_int_equal(rep.sharp_edges, 12);
  bsurf_cloud_free(&out);
  bsurf_cloud_free(&m);
}

/* Vertex sampling keeps the mesh's fields and replaces its normals. */
static void test_vertices_keep_fields(void **state) {
  (void)state;
  bsurf_cloud m, out;
  make_mesh(&m, cube_v, 8, cube_t, 12);
  bsurf_field *q = bsurf_cloud_add_field(&m, "quality", BSURF_FLOAT32);
  assert_non_null(q);
  for (int i = 0; i < 8; i++)
    q->values[i] = i * 0.5;
  assert_int_equal(bsurf_sample_mesh(&out, &m, NULL, NULL), BSURF_OK);
  const bsurf_field *oq = bsurf_cloud_field(&out, "quality");
  assert_non_null(oq);
  for (int i = 0; i < 8; i++)
    assert_true(oq->values[i] == i * 0.5);
  assert_memory_equal(out.xyz, cube_v, sizeof cube_v);
  bsurf_cloud_free(&out);
  bsurf_cloud_free(&m);
}

/* A flat square grid: no sharp edge (its border is not one). */
static void test_plane_mesh(void **state) {
  (void)state;
  enum { G = 4 };
  double v[3 * (G + 1) * (G + 1)];
  uint32_t t[3 * 2 * G * G];
  size_t nf = 0;
  for (int i = 0; i <= G; i++)
    for (int j = 0; j <= G; j++) {
      double *p = &v[3 * (i * (G + 1) + j)];
      p[0] = i;
      p[1] = j;
      p[2] = 0;
    }
  for (int i = 0; i < G; i++)
    for (int j = 0; j < G; j++) {
      uint32_t a = (uint32_t)(i * (G + 1) + j), b = a + G + 1;
      uint32_t tt[6] = {a, b, b + 1, a, b + 1, a + 1};
      memcpy(&t[3 * nf], tt, sizeof tt);
      nf += 2;
    }
  bsurf_cloud m, out;
  make_mesh(&m, v, (G + 1) * (G + 1), t, nf);
  bsurf_sample_options o = bsurf_sample_options_default();
  o.points = 500;
  bsurf_sample_report rep;
  assert_int_equal(bsurf_sample_mesh(&out, &m, &o, &rep), BSURF_OK);
  assert_int_equal(rep.sharp_edges, 0);
  assert_int_equal(rep.boundary_edges, 4 * G);
  assert_true(fabs(rep.no_feature_dist - sqrt(2.0) * G) < 1e-12);
  assert_int_equal(rep.feature_points, 0);
  const bsurf_field *fd = bsurf_cloud_field(&out, "feature_dist"),
                    *ff = bsurf_cloud_field(&out, "feature");
  for (size_t i = 0; i < out.point_count; i++) {
    assert_true(fd->values[i] == rep.no_feature_dist);
    assert_true(ff->values[i] == 0);
    assert_true(out.xyz[3 * i + 2] == 0 && fabs(out.normals[3 * i + 2]) == 1);
  }
  bsurf_cloud_free(&out);
  bsurf_cloud_free(&m);
}

/* Area sampling picks faces in proportion to their area; zero-area faces never. */
static void test_area_weights(void **state) {
  (void)state;
  const double v[] = {0, 0, 0, 1, 0, 0, 0, 2, 0, /* area 1 */ 5,
                      0, 0, 8, 0, 0, 5, 2, 0, /* area 3 */
                      9, 0, 0, 9, 1, 0};
  const uint32_t t[] = {0, 1, 2, 6, 7, 6, /* degenerate */ 3, 4, 5};
  bsurf_cloud m, out;
  make_mesh(&m, v, 8, t, 3);
  bsurf_sample_options o = bsurf_sample_options_default();
  o.points = 40000;
  bsurf_sample_report rep;
  assert_int_equal(bsurf_sample_mesh(&out, &m, &o, &rep), BSURF_OK);
  assert_int_equal(rep.degenerate_faces, 1);
  assert_true(fabs(rep.area - 4) < 1e-12);
  size_t first = 0;
  for (size_t i = 0; i < out.point_count; i++) {
    const double *p = &out.xyz[3 * i];
    assert_true((p[0] >= 0 && p[0] <= 1) || (p[0] >= 5 && p[0] <= 8));
    first += p[0] <= 1;
  }
  assert_true(fabs((double)first / 40000 - 0.25) < 0.01);
  bsurf_cloud_free(&out);
  bsurf_cloud_free(&m);
}

/* Larger mesh: the BVH answer equals brute force over all sharp segments. */
static void test_feature_dist_brute_force(void **state) {
  (void)state;
  /* a "staircase" height field: z = floor(x) steps give sharp edges */
  enum { G = 24 };
  double v[3 * (G + 1) * (G + 1)];
  uint32_t t[3 * 2 * G * G];
  size_t nf = 0;
  for (int i = 0; i <= G; i++)
    for (int j = 0; j <= G; j++) {
      double *p = &v[3 * (i * (G + 1) + j)];
      p[0] = i * 0.1;
      p[1] = j * 0.1 + 0.01 * i;
      p[2] = (i / 4) * 0.3 + 0.05 * sin(j);
    }
  for (int i = 0; i < G; i++)
    for (int j = 0; j < G; j++) {
      uint32_t a = (uint32_t)(i * (G + 1) + j), b = a + G + 1;
      uint32_t tt[6] = {a, b, b + 1, a, b + 1, a + 1};
      memcpy(&t[3 * nf], tt, sizeof tt);
      nf += 2;
    }
  bsurf_cloud m, out;
  make_mesh(&m, v, (G + 1) * (G + 1), t, nf);
  bsurf_sample_options o = bsurf_sample_options_default();
  o.points = 5000;
  bsurf_sample_report rep;
  assert_int_equal(bsurf_sample_mesh(&out, &m, &o, &rep), BSURF_OK);
  assert_true(rep.sharp_edges > 20);
  /* the sharp edges again, by brute force over all edges of the grid */
  double(*seg)[6] = malloc(sizeof(double[6]) * 3 * nf);
  size_t ns = 0;
  double nrm[3 * 2 * G * G];
  for (size_t f = 0; f < nf; f++) {
    const double *a = &v[3 * t[3 * f]], *b = &v[3 * t[3 * f + 1]], *c = &v[3 * t[3 * f + 2]];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
           e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double *n = &nrm[3 * f];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double l = sqrt(dot3(n, n));
    for (int k = 0; k < 3; k++)
      n[k] /= l;
  }
  for (size_t f = 0; f < nf; f++)
    for (size_t g = f + 1; g < nf; g++) {
      int shared = 0;
      uint32_t s[2];
      for (int x = 0; x < 3; x++)
        for (int y = 0; y < 3; y++)
          if (t[3 * f + x] == t[3 * g + y] && shared < 2) s[shared++] = t[3 * f + x];
      if (shared != 2) continue;
      if (acos(fmin(1, dot3(&nrm[3 * f], &nrm[3 * g]))) <= 30 * DEG) continue;
      memcpy(seg[ns], &v[3 * s[0]], sizeof(double) * 3);
      memcpy(&seg[ns][3], &v[3 * s[1]], sizeof(double) * 3);
      ns++;
    }
  assert_int_equal(ns, rep.sharp_edges);
  const bsurf_field *fd = bsurf_cloud_field(&out, "feature_dist");
  for (size_t i = 0; i < out.point_count; i++) {
    double best = INFINITY;
    for (size_t s = 0; s < ns; s++) {
      double d = ref_seg_dist(&out.xyz[3 * i], seg[s], &seg[s][3]);
      if (d < best) best = d;
    }
    assert_true(fabs(fd->values[i] - best) < 1e-12);
  }
  free(seg);
  bsurf_cloud_free(&out);
  bsurf_cloud_free(&m);
}

/* ---- evaluation ---- */

static void test_angles(void **state) {
  (void)state;
  const double x[3] = {1, 0, 0}, y[3] = {0, 2, 0}, mx[3] = {-3, 0, 0}, d[3] = {1, 1, 0},
               z0[3] = {0, 0, 0};
  assert_true(bsurf_normal_angle(x, x) == 0);
  assert_true(fabs(bsurf_normal_angle(x, y) - PI / 2) < 1e-15);
  assert_true(bsurf_normal_angle(x, mx) == 0); /* unoriented */
  assert_true(fabs(bsurf_normal_angle(x, d) - PI / 4) < 1e-15);
  assert_true(fabs(bsurf_normal_angle(mx, d) - PI / 4) < 1e-15);
  assert_true(isnan(bsurf_normal_angle(x, z0)));
  /* accurate for tiny angles, where acos would return 0 */
  const double e[3] = {1, 1e-9, 0};
  assert_true(fabs(bsurf_normal_angle(x, e) - 1e-9) < 1e-20);
}

static void test_eval_normals(void **state) {
  (void)state;
  const double deg[5] = {0, 3, 8, 20, 1};
  double truth[15], result[15], angles[5];
  for (int i = 0; i < 5; i++) {
    double s = i % 2 ? -1 : 1; /* flipped results count as right */
    truth[3 * i] = 0;
    truth[3 * i + 1] = 0;
    truth[3 * i + 2] = 1;
    result[3 * i] = s * sin(deg[i] * DEG);
    result[3 * i + 1] = 0;
    result[3 * i + 2] = s * cos(deg[i] * DEG);
  }
  bsurf_angle_stats st;
  assert_int_equal(bsurf_eval_normals(result, truth, 5, angles, &st, NULL), BSURF_OK);
  for (int i = 0; i < 5; i++)
    assert_true(fabs(angles[i] - deg[i] * DEG) < 1e-14);
  assert_int_equal(st.count, 5);
  assert_true(fabs(st.mean_rad - 32.0 / 5 * DEG) < 1e-14);
  assert_true(fabs(st.mean_deg - 32.0 / 5) < 1e-12);
  assert_true(fabs(st.median_rad - 3 * DEG) < 1e-14);
  assert_true(fabs(st.rms_rad - sqrt((9 + 64 + 400 + 1) / 5.0) * DEG) < 1e-14);
  assert_true(st.under5deg == 3.0 / 5);
  assert_true(st.under10deg == 4.0 / 5);
  /* even count: the mean of the two middle values */
  assert_int_equal(bsurf_eval_normals(result, truth, 4, NULL, &st, NULL), BSURF_OK);
  assert_true(fabs(st.median_rad - 5.5 * DEG) < 1e-14);
  /* a cloud against itself */
  assert_int_equal(bsurf_eval_normals(truth, truth, 5, NULL, &st, NULL), BSURF_OK);
  assert_true(st.mean_rad == 0 && st.rms_rad == 0 && st.under5deg == 1 && st.under10deg == 1);
  /* masks select subsets; an empty subset is all NaN */
  const uint8_t mask[5] = {1, 0, 1, 1, 0};
  assert_int_equal(bsurf_angle_stats_compute(angles, mask, 1, 5, &st), BSURF_OK);
  assert_int_equal(st.count, 3);
  assert_true(fabs(st.median_rad - 8 * DEG) < 1e-14);
  assert_int_equal(bsurf_angle_stats_compute(angles, mask, 0, 5, &st), BSURF_OK);
  assert_int_equal(st.count, 2);
  assert_true(fabs(st.mean_rad - 2 * DEG) < 1e-14);
  assert_int_equal(bsurf_angle_stats_compute(angles, mask, 7, 5, &st), BSURF_OK);
  assert_int_equal(st.count, 0);
  assert_true(isnan(st.mean_rad) && isnan(st.under5deg));
  /* a zero normal is refused, naming the point */
  result[3 * 2] = result[3 * 2 + 1] = result[3 * 2 + 2] = 0;
  size_t bad = 99;
  assert_int_equal(bsurf_eval_normals(result, truth, 5, NULL, &st, &bad), BSURF_ERR_INVALID_VALUE);
  assert_int_equal(bad, 2);
}

static void test_quantile_split(void **state) {
  (void)state;
  double v[20];
  for (int i = 0; i < 20; i++)
    v[i] = (double)((i * 7) % 20); /* 0 .. 19, shuffled */
  uint8_t high[20];
  double t;
  size_t nh;
  assert_int_equal(bsurf_quantile_split(v, 20, 0.85, high, &t, &nh, NULL), BSURF_OK);
  assert_int_equal(nh, 3); /* the highest 15% */
  assert_true(t == 16);
  for (int i = 0; i < 20; i++)
    assert_int_equal(high[i], v[i] >= 17);
  assert_int_equal(bsurf_quantile_split(v, 20, 0.5, high, &t, &nh, NULL), BSURF_OK);
  assert_int_equal(nh, 10);
  assert_int_equal(bsurf_quantile_split(v, 20, 0, high, &t, &nh, NULL), BSURF_OK);
  assert_int_equal(nh, 20);
  assert_true(isinf(t) && t < 0);
  assert_int_equal(bsurf_quantile_split(v, 20, 1, high, &t, &nh, NULL), BSURF_OK);
  assert_int_equal(nh, 0);
  /* 100 distinct values: 15 high at 0.85, 10 at 0.9 */
  double w[100];
  for (int i = 0; i < 100; i++)
    w[i] = 100 - i;
  assert_int_equal(bsurf_quantile_split(w, 100, 0.85, NULL, NULL, &nh, NULL), BSURF_OK);
  assert_int_equal(nh, 15);
  assert_int_equal(bsurf_quantile_split(w, 100, 0.9, NULL, NULL, &nh, NULL), BSURF_OK);
  assert_int_equal(nh, 10);
  /* ties with the threshold stay low */
  const double ties[5] = {1, 1, 1, 1, 2};
  assert_int_equal(bsurf_quantile_split(ties, 5, 0.5, high, &t, &nh, NULL), BSURF_OK);
  assert_int_equal(nh, 1);
  assert_true(t == 1 && high[4] == 1);
  /* bad input */
  assert_int_equal(bsurf_quantile_split(v, 20, 1.5, high, &t, &nh, NULL), BSURF_ERR_INVALID_ARG);
  v[4] = NAN;
  size_t bad = 0;
  assert_int_equal(bsurf_quantile_split(v, 20, 0.85, high, &t, &nh, &bad), BSURF_ERR_INVALID_VALUE);
  assert_int_equal(bad, 4);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_octahedron_vertex_normals),
      cmocka_unit_test(test_icosphere_vertex_normals),
      cmocka_unit_test(test_vertex_without_face),
      cmocka_unit_test(test_cube_mesh),
      cmocka_unit_test(test_vertices_keep_fields),
      cmocka_unit_test(test_plane_mesh),
      cmocka_unit_test(test_area_weights),
      cmocka_unit_test(test_feature_dist_brute_force),
      cmocka_unit_test(test_angles),
      cmocka_unit_test(test_eval_normals),
      cmocka_unit_test(test_quantile_split),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
