/* Position error: the distance from points to a true surface.
 *
 * The true surface is a triangle mesh (exact point-to-triangle distance,
 * accelerated by a bounding-volume hierarchy), a generated shape
 * (bsurf_shape_distance) or, when only points with normals are known, the
 * tangent plane of the corresponding truth point.
 *
 * Point to triangle: the closest point by Voronoi regions of C. Ericson,
 * "Real-Time Collision Detection" (Morgan Kaufmann 2005), section 5.1.5,
 * ClosestPtPointTriangle: the three vertex regions, the three edge regions
 * and the face region are told apart by the signs of dot products and of the
 * barycentric numerators va, vb, vc. Two changes for robustness:
 *  - the offset q - p is built from differences (p - a, b - a, ...) only, so
 *    its rounding error scales with the triangle's size and the distance,
 *    never with how far the mesh is from the origin;
 *  - in the face region the closest point is the foot of the perpendicular,
 *    p - ((p - a) . n / n . n) n with n = (b - a) x (c - a), instead of the
 *    barycentric combination, whose numerators cancel on thin triangles;
 *  - a degenerate triangle (zero area: collinear or repeated vertices) has no
 *    face region and would divide 0 by 0 there; it is treated as its three
 *    edges (segments, a zero-length one being a point), and every division of
 *    the edge regions is guarded, so no input gives NaN.
 *
 * The hierarchy is the shared one of src/common/bvh.h over the triangles'
 * boxes and centroids: its query returns the minimum of the triangle distance
 * over all faces, bit for bit, whatever order the search takes (equal
 * distances keep the lowest face index); the tests compare it with a
 * brute-force loop.
 *
 * Per-point loops run through bsurf_parallel_points and write only their own
 * point's output: results are the same for any thread count. */
#include "common/bvh.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- small vector helpers ---- */

static void sub3(const double *a, const double *b, double *out) {
  out[0] = a[0] - b[0];
  out[1] = a[1] - b[1];
  out[2] = a[2] - b[2];
}

static double dot3(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* ---- point to triangle (Ericson 5.1.5) ---- */

/* Squared distance from p to the segment [a, b] (a point when a == b);
 * *t out: the parameter of the closest point a + t (b - a). */
static double seg_dist2(const double *p, const double *a, const double *b, double *t) {
  double ab[3], ap[3];
  sub3(b, a, ab);
  sub3(p, a, ap);
  double ll = dot3(ab, ab), s = ll > 0 ? dot3(ap, ab) / ll : 0.0;
  s = s < 0 ? 0 : s > 1 ? 1 : s;
  double e[3] = {s * ab[0] - ap[0], s * ab[1] - ap[1], s * ab[2] - ap[2]};
  *t = s;
  return dot3(e, e);
}

/* A zero-area triangle: the nearest of its three edges. */
static double degenerate_dist2(const double *p, const double *a, const double *b, const double *c,
                               double *closest) {
  const double *ends[3][2] = {{a, b}, {b, c}, {c, a}};
  double best = INFINITY, bt = 0;
  int be = 0;
  for (int e = 0; e < 3; e++) {
    double t, d = seg_dist2(p, ends[e][0], ends[e][1], &t);
    if (d < best) {
      best = d;
      bt = t;
      be = e;
    }
  }
  if (closest) {
    const double *u = ends[be][0], *v = ends[be][1];
    for (int k = 0; k < 3; k++)
      closest[k] = u[k] + bt * (v[k] - u[k]);
  }
  return best;
}

/* x / y for the barycentric parameters, 0 when y is not positive (only a
 * degenerate configuration gets there), clamped to [0, 1]. */
static double ratio01(double x, double y) {
  double r = y > 0 ? x / y : 0.0;
  return r < 0 ? 0 : r > 1 ? 1 : r;
}

/* Squared distance from p to triangle (a, b, c); closest out (may be NULL). */
static double tri_dist2(const double *p, const double *a, const double *b, const double *c,
                        double *closest) {
  double ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
  sub3(b, a, ab);
  sub3(c, a, ac);
  /* zero area (to rounding): |ab x ac|^2 = |ab|^2 |ac|^2 sin^2 */
  double n[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2],
                 ab[0] * ac[1] - ab[1] * ac[0]};
  if (!(dot3(n, n) > 1e-30 * dot3(ab, ab) * dot3(ac, ac)))
    return degenerate_dist2(p, a, b, c, closest);

  const double *base; /* the closest point is base + u dir1 + v dir2 */
  double u = 0, v = 0, dir2[3] = {0, 0, 0};
  const double *dir1 = ab, *off; /* off = p - base */

  sub3(p, a, ap);
  double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
  sub3(p, b, bp);
  double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
  sub3(p, c, cp);
  double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
  /* the barycentric numerators of the closest point (Ericson's va, vb, vc) */
  double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;

  if (d1 <= 0 && d2 <= 0) { /* vertex region a */
    base = a, off = ap;
  } else if (d3 >= 0 && d4 <= d3) { /* vertex region b */
    base = b, off = bp;
  } else if (vc <= 0 && d1 >= 0 && d3 <= 0) { /* edge region ab */
    base = a, off = ap, u = ratio01(d1, d1 - d3);
  } else if (d6 >= 0 && d5 <= d6) { /* vertex region c */
    base = c, off = cp;
  } else if (vb <= 0 && d2 >= 0 && d6 <= 0) { /* edge region ac */
    base = a, off = ap, dir1 = ac, u = ratio01(d2, d2 - d6);
  } else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) { /* edge region bc */
    double bc[3];
    sub3(c, b, bc);
    memcpy(dir2, bc, sizeof bc);
    base = b, off = bp, v = ratio01(d4 - d3, (d4 - d3) + (d5 - d6));
  } else { /* face region: the foot of the perpendicular on the plane */
    /* Ericson returns a + v ab + w ac with v = vb / (va + vb + vc), ...;
     * va, vb, vc lose digits to cancellation on thin triangles, while the
     * projection along n = ab x ac does not (and gives the same point). */
    double s = dot3(ap, n) / dot3(n, n);
    for (int k = 0; k < 3; k++)
      q[k] = -s * n[k];
    if (closest)
      for (int k = 0; k < 3; k++)
        closest[k] = p[k] + q[k];
    return dot3(q, q);
  }
  for (int k = 0; k < 3; k++)
    q[k] = u * dir1[k] + v * dir2[k] - off[k]; /* closest - p */
  if (closest)
    for (int k = 0; k < 3; k++)
      closest[k] = base[k] + (u * dir1[k] + v * dir2[k]);
  return dot3(q, q);
}

double bsurf_triangle_distance(const double p[3], const double a[3], const double b[3],
                               const double c[3], double closest[3]) {
  return sqrt(tri_dist2(p, a, b, c, closest));
}

/* ---- the hierarchy (src/common/bvh.h) over the triangles ---- */

typedef struct tri {
  double v[3][3];
} tri;

struct bsurf_mesh_index {
  size_t tri_count;
  tri *tris;    /* in the hierarchy's leaf order */
  size_t *face; /* the mesh's face index of tris[i] */
  bsurf_bvh bvh;
};

void bsurf_mesh_index_free(bsurf_mesh_index *index) {
  if (!index) return;
  free(index->tris);
  free(index->face);
  bsurf_bvh_free(&index->bvh);
  free(index);
}

bsurf_status bsurf_mesh_index_build(bsurf_mesh_index **index, const bsurf_cloud *mesh) {
  BSURF_REQUIRE(index, "index is NULL");
  *index = NULL;
  BSURF_REQUIRE(mesh && mesh->xyz, "mesh is NULL or has no vertices");
  BSURF_REQUIRE(mesh->faces && mesh->face_count > 0, "the mesh has no face");
  const size_t m = mesh->face_count, n = mesh->point_count;
  for (size_t i = 0; i < 3 * m; i++)
    BSURF_REQUIRE(mesh->faces[i] < n, "face %zu uses vertex %u of %zu", i / 3,
                  (unsigned)mesh->faces[i], n);
  for (size_t i = 0; i < 3 * n; i++)
    if (!isfinite(mesh->xyz[i])) return BSURF_ERR_INVALID_VALUE;

  bsurf_mesh_index *ix = calloc(1, sizeof *ix);
  double *box = bsurf_alloc_array(m, 6 * sizeof(double));
  double *center = bsurf_alloc_array(m, 3 * sizeof(double));
  if (ix) {
    ix->tris = bsurf_alloc_array(m, sizeof(tri));
    ix->face = bsurf_alloc_array(m, sizeof(size_t));
  }
  bsurf_status st = BSURF_ERR_NOMEM;
  if (!ix || !box || !center || !ix->tris || !ix->face) goto fail;
  for (size_t f = 0; f < m; f++) {
    const double *v[3];
    for (int k = 0; k < 3; k++)
      v[k] = &mesh->xyz[3 * (size_t)mesh->faces[3 * f + (size_t)k]];
    for (int k = 0; k < 3; k++) {
      double lo = v[0][k], hi = v[0][k];
      for (int j = 1; j < 3; j++) {
        if (v[j][k] < lo) lo = v[j][k];
        if (v[j][k] > hi) hi = v[j][k];
      }
      box[6 * f + (size_t)k] = lo;
      box[6 * f + 3 + (size_t)k] = hi;
      center[3 * f + (size_t)k] = (v[0][k] + v[1][k] + v[2][k]) / 3.0;
    }
  }
  st = bsurf_bvh_build(&ix->bvh, box, center, m);
  if (st != BSURF_OK) goto fail;
  for (size_t i = 0; i < m; i++) {
    size_t f = ix->bvh.order[i];
    ix->face[i] = f;
    for (int v = 0; v < 3; v++)
      memcpy(ix->tris[i].v[v], &mesh->xyz[3 * (size_t)mesh->faces[3 * f + (size_t)v]],
             3 * sizeof(double));
  }
  ix->tri_count = m;
  free(box);
  free(center);
  *index = ix;
  return BSURF_OK;
fail:
  free(box);
  free(center);
  bsurf_mesh_index_free(ix);
  return st;
}

static double tri_slot_dist2(const void *ctx, size_t slot, const double p[3]) {
  const tri *t = &((const bsurf_mesh_index *)ctx)->tris[slot];
  return tri_dist2(p, t->v[0], t->v[1], t->v[2], NULL);
}

/* Squared distance to the nearest triangle; *face and closest (may be NULL). */
static double mesh_nearest(const bsurf_mesh_index *ix, const double *p, size_t *face,
                           double *closest) {
  size_t best_i = 0;
  double best = bsurf_bvh_nearest(&ix->bvh, p, tri_slot_dist2, ix, &best_i);
  if (face) *face = ix->face[best_i];
  if (closest) {
    const tri *t = &ix->tris[best_i];
    tri_dist2(p, t->v[0], t->v[1], t->v[2], closest);
  }
  return best;
}

double bsurf_mesh_distance(const bsurf_mesh_index *index, const double p[3], size_t *face,
                           double closest[3]) {
  if (!index || !isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) {
    if (closest) closest[0] = closest[1] = closest[2] = NAN;
    if (face) *face = 0;
    return NAN;
  }
  return sqrt(mesh_nearest(index, p, face, closest));
}

/* ---- per-point position errors ---- */

typedef struct position_ctx {
  const double *xyz;
  const bsurf_true_surface *s;
  double *dist;
} position_ctx;

static void position_point(void *vctx, int thread, size_t i) {
  (void)thread;
  const position_ctx *c = vctx;
  const double *p = &c->xyz[3 * i];
  const bsurf_true_surface *s = c->s;
  switch (s->kind) {
  case BSURF_SURFACE_MESH: c->dist[i] = bsurf_mesh_distance(s->mesh, p, NULL, NULL); break;
  case BSURF_SURFACE_SHAPE: c->dist[i] = bsurf_shape_distance(s->shape, p); break;
  case BSURF_SURFACE_TANGENT_PLANE: {
    size_t j = s->match ? s->match[i] : i;
    const double *t = &s->truth_xyz[3 * j], *n = &s->truth_normals[3 * j];
    double d[3], nn = sqrt(dot3(n, n));
    sub3(p, t, d);
    c->dist[i] = nn > 0 && isfinite(nn) ? fabs(dot3(d, n)) / nn : NAN;
    break;
  }
  }
}

bsurf_status bsurf_position_errors(const double *xyz, size_t count,
                                   const bsurf_true_surface *surface, int threads, double *dist,
                                   bsurf_progress_fn progress, void *progress_user) {
  BSURF_REQUIRE(surface, "surface is NULL");
  BSURF_REQUIRE(!count || (xyz && dist), "xyz or dist is NULL");
  switch (surface->kind) {
  case BSURF_SURFACE_MESH: BSURF_REQUIRE(surface->mesh, "surface->mesh is NULL (kind MESH)"); break;
  case BSURF_SURFACE_SHAPE:
    BSURF_REQUIRE((unsigned)surface->shape <= BSURF_SHAPE_PLANE,
                  "surface->shape = %d: not a bsurf_shape", (int)surface->shape);
    break;
  case BSURF_SURFACE_TANGENT_PLANE:
    BSURF_REQUIRE(surface->truth_xyz && surface->truth_normals,
                  "surface->truth_xyz or truth_normals is NULL (kind TANGENT_PLANE)");
    BSURF_REQUIRE(surface->match || surface->truth_count == count,
                  "surface->truth_count = %zu differs from count = %zu and no match is given",
                  surface->truth_count, count);
    for (size_t i = 0; surface->match && i < count; i++)
      BSURF_REQUIRE(surface->match[i] < surface->truth_count,
                    "surface->match[%zu] = %u: must be below %zu", i, (unsigned)surface->match[i],
                    surface->truth_count);
    break;
  default:
    return bsurf_invalid(__func__, "surface->kind = %d: not a bsurf_surface_kind",
                         (int)surface->kind);
  }
  position_ctx c = {xyz, surface, dist};
  bsurf_status st =
      bsurf_parallel_points(count, threads, position_point, &c, progress, progress_user);
  if (st != BSURF_OK) return st;
  for (size_t i = 0; i < count; i++)
    if (isnan(dist[i])) return BSURF_ERR_INVALID_VALUE;
  return BSURF_OK;
}

/* ---- correspondence ---- */

typedef struct match_ctx {
  const bsurf_knn_index *index;
  const double *xyz;
  uint32_t *match;
  int failed; /* set (never cleared) by a failing query; read after the loop */
} match_ctx;

static void match_point(void *vctx, int thread, size_t i) {
  (void)thread;
  match_ctx *c = vctx;
  if (bsurf_knn_query(c->index, &c->xyz[3 * i], 1, &c->match[i], NULL) != BSURF_OK) {
#ifdef _OPENMP
#pragma omp atomic write
#endif
    c->failed = 1;
  }
}

bsurf_status bsurf_match_nearest(const double *truth_xyz, size_t truth_count, const double *xyz,
                                 size_t count, int threads, uint32_t *match) {
  BSURF_REQUIRE(truth_xyz, "truth_xyz is NULL");
  BSURF_REQUIRE(truth_count >= 1 && truth_count <= UINT32_MAX,
                "truth_count = %zu: must be in [1, 2^32 - 1]", truth_count);
  BSURF_REQUIRE(!count || (xyz && match), "xyz or match is NULL");
  bsurf_knn_index *index = NULL;
  bsurf_status st = bsurf_knn_build(&index, truth_xyz, truth_count);
  if (st != BSURF_OK) return st;
  match_ctx c = {index, xyz, match, 0};
  st = bsurf_parallel_points(count, threads, match_point, &c, NULL, NULL);
  if (st == BSURF_OK && c.failed) st = BSURF_ERR_INVALID_VALUE;
  bsurf_knn_free(index);
  return st;
}

/* ---- statistics ---- */

bsurf_status bsurf_distance_stats_compute(const double *dist, const uint8_t *mask, uint8_t keep,
                                          size_t count, bsurf_distance_stats *stats) {
  BSURF_REQUIRE(stats, "stats is NULL");
  BSURF_REQUIRE(!count || dist, "dist is NULL");
  size_t n = 0;
  double sum = 0, sum2 = 0, max = 0;
  for (size_t i = 0; i < count; i++) {
    if (mask && mask[i] != keep) continue;
    double d = dist[i];
    n++;
    sum += d;
    sum2 += d * d;
    if (d > max || isnan(d)) max = d;
  }
  stats->count = n;
  if (n == 0) {
    stats->mean = stats->rms = stats->max = NAN;
    return BSURF_OK;
  }
  stats->mean = sum / (double)n;
  stats->rms = sqrt(sum2 / (double)n);
  stats->max = max;
  return BSURF_OK;
}
