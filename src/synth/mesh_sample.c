/* Ground truth from triangle meshes: vertex normals, sharp edges, samples.
 *
 * Thesis 5.2.2: "Starting from smooth triangle meshes, we used their
 * connectivity to compute reliable normals at the vertices. These normals
 * were used as the ground truth" — here the area-weighted average of the
 * incident faces' normals (the sum of their unnormalised cross products).
 * Thesis 5.3.2 and 7.1.2 evaluate separately on the feature areas of the Cube
 * and the Fandisk; we define them from the mesh: an edge is sharp when the
 * angle between its two faces' normals exceeds a threshold (30 degrees by
 * default), `feature_dist` is the exact distance to the nearest sharp edge
 * segment and `feature` marks the points within a width of one.
 *
 * Decisions:
 *  - Boundary edges (one face) are not sharp: a mesh's border is where the
 *    scan stopped, not a crease of the surface. Non-manifold edges (3+
 *    faces) are sharp when any two of their faces differ by more than the
 *    threshold.
 *  - Two faces that walk their common edge the same way are oriented
 *    inconsistently; one normal is flipped before measuring their angle, so
 *    a flat region of a badly oriented mesh does not become a 180-degree
 *    "edge". Zero-area faces have no normal and are ignored.
 *  - The width is in units of the nominal spacing s = sqrt(area / points),
 *    like bsurf_generate's, so "2" means about two point spacings for vertex
 *    sampling and for area sampling alike.
 *  - A mesh without sharp edges gets feature_dist = its bounding-box diagonal
 *    (larger than any distance on it; a finite number keeps PLY files and
 *    JSON means usable) and feature = 0.
 *  - Nearest sharp edge: a bounding-volume hierarchy over the segments
 *    (median splits, leaves of <= 4), searched nearest-box-first with
 *    pruning; the distance is the same function as a brute-force minimum,
 *    so the value is exact and independent of the search order.
 *
 * Every random draw comes from the generator keyed by (seed, sample index);
 * loops over points write only their own outputs, so results do not depend
 * on the thread count. */
#include "common/bvh.h"
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

bsurf_sample_options bsurf_sample_options_default(void) {
  bsurf_sample_options o = {.seed = 1, .sharp_angle_deg = 30.0, .feature_width = 2.0};
  return o;
}

static void sub3(const double *a, const double *b, double *out) {
  out[0] = a[0] - b[0];
  out[1] = a[1] - b[1];
  out[2] = a[2] - b[2];
}

static void cross3(const double *a, const double *b, double *out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double norm3(const double *a) {
  return sqrt(dot3(a, a));
}

static bsurf_status check_mesh(const bsurf_cloud *mesh) {
  BSURF_REQUIRE_IN("mesh", mesh && mesh->xyz, "mesh is NULL or has no vertices");
  BSURF_REQUIRE_IN("mesh", mesh->faces && mesh->face_count > 0, "the mesh has no face");
  const size_t n = mesh->point_count;
  for (size_t i = 0; i < 3 * mesh->face_count; i++)
    BSURF_REQUIRE_IN("mesh", mesh->faces[i] < n, "face %zu uses vertex %u of %zu", i / 3,
                     (unsigned)mesh->faces[i], n);
  for (size_t i = 0; i < 3 * n; i++)
    if (!isfinite(mesh->xyz[i])) return BSURF_ERR_INVALID_VALUE;
  return BSURF_OK;
}

/* Unnormalised face normal (b - a) x (c - a): twice the area times the unit normal. */
static void face_cross(const bsurf_cloud *mesh, size_t f, double *out) {
  const uint32_t *t = &mesh->faces[3 * f];
  double e1[3], e2[3];
  sub3(&mesh->xyz[3 * (size_t)t[1]], &mesh->xyz[3 * (size_t)t[0]], e1);
  sub3(&mesh->xyz[3 * (size_t)t[2]], &mesh->xyz[3 * (size_t)t[0]], e2);
  cross3(e1, e2, out);
}

static size_t accumulate_normals(const bsurf_cloud *mesh, double *normals) {
  memset(normals, 0, sizeof(double) * 3 * mesh->point_count);
  for (size_t f = 0; f < mesh->face_count; f++) {
    double c[3];
    face_cross(mesh, f, c);
    for (int k = 0; k < 3; k++) {
      double *n = &normals[3 * (size_t)mesh->faces[3 * f + k]];
      n[0] += c[0];
      n[1] += c[1];
      n[2] += c[2];
    }
  }
  size_t without = 0;
  for (size_t i = 0; i < mesh->point_count; i++) {
    double *n = &normals[3 * i];
    double len = norm3(n);
    if (len > 0 && isfinite(len)) {
      n[0] /= len;
      n[1] /= len;
      n[2] /= len;
    } else {
      n[0] = n[1] = n[2] = 0;
      without++;
    }
  }
  return without;
}

bsurf_status bsurf_mesh_vertex_normals(const bsurf_cloud *mesh, double *normals,
                                       size_t *without_normal) {
  BSURF_REQUIRE(normals, "normals is NULL");
  bsurf_status st = check_mesh(mesh);
  if (st != BSURF_OK) return st;
  size_t without = accumulate_normals(mesh, normals);
  if (without_normal) *without_normal = without;
  return BSURF_OK;
}

/* ---- edges ---- */

typedef struct half_edge {
  uint32_t other; /* the larger vertex index */
  uint32_t face;
  uint8_t forward; /* 1 when the face walks min -> max */
} half_edge;

/* Angle between the unit normals of two faces of an edge, with one flipped
 * when the faces walk the edge the same way (inconsistent orientation). */
static double dihedral(const double *unit_normals, const half_edge *a, const half_edge *b) {
  const double *na = &unit_normals[3 * (size_t)a->face], *nb = &unit_normals[3 * (size_t)b->face];
  double s = a->forward == b->forward ? -1.0 : 1.0;
  double m[3] = {s * nb[0], s * nb[1], s * nb[2]}, c[3];
  cross3(na, m, c);
  return atan2(norm3(c), dot3(na, m));
}

typedef struct edge_info {
  size_t edges, boundary, nonmanifold, inconsistent;
  double length_sum;
  size_t sharp_count;
  uint32_t *sharp; /* sharp_count x 2 vertex indices */
} edge_info;

/* Groups the 3F half-edges by their smaller vertex (a counting sort), then
 * by the larger one within each group; every group of equal (min, max) is
 * one undirected edge. */
static bsurf_status find_edges(const bsurf_cloud *mesh, const double *unit_normals,
                               const uint8_t *degenerate, double sharp_rad, edge_info *info) {
  const size_t n = mesh->point_count, F = mesh->face_count, H = 3 * F;
  memset(info, 0, sizeof *info);
  size_t *start = bsurf_calloc_array(n + 1, sizeof(size_t));
  half_edge *he = bsurf_alloc_array(H, sizeof(half_edge));
  /* at most one sharp edge per half-edge pair: H / 2 + 1 bounds the count */
  uint32_t *sharp = bsurf_alloc_array(H + 2, sizeof(uint32_t));
  if (!start || !he || !sharp) {
    free(start);
    free(he);
    free(sharp);
    return BSURF_ERR_NOMEM;
  }
  for (size_t f = 0; f < F; f++)
    for (int k = 0; k < 3; k++) {
      uint32_t a = mesh->faces[3 * f + k], b = mesh->faces[3 * f + (k + 1) % 3];
      if (a != b) start[(a < b ? a : b) + 1]++; /* a repeated corner is no edge */
    }
  for (size_t i = 0; i < n; i++)
    start[i + 1] += start[i];
  size_t *fill = bsurf_alloc_array(n + 1, sizeof(size_t));
  if (!fill) {
    free(start);
    free(he);
    free(sharp);
    return BSURF_ERR_NOMEM;
  }
  memcpy(fill, start, sizeof(size_t) * (n + 1));
  for (size_t f = 0; f < F; f++)
    for (int k = 0; k < 3; k++) {
      uint32_t a = mesh->faces[3 * f + k], b = mesh->faces[3 * f + (k + 1) % 3];
      if (a == b) continue;
      half_edge e;
      e.other = a < b ? b : a;
      e.face = (uint32_t)f;
      e.forward = a < b;
      he[fill[a < b ? a : b]++] = e;
    }
  free(fill);
  size_t nsharp = 0;
  for (size_t v = 0; v < n; v++) {
    half_edge *g = &he[start[v]];
    size_t cnt = start[v + 1] - start[v];
    /* insertion sort by (other, face): groups are small (the valence) */
    for (size_t i = 1; i < cnt; i++) {
      half_edge x = g[i];
      size_t j = i;
      while (j > 0 &&
             (g[j - 1].other > x.other || (g[j - 1].other == x.other && g[j - 1].face > x.face))) {
        g[j] = g[j - 1];
        j--;
      }
      g[j] = x;
    }
    for (size_t i = 0; i < cnt;) {
      size_t j = i + 1;
      while (j < cnt && g[j].other == g[i].other)
        j++;
      size_t m = j - i;
      info->edges++;
      double d[3];
      sub3(&mesh->xyz[3 * (size_t)g[i].other], &mesh->xyz[3 * v], d);
      info->length_sum += norm3(d);
      if (m == 1) {
        info->boundary++;
      } else {
        if (m > 2) info->nonmanifold++;
        int is_sharp = 0, inconsistent = 0;
        for (size_t a = i; a < j; a++)
          for (size_t b = a + 1; b < j; b++) {
            if (g[a].forward == g[b].forward) inconsistent = 1;
            if (degenerate[g[a].face] || degenerate[g[b].face]) continue;
            if (dihedral(unit_normals, &g[a], &g[b]) > sharp_rad) is_sharp = 1;
          }
        info->inconsistent += (size_t)inconsistent;
        if (is_sharp) {
          sharp[2 * nsharp] = (uint32_t)v;
          sharp[2 * nsharp + 1] = g[i].other;
          nsharp++;
        }
      }
      i = j;
    }
  }
  free(start);
  free(he);
  info->sharp_count = nsharp;
  info->sharp = sharp;
  return BSURF_OK;
}

/* ---- nearest sharp edge: the shared hierarchy (src/common/bvh.h) over segments ---- */

typedef struct seg {
  double a[3], b[3];
} seg;

typedef struct seg_tree {
  seg *segs; /* in the hierarchy's leaf order */
  bsurf_bvh bvh;
} seg_tree;

/* Squared distance from p to the segment [a, b]. */
static double seg_dist2(const double *p, const seg *s) {
  double d[3], w[3];
  sub3(s->b, s->a, d);
  sub3(p, s->a, w);
  double dd = dot3(d, d), t = dd > 0 ? dot3(w, d) / dd : 0.0;
  if (t < 0) t = 0;
  if (t > 1) t = 1;
  double q[3] = {s->a[0] + t * d[0] - p[0], s->a[1] + t * d[1] - p[1], s->a[2] + t * d[2] - p[2]};
  return dot3(q, q);
}

static double seg_slot_dist2(const void *ctx, size_t slot, const double p[3]) {
  return seg_dist2(p, &((const seg_tree *)ctx)->segs[slot]);
}

static void seg_tree_free(seg_tree *t) {
  free(t->segs);
  bsurf_bvh_free(&t->bvh);
  memset(t, 0, sizeof *t);
}

/* The tree of the m segments (pairs of point indices into xyz). */
static bsurf_status seg_tree_build(seg_tree *t, const double *xyz, const uint32_t *pairs,
                                   size_t m) {
  memset(t, 0, sizeof *t);
  double *box = bsurf_alloc_array(m, 6 * sizeof(double));
  double *center = bsurf_alloc_array(m, 3 * sizeof(double));
  t->segs = bsurf_alloc_array(m, sizeof(seg));
  bsurf_status st = BSURF_ERR_NOMEM;
  if (box && center && t->segs) {
    for (size_t i = 0; i < m; i++) {
      const double *a = &xyz[3 * (size_t)pairs[2 * i]], *b = &xyz[3 * (size_t)pairs[2 * i + 1]];
      for (int k = 0; k < 3; k++) {
        box[6 * i + (size_t)k] = a[k] < b[k] ? a[k] : b[k];
        box[6 * i + 3 + (size_t)k] = a[k] < b[k] ? b[k] : a[k];
        center[3 * i + (size_t)k] = 0.5 * (a[k] + b[k]);
      }
    }
    st = bsurf_bvh_build(&t->bvh, box, center, m);
  }
  if (st == BSURF_OK)
    for (size_t s = 0; s < m; s++) {
      size_t i = t->bvh.order[s];
      memcpy(t->segs[s].a, &xyz[3 * (size_t)pairs[2 * i]], sizeof(double) * 3);
      memcpy(t->segs[s].b, &xyz[3 * (size_t)pairs[2 * i + 1]], sizeof(double) * 3);
    }
  free(box);
  free(center);
  if (st != BSURF_OK) seg_tree_free(t);
  return st;
}

/* ---- sampling ---- */

/* Removes the points with keep[i] == 0 (positions, normals, fields), in order. */
static void compact(bsurf_cloud *c, const uint8_t *keep) {
  size_t j = 0;
  for (size_t i = 0; i < c->point_count; i++) {
    if (!keep[i]) continue;
    if (j != i) {
      memcpy(&c->xyz[3 * j], &c->xyz[3 * i], sizeof(double) * 3);
      if (c->normals) memcpy(&c->normals[3 * j], &c->normals[3 * i], sizeof(double) * 3);
      for (size_t f = 0; f < c->field_count; f++)
        c->fields[f].values[j] = c->fields[f].values[i];
    }
    j++;
  }
  c->point_count = j;
}

/* First face with cum[f] > u (faces of zero area are never chosen); the last
 * face of non-zero area if rounding put u at the total. */
static size_t pick_face(const double *cum, size_t F, double u, size_t last_positive) {
  size_t lo = 0, hi = F;
  while (lo < hi) {
    size_t mid = lo + (hi - lo) / 2;
    if (cum[mid] > u)
      hi = mid;
    else
      lo = mid + 1;
  }
  return lo < F ? lo : last_positive;
}

bsurf_status bsurf_sample_mesh(bsurf_cloud *out, const bsurf_cloud *mesh,
                               const bsurf_sample_options *opts, bsurf_sample_report *report) {
  BSURF_REQUIRE(out, "out is NULL");
  bsurf_cloud_init(out);
  bsurf_sample_options o = opts ? *opts : bsurf_sample_options_default();
  BSURF_REQUIRE(o.sharp_angle_deg >= 0 && o.sharp_angle_deg <= 180,
                "sharp_angle_deg = %g: must be in [0, 180]", o.sharp_angle_deg);
  BSURF_REQUIRE(o.feature_width >= 0 && isfinite(o.feature_width),
                "feature_width = %g: must be finite and >= 0", o.feature_width);
  BSURF_REQUIRE(o.threads >= 0, "threads = %d: must be >= 0 (0 = all cores)", o.threads);
  bsurf_status st = check_mesh(mesh);
  if (st != BSURF_OK) return st;
  if (mesh->face_count > UINT32_MAX) return BSURF_ERR_UNSUPPORTED;
  const size_t F = mesh->face_count;
  const int T = bsurf_threads_resolve(o.threads);
  (void)T;
  bsurf_sample_report rep;
  memset(&rep, 0, sizeof rep);

  /* face normals and areas; cumulative area in face order */
  double *unit = bsurf_alloc_array(F, 3 * sizeof(double));
  double *cum = bsurf_alloc_array(F, sizeof(double));
  uint8_t *degenerate = bsurf_alloc_array(F, 1);
  edge_info edges;
  memset(&edges, 0, sizeof edges);
  seg_tree tree;
  memset(&tree, 0, sizeof tree);
  uint8_t *keep = NULL;
  if (!unit || !cum || !degenerate) {
    st = BSURF_ERR_NOMEM;
    goto fail;
  }
  double total = 0;
  size_t last_positive = F;
  for (size_t f = 0; f < F; f++) {
    double c[3];
    face_cross(mesh, f, c);
    double len = norm3(c);
    degenerate[f] = !(len > 0) || !isfinite(len);
    for (int k = 0; k < 3; k++)
      unit[3 * f + k] = degenerate[f] ? 0.0 : c[k] / len;
    if (degenerate[f])
      rep.degenerate_faces++;
    else
      last_positive = f;
    total += degenerate[f] ? 0.0 : 0.5 * len;
    cum[f] = total;
  }
  if (!(total > 0) || !isfinite(total)) {
    st = BSURF_ERR_INVALID_VALUE; /* every face has zero area */
    goto fail;
  }
  rep.area = total;

  st = find_edges(mesh, unit, degenerate, o.sharp_angle_deg * PI / 180.0, &edges);
  if (st != BSURF_OK) goto fail;
  rep.edges = edges.edges;
  rep.sharp_edges = edges.sharp_count;
  rep.boundary_edges = edges.boundary;
  rep.nonmanifold_edges = edges.nonmanifold;
  rep.inconsistent_edges = edges.inconsistent;
  rep.mean_edge_length = edges.edges ? edges.length_sum / (double)edges.edges : 0.0;
  rep.no_feature_dist = bsurf_bounding_box(mesh->xyz, mesh->point_count, NULL, NULL);

  if (o.points == 0) {
    st = bsurf_cloud_copy(out, mesh);
    if (st != BSURF_OK) goto fail;
    free(out->faces);
    out->faces = NULL;
    out->face_count = 0;
    if (!out->normals) {
      out->normals = bsurf_alloc_array(out->point_count, 3 * sizeof(double));
      if (!out->normals) {
        st = BSURF_ERR_NOMEM;
        goto fail;
      }
    }
    out->normal_type = BSURF_FLOAT64;
    rep.vertices_dropped = accumulate_normals(mesh, out->normals);
    if (rep.vertices_dropped) {
      keep = bsurf_alloc_array(out->point_count, 1);
      if (!keep) {
        st = BSURF_ERR_NOMEM;
        goto fail;
      }
      for (size_t i = 0; i < out->point_count; i++) {
        const double *n = &out->normals[3 * i];
        keep[i] = n[0] != 0 || n[1] != 0 || n[2] != 0;
      }
      compact(out, keep);
    }
  } else {
    st = bsurf_cloud_alloc(out, o.points, 1);
    if (st != BSURF_OK) goto fail;
    out->normal_type = BSURF_FLOAT64;
    const long long count = (long long)o.points;
    const double *xyz = mesh->xyz;
    const uint32_t *faces = mesh->faces;
    double *pts = out->xyz, *nrm = out->normals;
#ifdef _OPENMP
#pragma omp parallel for num_threads(T) schedule(static)
#endif
    for (long long ii = 0; ii < count; ii++) {
      size_t i = (size_t)ii;
      bsurf_rng rng;
      bsurf_rng_init(&rng, o.seed, i, 0x6d657368ull /* "mesh" */);
      size_t f = pick_face(cum, F, bsurf_rng_uniform(&rng) * total, last_positive);
      double r1 = bsurf_rng_uniform(&rng), r2 = bsurf_rng_uniform(&rng);
      if (r1 + r2 > 1) { /* fold the unit square onto the triangle */
        r1 = 1 - r1;
        r2 = 1 - r2;
      }
      const double *a = &xyz[3 * (size_t)faces[3 * f]], *b = &xyz[3 * (size_t)faces[3 * f + 1]],
                   *c = &xyz[3 * (size_t)faces[3 * f + 2]];
      for (int k = 0; k < 3; k++) {
        pts[3 * i + k] = a[k] + r1 * (b[k] - a[k]) + r2 * (c[k] - a[k]);
        nrm[3 * i + k] = unit[3 * f + k];
      }
    }
  }
  if (out->point_count == 0) {
    st = BSURF_ERR_TOO_FEW_POINTS;
    goto fail;
  }

  rep.spacing = sqrt(total / (double)out->point_count);
  rep.feature_width = o.feature_width * rep.spacing;
  bsurf_field *fd = bsurf_cloud_add_field(out, "feature_dist", BSURF_FLOAT32);
  bsurf_field *ff = fd ? bsurf_cloud_add_field(out, "feature", BSURF_UINT8) : NULL;
  if (!ff) {
    st = BSURF_ERR_NOMEM;
    goto fail;
  }
  fd = bsurf_cloud_field(out, "feature_dist"); /* the fields array may have moved */
  double *dist = fd->values, *flag = ff->values;
  const double *pts = out->xyz;
  const long long count = (long long)out->point_count;
  const double width = rep.feature_width;
  if (edges.sharp_count == 0) {
    for (long long i = 0; i < count; i++) {
      dist[i] = rep.no_feature_dist;
      flag[i] = 0;
    }
  } else {
    st = seg_tree_build(&tree, mesh->xyz, edges.sharp, edges.sharp_count);
    if (st != BSURF_OK) goto fail;
    const seg_tree *tp = &tree;
#ifdef _OPENMP
#pragma omp parallel for num_threads(T) schedule(dynamic, 256)
#endif
    for (long long i = 0; i < count; i++) {
      double d = sqrt(bsurf_bvh_nearest(&tp->bvh, &pts[3 * (size_t)i], seg_slot_dist2, tp, NULL));
      dist[i] = d;
      flag[i] = d <= width ? 1.0 : 0.0;
    }
  }
  for (long long i = 0; i < count; i++)
    rep.feature_points += flag[i] != 0;

  if (report) *report = rep;
  st = BSURF_OK;
fail: /* and the end of a success: the scratch freed, the output kept */
  seg_tree_free(&tree);
  free(edges.sharp);
  free(unit);
  free(cum);
  free(degenerate);
  free(keep);
  if (st != BSURF_OK) bsurf_cloud_free(out);
  return st;
}
