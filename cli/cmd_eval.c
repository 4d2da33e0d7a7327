/* bootsurf eval: compare a result with ground truth of the same points.
 *
 * Thesis 5.2.2: mean angle between estimated and ground-truth normals
 * (Tables 5.1, 5.3-5.9), and the split of 5.2.3 (Table 5.2) into the
 * points with the highest 15% of a per-point value (bootstrap variance) and
 * the rest (--split normal_var:0.85).
 *
 * Chapter 7: precision, recall and F1 of the result's `feature` field
 * against the truth's (the "features" section).
 *
 * Position error (smoothing, denoising): the distance of each result point
 * to the true surface -- a mesh (--surface, or the truth's own faces), the
 * generated shape the truth samples (bsurf_cloud.shape), or the tangent
 * plane of the corresponding truth point -- in model units and in units of
 * the truth's spacing h, split into feature and non-feature points when the
 * truth has a `feature` field.
 *
 * Correspondence (tangent plane, feature labels, a --split field of the
 * truth): result point i is truth point i when the clouds have the same
 * number of points, else the nearest truth point. Normals and features
 * compare by index only, so they need the same number of points.
 *
 * The command is a list of sections ("normals", "features", "position"),
 * each present when the inputs allow it: a section says what it needs,
 * computes its per-point data once, then writes its summary for any group
 * of points (all, high, low) as JSON or as a table. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { GROUP_ALL = 0, GROUP_HIGH, GROUP_LOW, GROUP_COUNT };
static const char *const group_names[GROUP_COUNT] = {"all", "high", "low"};

/* Position error is also summarised over the truth's feature labels. */
enum { PART_ALL = 0, PART_FEATURE, PART_NON_FEATURE, PART_COUNT };
static const char *const part_keys[PART_COUNT] = {"all", "feature", "non_feature"};
static const char *const part_words[PART_COUNT] = {"", " feature", " non-feature"};

/* The true surface of the position error, in order of preference. */
enum { SURF_NONE = 0, SURF_MESH, SURF_SHAPE, SURF_TANGENT_PLANE };
static const char *const surf_names[] = {"none", "mesh", "shape", "tangent_plane"};

typedef struct eval_ctx {
  const char *result_path, *truth_path;
  const bsurf_cloud *result, *truth;
  int threads, quiet;
  /* --split FIELD:Q: high[i] = 1 for the points above the q-quantile */
  const char *split_field;
  double split_q, threshold;
  uint8_t *high;
  size_t group_points[GROUP_COUNT];
  /* result point i corresponds to truth point match[i] (NULL: to point i) */
  uint32_t *match;
  const char *correspondence; /* "index", "nearest", or "none" (not needed) */
  /* position: the surface, its source (file or shape name), h */
  int surf;
  const bsurf_cloud *mesh; /* SURF_MESH: --surface or the truth */
  const char *surf_source;
  bsurf_shape shape;
  const char *surface_path;
  double h;
  int has_feature; /* the truth has `feature`: the feature split exists */
  /* per-section results, per group */
  bsurf_angle_stats normals[GROUP_COUNT];
  bsurf_feature_stats features[GROUP_COUNT];
  bsurf_distance_stats position[GROUP_COUNT][PART_COUNT];
} eval_ctx;

/* The truth point that corresponds to result point i. */
static size_t truth_index(const eval_ctx *e, size_t i) {
  return e->match ? e->match[i] : i;
}

/* The points of a group: mask and the value selected (mask NULL = all). */
static const uint8_t *group_mask(const eval_ctx *e, int g, uint8_t *keep) {
  *keep = g == GROUP_HIGH ? 1 : 0;
  return g == GROUP_ALL ? NULL : e->high;
}

typedef struct eval_section {
  const char *name; /* the JSON key */
  /* NULL when the inputs allow the section, else what is missing */
  const char *(*missing)(const eval_ctx *e, char *buf, size_t n);
  /* computes every group's summary; 0 or an exit code (message printed) */
  int (*compute)(eval_ctx *e);
  void (*json)(cli_json *j, const eval_ctx *e, int group);
  void (*text_header)(FILE *f, const eval_ctx *e);
  void (*text_row)(FILE *f, const eval_ctx *e, int group);
} eval_section;

/* Normals and features compare point i with truth point i. */
static const char *count_mismatch(const eval_ctx *e, char *buf, size_t n) {
  if (e->result->point_count == e->truth->point_count) return NULL;
  snprintf(buf, n,
           "%s has %zu points but %s (the truth) has %zu; this compares the same points in the "
           "same order",
           e->result_path, e->result->point_count, e->truth_path, e->truth->point_count);
  return buf;
}

/* A result field bit-identical to the truth's is the truth passed along
 * (e.g. the exact normals of a generated file), not a result: never scored. */
#define IDENTICAL_TO_TRUTH                                                                         \
  "%s's %s are bit-identical to those of %s: ground truth passed along, not a result; refusing "   \
  "to score them"

/* ---- normals: unoriented angle errors ---- */

static const char *normals_missing(const eval_ctx *e, char *buf, size_t n) {
  if (count_mismatch(e, buf, n)) return buf;
  if (!e->result->normals)
    snprintf(buf, n, "%s has no normals (nx ny nz)", e->result_path);
  else if (!e->truth->normals)
    snprintf(buf, n, "%s (the truth) has no normals (nx ny nz, or true_nx true_ny true_nz)",
             e->truth_path);
  else if (e->result->point_count && memcmp(e->result->normals, e->truth->normals,
                                            3 * e->result->point_count * sizeof(double)) == 0)
    snprintf(buf, n, IDENTICAL_TO_TRUTH, e->result_path, "normals", e->truth_path);
  else
    return NULL;
  return buf;
}

static double vec_len(const double *v) {
  return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

static int normals_compute(eval_ctx *e) {
  size_t n = e->result->point_count, bad = 0;
  double *angles = malloc(sizeof(double) * (n ? n : 1));
  if (!angles) return cli_error("out of memory");
  bsurf_status st =
      bsurf_eval_normals(e->result->normals, e->truth->normals, n, angles, NULL, &bad);
  if (st == BSURF_ERR_INVALID_VALUE) {
    free(angles);
    const char *which = vec_len(&e->result->normals[3 * bad]) > 0 ? e->truth_path : e->result_path;
    return cli_error("%s: point %zu (0-based) has a zero-length normal", which, bad);
  }
  for (int g = 0; g < GROUP_COUNT && st == BSURF_OK; g++) {
    uint8_t keep;
    const uint8_t *mask = group_mask(e, g, &keep);
    if (g != GROUP_ALL && !mask) break;
    st = bsurf_angle_stats_compute(angles, mask, keep, n, &e->normals[g]);
  }
  free(angles);
  if (st != BSURF_OK) return cli_error("normals: %s", bsurf_strerror(st));
  return 0;
}

static void normals_json(cli_json *j, const eval_ctx *e, int group) {
  const bsurf_angle_stats *s = &e->normals[group];
  json_obj(j, "normals");
  json_num(j, "mean_rad", s->mean_rad);
  json_num(j, "median_rad", s->median_rad);
  json_num(j, "rms_rad", s->rms_rad);
  json_num(j, "mean_deg", s->mean_deg);
  json_num(j, "under5deg", s->under5deg);
  json_num(j, "under10deg", s->under10deg);
  json_close_obj(j);
}

static void normals_text_header(FILE *f, const eval_ctx *e) {
  (void)e;
  fprintf(f, "  normal angle error %10s %10s %10s %9s %7s %7s\n", "mean rad", "median rad",
          "rms rad", "mean deg", "<5deg", "<10deg");
}

static void normals_text_row(FILE *f, const eval_ctx *e, int group) {
  const bsurf_angle_stats *s = &e->normals[group];
  fprintf(f, "    %-16s %10.6f %10.6f %10.6f %9.4f %6.2f%% %6.2f%%\n", group_names[group],
          s->mean_rad, s->median_rad, s->rms_rad, s->mean_deg, 100 * s->under5deg,
          100 * s->under10deg);
}

/* ---- features: precision, recall, F1 of `feature` (thesis ch. 7) ---- */

static const char *features_missing(const eval_ctx *e, char *buf, size_t n) {
  if (count_mismatch(e, buf, n)) return buf;
  if (!bsurf_cloud_field(e->result, "feature"))
    snprintf(buf, n, "%s has no field 'feature'", e->result_path);
  else if (!bsurf_cloud_field(e->truth, "feature"))
    snprintf(buf, n, "%s (the truth) has no field 'feature' (or 'true_feature')", e->truth_path);
  else if (e->result->point_count && memcmp(bsurf_cloud_field(e->result, "feature")->values,
                                            bsurf_cloud_field(e->truth, "feature")->values,
                                            e->result->point_count * sizeof(double)) == 0)
    snprintf(buf, n, IDENTICAL_TO_TRUTH, e->result_path, "feature labels", e->truth_path);
  else
    return NULL;
  return buf;
}

static int features_compute(eval_ctx *e) {
  size_t n = e->result->point_count;
  const double *rv = bsurf_cloud_field(e->result, "feature")->values;
  const double *tv = bsurf_cloud_field(e->truth, "feature")->values;
  uint8_t *r = malloc(n ? n : 1), *t = malloc(n ? n : 1);
  if (!r || !t) {
    free(r);
    free(t);
    return cli_error("out of memory");
  }
  for (int g = 0; g < GROUP_COUNT; g++) {
    uint8_t keep;
    const uint8_t *mask = group_mask(e, g, &keep);
    if (g != GROUP_ALL && !mask) break;
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
      if (mask && mask[i] != keep) continue;
      r[m] = rv[i] != 0;
      t[m++] = tv[i] != 0;
    }
    bsurf_eval_features(r, t, m, &e->features[g]);
  }
  free(r);
  free(t);
  return 0;
}

static void features_json(cli_json *j, const eval_ctx *e, int group) {
  const bsurf_feature_stats *s = &e->features[group];
  json_obj(j, "features");
  json_num(j, "precision", s->precision);
  json_num(j, "recall", s->recall);
  json_num(j, "f1", s->f1);
  json_int(j, "true_positives", (long long)s->true_pos);
  json_int(j, "false_positives", (long long)s->false_pos);
  json_int(j, "false_negatives", (long long)s->false_neg);
  json_close_obj(j);
}

static void features_text_header(FILE *f, const eval_ctx *e) {
  (void)e;
  fprintf(f, "  features           %10s %10s %10s %9s %7s %7s\n", "precision", "recall", "F1", "TP",
          "FP", "FN");
}

static void features_text_row(FILE *f, const eval_ctx *e, int group) {
  const bsurf_feature_stats *s = &e->features[group];
  fprintf(f, "    %-16s %10.4f %10.4f %10.4f %9zu %7zu %7zu\n", group_names[group], s->precision,
          s->recall, s->f1, s->true_pos, s->false_pos, s->false_neg);
}

/* ---- position: distance of each result point to the true surface ---- */

/* The true surface (bsurf_eval_position_surface, the library's order of
 * preference: --surface, the truth's faces, its generated shape, its
 * normals) and where it comes from. */
static void position_pick_surface(eval_ctx *e, const bsurf_cloud *surface) {
  bsurf_surface_kind kind;
  e->surf = SURF_NONE;
  if (bsurf_eval_position_surface(e->truth, surface, &kind, &e->shape)) {
    e->surf = kind == BSURF_SURFACE_MESH    ? SURF_MESH
              : kind == BSURF_SURFACE_SHAPE ? SURF_SHAPE
                                            : SURF_TANGENT_PLANE;
    e->mesh = surface ? surface : e->truth;
    e->surf_source = kind == BSURF_SURFACE_SHAPE             ? bsurf_shape_name(e->shape)
                     : kind == BSURF_SURFACE_MESH && surface ? e->surface_path
                                                             : e->truth_path;
  }
  if (e->truth->shape[0] && e->surf != SURF_SHAPE && !surface && !e->truth->face_count)
    cli_warn("%s: unknown shape '%s' in the header, not used", e->truth_path, e->truth->shape);
}

static const char *position_missing(const eval_ctx *e, char *buf, size_t n) {
  if (e->surf != SURF_NONE) return NULL;
  snprintf(buf, n,
           "no true surface: %s (the truth) has no faces, no generated shape and no normals; "
           "give --surface MESH",
           e->truth_path);
  return buf;
}

/* bsurf_eval_position with the correspondence and split of the command. */
static int position_compute(eval_ctx *e) {
  if (e->truth->point_count < 2)
    cli_warn("%s (the truth) has fewer than 2 points: no spacing h", e->truth_path);
  bsurf_position_eval_options o;
  memset(&o, 0, sizeof o);
  o.surface = e->surf == SURF_MESH && e->mesh != e->truth ? e->mesh : NULL;
  o.match = e->match;
  o.high = e->high;
  o.threads = e->threads;
  cli_progress prog;
  cli_progress_init(&prog, "position", e->quiet);
  o.progress = cli_progress_cb;
  o.progress_user = &prog;
  bsurf_position_eval r;
  bsurf_status st =
      bsurf_eval_position(e->result->xyz, e->result->point_count, e->truth, &o, &r, NULL);
  cli_progress_done(&prog);
  e->h = r.h;
  e->has_feature = r.has_feature;
  memcpy(e->position, r.stats, sizeof e->position);
  if (st == BSURF_OK) return 0;
  switch (r.stage) {
  case BSURF_POSITION_STAGE_SPACING:
    return cli_error("position: spacing h of %s: %s", e->truth_path, bsurf_strerror(st));
  case BSURF_POSITION_STAGE_MESH:
    return cli_error("%s: %s", e->surf_source,
                     st == BSURF_ERR_INVALID_ARG ? "a face has a vertex index out of range"
                                                 : bsurf_strerror(st));
  case BSURF_POSITION_STAGE_DISTANCE:
    if (st == BSURF_ERR_INVALID_VALUE)
      return cli_error(
          "%s: truth point %zu (0-based, for result point %zu) has a zero-length normal",
          e->truth_path, r.bad_point < e->result->point_count ? r.bad_truth_point : 0, r.bad_point);
    break;
  default: break;
  }
  return cli_error("position: %s", bsurf_strerror(st));
}

static void position_json_stats(cli_json *j, const bsurf_distance_stats *s, double h,
                                int with_points) {
  if (with_points) json_int(j, "points", (long long)s->count);
  json_num(j, "mean", s->mean);
  json_num(j, "rms", s->rms);
  json_num(j, "max", s->max);
  json_num(j, "mean_h", s->mean / h);
  json_num(j, "rms_h", s->rms / h);
  json_num(j, "max_h", s->max / h);
}

static void position_json(cli_json *j, const eval_ctx *e, int group) {
  json_obj(j, "position");
  if (group == GROUP_ALL) {
    json_str(j, "surface", surf_names[e->surf]);
    json_str(j, "source", e->surf_source);
    json_str(j, "correspondence", e->correspondence);
    json_num(j, "h", e->h);
  }
  position_json_stats(j, &e->position[group][PART_ALL], e->h, group != GROUP_ALL);
  for (int part = PART_FEATURE; e->has_feature && part < PART_COUNT; part++) {
    json_obj(j, part_keys[part]);
    position_json_stats(j, &e->position[group][part], e->h, 1);
    json_close_obj(j);
  }
  json_close_obj(j);
}

static void position_text_header(FILE *f, const eval_ctx *e) {
  fprintf(f, "  position error: surface %s (%s), correspondence %s, h = %.6g\n",
          surf_names[e->surf], e->surf_source, e->correspondence, e->h);
  fprintf(f, "    %-20s %9s %11s %11s %11s %9s %9s %9s\n", "", "points", "mean", "rms", "max",
          "mean/h", "rms/h", "max/h");
}

static void position_text_row(FILE *f, const eval_ctx *e, int group) {
  for (int part = 0; part < (e->has_feature ? PART_COUNT : 1); part++) {
    const bsurf_distance_stats *s = &e->position[group][part];
    char label[32];
    snprintf(label, sizeof label, "%s%s", group_names[group], part_words[part]);
    fprintf(f, "    %-20s %9zu %11.5g %11.5g %11.5g %9.4f %9.4f %9.4f\n", label, s->count, s->mean,
            s->rms, s->max, s->mean / e->h, s->rms / e->h, s->max / e->h);
  }
}

static const eval_section sections[] = {
    {"normals", normals_missing, normals_compute, normals_json, normals_text_header,
     normals_text_row},
    {"features", features_missing, features_compute, features_json, features_text_header,
     features_text_row},
    {"position", position_missing, position_compute, position_json, position_text_header,
     position_text_row},
};
#define SECTION_COUNT ((int)(sizeof sections / sizeof sections[0]))

/* ---- the command ---- */

/* "FIELD:Q" -> field name (in buf) and q in [0, 1]; 0 or a usage error. */
static int parse_split(const cli_command *cmd, const char *arg, char *field, size_t n, double *q) {
  const char *colon = strrchr(arg, ':');
  if (!colon || colon == arg || (size_t)(colon - arg) >= n)
    return cli_usage_error(cmd, "--split needs FIELD:Q, e.g. normal_var:0.85, not '%s'", arg);
  memcpy(field, arg, (size_t)(colon - arg));
  field[colon - arg] = 0;
  char *end = NULL;
  *q = strtod(colon + 1, &end);
  if (end == colon + 1 || *end || !(*q >= 0 && *q <= 1))
    return cli_usage_error(cmd, "--split quantile must be a number from 0 to 1, not '%s'",
                           colon + 1);
  return 0;
}

/* The --split field from the result, else from the truth (through the
 * correspondence); 0 or an exit code. */
static int run_split(eval_ctx *e) {
  const bsurf_field *f = bsurf_cloud_field(e->result, e->split_field);
  const char *where = e->result_path;
  int from_truth = 0;
  if (!f) {
    f = bsurf_cloud_field(e->truth, e->split_field);
    where = e->truth_path;
    from_truth = 1;
  }
  if (!f)
    return cli_error("--split: neither %s nor %s has a field '%s'", e->result_path, e->truth_path,
                     e->split_field);
  size_t n = e->result->point_count, bad = 0;
  const double *values = f->values;
  double *mapped = NULL;
  if (from_truth && e->match) {
    if (!(mapped = malloc(sizeof(double) * (n ? n : 1)))) return cli_error("out of memory");
    for (size_t i = 0; i < n; i++)
      mapped[i] = f->values[e->match[i]];
    values = mapped;
  }
  e->high = malloc(n ? n : 1);
  if (!e->high) {
    free(mapped);
    return cli_error("out of memory");
  }
  bsurf_status st = bsurf_quantile_split(values, n, e->split_q, e->high, &e->threshold,
                                         &e->group_points[GROUP_HIGH], &bad);
  free(mapped);
  if (st == BSURF_ERR_INVALID_VALUE)
    return cli_error("%s: field '%s' is NaN at point %zu (0-based)", where, e->split_field,
                     from_truth ? truth_index(e, bad) : bad);
  if (st != BSURF_OK) return cli_error("--split: %s", bsurf_strerror(st));
  e->group_points[GROUP_LOW] = n - e->group_points[GROUP_HIGH];
  return 0;
}

/* Result point i <-> truth point i when the counts agree, else the nearest
 * truth point; computed only when something needs it (tangent planes, the
 * truth's feature labels for position, a --split field of the truth). */
static int run_correspondence(eval_ctx *e) {
  const size_t n = e->result->point_count, nt = e->truth->point_count;
  int split_from_truth = e->split_field && !bsurf_cloud_field(e->result, e->split_field) &&
                         bsurf_cloud_field(e->truth, e->split_field);
  int position_needs = e->surf == SURF_TANGENT_PLANE ||
                       (e->surf != SURF_NONE && bsurf_cloud_field(e->truth, "feature"));
  if (n == nt) {
    e->correspondence = "index";
    return 0;
  }
  if (!split_from_truth && !position_needs) {
    e->correspondence = "none";
    return 0;
  }
  e->correspondence = "nearest";
  if (nt == 0) return cli_error("%s (the truth) has no points", e->truth_path);
  if (nt > UINT32_MAX) return cli_error("%s (the truth) has too many points", e->truth_path);
  e->match = malloc(sizeof(uint32_t) * (n ? n : 1));
  if (!e->match) return cli_error("out of memory");
  bsurf_status st = bsurf_match_nearest(e->truth->xyz, nt, e->result->xyz, n, e->threads, e->match);
  if (st != BSURF_OK) return cli_error("correspondence: %s", bsurf_strerror(st));
  return 0;
}

int cmd_eval(const cli_command *cmd, int argc, char **argv) {
  const char *truth_path = NULL, *split = NULL, *surface_path = NULL;
  int json = 0, quiet = 0, threads = 0;
  cli_option opts[] = {
      {0, "truth", ARG_STRING, &truth_path, "FILE",
       "ground truth: points (normals, feature) of the true surface", 1, 0},
      {0, "surface", ARG_STRING, &surface_path, "MESH",
       "true surface of the position error: a triangle mesh (e.g. the one TRUTH was sampled from)",
       1, 0},
      {0, "split", ARG_STRING, &split, "FIELD:Q",
       "also summarise the points whose FIELD is above its Q-quantile (high) and the rest (low)", 1,
       0},
      CLI_OPT_THREADS(threads),
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int rc =
      cli_parse_one(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, "RESULT file");
  if (rc != CLI_PARSED) return rc;
  if (!truth_path) return cli_usage_error(cmd, "missing --truth TRUTH");
  char split_field[BSURF_FIELD_NAME_MAX];
  double split_q = 0;
  if (split && parse_split(cmd, split, split_field, sizeof split_field, &split_q)) return CLI_USAGE;

  double t0 = cli_now();
  bsurf_cloud result, truth, surface;
  bsurf_cloud_init(&result);
  bsurf_cloud_init(&truth);
  bsurf_cloud_init(&surface);
  eval_ctx e;
  memset(&e, 0, sizeof e);
  int available[SECTION_COUNT], navailable = 0;
  char reasons[SECTION_COUNT][512];
  rc = 1;
  if (cli_read_cloud(pos[0], &result) || cli_read_cloud(truth_path, &truth)) goto done;
  /* the truth's true_* fields (noise keeps them) are its normals and labels */
  if (cli_truth_from_fields(&truth)) goto done;
  if (surface_path) {
    if (cli_read_cloud(surface_path, &surface)) goto done;
    if (!surface.face_count) {
      rc = cli_error("%s has no faces: --surface needs a triangle mesh", surface_path);
      goto done;
    }
  }
  rc = 0;
  e.result_path = pos[0];
  e.truth_path = truth_path;
  e.surface_path = surface_path;
  e.result = &result;
  e.truth = &truth;
  e.threads = threads;
  e.quiet = quiet;
  e.group_points[GROUP_ALL] = result.point_count;
  position_pick_surface(&e, surface_path ? &surface : NULL);
  if (split) {
    e.split_field = split_field;
    e.split_q = split_q;
  }
  if ((rc = run_correspondence(&e)) != 0) goto done;
  if (split && (rc = run_split(&e)) != 0) goto done;
  for (int s = 0; s < SECTION_COUNT; s++) {
    available[s] = sections[s].missing(&e, reasons[s], sizeof reasons[s]) == NULL;
    navailable += available[s];
  }
  if (navailable == 0) {
    for (int s = 0; s < SECTION_COUNT; s++)
      cli_warn("%s: %s", sections[s].name, reasons[s]);
    rc = cli_error("nothing to evaluate: %s",
                   SECTION_COUNT == 1 ? reasons[0] : "see the warnings above");
    goto done;
  }
  for (int s = 0; s < SECTION_COUNT; s++)
    if (!available[s] && strstr(reasons[s], "bit-identical")) cli_warn("%s", reasons[s]);
  for (int s = 0; s < SECTION_COUNT; s++)
    if (available[s] && (rc = sections[s].compute(&e)) != 0) goto done;

  double secs = cli_now() - t0;
  int groups = split ? GROUP_COUNT : 1;
  if (json) {
    cli_json j;
    json_begin(&j, stdout);
    json_str(&j, "command", "eval");
    json_str(&j, "input", pos[0]);
    json_str(&j, "truth", truth_path);
    json_int(&j, "points", (long long)result.point_count);
    json_int(&j, "truth_points", (long long)truth.point_count);
    for (int s = 0; s < SECTION_COUNT; s++)
      if (available[s]) sections[s].json(&j, &e, GROUP_ALL);
    if (split) {
      json_obj(&j, "split");
      json_str(&j, "field", split_field);
      json_num(&j, "quantile", split_q);
      json_num(&j, "threshold", e.threshold);
      for (int g = GROUP_HIGH; g < groups; g++) {
        json_obj(&j, group_names[g]);
        json_int(&j, "points", (long long)e.group_points[g]);
        for (int s = 0; s < SECTION_COUNT; s++)
          if (available[s]) sections[s].json(&j, &e, g);
        json_close_obj(&j);
      }
      json_close_obj(&j);
    }
    json_int(&j, "threads", bsurf_threads_resolve(threads));
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("eval %s against %s: %zu points (truth %zu), %.2f s\n", pos[0], truth_path,
           result.point_count, truth.point_count, secs);
    if (split)
      printf("  split by %s at quantile %g (threshold %.6g): high %zu points (above), low %zu\n",
             split_field, split_q, e.threshold, e.group_points[GROUP_HIGH],
             e.group_points[GROUP_LOW]);
    for (int s = 0; s < SECTION_COUNT; s++) {
      if (!available[s]) {
        printf("  %s: not evaluated: %s\n", sections[s].name, reasons[s]);
        continue;
      }
      sections[s].text_header(stdout, &e);
      for (int g = 0; g < groups; g++)
        sections[s].text_row(stdout, &e, g);
    }
    cli_print_input_report(stdout);
  }
done:
  free(e.high);
  free(e.match);
  bsurf_cloud_free(&result);
  bsurf_cloud_free(&truth);
  bsurf_cloud_free(&surface);
  return rc;
}
