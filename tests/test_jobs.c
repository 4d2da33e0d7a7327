/* The jobs of include/bootsurf.h (issue 18): bsurf_normals_job,
 * bsurf_smooth_job and bsurf_features_job, each in memory and tiled on the
 * same noisy cube. The tiled output file must hold the bytes the in-memory
 * cloud writes (every field bit-identical), and the summaries the same
 * numbers (counts and h exactly; field means summed per tile agree to
 * rounding). Bad options: BSURF_ERR_INVALID_ARG with a message naming the
 * job and the parameter. Only the public header is used. */
// clang-format off
/* cmocka.h needs these first */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
// clang-format on

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bootsurf.h"
#include "test_util.h"

/* c written to path (the inputs below, made once), then freed: 1 */
static int written(const char *path, bsurf_cloud *c) {
  bsurf_failure err;
  assert_int_equal(bsurf_write(path, c, NULL, &err), BSURF_OK);
  bsurf_cloud_free(c);
  return 1;
}

/* The input: a noisy cube (sharp edges; its feature and feature_dist
 * fields are the truth the features job keeps as *_in), binary PLY. */
static const char *input_path(void) {
  static int made = 0;
  const char *path = tmp_path("jobs_cube.ply");
  if (!made) {
    bsurf_cloud c;
    assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 3000, BSURF_SAMPLING_RANDOM, 7, 2),
                     BSURF_OK);
    assert_int_equal(bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.3,
                                     sqrt(24.0 / (double)c.point_count), 3),
                     BSURF_OK);
    made = written(path, &c);
  }
  return path;
}

/* The cylinder sampled on rings 8 spacings apart of test_util.h
 * (ring_cylinder): the guard's sheet fits read none of the noise there,
 * most points are section-sampled, and it takes the K selection's reading
 * (test_smooth's test_noise_rings). */
static const char *rings_path(void) {
  static int made = 0;
  const char *path = tmp_path("jobs_rings.ply");
  if (!made) {
    bsurf_cloud c;
    bsurf_cloud_init(&c);
    c.xyz = malloc(3600 * 3 * sizeof(double));
    c.normals = malloc(3600 * 3 * sizeof(double));
    assert_non_null(c.xyz);
    assert_non_null(c.normals);
    c.point_count = ring_cylinder(8, c.xyz, c.normals);
    assert_int_equal(c.point_count, 3600);
    made = written(path, &c);
  }
  return path;
}

/* the input of the in-memory and tiled pairs (pair_open) */
static const char *(*pair_input)(void) = input_path;

static void read_file(const char *path, char **data, size_t *size) {
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  fseek(f, 0, SEEK_END);
  *size = (size_t)ftell(f);
  fseek(f, 0, SEEK_SET);
  *data = malloc(*size ? *size : 1);
  assert_non_null(*data);
  assert_int_equal(fread(*data, 1, *size, f), *size);
  fclose(f);
}

/* The same bytes: every field of every point bit-identical. */
static void assert_same_file(const char *a, const char *b) {
  char *da, *db;
  size_t na, nb;
  read_file(a, &da, &na);
  read_file(b, &db, &nb);
  assert_int_equal(na, nb);
  if (memcmp(da, db, na) != 0) fail_msg("%s and %s differ", a, b);
  free(da);
  free(db);
}

/* One job run twice: in memory on the input read into c, and tiled (tiles
 * of about 700 points: several, with halos) into tiled_path. */
typedef struct pair {
  bsurf_cloud c;
  bsurf_job_io mem, tiled;
  char mem_path[1200], tiled_path[1200];
} pair;

static void pair_open(pair *p, const char *name) {
  bsurf_failure err;
  bsurf_cloud_init(&p->c);
  assert_int_equal(bsurf_read(pair_input(), &p->c, &err), BSURF_OK);
  char file[64];
  snprintf(file, sizeof file, "jobs_%s_mem.ply", name);
  snprintf(p->mem_path, sizeof p->mem_path, "%s", tmp_path(file));
  snprintf(file, sizeof file, "jobs_%s_tiled.ply", name);
  snprintf(p->tiled_path, sizeof p->tiled_path, "%s", tmp_path(file));
  memset(&p->mem, 0, sizeof p->mem);
  p->mem.cloud = &p->c;
  memset(&p->tiled, 0, sizeof p->tiled);
  p->tiled.input = pair_input();
  p->tiled.output = p->tiled_path;
  p->tiled.tile_points = 700;
}

/* After both runs: the in-memory cloud written holds the tiled file's bytes. */
static void pair_close(pair *p, size_t tiles) {
  bsurf_failure err;
  assert_true(tiles > 1);
  assert_int_equal(bsurf_write(p->mem_path, &p->c, NULL, &err), BSURF_OK);
  assert_same_file(p->mem_path, p->tiled_path);
  bsurf_cloud_free(&p->c);
}

/* the per-tile sums of the means: equal to rounding */
static void assert_means(const double *a, const double *b, int count) {
  for (int f = 0; f < count; f++)
    assert_true(fabs(a[f] - b[f]) <= 1e-12 * fabs(a[f]) + 1e-300);
}

static void run_normals(const bsurf_normals_job_options *o, const char *name) {
  pair p;
  pair_open(&p, name);
  bsurf_normals_job_summary sm, st;
  bsurf_failure err = {0, -1, ""};
  assert_int_equal(bsurf_normals_job(&p.mem, o, &sm, NULL), BSURF_OK);
  assert_int_equal(bsurf_normals_job(&p.tiled, o, &st, &err), BSURF_OK);
  assert_int_equal(sm.points, st.points);
  assert_memory_equal(&sm.h, &st.h, sizeof sm.h);
  assert_int_equal(sm.duplicates, st.duplicates);
  assert_memory_equal(&sm.report, &st.report, sizeof sm.report);
  assert_int_equal(sm.field_count, st.field_count);
  for (int f = 0; f < sm.field_count; f++)
    assert_string_equal(sm.field_names[f], st.field_names[f]);
  assert_means(sm.means, st.means, sm.field_count);
  pair_close(&p, st.tiles);
}

static void test_normals_job(void **state) {
  (void)state;
  bsurf_normals_job_options o = bsurf_normals_job_options_default();
  o.normals.k = 15;
  o.normals.bootstrap = 6;
  o.test_error = 1; /* two tiled stages: the reference normals first */
  run_normals(&o, "normals");
  /* the per-point choice of K (nested candidates in one pass) */
  const int ks[3] = {10, 15, 20};
  o.select_k = ks;
  o.select_k_count = 3;
  /* the default rule, AUTO, is MSE in memory and in tiles (four tiled
   * stages: the noise, its pool, the first choices, the choice): the same
   * bytes, whatever the pool */
  pair p;
  pair_open(&p, "normals_auto");
  bsurf_normals_job_summary sm, st;
  assert_int_equal(bsurf_normals_job(&p.mem, &o, &sm, NULL), BSURF_OK);
  assert_int_equal(sm.select_rule, BSURF_KSELECT_MSE);
  assert_int_equal(bsurf_normals_job(&p.tiled, &o, &st, NULL), BSURF_OK);
  assert_int_equal(st.select_rule, BSURF_KSELECT_MSE);
  pair_close(&p, st.tiles);
  run_normals(&o, "normals_mse");
  o.noise_pool = BSURF_NOISE_POOL_LOCAL;
  o.normals.bootstrap = 0;
  run_normals(&o, "normals_mse_local");
  o.noise_pool = BSURF_NOISE_POOL_GLOBAL;
  o.normals.bootstrap = 6;
  o.select_rule = BSURF_KSELECT_TEST_ERROR;
  run_normals(&o, "normals_select");
  /* and of the polynomial degree */
  const int ds[2] = {1, 2};
  o.normals.fit = BSURF_NORMAL_POLY;
  o.select_degree = ds;
  o.select_degree_count = 2;
  run_normals(&o, "normals_degree");
  /* the default rule with the degree: the joint MSE rule in memory (its
   * bootstrap at the chosen K and degree, bsurf_estimate_normals_at_kd),
   * and in tiles (the four stages of the PCA rule's), the same bytes */
  o.select_rule = BSURF_KSELECT_AUTO;
  pair_open(&p, "normals_degree_auto");
  assert_int_equal(bsurf_normals_job(&p.mem, &o, &sm, NULL), BSURF_OK);
  assert_int_equal(sm.select_rule, BSURF_KSELECT_MSE);
  const bsurf_field *fk = bsurf_cloud_field(&p.c, "k_selected");
  const bsurf_field *fd = bsurf_cloud_field(&p.c, "degree_selected");
  assert_non_null(fk);
  assert_non_null(fd);
  for (size_t i = 0; i < p.c.point_count; i++) {
    assert_true(fk->values[i] == 10 || fk->values[i] == 15 || fk->values[i] == 20);
    assert_true(fd->values[i] == 1 || fd->values[i] == 2);
  }
  assert_int_equal(bsurf_normals_job(&p.tiled, &o, &st, NULL), BSURF_OK);
  assert_int_equal(st.select_rule, BSURF_KSELECT_MSE);
  pair_close(&p, st.tiles);
  run_normals(&o, "normals_degree_mse");
}

/* o in memory, ot (NULL: o) in tiles: the same bytes */
static void run_smooth(const bsurf_smooth_job_options *o, const bsurf_smooth_job_options *ot,
                       const char *name) {
  pair p;
  pair_open(&p, name);
  bsurf_smooth_job_summary sm, st;
  bsurf_failure err = {0, -1, ""};
  assert_int_equal(bsurf_smooth_job(&p.mem, o, &sm, NULL), BSURF_OK);
  assert_int_equal(bsurf_smooth_job(&p.tiled, ot ? ot : o, &st, &err), BSURF_OK);
  assert_int_equal(sm.method, st.method);
  assert_null(p.c.normals); /* they belonged to the points before they moved */
  assert_int_equal(sm.points, st.points);
  assert_memory_equal(&sm.h, &st.h, sizeof sm.h);
  assert_string_equal(sm.estimator, st.estimator);
  assert_int_equal(sm.field_count, st.field_count);
  /* summed in index order in both: the same bits */
  assert_memory_equal(sm.means, st.means, (size_t)sm.field_count * sizeof(double));
  const bsurf_smooth_report *a = &sm.report, *b = &st.report;
  assert_memory_equal(&a->error, &b->error, sizeof a->error);
  assert_memory_equal(&a->mean_error, &b->mean_error, sizeof(double));
  if (o->smooth.method == BSURF_SMOOTH_NAIVE) { /* what the command prints of each */
    assert_memory_equal(&a->threshold, &b->threshold, sizeof(double));
    assert_int_equal(a->projected, b->projected);
    assert_true(a->projected > 0 && a->projected < sm.points);
  } else {
    assert_memory_equal(&a->h1, &b->h1, sizeof(double));
    assert_memory_equal(&a->h2, &b->h2, sizeof(double));
  }
  assert_int_equal(a->moved_points, b->moved_points);
  assert_memory_equal(&a->moved_mean, &b->moved_mean, sizeof(double));
  assert_memory_equal(&a->moved_max, &b->moved_max, sizeof(double));
  /* the guard's readings of the noise and the level it took */
  assert_memory_equal(&a->noise, &b->noise, sizeof(double));
  assert_memory_equal(&a->noise_fits, &b->noise_fits, sizeof(double));
  assert_memory_equal(&a->noise_select, &b->noise_select, sizeof(double));
  assert_memory_equal(&a->section_share, &b->section_share, sizeof(double));
  assert_int_equal(a->misfit_fits, b->misfit_fits);
  pair_close(&p, st.tiles);
}

/* The guard's second reading of the noise tile by tile: on the ring-sampled
 * cylinder the level taken is the selection's (the fits' reading is
 * blind), the same bits as in memory for naive and bilateral. */
static void test_smooth_job_rings(void **state) {
  (void)state;
  pair_input = rings_path;
  bsurf_smooth_job_options o = bsurf_smooth_job_options_default();
  o.smooth.error.bootstrap = 6;
  for (int m = 0; m < 2; m++) {
    o.smooth.method = m ? BSURF_SMOOTH_BILATERAL : BSURF_SMOOTH_NAIVE;
    run_smooth(&o, NULL, m ? "rings_bilateral" : "rings_naive");
    pair p;
    pair_open(&p, "rings_check");
    bsurf_smooth_job_summary s;
    assert_int_equal(bsurf_smooth_job(&p.mem, &o, &s, NULL), BSURF_OK);
    assert_true(s.report.noise == s.report.noise_select);
    assert_true(s.report.section_share > 0.05);
    assert_true(s.report.noise_fits < 0.1 * s.report.noise_select);
    bsurf_cloud_free(&p.c);
  }
  pair_input = input_path;
}

static void test_smooth_job(void **state) {
  (void)state;
  bsurf_smooth_job_options o = bsurf_smooth_job_options_default();
  o.smooth.error.k = 20;
  o.smooth.error.bootstrap = 6;
  o.smooth.h1 = 1.5; /* 1.5 h */
  o.h1_in_h = 1;
  /* the default, AUTO: bilateral in tiles, the bytes of BILATERAL in memory */
  assert_int_equal(o.smooth.method, BSURF_SMOOTH_AUTO);
  bsurf_smooth_job_options ob = o;
  ob.smooth.method = BSURF_SMOOTH_BILATERAL;
  run_smooth(&ob, &o, "bilateral");
  /* AUTO in memory: multipass, bit for bit */
  bsurf_smooth_job_options om = o;
  om.smooth.method = BSURF_SMOOTH_MULTIPASS;
  bsurf_cloud c[2];
  for (int r = 0; r < 2; r++) {
    bsurf_failure err;
    bsurf_cloud_init(&c[r]);
    assert_int_equal(bsurf_read(input_path(), &c[r], &err), BSURF_OK);
    bsurf_job_io io = {0};
    io.cloud = &c[r];
    bsurf_smooth_job_summary s;
    assert_int_equal(bsurf_smooth_job(&io, r ? &om : &o, &s, NULL), BSURF_OK);
    assert_int_equal(s.method, BSURF_SMOOTH_MULTIPASS);
    assert_int_equal(s.field_count, 5);
  }
  assert_memory_equal(c[0].xyz, c[1].xyz, c[0].point_count * 3 * sizeof(double));
  for (int r = 0; r < 2; r++)
    bsurf_cloud_free(&c[r]);
  o.smooth.method = BSURF_SMOOTH_NAIVE;
  o.smooth.threshold = 0.8; /* 0.8 h */
  o.threshold_in_h = 1;
  run_smooth(&o, NULL, "naive");
}

static void run_features(const bsurf_feature_options *o, const char *name) {
  pair p;
  pair_open(&p, name);
  bsurf_features_job_summary sm, st;
  bsurf_failure err = {0, -1, ""};
  assert_int_equal(bsurf_features_job(&p.mem, o, &sm, NULL), BSURF_OK);
  assert_int_equal(bsurf_features_job(&p.tiled, o, &st, &err), BSURF_OK);
  assert_int_equal(sm.points, st.points);
  assert_memory_equal(&sm.h, &st.h, sizeof sm.h);
  assert_string_equal(sm.field_names[1], st.field_names[1]);
  /* the generated cube's truth: kept as feature_in (and feature_dist_in) */
  assert_int_equal(sm.kept[0], 1);
  assert_int_equal(st.kept[0], 1);
  assert_int_equal(sm.kept[1], st.kept[1]);
  assert_non_null(bsurf_cloud_field(&p.c, "feature_in"));
  assert_memory_equal(&sm.report.threshold, &st.report.threshold, sizeof(double));
  assert_int_equal(sm.report.feature_points, st.report.feature_points);
  assert_true(sm.report.feature_points > 0 && sm.report.feature_points < sm.points);
  if (o->method == BSURF_FEATURES_DISTANCE) {
    assert_memory_equal(&sm.report.max_radius, &st.report.max_radius, sizeof(double));
    assert_int_equal(sm.report.immediate, st.report.immediate);
  }
  /* the null rule's numbers: equal, and NAN in both where the method or
   * rule has none (bootsurf.h; a tiled run once left them 0) */
  const double *fm[] = {&sm.report.noise_level,      &sm.report.edge_power,
                        &sm.report.border_threshold, &sm.report.quadric_threshold,
                        &sm.report.quadric_power,    &sm.report.quadric_noise},
               *ft[] = {&st.report.noise_level,      &st.report.edge_power,
                        &st.report.border_threshold, &st.report.quadric_threshold,
                        &st.report.quadric_power,    &st.report.quadric_noise};
  const int null_rule = o->method == BSURF_FEATURES_VARIANCE && isnan(o->threshold) &&
                        o->tail_rule == BSURF_TAIL_NULL;
  for (int f = 0; f < 6; f++) {
    if (isnan(*fm[f]))
      assert_true(isnan(*ft[f]));
    else
      assert_memory_equal(fm[f], ft[f], sizeof(double));
    if (!null_rule) assert_true(isnan(*fm[f]));
  }
  assert_int_equal(sm.report.quadric_k, st.report.quadric_k);
  assert_int_equal(sm.report.quadric_cleared, st.report.quadric_cleared);
  assert_int_equal(sm.report.border_points, st.report.border_points);
  if (!null_rule) assert_int_equal(sm.report.border_points, 0);
  pair_close(&p, st.tiles);
}

static void test_features_job(void **state) {
  (void)state;
  bsurf_feature_options o = bsurf_feature_options_default();
  o.k_min = 10;
  o.k_max = 24;
  o.iterations = 2;
  run_features(&o, "distance");
  o.method = BSURF_FEATURES_VARIANCE;
  o.normals.k = 15;
  o.normals.bootstrap = 6;
  run_features(&o, "variance");
  o.tail_rule = BSURF_TAIL_OTSU;
  run_features(&o, "variance_otsu");
}

static void test_bad_options(void **state) {
  (void)state;
  pair p;
  pair_open(&p, "bad");
  bsurf_job_io mem = p.mem, tiled = p.tiled;
  bsurf_job_io none = {0};
  bsurf_normals_job_summary ns;
  bsurf_normals_job_options no = bsurf_normals_job_options_default();
  assert_invalid(bsurf_normals_job(NULL, &no, &ns, NULL), "bsurf_normals_job", "io is NULL");
  assert_invalid(bsurf_normals_job(&none, &no, &ns, NULL), "bsurf_normals_job", "neither");
  no.normals.k = 2;
  assert_invalid(bsurf_normals_job(&mem, &no, &ns, NULL), "bsurf_normals_job",
                 "opts->normals.k = 2");
  no = bsurf_normals_job_options_default();
  const int down[2] = {20, 10};
  no.select_k = down;
  no.select_k_count = 2;
  assert_invalid(bsurf_normals_job(&mem, &no, &ns, NULL), "bsurf_normals_job",
                 "opts->select_k[1] = 10");
  no = bsurf_normals_job_options_default();
  no.alpha = 2;
  assert_invalid(bsurf_normals_job(&mem, &no, &ns, NULL), "bsurf_normals_job", "opts->alpha = 2");
  no = bsurf_normals_job_options_default();
  no.orient = BSURF_ORIENT_MST;
  assert_invalid(bsurf_normals_job(&tiled, &no, &ns, NULL), "bsurf_normals_job", "in memory only");
  no = bsurf_normals_job_options_default();
  no.normals.k = 4000; /* more than the 3000 points */
  assert_int_equal(bsurf_normals_job(&mem, &no, &ns, NULL), BSURF_ERR_TOO_FEW_POINTS);
  assert_non_null(strstr(bsurf_last_message(), "fewer than K = 4000"));

  bsurf_smooth_job_summary ss;
  bsurf_smooth_job_options so = bsurf_smooth_job_options_default();
  so.smooth.method = (bsurf_smooth_method)7;
  assert_invalid(bsurf_smooth_job(&mem, &so, &ss, NULL), "bsurf_smooth_job",
                 "opts->smooth.method = 7");
  so = bsurf_smooth_job_options_default();
  so.smooth.error.k = 5; /* degree 3 needs 10 */
  assert_invalid(bsurf_smooth_job(&mem, &so, &ss, NULL), "bsurf_smooth_job",
                 "opts->smooth.error.k = 5");
  so = bsurf_smooth_job_options_default();
  so.smooth.method = BSURF_SMOOTH_MULTIPASS;
  assert_invalid(bsurf_smooth_job(&tiled, &so, &ss, NULL), "bsurf_smooth_job", "MULTIPASS");

  bsurf_features_job_summary fs;
  bsurf_feature_options fo = bsurf_feature_options_default();
  fo.method = (bsurf_feature_method)5;
  assert_invalid(bsurf_features_job(&mem, &fo, &fs, NULL), "bsurf_features_job",
                 "opts->method = 5");
  fo = bsurf_feature_options_default();
  fo.method = BSURF_FEATURES_DISTANCE;
  fo.k_max = fo.k_min - 1;
  assert_invalid(bsurf_features_job(&mem, &fo, &fs, NULL), "bsurf_features_job", "opts->k_max");
  fo = bsurf_feature_options_default();
  fo.feature_angle = 200;
  assert_invalid(bsurf_features_job(&mem, &fo, &fs, NULL), "bsurf_features_job",
                 "opts->feature_angle = 200 must be in [0, 180)");
  fo = bsurf_feature_options_default();
  fo.variance_k_max = -1;
  assert_invalid(bsurf_features_job(&mem, &fo, &fs, NULL), "bsurf_features_job",
                 "opts->variance_k_max = -1 must be in [0, 65535]");
  fo = bsurf_feature_options_default();
  fo.method = BSURF_FEATURES_VARIANCE;
  fo.normals.bootstrap = 1;
  assert_invalid(bsurf_features_job(&mem, &fo, &fs, NULL), "bsurf_features_job",
                 "opts->normals.bootstrap = 1");
  assert_invalid(bsurf_features_job(&mem, NULL, NULL, NULL), "bsurf_features_job",
                 "summary is NULL");
  /* nothing was added to the cloud by the refused calls */
  assert_null(bsurf_cloud_field(&p.c, "normal_var"));
  bsurf_cloud_free(&p.c);
}

/* bsurf_smooth_job_memory: the bytes per point of smooth's arrays, counted
 * from its allocations (smooth_stages.c, bsurf_smooth_stage1_bytes and
 * bsurf_smooth_passes_bytes), with the scale rule's K_max */
static void test_smooth_plan(void **state) {
  (void)state;
  bsurf_smooth_job_plan sp;
  /* the defaults: multipass (AUTO in memory), K = 50, degree 3 (m = 10),
   * the guard, the stop rule, the parallel order; the scale rule's cap 8 K:
   * smoothed 24; stage 1 (guard 32, fits 8 x 27, degrees 4) at 50 held
   * while the 400-neighbour table (1600 + 4) and multipass at 400 run
   * (stage 1 252, passes 36 + 84 + 8 x 400) */
  assert_int_equal(bsurf_smooth_job_memory(NULL, &sp), BSURF_OK);
  assert_int_equal(sp.method, BSURF_SMOOTH_MULTIPASS);
  assert_int_equal(sp.k, 50);
  assert_int_equal(sp.k_max, 400);
  assert_int_equal(sp.field_count, 5);
  assert_true(sp.point_bytes == 24 + 252 + 1604 + 252 + 120 + 3200);
  assert_true(sp.k_max_bytes == 12);
  bsurf_smooth_job_options o = bsurf_smooth_job_options_default();
  o.smooth.k_max = 100;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_int_equal(sp.k_max, 100);
  assert_true(sp.point_bytes == 24 + 252 + 404 + 252 + 120 + 800);
  /* K fixed (--k-max = K, or no guard): multipass at 50 only */
  o.smooth.k_max = 50;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_int_equal(sp.k_max, 50);
  assert_true(sp.point_bytes == 24 + 252 + 120 + 400 && sp.k_max_bytes == 0);
  o = bsurf_smooth_job_options_default();
  o.smooth.guard = 0;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_true(sp.k_max == 50 && sp.point_bytes == 24 + 220 + 120 + 400);
  /* a fixed pass count: the time blocks' maps, 4 bytes a thread */
  o = bsurf_smooth_job_options_default();
  o.smooth.iterations = 10;
  o.smooth.error.threads = 2;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_true(sp.point_bytes == 24 + 252 + 1604 + 252 + 128 + 3200);
  /* the sequential sweep: no reverse lists; the stop rule's copy 24 */
  o = bsurf_smooth_job_options_default();
  o.smooth.order = BSURF_ORDER_SEQUENTIAL;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_true(sp.point_bytes == 24 + 252 + 1604 + 252 + 60 && sp.k_max_bytes == 4);
  /* bilateral (fits 8 x 24 + 4, guard 32; e2, w2, reverse lists 8 + 4 K) and
   * naive (the guard's records): below the guard's second reading of the
   * noise, the 80-neighbourhoods (4 x 80, their order 4) and its passes'
   * values (32) held with stage 1's records */
  o = bsurf_smooth_job_options_default();
  o.smooth.method = BSURF_SMOOTH_BILATERAL;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_true(sp.method == BSURF_SMOOTH_BILATERAL && sp.k_max == 50 && sp.field_count == 3);
  assert_true(sp.point_bytes == 24 + 228 + 320 + 4 + 32);
  o.smooth.guard = 0; /* no second reading */
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_true(sp.point_bytes == 24 + 196 + 224);
  o.smooth.guard = 1;
  o.smooth.method = BSURF_SMOOTH_NAIVE;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_OK);
  assert_true(sp.point_bytes == 24 + 32 + 320 + 4 + 32);
  /* refused as the job refuses them */
  o = bsurf_smooth_job_options_default();
  o.smooth.k_max = 20;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_ERR_INVALID_ARG);
  assert_non_null(strstr(bsurf_last_message(), "k_max = 20"));
  o.smooth.k_max = 0;
  o.smooth.k_min = 2;
  assert_int_equal(bsurf_smooth_job_memory(&o, &sp), BSURF_ERR_INVALID_ARG);
  assert_int_equal(bsurf_smooth_job_memory(NULL, NULL), BSURF_ERR_INVALID_ARG);
}

/* bsurf_normals_job_memory: the rule resolved, K_max, the fields and the
 * bytes a point, exactly (the sums of the allocations its comment lists),
 * for known settings; bad options refused by name. */
static void test_normals_plan(void **state) {
  (void)state;
  bsurf_normals_job_plan jp;
  /* the defaults: PCA, K = 30, B = 50, no selection: the normals, normal_var
   * and normal_err buffers (40 bytes) */
  assert_int_equal(bsurf_normals_job_memory(NULL, &jp), BSURF_OK);
  assert_int_equal(jp.select_rule, BSURF_KSELECT_TEST_ERROR);
  assert_int_equal(jp.k_max, 30);
  assert_int_equal(jp.field_count, 1); /* normal_var */
  assert_true(jp.point_bytes == 40 && jp.cloud_bytes == 0);
  bsurf_normals_job_options o = bsurf_normals_job_options_default();
  const int ks[4] = {10, 20, 30, 40}, ds[2] = {1, 2};
  o.select_k = ks;
  o.select_k_count = 4;
  o.normals.bootstrap = 0;
  /* AUTO with candidates >= 7: MSE; 40 + 64 + 8 + 364 with 4 PCA
   * candidates, the global median's 24 bytes a point of the cloud when
   * tiled (two pooled values and the median's copy) */
  assert_int_equal(bsurf_normals_job_memory(&o, &jp), BSURF_OK);
  assert_int_equal(jp.select_rule, BSURF_KSELECT_MSE);
  assert_int_equal(jp.k_max, 40);
  assert_int_equal(jp.field_count, 3); /* normal_err, k_selected, two_sheet */
  assert_true(jp.point_bytes == 476 && jp.cloud_bytes == 24);
  o.noise_k = 50; /* beyond the candidates: K_max */
  o.noise_pool = BSURF_NOISE_POOL_LOCAL;
  assert_int_equal(bsurf_normals_job_memory(&o, &jp), BSURF_OK);
  assert_int_equal(jp.k_max, 50);
  assert_true(jp.point_bytes == 476 && jp.cloud_bytes == 0);
  /* POLY with two degrees: 8 candidates, 40 more bytes each, no empirical
   * bias (32 fewer) */
  o = bsurf_normals_job_options_default();
  o.select_k = ks;
  o.select_k_count = 4;
  o.select_degree = ds;
  o.select_degree_count = 2;
  o.normals.fit = BSURF_NORMAL_POLY;
  assert_int_equal(bsurf_normals_job_memory(&o, &jp), BSURF_OK);
  assert_int_equal(jp.select_rule, BSURF_KSELECT_MSE);
  assert_int_equal(jp.field_count, 4); /* normal_var, normal_err, k and degree */
  assert_true(jp.point_bytes == 604 && jp.cloud_bytes == 24);
  /* AUTO with a candidate below 7: the test error; its reference normals
   * (24) and selection arrays (64 + 8) */
  const int small[2] = {6, 20};
  o = bsurf_normals_job_options_default();
  o.select_k = small;
  o.select_k_count = 2;
  o.k_ref = 45;
  assert_int_equal(bsurf_normals_job_memory(&o, &jp), BSURF_OK);
  assert_int_equal(jp.select_rule, BSURF_KSELECT_TEST_ERROR);
  assert_int_equal(jp.k_max, 45);
  assert_true(jp.point_bytes == 136 && jp.cloud_bytes == 0);
  /* the curve: every candidate's error and variance, and with the truth its
   * normal (16 + 24 per candidate) */
  bsurf_normals_curve_row rows[2];
  o.curve = rows;
  assert_int_equal(bsurf_normals_job_memory(&o, &jp), BSURF_OK);
  assert_true(jp.point_bytes == 136 + 32);
  const double truth[3] = {0, 0, 1};
  o.curve_truth = truth;
  assert_int_equal(bsurf_normals_job_memory(&o, &jp), BSURF_OK);
  assert_true(jp.point_bytes == 136 + 32 + 48);
  /* bad options: the job's checks, named as this function's */
  assert_invalid(bsurf_normals_job_memory(&o, NULL), "bsurf_normals_job_memory", "plan");
  o = bsurf_normals_job_options_default();
  o.alpha = 2;
  assert_invalid(bsurf_normals_job_memory(&o, &jp), "bsurf_normals_job_memory", "opts->alpha = 2");
  o = bsurf_normals_job_options_default();
  o.select_rule = BSURF_KSELECT_MSE; /* without candidates */
  assert_invalid(bsurf_normals_job_memory(&o, &jp), "bsurf_normals_job_memory",
                 "needs opts->select_k");
  o.select_k = small; /* a candidate below 7 */
  o.select_k_count = 2;
  assert_invalid(bsurf_normals_job_memory(&o, &jp), "bsurf_normals_job_memory",
                 "candidates K >= 7");
}

int main(void) {
  tmp_dir_init();
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_normals_job),      cmocka_unit_test(test_smooth_job),
      cmocka_unit_test(test_smooth_job_rings), cmocka_unit_test(test_features_job),
      cmocka_unit_test(test_bad_options),      cmocka_unit_test(test_normals_plan),
      cmocka_unit_test(test_smooth_plan),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
