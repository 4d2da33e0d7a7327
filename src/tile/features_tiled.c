/* features --method distance (thesis 7.1) tile by tile, with the bits of
 * bsurf_detect_features (docs/scaling.md, "Features distance in stages").
 *
 * The in-memory method is a chain of global steps; each step here is a
 * tiled run (bsurf_tiles_run: proven K-neighbourhoods, every tile's rows
 * exactly the whole cloud's) calling the very stage functions of
 * features.c that bsurf_detect_features calls, and the global numbers
 * between them are taken over the values read back in index order, as the
 * in-memory loops take them:
 *
 *  (a) noise_factor > 0: f(K) = lambda0 / lambda2 at every size K of the
 *      sample (every stride-th global index, bsurf_fdist_sample), kept by
 *      sample number in memory (at most ~4M values, as in memory; summed
 *      over the ranks, each value coming from the one tile that holds the
 *      point); then the per-size medians and T_{a/c}(K).
 *  (b) the raw map: the radius where the growth stops, and the state (0, 1,
 *      2 = stopped at k_min), per point (K = k_max).
 *  (c) max(radius) = R over the raw map in index order; the points that
 *      stopped at once get -R (applied as the values are read next).
 *  (d) the Jacobi passes of the bilateral filter, Eq. 7.1: each a tiled run
 *      with K = filter_k whose tiles read the previous pass's values of
 *      every local point (values_in): a point's filter neighbours are its
 *      first filter_k, inside its proven K-ball, so the normal halo holds
 *      them. sigma_a = h (the engine's h is the in-memory double), sigma_b =
 *      sigma_range x R.
 *  (e) T_h: Otsu's split of the positive values (all of them in memory,
 *      8 bytes per point, as variance's tail threshold), or a fraction of
 *      the map's maximum; then feature_dist and feature are written by a
 *      pointwise stage (bsurf_tiles_map).
 *
 * Values per point on disk: (raw or filtered map, state) + the engine's
 * column, 24 bytes, two files at a time while a pass runs. */
#include "algo/algo.h"
#include "common/common.h"
#include "algo/smooth_stages.h"
#include "tile/tile_engine.h"

#include "io/io.h"

#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct fd_run {
  bsurf_feature_options o; /* no progress: the engine reports it */
  const bsurf_tile_ops *base;
  double *T;        /* T_{a/c} per size */
  size_t stride, m; /* the sample of the medians */
  double *sample;   /* sizes x m */
  double h, R;
  int fixup;        /* the -R fix-up is still to apply to the values read */
  size_t immediate; /* points that stopped at k_min */
  double mx;        /* the largest map value */
  double *pos;      /* auto T_h: the positive map values, index order */
  size_t npos;
  double thr; /* T_h, absolute */
  size_t features;
} fd_run;

/* a point's map value from its two columns (map, state) */
static double fd_value(const fd_run *f, const double *v) {
  return f->fixup ? bsurf_fdist_fixed(v[0], (int)v[1], f->R) : v[0];
}

/* (a) */
static bsurf_status run_sample(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  fd_run *f = user;
  /* no values per point: the sample is kept by sample number in f->sample */
  return bsurf_fdist_sample_ratios(t->xyz, t->nb, &f->o, t->point_index, f->stride, f->m,
                                   f->sample);
}

/* (b) */
static bsurf_status run_raw(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  const fd_run *f = user;
  const size_t nc = t->core_count;
  double *dist = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  uint8_t *state = bsurf_alloc_array(nc ? nc : 1, 1);
  bsurf_status st = dist && state ? bsurf_fdist_raw(t->xyz, t->nb, &f->o, f->T, dist, NULL, state)
                                  : BSURF_ERR_NOMEM;
  for (size_t r = 0; r < nc && st == BSURF_OK; r++) {
    t->values_out[2 * r] = dist[r];
    t->values_out[2 * r + 1] = state[r];
  }
  free(dist);
  free(state);
  return st;
}

/* (d): one pass of Eq. 7.1 over the tile's rows */
static bsurf_status run_filter(void *user, const bsurf_tile *t, bsurf_cloud *core, double *sums) {
  (void)core;
  (void)sums;
  const fd_run *f = user;
  const size_t nc = t->core_count, nl = t->local_count;
  double *in = bsurf_alloc_array(nl ? nl : 1, sizeof(double)),
         *out = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  bsurf_status st = in && out ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t l = 0; l < nl && st == BSURF_OK; l++)
    in[l] = fd_value(f, &t->values[2 * l]);
  if (st == BSURF_OK) st = bsurf_fdist_filter(t->xyz, t->nb, &f->o, f->h, f->R, in, out);
  for (size_t r = 0; r < nc && st == BSURF_OK; r++) {
    t->values_out[2 * r] = out[r];
    t->values_out[2 * r + 1] =
        t->values[2 * (size_t)t->nb->idx[r * (size_t)t->nb->k] + 1]; /* the state */
  }
  free(in);
  free(out);
  return st;
}

/* The values (nv per point) of every point in index order, a chunk at a time. */
static bsurf_status values_scan_n(void *f, const bsurf_tile_values *vals, size_t nv,
                                  void (*fn)(void *, size_t, const double *)) {
  const size_t per = 65536;
  double *buf = bsurf_alloc_array(per, nv * sizeof(double));
  bsurf_status st = buf ? BSURF_OK : BSURF_ERR_NOMEM;
  for (size_t i = 0; i < vals->count && st == BSURF_OK; i += per) {
    size_t m = vals->count - i < per ? vals->count - i : per;
    st = bsurf_tile_values_read(vals, i, m, buf);
    if (st == BSURF_OK) fn(f, m, buf);
  }
  free(buf);
  return st;
}

static bsurf_status values_scan(fd_run *f, const bsurf_tile_values *vals,
                                void (*fn)(void *, size_t, const double *)) {
  return values_scan_n(f, vals, 2, fn);
}

/* (c): R = max of the raw map, in index order as distance_raw takes it */
static void scan_radius(void *vf, size_t count, const double *v) {
  fd_run *f = vf;
  for (size_t i = 0; i < count; i++) {
    bsurf_fdist_max_radius(&v[2 * i], 1, &f->R);
    f->immediate += v[2 * i + 1] == 2;
  }
}

/* (e): the maximum and the positive values of the final map */
static void scan_final(void *vf, size_t count, const double *v) {
  fd_run *f = vf;
  for (size_t i = 0; i < count; i++) {
    double x = fd_value(f, &v[2 * i]);
    bsurf_fdist_max_radius(&x, 1, &f->mx);
    if (f->pos && x > 0) f->pos[f->npos++] = x;
  }
}

static void scan_count(void *vf, size_t count, const double *v) {
  fd_run *f = vf;
  for (size_t i = 0; i < count; i++)
    f->features += (size_t)bsurf_fdist_feature(fd_value(f, &v[2 * i]), (int)v[2 * i + 1], f->thr,
                                               f->o.threshold);
}

/* the output: the caller's fields, then feature_dist and feature */
static bsurf_status prepare_out(void *user, bsurf_cloud *c) {
  const fd_run *f = user;
  return f->base->prepare(f->base->user, c);
}

static bsurf_status map_out(void *user, size_t first, bsurf_cloud *c, const double *values) {
  (void)first;
  const fd_run *f = user;
  bsurf_field *score = bsurf_cloud_field(c, "feature_dist"),
              *feat = bsurf_cloud_field(c, "feature");
  if (!score || !feat) return BSURF_ERR_INVALID_ARG;
  for (size_t i = 0; i < c->point_count; i++) {
    double x = fd_value(f, &values[2 * i]);
    score->values[i] = x;
    feat->values[i] = bsurf_fdist_feature(x, (int)values[2 * i + 1], f->thr, f->o.threshold);
  }
  return BSURF_OK;
}

/* One tiled run of a stage: K = k, values in (NULL: none) and out
 * (nvalues per point; 0 and out NULL: the tiles keep their results in f). */
static bsurf_status stage(const char *input, const char *output, fd_run *f, int k, size_t nvalues,
                          bsurf_status (*run)(void *, const bsurf_tile *, bsurf_cloud *, double *),
                          const bsurf_tile_values *in, bsurf_tile_values *out,
                          bsurf_tile_report *rep, bsurf_failure *err) {
  bsurf_tile_ops ops = *f->base;
  ops.k = k;
  /* tiles of at least twice the stage's K (the tile engine's least: a stage
   * at a larger K than the caller planned for, K_q or the chosen K; the
   * tiles' size changes no value, their halos are proven) */
  if (ops.tile_points < 2 * (size_t)k) ops.tile_points = 2 * (size_t)k;
  ops.user = f;
  ops.prepare = NULL; /* no output file: values only */
  ops.run = run;
  ops.nsums = 0;
  ops.nvalues = nvalues;
  ops.values_out = out;
  ops.values_in = in;
  ops.reverse = 0;
  rep->sums = NULL;
  return bsurf_tiles_run(input, output, &ops, rep, err);
}

/* A step every rank runs on its own (reading the values back): the ranks
 * agree on its failure before the next collective run. */
static bsurf_status agree_local(const bsurf_tile_comm *cm, bsurf_status st) {
  if (!cm) return st;
  int failed = cm->max(cm->user, st != BSURF_OK);
  return failed && st == BSURF_OK ? BSURF_ERR_IO : st;
}

/* The vertex count of a binary PLY file (0 when it cannot be read: the
 * first tiled run then says why, with the reader's message). */
static size_t ply_points(const char *path) {
  int fd = open(path, O_RDONLY);
  if (fd < 0) return 0;
  struct stat sb;
  size_t n = 0;
  if (fstat(fd, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > 0) {
    void *data = mmap(NULL, (size_t)sb.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
    if (data != MAP_FAILED) {
      io_ply_layout layout;
      bsurf_cloud schema;
      if (io_ply_map(data, (size_t)sb.st_size, &layout, &schema, NULL) == BSURF_OK) {
        n = layout.count;
        io_ply_layout_free(&layout);
        bsurf_cloud_free(&schema);
      }
      munmap(data, (size_t)sb.st_size);
    }
  }
  close(fd);
  return n;
}

/* The start of both tiled methods: err and report cleared, the arguments
 * checked, f zeroed with the options (no progress: the engine reports it). */
static bsurf_status fd_begin(fd_run *f, const char *input, const char *output,
                             const bsurf_tile_ops *ops, const bsurf_feature_options *opts,
                             bsurf_feature_report *report, bsurf_tile_report *tiles,
                             bsurf_failure *err) {
  if (err) err->line = 0, err->byte = -1, err->message[0] = 0;
  if (report) bsurf_feature_report_clear(report);
  if (!input || !output || !ops || !ops->prepare || !tiles)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "invalid arguments");
  memset(f, 0, sizeof *f);
  f->o = opts ? *opts : bsurf_feature_options_default();
  f->o.progress = NULL;
  f->o.progress_user = NULL;
  f->base = ops;
  return BSURF_OK;
}

bsurf_status bsurf_features_distance_tiled(const char *input, const char *output,
                                           const bsurf_tile_ops *ops,
                                           const bsurf_feature_options *opts,
                                           bsurf_feature_report *report, bsurf_tile_report *tiles,
                                           bsurf_failure *err) {
  fd_run f;
  bsurf_status st0 = fd_begin(&f, input, output, ops, opts, report, tiles, err);
  if (st0 != BSURF_OK) return st0;
  if (f.o.method != BSURF_FEATURES_DISTANCE ||
      bsurf_fdist_check(&f.o, f.o.k_max, SIZE_MAX) != BSURF_OK)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "invalid options of the distance method");
  const int sizes = bsurf_fdist_sizes(&f.o), fk = bsurf_fdist_filter_k(&f.o);
  const bsurf_tile_comm *cm = ops->comm;
  bsurf_tile_values cur = {-1, 0, 0}, next = {-1, 0, 0};
  bsurf_tile_report rep;
  memset(&rep, 0, sizeof rep);
  bsurf_status st = BSURF_OK;
  f.T = bsurf_alloc_array((size_t)sizes, sizeof(double));
  if (!f.T) st = BSURF_ERR_NOMEM;

  /* (a) T_{a/c} per size: the medians of the sample's f(K), or T alone */
  const size_t n = f.o.noise_factor > 0 ? ply_points(input) : 0;
  if (st == BSURF_OK && f.o.noise_factor > 0) {
    bsurf_fdist_sample(&f.o, n, &f.stride, &f.m);
    f.sample = bsurf_calloc_array(f.m ? f.m * (size_t)sizes : 1, sizeof(double));
    if (!f.sample) st = BSURF_ERR_NOMEM;
  }
  st = agree_local(cm, st); /* the allocations, before the first collective run */
  if (st == BSURF_OK && f.o.noise_factor > 0) {
    st = stage(input, output, &f, f.o.k_max, 0, run_sample, NULL, NULL, &rep, err);
    if (st == BSURF_OK && rep.points != n) /* the file changed under us */
      st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "the input changed during the run");
    /* each sampled value comes from the one tile holding its point: the
     * other ranks add zeros, exactly */
    if (st == BSURF_OK && cm) cm->sum(cm->user, f.sample, f.m * (size_t)sizes);
  }
  if (st == BSURF_OK) bsurf_fdist_thresholds(&f.o, f.m, f.sample, f.T);
  free(f.sample);
  f.sample = NULL;

  /* (b) the raw map and the states; (c) R and the points stopped at once */
  if (st == BSURF_OK) st = stage(input, output, &f, f.o.k_max, 2, run_raw, NULL, &cur, tiles, err);
  if (st == BSURF_OK) st = agree_local(cm, values_scan(&f, &cur, scan_radius));
  f.h = tiles->h;
  f.fixup = 1;

  /* (d) the passes of Eq. 7.1, each reading the previous one's values */
  const int passes = st == BSURF_OK ? bsurf_fdist_filter_passes(&f.o, f.R) : 0;
  for (int it = 0; it < passes && st == BSURF_OK; it++) {
    st = stage(input, output, &f, fk > 2 ? fk : 2, 2, run_filter, &cur, &next, &rep, err);
    bsurf_tile_values_close(&cur);
    cur = next;
    next.fd = -1;
    f.fixup = 0; /* the first pass applied it */
  }

  /* (e) T_h over the final map, the feature count, the output */
  const bsurf_status passed = st; /* the same on every rank (the runs agree) */
  if (st == BSURF_OK && isnan(f.o.threshold) &&
      !(f.pos = bsurf_alloc_array(cur.count ? cur.count : 1, sizeof(double))))
    st = BSURF_ERR_NOMEM;
  f.mx = -INFINITY;
  if (st == BSURF_OK) st = values_scan(&f, &cur, scan_final);
  if (st == BSURF_OK)
    f.thr = isnan(f.o.threshold) ? bsurf_fdist_otsu_positive(f.pos, f.npos) : f.o.threshold * f.mx;
  free(f.pos);
  f.pos = NULL;
  if (st == BSURF_OK) st = values_scan(&f, &cur, scan_count);
  if (passed == BSURF_OK) st = agree_local(cm, st);
  if (st == BSURF_OK) {
    bsurf_tile_ops mo = *ops;
    mo.user = &f;
    mo.prepare = prepare_out;
    st = bsurf_tiles_map(input, output, &mo, &cur, map_out, err);
  }
  if (st == BSURF_ERR_NOMEM && err && !err->message[0]) bsurf_fail(err, st, 0, -1, "out of memory");
  if (st == BSURF_OK && report) {
    report->threshold = f.thr;
    report->feature_points = f.features;
    report->max_radius = f.R;
    report->immediate = f.immediate;
    report->ratio_threshold_kmin = f.T[0];
  }
  free(f.T);
  bsurf_tile_values_close(&cur);
  bsurf_tile_values_close(&next);
  return st;
}

/* ---- features --method variance with the NULL rule in stages (the other
 * rules: cli/cmd_features.c) ----
 *  (v1) K = normals.k: nu (bootstrap normals keyed by global index, as in
 *       memory) and, per point, u = nu d, lambda0, lambda0 / tr, w (mu0
 *       where two sheets), the border statistic b and the spread g
 *       (bsurf_fvar_local);
 *  (v2) s^2 = median lambda0, eta = median lambda0 / tr and the expected
 *       lambda0 E(g) (bsurf_fvar_fit: the sorted g, then lambda0 by g's
 *       bin) over the values read back in index order (8 bytes per point in
 *       memory at a time); then the null patch's t_alpha, the border's t_b
 *       and sigma_0 (bsurf_fvar_null, the in-memory function);
 *  (v3) K = k_f, reading (v1)'s values of the tile's points: u and w scaled
 *       by s^2 / E(g) (bsurf_fvar_fit_scale), z = the median of u over the
 *       first k_f neighbours / s^2, zb = that of b;
 *  (vq) the quadric check (quadric_angle > 0, a noise level given): K_q
 *       and t_q at sigma_0 times the noise read over s (bsurf_fvar_quadric_k,
 *       the in-memory function);
 *       K = K_q: (v1)'s values of the tile's points and the residual
 *       variance of each one's quadric (bsurf_fvar_quadric_rss's);
 *  (v3) K = k_f, reading (v1)'s (or (vq)'s) values of the tile's points: as
 *       above, and q = the median of the quadric's residual variance over
 *       the same neighbours / the noise level (NAN without the check);
 *  (v4) t = max(t_alpha, Otsu's split of z, all of it in memory:
 *       bsurf_fvar_split, the in-memory function); the
 *       feature count and its parts (bsurf_fvar_count of z, zb and q);
 *       the output by a pointwise stage. */

/* (v1)'s values per point: u, lambda0, lambda0 / tr, w, b, g; (vq) adds the
 * quadric's residual variance */
#define NV 6
/* (v3)'s: z, zb, q */
#define NZ 3

typedef struct fv_run {
  fd_run fd; /* first: the stages get &fd as their user */
  double s2;
  double level; /* the noise variance q is read against */
  size_t nv;    /* the values per point (v3) reads: NV, or NV + 1 after (vq) */
  bsurf_fvar_fit fit;
  int col; /* (v2)'s column */
  double *all;
  size_t nall, features;
  bsurf_fvar_result res;
} fv_run;

/* (v1) */
static bsurf_status run_var_local(void *user, const bsurf_tile *t, bsurf_cloud *core,
                                  double *sums) {
  (void)core;
  (void)sums;
  const fv_run *v = user;
  const size_t nc = t->core_count;
  double *nu = bsurf_alloc_array(7 * (nc ? nc : 1), sizeof(double));
  if (!nu) return BSURF_ERR_NOMEM;
  double *u = nu + nc, *l0 = u + nc, *ratio = l0 + nc, *w = ratio + nc, *b = w + nc, *g = b + nc;
  bsurf_normal_options no = v->fd.o.normals;
  no.threads = v->fd.o.threads;
  no.progress = NULL;
  no.point_index = t->point_index;
  bsurf_normal_fields nf = {NULL, nu, NULL};
  bsurf_status st = bsurf_estimate_normals(t->xyz, t->nb, NULL, &no, &nf, NULL);
  if (st == BSURF_OK)
    st = bsurf_fvar_local(t->xyz, t->nb, no.k, v->fd.o.threads, nu, u, l0, ratio, w, b, g);
  for (size_t r = 0; r < nc && st == BSURF_OK; r++) {
    t->values_out[NV * r] = u[r];
    t->values_out[NV * r + 1] = l0[r];
    t->values_out[NV * r + 2] = ratio[r];
    t->values_out[NV * r + 3] = w[r];
    t->values_out[NV * r + 4] = b[r];
    t->values_out[NV * r + 5] = g[r];
  }
  free(nu);
  return st;
}

/* (vq) */
static bsurf_status run_var_quadric(void *user, const bsurf_tile *t, bsurf_cloud *core,
                                    double *sums) {
  (void)core;
  (void)sums;
  const fv_run *v = user;
  const size_t nc = t->core_count;
  double *rss = bsurf_alloc_array(nc ? nc : 1, sizeof(double));
  if (!rss) return BSURF_ERR_NOMEM;
  bsurf_status st =
      bsurf_fvar_quadric_rss(t->xyz, t->nb, v->res.quadric_k, v->fd.o.threads, rss, NULL, NULL);
  for (size_t r = 0; r < nc && st == BSURF_OK; r++) {
    /* each row's point first: its local index */
    const size_t l = t->nb->idx[r * (size_t)t->nb->k];
    memcpy(&t->values_out[(NV + 1) * r], &t->values[NV * l], NV * sizeof(double));
    t->values_out[(NV + 1) * r + NV] = rss[r];
  }
  free(rss);
  return st;
}

/* (v3) */
static bsurf_status run_var_filter(void *user, const bsurf_tile *t, bsurf_cloud *core,
                                   double *sums) {
  (void)core;
  (void)sums;
  const fv_run *v = user;
  const size_t nl = t->local_count, nv = v->nv;
  const size_t m = nl ? nl : 1, nc = t->core_count;
  double *u = bsurf_alloc_array(8 * m, sizeof(double));
  if (!u) return BSURF_ERR_NOMEM;
  double *w = u + m, *b = w + m, *z = b + m, *zb = z + m, *g = zb + m, *rss = g + m, *q = rss + m;
  for (size_t l = 0; l < nl; l++) {
    u[l] = t->values[nv * l];
    w[l] = t->values[nv * l + 3];
    b[l] = t->values[nv * l + 4];
    g[l] = t->values[nv * l + 5];
    if (v->res.quadric_k) rss[l] = t->values[nv * l + NV];
  }
  bsurf_fvar_fit_scale(&v->fit, v->s2, nl, g, u, w);
  const int kf = bsurf_fvar_filter_k(&v->fd.o), k = v->fd.o.normals.k;
  bsurf_status st = bsurf_fvar_filter(t->nb, kf, v->fd.o.threads, v->s2, k, u, w, z);
  if (st == BSURF_OK) st = bsurf_fvar_filter(t->nb, kf, v->fd.o.threads, 0, k, b, NULL, zb);
  if (st == BSURF_OK && v->res.quadric_k)
    st = bsurf_fvar_filter(t->nb, kf, v->fd.o.threads, v->level, v->res.quadric_k, rss, NULL, q);
  for (size_t r = 0; r < nc && st == BSURF_OK; r++) {
    t->values_out[NZ * r] = z[r];
    t->values_out[NZ * r + 1] = zb[r];
    t->values_out[NZ * r + 2] = v->res.quadric_k ? q[r] : NAN;
  }
  free(u);
  return st;
}

/* (v2): the column v->col of the NV values into v->all */
static void scan_col(void *vv, size_t count, const double *x) {
  fv_run *v = vv;
  for (size_t i = 0; i < count; i++)
    v->all[v->nall++] = x[NV * i + (size_t)v->col];
}

/* lambda0 into its bin of g (bsurf_fvar_fit) */
static void scan_fit(void *vv, size_t count, const double *x) {
  fv_run *v = vv;
  for (size_t i = 0; i < count; i++)
    bsurf_fvar_fit_put(&v->fit, v->all, x[NV * i + 5], x[NV * i + 1]);
}

/* (v4): z of the rows (z, zb, q); then the features */
static void scan_z(void *vv, size_t count, const double *x) {
  fv_run *v = vv;
  for (size_t i = 0; i < count; i++)
    v->all[v->nall++] = x[NZ * i];
}

static void scan_features(void *vv, size_t count, const double *x) {
  fv_run *v = vv;
  for (size_t i = 0; i < count; i++) {
    const double *y = &x[NZ * i];
    bsurf_fvar_count(&v->res, y[0], y[1], y[2], &v->features);
  }
}

static bsurf_status map_var(void *user, size_t first, bsurf_cloud *c, const double *values) {
  (void)first;
  const fv_run *v = user;
  bsurf_field *score = bsurf_cloud_field(c, "variance_z"), *feat = bsurf_cloud_field(c, "feature");
  if (!score || !feat) return BSURF_ERR_INVALID_ARG;
  for (size_t i = 0; i < c->point_count; i++) {
    const double *y = &values[NZ * i];
    score->values[i] = y[0];
    feat->values[i] = bsurf_fvar_feature(&v->res, y[0], y[1], y[2]);
  }
  return BSURF_OK;
}

static bsurf_status prepare_var(void *user, bsurf_cloud *c) {
  const fv_run *v = user;
  return v->fd.base->prepare(v->fd.base->user, c);
}

bsurf_status bsurf_features_variance_tiled(const char *input, const char *output,
                                           const bsurf_tile_ops *ops,
                                           const bsurf_feature_options *opts, double quadric_noise,
                                           bsurf_feature_report *report, bsurf_tile_report *tiles,
                                           bsurf_failure *err) {
  fv_run v;
  memset(&v, 0, sizeof v);
  v.nv = NV;
  bsurf_status st0 = fd_begin(&v.fd, input, output, ops, opts, report, tiles, err);
  if (st0 != BSURF_OK) return st0;
  const bsurf_feature_options *o = &v.fd.o;
  const int kf = bsurf_fvar_filter_k(o);
  if (o->method != BSURF_FEATURES_VARIANCE || o->tail_rule != BSURF_TAIL_NULL ||
      !isnan(o->threshold) || o->normals.bootstrap < 2 || o->normals.k < 3 ||
      !(o->false_positive_rate > 0 && o->false_positive_rate < 1) || o->variance_filter_k < 0)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1,
                      "invalid options of the variance method's null rule");
  const bsurf_tile_comm *cm = ops->comm;
  bsurf_tile_values local = {-1, 0, 0}, z = {-1, 0, 0};
  bsurf_tile_report rep;
  memset(&rep, 0, sizeof rep);
  /* (v1) */
  bsurf_status st =
      stage(input, output, &v.fd, o->normals.k, NV, run_var_local, NULL, &local, tiles, err);
  /* (v2) */
  double eta = 0;
  if (st == BSURF_OK && !(v.all = bsurf_alloc_array(local.count ? local.count : 1, sizeof(double))))
    st = BSURF_ERR_NOMEM;
  v.col = 1;
  if (st == BSURF_OK) st = values_scan_n(&v, &local, NV, scan_col);
  if (st == BSURF_OK) v.s2 = bsurf_median(v.all, v.nall);
  v.nall = 0;
  v.col = 5;
  if (st == BSURF_OK) st = values_scan_n(&v, &local, NV, scan_col);
  if (st == BSURF_OK) bsurf_fvar_fit_prepare(&v.fit, v.all, v.nall);
  if (st == BSURF_OK) st = values_scan_n(&v, &local, NV, scan_fit);
  if (st == BSURF_OK) bsurf_fvar_fit_solve(&v.fit, v.all, v.s2);
  v.nall = 0;
  v.col = 2;
  if (st == BSURF_OK) st = values_scan_n(&v, &local, NV, scan_col);
  if (st == BSURF_OK) eta = bsurf_median(v.all, v.nall);
  st = agree_local(cm, st);
  /* the null (t_alpha, t_b, sigma_0: the in-memory function) */
  if (st == BSURF_OK) st = bsurf_fvar_null(o, v.s2, eta, &v.res);
  /* (vq): as in memory (features_variance.c, quadric_check), with the noise
   * level the caller read (NAN: none) */
  bsurf_tile_values withq = {-1, 0, 0};
  const int check =
      o->quadric_angle > 0 && v.s2 > 0 && quadric_noise > 0 && v.nall > BSURF_SMOOTH_SELECT_K;
  if (st == BSURF_OK && check) {
    int kq = 0;
    v.res.quadric_noise = sqrt(quadric_noise);
    st = bsurf_fvar_quadric_k(o, bsurf_fvar_quadric_sigma(&v.res, quadric_noise, v.s2),
                              bsurf_fvar_k_cap(o, v.nall), &kq, &v.res.quadric_threshold,
                              &v.res.quadric_power);
    if (st == BSURF_OK && kq) {
      v.res.quadric_k = kq;
      v.level = quadric_noise;
      st = stage(input, output, &v.fd, kq, NV + 1, run_var_quadric, &local, &withq, &rep, err);
      v.nv = NV + 1;
    }
    st = agree_local(cm, st);
  }
  /* (v3) */
  if (st == BSURF_OK)
    st = stage(input, output, &v.fd, kf, NZ, run_var_filter, v.res.quadric_k ? &withq : &local, &z,
               &rep, err);
  bsurf_tile_values_close(&local);
  bsurf_tile_values_close(&withq);
  /* (v4) */
  const bsurf_status passed = st;
  v.nall = 0;
  if (st == BSURF_OK) st = values_scan_n(&v, &z, NZ, scan_z);
  if (st == BSURF_OK) st = bsurf_fvar_split(v.all, v.nall, &v.res);
  if (st == BSURF_OK) st = values_scan_n(&v, &z, NZ, scan_features);
  free(v.all);
  v.all = NULL;
  if (passed == BSURF_OK) st = agree_local(cm, st);
  if (st == BSURF_OK) {
    bsurf_tile_ops mo = *ops;
    mo.user = &v;
    mo.prepare = prepare_var;
    st = bsurf_tiles_map(input, output, &mo, &z, map_var, err);
  }
  if (st == BSURF_ERR_NOMEM && err && !err->message[0]) bsurf_fail(err, st, 0, -1, "out of memory");
  if (st == BSURF_OK && report) {
    bsurf_fvar_report(&v.res, report);
    report->feature_points = v.features;
    report->ratio_threshold_kmin = NAN;
  }
  free(v.all);
  bsurf_tile_values_close(&local);
  bsurf_tile_values_close(&z);
  return st;
}
