/* The position section of `bootsurf eval` (and bootsurf.evaluate): the
 * distance of each result point (e.g. a smoothed cloud, thesis ch. 6) to the
 * true surface, summarised over all points, the groups of a split (5.2.3)
 * and the truth's feature / non-feature points (ch. 7).
 *
 * It puts together the pieces of surface_distance.c: the choice of the true
 * surface, the correspondence of result and truth points, the truth's
 * spacing h (the unit of the thesis's noise levels, 4.2), the per-point
 * distances and their statistics, summed in point order. */
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int bsurf_eval_position_surface(const bsurf_cloud *truth, const bsurf_cloud *surface,
                                bsurf_surface_kind *kind, bsurf_shape *shape) {
  bsurf_shape sh = BSURF_SHAPE_SPHERE;
  bsurf_surface_kind k;
  if (!truth) return 0;
  if ((surface && surface->face_count) || truth->face_count)
    k = BSURF_SURFACE_MESH;
  else if (truth->shape[0] && bsurf_shape_from_name(truth->shape, &sh) == 0)
    k = BSURF_SURFACE_SHAPE;
  else if (truth->normals)
    k = BSURF_SURFACE_TANGENT_PLANE;
  else
    return 0;
  if (kind) *kind = k;
  if (shape) *shape = sh;
  return 1;
}

/* Each group's and part's statistics of dist (n points). */
static bsurf_status position_stats(const double *dist, size_t n, const uint8_t *high,
                                   const uint8_t *feat, bsurf_position_eval *out) {
  uint8_t *sel = malloc(n ? n : 1);
  if (!sel) return BSURF_ERR_NOMEM;
  for (int g = 0; g < out->groups; g++)
    for (int part = 0; part < (feat ? BSURF_POSITION_PARTS : 1); part++) {
      for (size_t i = 0; i < n; i++)
        sel[i] =
            (g == BSURF_POSITION_ALL || high[i] == (g == BSURF_POSITION_HIGH)) &&
            (part == BSURF_POSITION_PART_ALL || feat[i] == (part == BSURF_POSITION_PART_FEATURE));
      bsurf_distance_stats_compute(dist, sel, 1, n, &out->stats[g][part]);
    }
  free(sel);
  return BSURF_OK;
}

bsurf_status bsurf_eval_position(const double *xyz, size_t count, const bsurf_cloud *truth,
                                 const bsurf_position_eval_options *opts, bsurf_position_eval *out,
                                 double *dist) {
  BSURF_REQUIRE(out, "out is NULL");
  memset(out, 0, sizeof *out);
  BSURF_REQUIRE(truth, "truth is NULL");
  BSURF_REQUIRE(!count || xyz, "xyz is NULL");
  bsurf_position_eval_options o;
  if (opts)
    o = *opts;
  else
    memset(&o, 0, sizeof o);
  BSURF_REQUIRE(!o.surface || o.surface->face_count, "opts->surface has no faces: a triangle mesh "
                                                     "is needed");
  bsurf_shape shape;
  if (!bsurf_eval_position_surface(truth, o.surface, &out->surface, &shape))
    return bsurf_invalid(__func__, "no true surface: the truth has no faces, no generated shape "
                                   "and no normals, and no surface mesh is given");
  const size_t nt = truth->point_count;
  const bsurf_field *tf = bsurf_cloud_field(truth, "feature");
  out->surface_is_truth = out->surface == BSURF_SURFACE_MESH && !o.surface;
  out->has_feature = tf != NULL;
  out->groups = o.high ? BSURF_POSITION_GROUPS : 1;
  out->h = NAN;

  bsurf_status st = BSURF_OK;
  uint32_t *match = NULL;
  double *own = NULL;
  uint8_t *feat = NULL;
  bsurf_mesh_index *index = NULL;
  out->stage = BSURF_POSITION_STAGE_SPACING;
  if (nt >= 2 && (st = bsurf_mean_spacing(truth->xyz, nt, o.threads, &out->h)) != BSURF_OK)
    goto done;
  /* the correspondence, when the tangent planes or the labels need it */
  const uint32_t *m = o.match;
  if (!m && count != nt && (out->surface == BSURF_SURFACE_TANGENT_PLANE || tf)) {
    out->stage = BSURF_POSITION_STAGE_MATCH;
    if (!(match = malloc(sizeof *match * (count ? count : 1)))) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    if ((st = bsurf_match_nearest(truth->xyz, nt, xyz, count, o.threads, match)) != BSURF_OK)
      goto done;
    m = match;
  }
  out->nearest = m != NULL;
  bsurf_true_surface s;
  memset(&s, 0, sizeof s);
  s.kind = out->surface;
  if (s.kind == BSURF_SURFACE_MESH) {
    out->stage = BSURF_POSITION_STAGE_MESH;
    if ((st = bsurf_mesh_index_build(&index, o.surface ? o.surface : truth)) != BSURF_OK) goto done;
    s.mesh = index;
  } else if (s.kind == BSURF_SURFACE_SHAPE) {
    s.shape = shape;
  } else {
    s.truth_xyz = truth->xyz;
    s.truth_normals = truth->normals;
    s.truth_count = nt;
    s.match = m;
  }
  out->stage = BSURF_POSITION_STAGE_DISTANCE;
  if (!dist && !(dist = own = malloc(sizeof *dist * (count ? count : 1)))) {
    st = BSURF_ERR_NOMEM;
    goto done;
  }
  st = bsurf_position_errors(xyz, count, &s, o.threads, dist, o.progress, o.progress_user);
  if (st == BSURF_ERR_INVALID_VALUE) {
    size_t bad = 0;
    while (bad < count && !isnan(dist[bad]))
      bad++;
    out->bad_point = bad;
    out->bad_truth_point = bad < count && m ? m[bad] : bad;
  }
  if (st != BSURF_OK) goto done;
  if (tf) {
    if (!(feat = malloc(count ? count : 1))) {
      st = BSURF_ERR_NOMEM;
      goto done;
    }
    for (size_t i = 0; i < count; i++)
      feat[i] = tf->values[m ? m[i] : i] != 0;
  }
  st = position_stats(dist, count, o.high, feat, out);
  if (st == BSURF_OK) out->stage = BSURF_POSITION_STAGE_NONE;
done:
  bsurf_mesh_index_free(index);
  free(match);
  free(own);
  free(feat);
  return st;
}
