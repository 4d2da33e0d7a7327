/* Tiled runs (bsurf_tiles_run, src/tile/tiles.c): the output file is the
 * in-memory run's, byte for byte, and h is the same double, for tiles down
 * to the smallest allowed size (many tile borders), on uniform and very
 * non-uniform clouds (a dense cluster, far outliers, exact duplicates),
 * extra properties of every type, and big-endian input; bad inputs give the
 * in-memory reader's errors and no output. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bootsurf.h"
#include "algo/smooth_stages.h"
#include "tile/tile_engine.h"
#include "test_util.h"

static const char *const names[4] = {"err_632", "err_632plus", "err_loo", "gamma"};

typedef struct job {
  bsurf_error_options eo;
  int normals; /* 1: normals (normal_var) instead of error */
  int cancel_after;
  int calls;
} job;

/* error with K, degree, B and threads */
static job error_job(int k, int degree, int bootstrap, int threads) {
  job j = {bsurf_error_options_default(), 0, 0, 0};
  j.eo.k = k;
  j.eo.degree = degree;
  j.eo.bootstrap = bootstrap;
  j.eo.threads = threads;
  return j;
}

static bsurf_status prepare(void *user, bsurf_cloud *c) {
  const job *j = user;
  if (j->normals) {
    if (!c->normals) {
      c->normals = calloc(3 * c->point_count, sizeof(double));
      c->normal_type = BSURF_FLOAT32;
    }
    return bsurf_cloud_add_field(c, "normal_var", BSURF_FLOAT32) ? BSURF_OK : BSURF_ERR_NOMEM;
  }
  for (int f = 0; f < 4; f++)
    if (!bsurf_cloud_add_field(c, names[f], f == 3 ? BSURF_FLOAT64 : BSURF_FLOAT32))
      return BSURF_ERR_NOMEM;
  return BSURF_OK;
}

/* The computation on any cloud: the whole one (point_index NULL) or a tile. */
static bsurf_status compute(const job *j, const double *xyz, const bsurf_neighbors *nb,
                            const uint64_t *point_index, bsurf_cloud *c) {
  if (j->normals) {
    bsurf_normal_options no = bsurf_normal_options_default();
    no.k = j->eo.k;
    no.bootstrap = 7;
    no.point_index = point_index;
    bsurf_normal_fields out = {c->normals, bsurf_cloud_field(c, "normal_var")->values, NULL};
    return bsurf_estimate_normals(xyz, nb, NULL, &no, &out, NULL);
  }
  bsurf_error_options eo = j->eo;
  eo.point_index = point_index;
  bsurf_error_fields out;
  memset(&out, 0, sizeof out);
  out.err_632 = bsurf_cloud_field(c, names[0])->values;
  out.err_632plus = bsurf_cloud_field(c, names[1])->values;
  out.err_loo = bsurf_cloud_field(c, names[2])->values;
  out.gamma = bsurf_cloud_field(c, names[3])->values;
  return bsurf_estimate_error(xyz, nb, NULL, &eo, &out, NULL);
}

static bsurf_status run(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  job *j = user;
  sums[0] += (double)t->core_count;
  assert_true(t->local_count >= t->core_count);
  return compute(j, t->xyz, t->nb, t->point_index, core);
}

static int cancel_progress(void *user, size_t done, size_t total) {
  job *j = user;
  (void)done;
  (void)total;
  return ++j->calls > j->cancel_after;
}

/* The in-memory reference: read, neighbourhoods, compute, write. */
static void reference(const char *in, const char *out, job *j, double *h, size_t *dups) {
  bsurf_cloud c;
  bsurf_failure err;
  assert_int_equal(bsurf_read(in, &c, &err), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, j->eo.k, 2, NULL, NULL),
                   BSURF_OK);
  assert_int_equal(prepare(j, &c), BSURF_OK);
  assert_int_equal(compute(j, c.xyz, &nb, NULL, &c), BSURF_OK);
  assert_int_equal(bsurf_write(out, &c, NULL, &err), BSURF_OK);
  *h = nb.h;
  *dups = 0;
  for (size_t i = 0; i < c.point_count; i++) {
    const double *a = c.xyz + 3 * i, *b = c.xyz + 3 * (size_t)nb.idx[i * (size_t)nb.k + 1];
    *dups += a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
  }
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
}

static unsigned char *slurp(const char *path, size_t *n) {
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  fseek(f, 0, SEEK_END);
  long len = ftell(f);
  fseek(f, 0, SEEK_SET);
  unsigned char *buf = malloc((size_t)len + 1);
  assert_int_equal(fread(buf, 1, (size_t)len, f), (size_t)len);
  fclose(f);
  *n = (size_t)len;
  return buf;
}

static void assert_same_file(const char *a, const char *b) {
  size_t na, nb;
  unsigned char *x = slurp(a, &na), *y = slurp(b, &nb);
  assert_int_equal(na, nb);
  size_t first = na;
  for (size_t i = 0; i < na; i++)
    if (x[i] != y[i]) {
      first = i;
      break;
    }
  if (first != na) fail_msg("%s and %s differ at byte %zu", a, b, first);
  free(x);
  free(y);
}

static bsurf_status tiled_ranges(const char *in, const char *out, job *j, size_t tile_points,
                                 size_t range_points, bsurf_tile_report *rep, double *sums) {
  bsurf_tile_ops ops;
  memset(&ops, 0, sizeof ops);
  ops.tile_points = tile_points;
  ops.range_points = range_points;
  ops.k = j->eo.k;
  ops.threads = 2;
  ops.user = j;
  ops.prepare = prepare;
  ops.run = run;
  ops.nsums = 1;
  if (j->cancel_after) {
    ops.progress = cancel_progress;
    ops.progress_user = j;
  }
  rep->sums = sums;
  bsurf_failure err;
  return bsurf_tiles_run(in, out, &ops, rep, &err);
}

static bsurf_status tiled(const char *in, const char *out, job *j, size_t tile_points,
                          bsurf_tile_report *rep, double *sums) {
  return tiled_ranges(in, out, j, tile_points, 0, rep, sums);
}

/* Every tile size gives the reference's bytes and h. */
static void check_tiles(const char *in, job *j, const size_t *sizes, int nsizes) {
  double h;
  size_t dups;
  reference(in, tmp_path("ref.ply"), j, &h, &dups);
  for (int s = 0; s < 2 * nsizes; s++) {
    bsurf_tile_report rep;
    double sums[1] = {0};
    /* the output assembled at once (one range here), then in ranges of 97
     * points (every tile's rows spread over many) */
    size_t range = s < nsizes ? 0 : 97;
    assert_int_equal(
        tiled_ranges(in, tmp_path("tiled.ply"), j, sizes[s % nsizes], range, &rep, sums), BSURF_OK);
    assert_same_file(tmp_path("ref.ply"), tmp_path("tiled.ply"));
    assert_true(rep.h == h); /* the same double */
    assert_int_equal(rep.duplicates, dups);
    assert_int_equal((size_t)sums[0], rep.points);
    if (sizes[s % nsizes] < rep.points / 4) assert_true(rep.tiles > 2);
  }
}

/* A noisy sphere with extra properties of every type. */
static void write_uniform(const char *path, size_t n) {
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, n, BSURF_SAMPLING_RANDOM, 5, 0),
                   BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.5, 0.02, 9),
      BSURF_OK);
  static const bsurf_type types[] = {BSURF_INT8,  BSURF_UINT8,  BSURF_INT16,   BSURF_UINT16,
                                     BSURF_INT32, BSURF_UINT32, BSURF_FLOAT32, BSURF_FLOAT64};
  for (int t = 0; t < 8; t++) {
    char name[16];
    snprintf(name, sizeof name, "extra%d", t);
    bsurf_field *f = bsurf_cloud_add_field(&c, name, types[t]);
    for (size_t i = 0; i < c.point_count; i++)
      f->values[i] = (double)((i * 37 + (size_t)t) % 100) - 20;
  }
  c.xyz_type = BSURF_FLOAT32; /* the scanner's usual float coordinates */
  bsurf_failure err;
  assert_int_equal(bsurf_write(path, &c, NULL, &err), BSURF_OK);
  bsurf_cloud_free(&c);
}

/* Density varying by 10^4: a sparse sphere, a dense ball inside a tile, a
 * plane strip, far outliers (their halos must grow), exact duplicates. */
static void write_nonuniform(const char *path) {
  bsurf_cloud s, c;
  assert_int_equal(bsurf_generate(&s, BSURF_SHAPE_SPHERE, 1500, BSURF_SAMPLING_RANDOM, 2, 0),
                   BSURF_OK);
  const size_t dense = 2500, strip = 1200, far = 7, dup = 40;
  size_t n = s.point_count + dense + strip + far + dup;
  assert_int_equal(bsurf_cloud_alloc(&c, n, 0), BSURF_OK);
  memcpy(c.xyz, s.xyz, 3 * s.point_count * sizeof(double));
  bsurf_rng r;
  bsurf_rng_init(&r, 7, 0, 0);
  size_t m = s.point_count;
  for (size_t i = 0; i < dense; i++, m++)
    for (int a = 0; a < 3; a++)
      c.xyz[3 * m + a] = (a == 0 ? 0.99 : 0.0) + 0.003 * bsurf_rng_normal(&r);
  for (size_t i = 0; i < strip; i++, m++) {
    c.xyz[3 * m] = 2 + 3 * bsurf_rng_uniform(&r);
    c.xyz[3 * m + 1] = 0.05 * bsurf_rng_uniform(&r);
    c.xyz[3 * m + 2] = -1;
  }
  for (size_t i = 0; i < far; i++, m++) {
    c.xyz[3 * m] = 40 + 3.0 * (double)i;
    c.xyz[3 * m + 1] = -30;
    c.xyz[3 * m + 2] = 25 * (double)(i % 2);
  }
  for (size_t i = 0; i < dup; i++, m++)
    memcpy(&c.xyz[3 * m], &c.xyz[3 * (i * 97 % (m - 1))], 3 * sizeof(double));
  /* interleave the parts so global order is not spatial */
  for (size_t i = n - 1; i > 0; i--) {
    size_t j = bsurf_rng_below(&r, (uint32_t)(i + 1));
    double t[3];
    memcpy(t, &c.xyz[3 * i], sizeof t);
    memcpy(&c.xyz[3 * i], &c.xyz[3 * j], sizeof t);
    memcpy(&c.xyz[3 * j], t, sizeof t);
  }
  bsurf_failure err;
  assert_int_equal(bsurf_write(path, &c, NULL, &err), BSURF_OK);
  bsurf_cloud_free(&c);
  bsurf_cloud_free(&s);
}

static void test_uniform_error(void **state) {
  (void)state;
  write_uniform(tmp_path("uniform.ply"), 6000);
  job j = {bsurf_error_options_default(), 0, 0, 0};
  j.eo.k = 20;
  j.eo.bootstrap = 8;
  j.eo.threads = 2;
  const size_t sizes[] = {40, 150, 1000, 100000};
  check_tiles(tmp_path("uniform.ply"), &j, sizes, 4);
}

static void test_uniform_normals(void **state) {
  (void)state;
  write_uniform(tmp_path("uniform.ply"), 5000);
  job j = {bsurf_error_options_default(), 1, 0, 0};
  j.eo.k = 15;
  const size_t sizes[] = {30, 400};
  check_tiles(tmp_path("uniform.ply"), &j, sizes, 2);
}

static void test_nonuniform(void **state) {
  (void)state;
  write_nonuniform(tmp_path("nonuniform.ply"));
  job j = error_job(12, 2, 5, 2);
  const size_t sizes[] = {24, 90, 500, 3000};
  check_tiles(tmp_path("nonuniform.ply"), &j, sizes, 4);
  job jn = {bsurf_error_options_default(), 1, 0, 0};
  jn.eo.k = 10;
  const size_t nsizes[] = {20, 333};
  check_tiles(tmp_path("nonuniform.ply"), &jn, nsizes, 2);
}

/* A big-endian file with float coordinates and a short field. */
static void test_big_endian(void **state) {
  (void)state;
  bsurf_cloud s;
  assert_int_equal(bsurf_generate(&s, BSURF_SHAPE_TORUS, 3000, BSURF_SAMPLING_RANDOM, 4, 0),
                   BSURF_OK);
  FILE *f = fopen(tmp_path("be.ply"), "wb");
  fprintf(
      f,
      "ply\nformat binary_big_endian 1.0\nelement vertex %zu\nproperty short id\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n",
      s.point_count);
  for (size_t i = 0; i < s.point_count; i++) {
    unsigned char rec[14];
    uint16_t id = (uint16_t)(i % 3000);
    rec[0] = (unsigned char)(id >> 8);
    rec[1] = (unsigned char)id;
    for (int a = 0; a < 3; a++) {
      float v = (float)s.xyz[3 * i + a];
      uint32_t u;
      memcpy(&u, &v, 4);
      for (int b = 0; b < 4; b++)
        rec[2 + 4 * a + b] = (unsigned char)(u >> (24 - 8 * b));
    }
    fwrite(rec, 1, sizeof rec, f);
  }
  fclose(f);
  bsurf_cloud_free(&s);
  job j = {bsurf_error_options_default(), 0, 0, 0};
  j.eo.k = 16;
  j.eo.bootstrap = 4;
  const size_t sizes[] = {32, 700};
  check_tiles(tmp_path("be.ply"), &j, sizes, 2);
}

/* ---- two-stage runs (first-stage values, reverse-neighbour halos) ---- */

static const char *const smooth_names[3] = {"err_632", "err_632plus", "moved"};

typedef struct smooth_job {
  bsurf_smooth_options so; /* resolved before the second stage */
  size_t nv;
  double threshold; /* features: t_h */
  double noise;     /* smoothing: the guard's noise variance (bsurf_smooth_noise) */
} smooth_job;

static bsurf_status smooth_prepare(void *user, bsurf_cloud *c) {
  (void)user;
  for (int f = 0; f < 3; f++)
    if (!bsurf_cloud_add_field(c, smooth_names[f], BSURF_FLOAT32)) return BSURF_ERR_NOMEM;
  return BSURF_OK;
}

static bsurf_status smooth_run1(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  const smooth_job *j = user;
  (void)core;
  sums[0] += (double)t->core_count;
  bsurf_smooth_options so = j->so;
  so.error.point_index = t->point_index;
  return bsurf_smooth_stage1(t->xyz, t->nb, &so, t->values_out, NULL);
}

static void smooth_fill(const smooth_job *j, bsurf_cloud *c, const double *values,
                        const uint32_t *point, const double *out, const double *moved) {
  for (size_t r = 0; r < c->point_count; r++) {
    const double *v = &values[(point ? (size_t)point[r] : r) * j->nv];
    memcpy(&c->xyz[3 * r], &out[3 * r], 3 * sizeof(double));
    bsurf_cloud_field(c, smooth_names[0])->values[r] = v[0];
    bsurf_cloud_field(c, smooth_names[1])->values[r] = v[1];
    bsurf_cloud_field(c, smooth_names[2])->values[r] = moved[r];
  }
}

static bsurf_status smooth_run2(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  const smooth_job *j = user;
  sums[0] += (double)t->core_count;
  const size_t n = t->core_count;
  uint32_t *point = malloc(n * sizeof *point);
  double *out = malloc(3 * n * sizeof(double));
  /* every tile point lies in its own neighbourhood: its own list holds it */
  for (size_t r = 0; r < n; r++) {
    point[r] = t->nb->idx[r * (size_t)t->nb->k];
    int self = 0;
    for (size_t e = t->rev_off[r]; e < t->rev_off[r + 1]; e++)
      self |= t->rev[e] == point[r];
    assert_true(self);
  }
  bsurf_status st = bsurf_smooth_stage2(t->xyz, t->local_count, t->values, n, point, t->rev_off,
                                        t->rev, &j->so, j->noise, out, t->values_out);
  if (st == BSURF_OK) smooth_fill(j, core, t->values, point, out, t->values_out);
  free(point);
  free(out);
  return st;
}

static bsurf_status smooth_map(void *user, size_t first, bsurf_cloud *c, const double *values) {
  const smooth_job *j = user;
  (void)first;
  size_t n = c->point_count;
  double *out = malloc(3 * n * sizeof(double)), *moved = malloc(n * sizeof(double));
  bsurf_status st =
      bsurf_smooth_stage2(c->xyz, n, values, n, NULL, NULL, NULL, &j->so, j->noise, out, moved);
  if (st == BSURF_OK) smooth_fill(j, c, values, NULL, out, moved);
  free(out);
  free(moved);
  return st;
}

static bsurf_tile_ops stage_ops(void *user, int k, size_t tile_points) {
  bsurf_tile_ops ops;
  memset(&ops, 0, sizeof ops);
  ops.tile_points = tile_points;
  ops.k = k;
  ops.threads = 2;
  ops.user = user;
  ops.nsums = 1;
  return ops;
}

/* Tiled naive and bilateral (parallel order) smoothing: the in-memory
 * bsurf_smooth's file, byte for byte, for every tile size. */
static void check_smooth(const char *path, bsurf_smooth_options so, const size_t *sizes,
                         int nsizes) {
  char in[1200]; /* tmp_path's buffers are reused */
  snprintf(in, sizeof in, "%s", path);
  bsurf_cloud c;
  bsurf_failure err;
  assert_int_equal(bsurf_read(in, &c, &err), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, so.error.k, 2, NULL, NULL),
                   BSURF_OK);
  assert_int_equal(smooth_prepare(NULL, &c), BSURF_OK);
  bsurf_smooth_fields sf = {bsurf_cloud_field(&c, smooth_names[0])->values,
                            bsurf_cloud_field(&c, smooth_names[1])->values,
                            bsurf_cloud_field(&c, smooth_names[2])->values, NULL, NULL};
  double *out = malloc(3 * c.point_count * sizeof(double));
  bsurf_smooth_report ref;
  assert_int_equal(bsurf_smooth(c.xyz, &nb, &so, out, &sf, &ref), BSURF_OK);
  memcpy(c.xyz, out, 3 * c.point_count * sizeof(double));
  assert_int_equal(bsurf_write(tmp_path("sref.ply"), &c, NULL, &err), BSURF_OK);
  const size_t n = c.point_count;
  free(out);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  for (int s = 0; s < nsizes; s++) {
    smooth_job j = {so, bsurf_smooth_stage_values(&so), 0, NAN};
    bsurf_tile_values vals = {-1, 0, 0}, moved = {-1, 0, 0};
    bsurf_tile_ops ops = stage_ops(&j, so.error.k, sizes[s]);
    ops.run = smooth_run1;
    ops.nvalues = j.nv;
    ops.values_out = &vals;
    bsurf_tile_report rep;
    double sums[1] = {0};
    rep.sums = sums;
    assert_int_equal(bsurf_tiles_run(in, tmp_path("stage1"), &ops, &rep, &err), BSURF_OK);
    assert_true(rep.h == ref.h);
    assert_int_equal((size_t)sums[0], n);
    /* |W| in index order, as bsurf_smooth sums it */
    double *v = malloc(n * j.nv * sizeof(double)), sw = 0;
    assert_int_equal(bsurf_tile_values_read(&vals, 0, n, v), BSURF_OK);
    for (size_t i = 0; i < n; i++)
      sw += v[i * j.nv + (size_t)bsurf_smooth_w_column(&so)];
    /* the guard's noise from the stage values, as bsurf_smooth makes it */
    double *scratch = malloc(n * sizeof(double));
    j.noise = so.guard ? bsurf_smooth_noise(&v[j.nv - BSURF_SMOOTH_SV], n, j.nv, scratch) : NAN;
    if (so.guard) assert_true(sqrt(j.noise) == ref.noise);
    free(scratch);
    free(v);
    assert_true(sw / (double)n == ref.mean_error);
    bsurf_smooth_resolve(&j.so, rep.h, sw / (double)n, j.noise);
    ops.prepare = smooth_prepare;
    if (so.method == BSURF_SMOOTH_NAIVE) {
      ops.range_points = 97;
      assert_int_equal(bsurf_tiles_map(in, tmp_path("stiled.ply"), &ops, &vals, smooth_map, &err),
                       BSURF_OK);
    } else {
      ops.run = smooth_run2;
      ops.values_in = &vals;
      ops.reverse = 1;
      ops.nvalues = 1;
      ops.values_out = &moved;
      sums[0] = 0;
      assert_int_equal(bsurf_tiles_run(in, tmp_path("stiled.ply"), &ops, &rep, &err), BSURF_OK);
      assert_int_equal((size_t)sums[0], n);
      assert_int_equal(moved.count, n);
      if (sizes[s] < n / 4) assert_true(rep.tiles > 2);
    }
    assert_same_file(tmp_path("sref.ply"), tmp_path("stiled.ply"));
    bsurf_tile_values_close(&vals);
    bsurf_tile_values_close(&moved);
  }
}

static void test_smooth_two_stage(void **state) {
  (void)state;
  write_uniform(tmp_path("uniform.ply"), 4000);
  write_nonuniform(tmp_path("nonuniform.ply"));
  bsurf_smooth_options so = bsurf_smooth_options_default();
  so.error.k = 12;
  so.error.degree = 2;
  so.error.bootstrap = 5;
  so.error.threads = 2;
  const size_t sizes[] = {24, 90, 700};
  for (int m = 0; m < 2; m++) {
    so.method = m ? BSURF_SMOOTH_BILATERAL : BSURF_SMOOTH_NAIVE;
    check_smooth(tmp_path("uniform.ply"), so, sizes, 3);
    check_smooth(tmp_path("nonuniform.ply"), so, sizes, 3);
  }
  /* a wider distance sigma: more of the reverse neighbours weigh */
  so.h1 = 0.05;
  check_smooth(tmp_path("nonuniform.ply"), so, sizes, 2);
  /* not tiled: the sequential sweep and the multipass */
  so.order = BSURF_ORDER_SEQUENTIAL;
  assert_int_equal(bsurf_smooth_stage_values(&so), 0);
  so.order = BSURF_ORDER_PARALLEL;
  so.method = BSURF_SMOOTH_MULTIPASS;
  assert_int_equal(bsurf_smooth_stage_values(&so), 0);
}

/* features --method variance: normal_var per tile, the automatic tail
 * threshold over every value, feature at a streamed second stage. */
static bsurf_status var_run1(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  const smooth_job *j = user;
  (void)core;
  sums[0] += (double)t->core_count;
  bsurf_normal_options no = bsurf_normal_options_default();
  no.k = j->so.error.k;
  no.bootstrap = 6;
  no.threads = 2;
  no.point_index = t->point_index;
  bsurf_normal_fields nf = {NULL, t->values_out, NULL};
  return bsurf_estimate_normals(t->xyz, t->nb, NULL, &no, &nf, NULL);
}

static bsurf_status var_prepare(void *user, bsurf_cloud *c) {
  (void)user;
  return bsurf_cloud_add_field(c, "normal_var", BSURF_FLOAT32) &&
                 bsurf_cloud_add_field(c, "feature", BSURF_UINT8)
             ? BSURF_OK
             : BSURF_ERR_NOMEM;
}

static bsurf_status var_map(void *user, size_t first, bsurf_cloud *c, const double *values) {
  const smooth_job *j = user;
  (void)first;
  for (size_t i = 0; i < c->point_count; i++) {
    bsurf_cloud_field(c, "normal_var")->values[i] = values[i];
    bsurf_cloud_field(c, "feature")->values[i] = values[i] > j->threshold;
  }
  return BSURF_OK;
}

static void test_features_two_stage(void **state) {
  (void)state;
  write_nonuniform(tmp_path("nonuniform.ply"));
  char in[1200]; /* tmp_path's buffers are reused */
  snprintf(in, sizeof in, "%s", tmp_path("nonuniform.ply"));
  bsurf_cloud c;
  bsurf_failure err;
  assert_int_equal(bsurf_read(in, &c, &err), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, 14, 2, NULL, NULL), BSURF_OK);
  bsurf_feature_options fo = bsurf_feature_options_default();
  fo.method = BSURF_FEATURES_VARIANCE;
  /* the rule this sketch of two stages reproduces; the null rule, in three
   * stages, is bsurf_features_variance_tiled (cli_tiles checks it) */
  fo.tail_rule = BSURF_TAIL_OTSU;
  fo.normals.k = 14;
  fo.normals.bootstrap = 6;
  fo.threads = 2;
  const size_t n = c.point_count;
  uint8_t *feat = malloc(n);
  double *score = malloc(n * sizeof(double));
  bsurf_feature_report ref;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, &fo, feat, score, &ref), BSURF_OK);
  assert_int_equal(var_prepare(NULL, &c), BSURF_OK);
  for (size_t i = 0; i < n; i++) {
    bsurf_cloud_field(&c, "normal_var")->values[i] = score[i];
    bsurf_cloud_field(&c, "feature")->values[i] = feat[i];
  }
  assert_int_equal(bsurf_write(tmp_path("fref.ply"), &c, NULL, &err), BSURF_OK);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  const size_t sizes[] = {28, 333};
  for (int s = 0; s < 2; s++) {
    smooth_job j;
    memset(&j, 0, sizeof j);
    j.so.error.k = 14;
    bsurf_tile_values vals = {-1, 0, 0};
    bsurf_tile_ops ops = stage_ops(&j, 14, sizes[s]);
    ops.run = var_run1;
    ops.nvalues = 1;
    ops.values_out = &vals;
    bsurf_tile_report rep;
    double sums[1] = {0};
    rep.sums = sums;
    assert_int_equal(bsurf_tiles_run(in, tmp_path("stage1"), &ops, &rep, &err), BSURF_OK);
    assert_int_equal(bsurf_tile_values_read(&vals, 0, n, score), BSURF_OK);
    assert_int_equal(bsurf_tail_threshold(score, n, fo.tail_rule, &j.threshold), BSURF_OK);
    assert_true(j.threshold == ref.threshold);
    ops.prepare = var_prepare;
    assert_int_equal(bsurf_tiles_map(in, tmp_path("ftiled.ply"), &ops, &vals, var_map, &err),
                     BSURF_OK);
    assert_same_file(tmp_path("fref.ply"), tmp_path("ftiled.ply"));
    /* a second stage refuses values of another input */
    vals.count--;
    assert_int_equal(bsurf_tiles_map(in, tmp_path("fbad.ply"), &ops, &vals, var_map, &err),
                     BSURF_ERR_INVALID_ARG);
    assert_int_equal(access(tmp_path("fbad.ply"), F_OK), -1);
    bsurf_tile_values_close(&vals);
  }
  free(feat);
  free(score);
}

/* features --method distance (7.1): bsurf_features_distance_tiled gives
 * bsurf_detect_features's file and report, byte for byte and bit for bit. */
static bsurf_status fd_prepare(void *user, bsurf_cloud *c) {
  (void)user;
  static const char *const fd_names[2] = {"feature_dist", "feature"};
  for (int t = 0; t < 2; t++) { /* an input's fields are kept as NAME_in, as the CLI does */
    bsurf_field *old = bsurf_cloud_field(c, fd_names[t]);
    if (old) snprintf(old->name, sizeof old->name, "%s_in", fd_names[t]);
  }
  return bsurf_cloud_add_field(c, fd_names[0], BSURF_FLOAT32) &&
                 bsurf_cloud_add_field(c, fd_names[1], BSURF_UINT8)
             ? BSURF_OK
             : BSURF_ERR_NOMEM;
}

static int fd_cancel(void *user, size_t done, size_t total) {
  (void)done;
  (void)total;
  return --*(int *)user < 0;
}

/* returns the feature count */
static size_t check_distance(const char *path, const bsurf_feature_options *fo, const size_t *sizes,
                             int nsizes) {
  char in[1200], ref_path[1200]; /* tmp_path's buffers are reused */
  snprintf(in, sizeof in, "%s", path);
  snprintf(ref_path, sizeof ref_path, "%s", tmp_path("dref.ply"));
  bsurf_cloud c;
  bsurf_failure err;
  assert_int_equal(bsurf_read(in, &c, &err), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, fo->k_max, 2, NULL, NULL),
                   BSURF_OK);
  const size_t n = c.point_count;
  uint8_t *feat = malloc(n);
  double *score = malloc(n * sizeof(double));
  bsurf_feature_report ref;
  assert_int_equal(bsurf_detect_features(c.xyz, &nb, fo, feat, score, &ref), BSURF_OK);
  assert_int_equal(fd_prepare(NULL, &c), BSURF_OK);
  for (size_t i = 0; i < n; i++) {
    bsurf_cloud_field(&c, "feature_dist")->values[i] = score[i];
    bsurf_cloud_field(&c, "feature")->values[i] = feat[i];
  }
  assert_int_equal(bsurf_write(ref_path, &c, NULL, &err), BSURF_OK);
  const double h = nb.h;
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  free(feat);
  free(score);
  for (int s = 0; s < nsizes; s++) {
    bsurf_tile_ops ops = stage_ops(NULL, 0, sizes[s]);
    ops.prepare = fd_prepare;
    ops.range_points = s % 2 ? 97 : 0;
    bsurf_tile_report tr;
    bsurf_feature_report rep;
    assert_int_equal(
        bsurf_features_distance_tiled(in, tmp_path("dtiled.ply"), &ops, fo, &rep, &tr, &err),
        BSURF_OK);
    assert_same_file(ref_path, tmp_path("dtiled.ply"));
    assert_true(tr.h == h);
    assert_int_equal(tr.points, n);
    if (sizes[s] < n / 4) assert_true(tr.tiles > 2);
    assert_true(rep.threshold == ref.threshold);
    assert_true(rep.max_radius == ref.max_radius);
    assert_true(rep.ratio_threshold_kmin == ref.ratio_threshold_kmin);
    assert_int_equal(rep.feature_points, ref.feature_points);
    assert_int_equal(rep.immediate, ref.immediate);
  }
  return ref.feature_points;
}

static void test_features_distance(void **state) {
  (void)state;
  bsurf_cloud c;
  bsurf_failure err;
  /* the cube: sharp edges, noise 0.5 h (its feature fields are kept as _in) */
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_CUBE, 3000, BSURF_SAMPLING_RANDOM, 3, 0),
                   BSURF_OK);
  assert_int_equal(
      bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_UNIFORM, 0.5, 0.04, 4),
      BSURF_OK);
  assert_int_equal(bsurf_write(tmp_path("dcube.ply"), &c, NULL, &err), BSURF_OK);
  bsurf_cloud_free(&c);
  write_uniform(tmp_path("uniform.ply"), 3000);
  write_nonuniform(tmp_path("nonuniform.ply"));
  bsurf_feature_options fo = bsurf_feature_options_default();
  fo.method = BSURF_FEATURES_DISTANCE;
  fo.k_min = 6;
  fo.k_max = 24;
  fo.k_step = 3;
  fo.threads = 2;
  const size_t sizes[] = {48, 700, 300};
  const size_t edges = check_distance(tmp_path("dcube.ply"), &fo, sizes, 2);
  assert_true(edges > 100 && edges < 1500); /* the cube's edges, not everything */
  check_distance(tmp_path("uniform.ply"), &fo, sizes + 2, 1);
  check_distance(tmp_path("nonuniform.ply"), &fo, sizes, 2);
  /* non-default filters: more passes and neighbours, one neighbour (the
   * point alone), none; a fixed T_h; no noise factor with the derivative */
  fo.iterations = 4;
  fo.filter_k = 20;
  fo.alpha = 0.9;
  check_distance(tmp_path("dcube.ply"), &fo, sizes, 1);
  check_distance(tmp_path("nonuniform.ply"), &fo, sizes + 2, 1);
  fo.iterations = 1;
  fo.filter_k = 1;
  check_distance(tmp_path("dcube.ply"), &fo, sizes + 2, 1);
  fo.iterations = 0;
  fo.threshold = 0.3;
  check_distance(tmp_path("dcube.ply"), &fo, sizes + 2, 1);
  fo.iterations = 3;
  fo.filter_k = 0;
  fo.noise_factor = 0;
  fo.derivative = 0.5;
  check_distance(tmp_path("nonuniform.ply"), &fo, sizes, 1);
  /* refused: bad options, a cancelled chain; nothing written */
  fo = bsurf_feature_options_default();
  fo.method = BSURF_FEATURES_DISTANCE;
  bsurf_tile_ops ops = stage_ops(NULL, 0, 400);
  ops.prepare = fd_prepare;
  bsurf_tile_report tr;
  bsurf_feature_report rep;
  char out[1200];
  snprintf(out, sizeof out, "%s", tmp_path("drefused.ply"));
  unlink(out);
  fo.k_min = 2;
  assert_int_equal(
      bsurf_features_distance_tiled(tmp_path("dcube.ply"), out, &ops, &fo, &rep, &tr, &err),
      BSURF_ERR_INVALID_ARG);
  fo.k_min = 15;
  fo.method = BSURF_FEATURES_VARIANCE;
  assert_int_equal(
      bsurf_features_distance_tiled(tmp_path("dcube.ply"), out, &ops, &fo, &rep, &tr, &err),
      BSURF_ERR_INVALID_ARG);
  fo.method = BSURF_FEATURES_DISTANCE;
  /* the progress calls of a whole chain (one per tile and per range of
   * every stage), then cancelled in the first stage, in the middle (a
   * filter pass) and at the last call (the output's stage) */
  int left = 1 << 30;
  ops.progress = fd_cancel;
  ops.progress_user = &left;
  assert_int_equal(
      bsurf_features_distance_tiled(tmp_path("dcube.ply"), out, &ops, &fo, &rep, &tr, &err),
      BSURF_OK);
  assert_int_equal(remove(out), 0);
  const int calls = (1 << 30) - left;
  assert_true(calls > 7 * (int)tr.tiles);
  const int at[3] = {0, calls / 2, calls - 1};
  for (int a = 0; a < 3; a++) {
    left = at[a];
    assert_int_equal(
        bsurf_features_distance_tiled(tmp_path("dcube.ply"), out, &ops, &fo, &rep, &tr, &err),
        BSURF_ERR_CANCELLED);
    assert_int_equal(access(out, F_OK), -1);
  }
}

/* Bad inputs: the reader's errors, nothing written. */
static void test_refusals(void **state) {
  (void)state;
  job j = {bsurf_error_options_default(), 0, 0, 0};
  j.eo.k = 10;
  bsurf_tile_report rep;
  double sums[1];
  char out[1200];
  snprintf(out, sizeof out, "%s", tmp_path("refused.ply"));
  unlink(out);
  /* ascii */
  FILE *f = fopen(tmp_path("a.ply"), "w");
  fprintf(f, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
             "y\nproperty float z\n"
             "end_header\n0 0 0\n");
  fclose(f);
  assert_int_equal(tiled(tmp_path("a.ply"), out, &j, 100, &rep, sums), BSURF_ERR_UNSUPPORTED);
  /* a mesh */
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 200, BSURF_SAMPLING_RANDOM, 1, 0),
                   BSURF_OK);
  c.faces = calloc(3, sizeof(uint32_t));
  c.faces[1] = 1, c.faces[2] = 2;
  c.face_count = 1;
  bsurf_failure err;
  assert_int_equal(bsurf_write(tmp_path("mesh.ply"), &c, NULL, &err), BSURF_OK);
  assert_int_equal(tiled(tmp_path("mesh.ply"), out, &j, 100, &rep, sums), BSURF_ERR_UNSUPPORTED);
  free(c.faces);
  c.faces = NULL;
  c.face_count = 0;
  /* a NaN at point 123 */
  c.xyz[3 * 123 + 1] = NAN;
  assert_int_equal(bsurf_write(tmp_path("nan.ply"), &c, NULL, &err), BSURF_OK);
  assert_int_equal(tiled(tmp_path("nan.ply"), out, &j, 100, &rep, sums), BSURF_ERR_INVALID_VALUE);
  assert_int_equal(rep.bad_point, 123);
  /* truncated */
  c.xyz[3 * 123 + 1] = 0;
  assert_int_equal(bsurf_write(tmp_path("cut.ply"), &c, NULL, &err), BSURF_OK);
  assert_int_equal(truncate(tmp_path("cut.ply"), 900), 0);
  assert_int_equal(tiled(tmp_path("cut.ply"), out, &j, 100, &rep, sums), BSURF_ERR_PARSE);
  /* fewer points than K, tiles too small */
  j.eo.k = 500;
  assert_int_equal(bsurf_write(tmp_path("ok.ply"), &c, NULL, &err), BSURF_OK);
  assert_int_equal(tiled(tmp_path("ok.ply"), out, &j, 1000, &rep, sums), BSURF_ERR_TOO_FEW_POINTS);
  j.eo.k = 10;
  assert_int_equal(tiled(tmp_path("ok.ply"), out, &j, 19, &rep, sums), BSURF_ERR_INVALID_ARG);
  /* cancelled after the first tile */
  j.cancel_after = 1;
  assert_int_equal(tiled(tmp_path("ok.ply"), out, &j, 40, &rep, sums), BSURF_ERR_CANCELLED);
  assert_int_equal(access(out, F_OK), -1);
  /* cancelled while the output is assembled: one call per tile, then one
   * per range of 50 points; stopped at the second range */
  j.cancel_after = 1 << 30;
  j.calls = 0;
  assert_int_equal(tiled_ranges(tmp_path("ok.ply"), out, &j, 40, 50, &rep, sums), BSURF_OK);
  assert_int_equal(j.calls, (int)(rep.tiles + (rep.points + 49) / 50));
  assert_int_equal(remove(out), 0);
  j.cancel_after = (int)rep.tiles + 1;
  j.calls = 0;
  assert_int_equal(tiled_ranges(tmp_path("ok.ply"), out, &j, 40, 50, &rep, sums),
                   BSURF_ERR_CANCELLED);
  assert_int_equal(access(out, F_OK), -1);
  bsurf_cloud_free(&c);
}

/* ---- ranks as threads: the collectives of bsurf_tile_comm over shared
 * memory, so that the distributed code paths (split passes, split assembly)
 * run here, under the sanitizers, and are compared bit for bit ---------- */

#define MAX_RANKS 5

typedef struct fake_world {
  int ranks;
  pthread_barrier_t bar;
  const void *slot[MAX_RANKS];
} fake_world;

typedef struct fake_rank {
  fake_world *w;
  int rank;
  bsurf_tile_comm comm;
  /* the run */
  const char *in, *out;
  job j;
  size_t tile_points, range_points;
  int cancels; /* this rank's progress callback cancels (j.cancel_after) */
  bsurf_tile_report rep;
  double sums[1];
  bsurf_failure err;
  bsurf_status st;
} fake_rank;

static void fake_barrier(void *u) {
  fake_rank *r = u;
  pthread_barrier_wait(&r->w->bar);
}

/* every rank's pointer in the slots, between two barriers */
static void publish(fake_rank *r, const void *p) {
  r->w->slot[r->rank] = p;
  pthread_barrier_wait(&r->w->bar);
}

static void fake_sum(void *u, double *v, size_t n) {
  fake_rank *r = u;
  publish(r, v);
  double *t = calloc(n ? n : 1, sizeof *t);
  for (int q = 0; q < r->w->ranks; q++)
    for (size_t i = 0; i < n; i++)
      t[i] += ((const double *)r->w->slot[q])[i];
  pthread_barrier_wait(&r->w->bar);
  memcpy(v, t, n * sizeof *v);
  free(t);
}

/* sum over ranks [0, upto) of count uint64 */
static void fake_u64(fake_rank *r, uint64_t *v, size_t n, int upto) {
  publish(r, v);
  uint64_t *t = calloc(n ? n : 1, sizeof *t);
  for (int q = 0; q < upto; q++)
    for (size_t i = 0; i < n; i++)
      t[i] += ((const uint64_t *)r->w->slot[q])[i];
  pthread_barrier_wait(&r->w->bar);
  memcpy(v, t, n * sizeof *v);
  free(t);
}

static void fake_sum_u64(void *u, uint64_t *v, size_t n) {
  fake_rank *r = u;
  fake_u64(r, v, n, r->w->ranks);
}

static void fake_exscan_u64(void *u, uint64_t *v, size_t n) {
  fake_rank *r = u;
  fake_u64(r, v, n, r->rank);
}

static int fake_max(void *u, int v) {
  fake_rank *r = u;
  publish(r, &v);
  int m = v;
  for (int q = 0; q < r->w->ranks; q++)
    if (*(const int *)r->w->slot[q] > m) m = *(const int *)r->w->slot[q];
  pthread_barrier_wait(&r->w->bar);
  return m;
}

static void fake_broadcast(void *u, void *data, size_t bytes) {
  fake_rank *r = u;
  publish(r, data);
  if (r->rank != 0) memcpy(data, r->w->slot[0], bytes);
  pthread_barrier_wait(&r->w->bar);
}

static void fake_allgather(void *u, const void *mine, void *all, size_t bytes) {
  fake_rank *r = u;
  publish(r, mine);
  for (int q = 0; q < r->w->ranks; q++)
    memcpy((char *)all + (size_t)q * bytes, r->w->slot[q], bytes);
  pthread_barrier_wait(&r->w->bar);
}

static void *fake_main(void *u) {
  fake_rank *r = u;
  bsurf_tile_ops ops;
  memset(&ops, 0, sizeof ops);
  ops.tile_points = r->tile_points;
  ops.range_points = r->range_points;
  ops.k = r->j.eo.k;
  ops.threads = 1;
  ops.user = &r->j;
  ops.prepare = prepare;
  ops.run = run;
  ops.nsums = 1;
  ops.comm = &r->comm;
  if (r->cancels) {
    ops.progress = cancel_progress;
    ops.progress_user = &r->j;
  }
  r->rep.sums = r->sums;
  r->st = bsurf_tiles_run(r->in, r->out, &ops, &r->rep, &r->err);
  return NULL;
}

/* bsurf_tiles_run on `ranks` threads sharing a fake_world; rank 0's report,
 * status and error in *rep, return and *err; every rank's report must agree.
 * Rank cancel_rank (-1: none) cancels after j->cancel_after progress calls. */
static bsurf_status tiled_ranks(int ranks, const char *in, const char *out, const job *j,
                                size_t tile_points, size_t range_points, int cancel_rank,
                                bsurf_tile_report *rep, double *sum, bsurf_failure *err) {
  fake_world w;
  memset(&w, 0, sizeof w);
  w.ranks = ranks;
  assert_int_equal(pthread_barrier_init(&w.bar, NULL, (unsigned)ranks), 0);
  fake_rank r[MAX_RANKS];
  pthread_t th[MAX_RANKS];
  for (int q = 0; q < ranks; q++) {
    memset(&r[q], 0, sizeof r[q]);
    r[q].w = &w;
    r[q].rank = q;
    r[q].comm = (bsurf_tile_comm){.rank = q,
                                  .ranks = ranks,
                                  .user = &r[q],
                                  .barrier = fake_barrier,
                                  .sum = fake_sum,
                                  .max = fake_max,
                                  .broadcast = fake_broadcast,
                                  .allgather = fake_allgather,
                                  .sum_u64 = fake_sum_u64,
                                  .exscan_u64 = fake_exscan_u64};
    r[q].in = in;
    r[q].out = out;
    r[q].j = *j;
    r[q].tile_points = tile_points;
    r[q].range_points = range_points;
    r[q].cancels = q == cancel_rank;
    assert_int_equal(pthread_create(&th[q], NULL, fake_main, &r[q]), 0);
  }
  for (int q = 0; q < ranks; q++)
    assert_int_equal(pthread_join(th[q], NULL), 0);
  pthread_barrier_destroy(&w.bar);
  for (int q = 1; q < ranks; q++) {
    assert_int_equal(r[q].st, r[0].st);
    if (r[0].st == BSURF_OK) {
      assert_true(r[q].rep.h == r[0].rep.h);
      assert_true(r[q].sums[0] == r[0].sums[0]);
      assert_int_equal(r[q].rep.duplicates, r[0].rep.duplicates);
    }
  }
  *rep = r[0].rep;
  *sum = r[0].sums[0];
  *err = r[0].err;
  return r[0].st;
}

/* 1 to 5 ranks, with many ranges per rank: the serial run's bytes, h (the
 * same double), duplicates and sums; a NaN at a late point is reported as
 * in one process (the lowest bad index, the same message), nothing written. */
static void test_ranks(void **state) {
  (void)state;
  write_nonuniform(tmp_path("ranks.ply"));
  job j = error_job(12, 2, 3, 1);
  double h;
  size_t dups;
  reference(tmp_path("ranks.ply"), tmp_path("ranks_ref.ply"), &j, &h, &dups);
  bsurf_tile_report serial;
  double serial_sum[1] = {0};
  assert_int_equal(tiled_ranges(tmp_path("ranks.ply"), tmp_path("ranks_ser.ply"), &j, 300, 100,
                                &serial, serial_sum),
                   BSURF_OK);
  assert_same_file(tmp_path("ranks_ref.ply"), tmp_path("ranks_ser.ply"));
  const size_t ranges[] = {0, 100, 64};
  for (int ranks = 1; ranks <= MAX_RANKS; ranks++)
    for (int g = 0; g < 3; g++) {
      bsurf_tile_report rep;
      double sum;
      bsurf_failure err;
      unlink(tmp_path("ranks_out.ply"));
      assert_int_equal(tiled_ranks(ranks, tmp_path("ranks.ply"), tmp_path("ranks_out.ply"), &j, 300,
                                   ranges[g], -1, &rep, &sum, &err),
                       BSURF_OK);
      assert_same_file(tmp_path("ranks_ref.ply"), tmp_path("ranks_out.ply"));
      assert_true(rep.h == h);
      assert_int_equal(rep.duplicates, dups);
      assert_true(sum == serial_sum[0]); /* summed per tile in tile order */
      assert_int_equal(rep.tiles, serial.tiles);
    }
  /* NaNs at two late points: the first is named, by every rank count */
  bsurf_cloud c;
  bsurf_failure err;
  assert_int_equal(bsurf_read(tmp_path("ranks.ply"), &c, &err), BSURF_OK);
  const size_t bad = c.point_count - 300;
  c.xyz[3 * bad + 2] = NAN;
  c.xyz[3 * (c.point_count - 5)] = INFINITY;
  assert_int_equal(bsurf_write(tmp_path("ranks_nan.ply"), &c, NULL, &err), BSURF_OK);
  bsurf_cloud_free(&c);
  bsurf_tile_report rep;
  double sum;
  bsurf_failure serr;
  assert_int_equal(tiled_ranks(1, tmp_path("ranks_nan.ply"), tmp_path("ranks_out.ply"), &j, 300, 0,
                               -1, &rep, &sum, &serr),
                   BSURF_ERR_INVALID_VALUE);
  assert_int_equal(rep.bad_point, bad);
  for (int ranks = 2; ranks <= MAX_RANKS; ranks++) {
    unlink(tmp_path("ranks_out.ply"));
    assert_int_equal(tiled_ranks(ranks, tmp_path("ranks_nan.ply"), tmp_path("ranks_out.ply"), &j,
                                 300, 0, -1, &rep, &sum, &err),
                     BSURF_ERR_INVALID_VALUE);
    assert_int_equal(rep.bad_point, bad);
    assert_string_equal(err.message, serr.message);
    assert_int_equal(access(tmp_path("ranks_out.ply"), F_OK), -1);
  }
  /* rank 1 of 3 stops at its second range (one progress call per tile of
   * its own, then one per range): every rank fails, nothing is written */
  size_t own = 0;
  for (size_t t = 1; t < serial.tiles; t += 3)
    own++;
  job jc = j;
  jc.cancel_after = (int)own + 1;
  unlink(tmp_path("ranks_out.ply"));
  assert_int_equal(tiled_ranks(3, tmp_path("ranks.ply"), tmp_path("ranks_out.ply"), &jc, 300, 100,
                               1, &rep, &sum, &err),
                   BSURF_ERR_CANCELLED);
  assert_int_equal(access(tmp_path("ranks_out.ply"), F_OK), -1);
  /* the same with a cancel after the last range: the run completes */
  jc.cancel_after = 1 << 30;
  assert_int_equal(tiled_ranks(3, tmp_path("ranks.ply"), tmp_path("ranks_out.ply"), &jc, 300, 100,
                               1, &rep, &sum, &err),
                   BSURF_OK);
  assert_same_file(tmp_path("ranks_ref.ply"), tmp_path("ranks_out.ply"));
}

int main(void) {
  tmp_dir_init();
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_uniform_error),      cmocka_unit_test(test_uniform_normals),
      cmocka_unit_test(test_nonuniform),         cmocka_unit_test(test_big_endian),
      cmocka_unit_test(test_refusals),           cmocka_unit_test(test_smooth_two_stage),
      cmocka_unit_test(test_features_two_stage), cmocka_unit_test(test_ranks),
      cmocka_unit_test(test_features_distance),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
