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

static char tmp_dir[1024];

static const char *tmp_path(const char *name) {
  static char buf[4][1200];
  static int slot = 0;
  slot = (slot + 1) % 4;
  snprintf(buf[slot], sizeof buf[slot], "%s/%s", tmp_dir, name);
  return buf[slot];
}

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
    if (!bsurf_cloud_add_field(c, names[f], f == 3 ? BSURF_FLOAT64 : BSURF_FLOAT32)) return BSURF_ERR_NOMEM;
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
  bsurf_error err;
  assert_int_equal(bsurf_read(in, &c, &err), BSURF_OK);
  bsurf_neighbors nb;
  assert_int_equal(bsurf_neighbors_build(&nb, c.xyz, c.point_count, j->eo.k, 2, NULL, NULL), BSURF_OK);
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
  bsurf_error err;
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
    assert_int_equal(tiled_ranges(in, tmp_path("tiled.ply"), j, sizes[s % nsizes], range, &rep, sums),
                     BSURF_OK);
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
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, n, BSURF_SAMPLING_RANDOM, 5, 0), BSURF_OK);
  assert_int_equal(bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.5, 0.02, 9), BSURF_OK);
  static const bsurf_type types[] = {BSURF_INT8, BSURF_UINT8, BSURF_INT16, BSURF_UINT16,
                                     BSURF_INT32, BSURF_UINT32, BSURF_FLOAT32, BSURF_FLOAT64};
  for (int t = 0; t < 8; t++) {
    char name[16];
    snprintf(name, sizeof name, "extra%d", t);
    bsurf_field *f = bsurf_cloud_add_field(&c, name, types[t]);
    for (size_t i = 0; i < c.point_count; i++) f->values[i] = (double)((i * 37 + (size_t)t) % 100) - 20;
  }
  c.xyz_type = BSURF_FLOAT32; /* the scanner's usual float coordinates */
  bsurf_error err;
  assert_int_equal(bsurf_write(path, &c, NULL, &err), BSURF_OK);
  bsurf_cloud_free(&c);
}

/* Density varying by 10^4: a sparse sphere, a dense ball inside a tile, a
 * plane strip, far outliers (their halos must grow), exact duplicates. */
static void write_nonuniform(const char *path) {
  bsurf_cloud s, c;
  assert_int_equal(bsurf_generate(&s, BSURF_SHAPE_SPHERE, 1500, BSURF_SAMPLING_RANDOM, 2, 0), BSURF_OK);
  const size_t dense = 2500, strip = 1200, far = 7, dup = 40;
  size_t n = s.point_count + dense + strip + far + dup;
  assert_int_equal(bsurf_cloud_alloc(&c, n, 0), BSURF_OK);
  memcpy(c.xyz, s.xyz, 3 * s.point_count * sizeof(double));
  bsurf_rng r;
  bsurf_rng_init(&r, 7, 0, 0);
  size_t m = s.point_count;
  for (size_t i = 0; i < dense; i++, m++)
    for (int a = 0; a < 3; a++) c.xyz[3 * m + a] = (a == 0 ? 0.99 : 0.0) + 0.003 * bsurf_rng_normal(&r);
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
  for (size_t i = 0; i < dup; i++, m++) memcpy(&c.xyz[3 * m], &c.xyz[3 * (i * 97 % (m - 1))], 3 * sizeof(double));
  /* interleave the parts so global order is not spatial */
  for (size_t i = n - 1; i > 0; i--) {
    size_t j = bsurf_rng_below(&r, (uint32_t)(i + 1));
    double t[3];
    memcpy(t, &c.xyz[3 * i], sizeof t);
    memcpy(&c.xyz[3 * i], &c.xyz[3 * j], sizeof t);
    memcpy(&c.xyz[3 * j], t, sizeof t);
  }
  bsurf_error err;
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
  assert_int_equal(bsurf_generate(&s, BSURF_SHAPE_TORUS, 3000, BSURF_SAMPLING_RANDOM, 4, 0), BSURF_OK);
  FILE *f = fopen(tmp_path("be.ply"), "wb");
  fprintf(f, "ply\nformat binary_big_endian 1.0\nelement vertex %zu\nproperty short id\nproperty float x\n"
             "property float y\nproperty float z\nend_header\n", s.point_count);
  for (size_t i = 0; i < s.point_count; i++) {
    unsigned char rec[14];
    uint16_t id = (uint16_t)(i % 3000);
    rec[0] = (unsigned char)(id >> 8);
    rec[1] = (unsigned char)id;
    for (int a = 0; a < 3; a++) {
      float v = (float)s.xyz[3 * i + a];
      uint32_t u;
      memcpy(&u, &v, 4);
      for (int b = 0; b < 4; b++) rec[2 + 4 * a + b] = (unsigned char)(u >> (24 - 8 * b));
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
  fprintf(f, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
             "end_header\n0 0 0\n");
  fclose(f);
  assert_int_equal(tiled(tmp_path("a.ply"), out, &j, 100, &rep, sums), BSURF_ERR_UNSUPPORTED);
  /* a mesh */
  bsurf_cloud c;
  assert_int_equal(bsurf_generate(&c, BSURF_SHAPE_SPHERE, 200, BSURF_SAMPLING_RANDOM, 1, 0), BSURF_OK);
  c.faces = calloc(3, sizeof(uint32_t));
  c.faces[1] = 1, c.faces[2] = 2;
  c.face_count = 1;
  bsurf_error err;
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
  assert_int_equal(tiled_ranges(tmp_path("ok.ply"), out, &j, 40, 50, &rep, sums), BSURF_ERR_CANCELLED);
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
  bsurf_error err;
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
    for (size_t i = 0; i < n; i++) t[i] += ((const double *)r->w->slot[q])[i];
  pthread_barrier_wait(&r->w->bar);
  memcpy(v, t, n * sizeof *v);
  free(t);
}

/* sum over ranks [0, upto) of count uint64 */
static void fake_u64(fake_rank *r, uint64_t *v, size_t n, int upto) {
  publish(r, v);
  uint64_t *t = calloc(n ? n : 1, sizeof *t);
  for (int q = 0; q < upto; q++)
    for (size_t i = 0; i < n; i++) t[i] += ((const uint64_t *)r->w->slot[q])[i];
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
  for (int q = 0; q < r->w->ranks; q++) memcpy((char *)all + (size_t)q * bytes, r->w->slot[q], bytes);
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
static bsurf_status tiled_ranks(int ranks, const char *in, const char *out, const job *j, size_t tile_points,
                                size_t range_points, int cancel_rank, bsurf_tile_report *rep, double *sum,
                                bsurf_error *err) {
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
  for (int q = 0; q < ranks; q++) assert_int_equal(pthread_join(th[q], NULL), 0);
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
  assert_int_equal(tiled_ranges(tmp_path("ranks.ply"), tmp_path("ranks_ser.ply"), &j, 300, 100, &serial, serial_sum),
                   BSURF_OK);
  assert_same_file(tmp_path("ranks_ref.ply"), tmp_path("ranks_ser.ply"));
  const size_t ranges[] = {0, 100, 64};
  for (int ranks = 1; ranks <= MAX_RANKS; ranks++)
    for (int g = 0; g < 3; g++) {
      bsurf_tile_report rep;
      double sum;
      bsurf_error err;
      unlink(tmp_path("ranks_out.ply"));
      assert_int_equal(tiled_ranks(ranks, tmp_path("ranks.ply"), tmp_path("ranks_out.ply"), &j, 300, ranges[g], -1, &rep,
                                   &sum, &err),
                       BSURF_OK);
      assert_same_file(tmp_path("ranks_ref.ply"), tmp_path("ranks_out.ply"));
      assert_true(rep.h == h);
      assert_int_equal(rep.duplicates, dups);
      assert_true(sum == serial_sum[0]); /* summed per tile in tile order */
      assert_int_equal(rep.tiles, serial.tiles);
    }
  /* NaNs at two late points: the first is named, by every rank count */
  bsurf_cloud c;
  bsurf_error err;
  assert_int_equal(bsurf_read(tmp_path("ranks.ply"), &c, &err), BSURF_OK);
  const size_t bad = c.point_count - 300;
  c.xyz[3 * bad + 2] = NAN;
  c.xyz[3 * (c.point_count - 5)] = INFINITY;
  assert_int_equal(bsurf_write(tmp_path("ranks_nan.ply"), &c, NULL, &err), BSURF_OK);
  bsurf_cloud_free(&c);
  bsurf_tile_report rep;
  double sum;
  bsurf_error serr;
  assert_int_equal(tiled_ranks(1, tmp_path("ranks_nan.ply"), tmp_path("ranks_out.ply"), &j, 300, 0, -1, &rep, &sum, &serr),
                   BSURF_ERR_INVALID_VALUE);
  assert_int_equal(rep.bad_point, bad);
  for (int ranks = 2; ranks <= MAX_RANKS; ranks++) {
    unlink(tmp_path("ranks_out.ply"));
    assert_int_equal(tiled_ranks(ranks, tmp_path("ranks_nan.ply"), tmp_path("ranks_out.ply"), &j, 300, 0, -1, &rep, &sum, &err),
                     BSURF_ERR_INVALID_VALUE);
    assert_int_equal(rep.bad_point, bad);
    assert_string_equal(err.message, serr.message);
    assert_int_equal(access(tmp_path("ranks_out.ply"), F_OK), -1);
  }
  /* rank 1 of 3 stops at its second range (one progress call per tile of
   * its own, then one per range): every rank fails, nothing is written */
  size_t own = 0;
  for (size_t t = 1; t < serial.tiles; t += 3) own++;
  job jc = j;
  jc.cancel_after = (int)own + 1;
  unlink(tmp_path("ranks_out.ply"));
  assert_int_equal(tiled_ranks(3, tmp_path("ranks.ply"), tmp_path("ranks_out.ply"), &jc, 300, 100, 1, &rep, &sum, &err),
                   BSURF_ERR_CANCELLED);
  assert_int_equal(access(tmp_path("ranks_out.ply"), F_OK), -1);
  /* the same with a cancel after the last range: the run completes */
  jc.cancel_after = 1 << 30;
  assert_int_equal(tiled_ranks(3, tmp_path("ranks.ply"), tmp_path("ranks_out.ply"), &jc, 300, 100, 1, &rep, &sum, &err),
                   BSURF_OK);
  assert_same_file(tmp_path("ranks_ref.ply"), tmp_path("ranks_out.ply"));
}

int main(void) {
  const char *t = getenv("BSURF_TMP");
  snprintf(tmp_dir, sizeof tmp_dir, "%s", t ? t : "/tmp");
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_uniform_error), cmocka_unit_test(test_uniform_normals),
      cmocka_unit_test(test_nonuniform),    cmocka_unit_test(test_big_endian),
      cmocka_unit_test(test_refusals),     cmocka_unit_test(test_ranks),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
