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
 * The command is a list of sections ("normals", "features"; "position"
 * later), each present when the inputs allow it: a section says
 * what it needs, computes its per-point data once, then writes its summary
 * for any group of points (all, high, low) as JSON or as a table row. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { GROUP_ALL = 0, GROUP_HIGH, GROUP_LOW, GROUP_COUNT };
static const char *const group_names[GROUP_COUNT] = {"all", "high", "low"};

typedef struct eval_ctx {
  const char *result_path, *truth_path;
  const bsurf_cloud *result, *truth;
  /* --split FIELD:Q: high[i] = 1 for the points above the q-quantile */
  const char *split_field;
  double split_q, threshold;
  uint8_t *high;
  size_t group_points[GROUP_COUNT];
  /* per-section results, per group */
  bsurf_angle_stats normals[GROUP_COUNT];
  bsurf_feature_stats features[GROUP_COUNT];
} eval_ctx;

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
  void (*text_header)(FILE *f);
  void (*text_row)(FILE *f, const eval_ctx *e, int group);
} eval_section;

/* ---- normals: unoriented angle errors ---- */

static const char *normals_missing(const eval_ctx *e, char *buf, size_t n) {
  if (!e->result->normals)
    snprintf(buf, n, "%s has no normals (nx ny nz)", e->result_path);
  else if (!e->truth->normals)
    snprintf(buf, n, "%s (the truth) has no normals (nx ny nz)", e->truth_path);
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

static void normals_text_header(FILE *f) {
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
  if (!bsurf_cloud_field(e->result, "feature"))
    snprintf(buf, n, "%s has no field 'feature'", e->result_path);
  else if (!bsurf_cloud_field(e->truth, "feature"))
    snprintf(buf, n, "%s (the truth) has no field 'feature'", e->truth_path);
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

static void features_text_header(FILE *f) {
  fprintf(f, "  features           %10s %10s %10s %9s %7s %7s\n", "precision", "recall", "F1", "TP",
          "FP", "FN");
}

static void features_text_row(FILE *f, const eval_ctx *e, int group) {
  const bsurf_feature_stats *s = &e->features[group];
  fprintf(f, "    %-16s %10.4f %10.4f %10.4f %9zu %7zu %7zu\n", group_names[group], s->precision,
          s->recall, s->f1, s->true_pos, s->false_pos, s->false_neg);
}

static const eval_section sections[] = {
    {"normals", normals_missing, normals_compute, normals_json, normals_text_header,
     normals_text_row},
    {"features", features_missing, features_compute, features_json, features_text_header,
     features_text_row},
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

static int run_split(eval_ctx *e) {
  const bsurf_field *f = bsurf_cloud_field(e->result, e->split_field);
  const char *where = e->result_path;
  if (!f) {
    f = bsurf_cloud_field(e->truth, e->split_field);
    where = e->truth_path;
  }
  if (!f)
    return cli_error("--split: neither %s nor %s has a field '%s'", e->result_path, e->truth_path,
                     e->split_field);
  size_t n = e->result->point_count, bad = 0;
  e->high = malloc(n ? n : 1);
  if (!e->high) return cli_error("out of memory");
  bsurf_status st = bsurf_quantile_split(f->values, n, e->split_q, e->high, &e->threshold,
                                         &e->group_points[GROUP_HIGH], &bad);
  if (st == BSURF_ERR_INVALID_VALUE)
    return cli_error("%s: field '%s' is NaN at point %zu (0-based)", where, e->split_field, bad);
  if (st != BSURF_OK) return cli_error("--split: %s", bsurf_strerror(st));
  e->group_points[GROUP_LOW] = n - e->group_points[GROUP_HIGH];
  return 0;
}

int cmd_eval(const cli_command *cmd, int argc, char **argv) {
  const char *truth_path = NULL, *split = NULL;
  int json = 0, quiet = 0;
  cli_option opts[] = {
      {0, "truth", ARG_STRING, &truth_path, "FILE",
       "ground truth: the same points in the same order", 1, 0},
      {0, "split", ARG_STRING, &split, "FIELD:Q",
       "also summarise the points whose FIELD is above its Q-quantile (high) and the rest (low)", 1,
       0},
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int npos;
  int rc = cli_parse(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, 1, &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos != 1) return cli_usage_error(cmd, "expected one RESULT file");
  if (!truth_path) return cli_usage_error(cmd, "missing --truth TRUTH");
  char split_field[BSURF_FIELD_NAME_MAX];
  double split_q = 0;
  if (split && parse_split(cmd, split, split_field, sizeof split_field, &split_q)) return CLI_USAGE;

  double t0 = cli_now();
  bsurf_cloud result, truth;
  bsurf_cloud_init(&result);
  bsurf_cloud_init(&truth);
  eval_ctx e;
  memset(&e, 0, sizeof e);
  if (cli_read_cloud(pos[0], &result)) return 1;
  if (cli_read_cloud(truth_path, &truth)) {
    bsurf_cloud_free(&result);
    return 1;
  }
  e.result_path = pos[0];
  e.truth_path = truth_path;
  e.result = &result;
  e.truth = &truth;
  e.group_points[GROUP_ALL] = result.point_count;
  int available[SECTION_COUNT], navailable = 0;
  char reasons[SECTION_COUNT][512];
  if (result.point_count != truth.point_count) {
    rc = cli_error("%s has %zu points but %s (the truth) has %zu; eval compares the same points in "
                   "the same order",
                   pos[0], result.point_count, truth_path, truth.point_count);
    goto done;
  }
  if (split) {
    e.split_field = split_field;
    e.split_q = split_q;
    if ((rc = run_split(&e)) != 0) goto done;
  }
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
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (!quiet) {
    printf("eval %s against %s: %zu points, %.2f s\n", pos[0], truth_path, result.point_count,
           secs);
    if (split)
      printf("  split by %s at quantile %g (threshold %.6g): high %zu points (above), low %zu\n",
             split_field, split_q, e.threshold, e.group_points[GROUP_HIGH],
             e.group_points[GROUP_LOW]);
    for (int s = 0; s < SECTION_COUNT; s++) {
      if (!available[s]) {
        printf("  %s: not evaluated: %s\n", sections[s].name, reasons[s]);
        continue;
      }
      sections[s].text_header(stdout);
      for (int g = 0; g < groups; g++)
        sections[s].text_row(stdout, &e, g);
    }
  }
done:
  free(e.high);
  bsurf_cloud_free(&result);
  bsurf_cloud_free(&truth);
  return rc;
}
