/* The `error` job (issue 18): bootstrap test-error estimates of every point
 * of a cloud, in memory or tile by tile (under MPI through the caller's
 * bsurf_tile_comm), through one call. The command line parses its options
 * and prints the summary; everything between is here. */
#include "jobs/jobs.h"

#include <string.h>

/* The output fields, in the order they are added to a cloud and written. */
static const char *const error_field_names[BSURF_ERROR_JOB_FIELDS] = {
    "err_train",   "err_boot", "err_loo",      "err_loo_center", "err_632",
    "err_632plus", "gamma",    "overfit_rate", "err_test",       "err_test_center"};

static void fields_slots(bsurf_error_fields *out, double **slots[BSURF_ERROR_JOB_FIELDS]) {
  memset(out, 0, sizeof *out);
  double **s[BSURF_ERROR_JOB_FIELDS] = {&out->err_train,      &out->err_boot,     &out->err_loo,
                                        &out->err_loo_center, &out->err_632,      &out->err_632plus,
                                        &out->gamma,          &out->overfit_rate, &out->err_test,
                                        &out->err_test_center};
  memcpy(slots, s, sizeof s);
}

/* Adds the job's fields to a cloud and points `out` at them. */
static bsurf_status add_fields(bsurf_cloud *c, int nfields, bsurf_error_fields *out) {
  double **slots[BSURF_ERROR_JOB_FIELDS];
  fields_slots(out, slots);
  for (int f = 0; f < nfields; f++)
    if (!bsurf_cloud_add_field(c, error_field_names[f], BSURF_FLOAT32))
      return bsurf_set_message(BSURF_ERR_NOMEM, "out of memory adding the field %s",
                               error_field_names[f]);
  /* looked up after every add: the table of fields moves, the values do not */
  for (int f = 0; f < nfields; f++)
    *slots[f] = bsurf_cloud_field(c, error_field_names[f])->values;
  return BSURF_OK;
}

/* ---- tiled: the same fields, tile by tile (bsurf_tiles_run) ---- */

typedef struct error_tiles {
  bsurf_error_options eo;
  int nfields;
} error_tiles;

/* sums: replicates total, skipped, degree reduced, centre unestimated, then
 * the field sums */
#define ERROR_SUMS (4 + BSURF_ERROR_JOB_FIELDS)

static bsurf_status error_prepare(void *user, bsurf_cloud *c) {
  const error_tiles *et = user;
  bsurf_error_fields out;
  return add_fields(c, et->nfields, &out);
}

static bsurf_status error_run(void *user, const bsurf_tile *tile, bsurf_cloud *core, double *sums) {
  const error_tiles *et = user;
  bsurf_error_options eo = et->eo;
  eo.point_index = tile->point_index;
  eo.progress = NULL;
  bsurf_error_fields out;
  double **slots[BSURF_ERROR_JOB_FIELDS];
  fields_slots(&out, slots);
  for (int f = 0; f < et->nfields; f++)
    *slots[f] = bsurf_cloud_field(core, error_field_names[f])->values;
  bsurf_error_report rep;
  bsurf_status st = bsurf_estimate_error(tile->xyz, tile->nb, NULL, &eo, &out, &rep);
  if (st != BSURF_OK) return st;
  bsurf_jobs_add_counts(sums, rep.replicates_total, rep.replicates_skipped, rep.degree_reduced,
                        rep.center_unestimated);
  for (int f = 0; f < et->nfields; f++)
    sums[4 + f] += bsurf_jobs_mean(*slots[f], core->point_count) * (double)core->point_count;
  return BSURF_OK;
}

static bsurf_status error_tiled(const bsurf_job_io *io, const bsurf_error_options *o,
                                bsurf_error_job_summary *s, bsurf_failure *err) {
  error_tiles et = {*o, s->field_count};
  double sums[ERROR_SUMS] = {0};
  bsurf_tile_ops ops;
  bsurf_jobs_tile_ops(&ops, io, o->k, o->threads, o->progress, o->progress_user, &et);
  ops.prepare = error_prepare;
  ops.run = error_run;
  ops.nsums = ERROR_SUMS;
  bsurf_tile_report tr;
  memset(&tr, 0, sizeof tr);
  tr.sums = sums;
  bsurf_status st = bsurf_tiles_run(io->input, io->output, &ops, &tr, err);
  s->tile_points = ops.tile_points;
  bsurf_jobs_tiled_numbers(&tr, &s->points, &s->h, &s->duplicates, &s->tiles, &s->bad_point);
  if (st != BSURF_OK) return st;
  bsurf_error_report *r = &s->report;
  bsurf_jobs_counts(sums, &r->replicates_total, &r->replicates_skipped, &r->degree_reduced,
                    &r->center_unestimated);
  bsurf_jobs_means(s->means, sums + 4, s->field_count, s->points);
  return BSURF_OK;
}

/* ---- in memory ---- */

static bsurf_status error_in_memory(const bsurf_job_io *io, const bsurf_error_options *o,
                                    bsurf_error_job_summary *s) {
  bsurf_cloud *c = io->cloud;
  const size_t n = c->point_count;
  if (io->test && io->test->point_count != n)
    return bsurf_invalid("bsurf_error_job",
                         "io->test has %zu points, io->cloud %zu: the same points are needed",
                         io->test->point_count, n);
  bsurf_neighbors nb;
  bsurf_status st =
      bsurf_jobs_neighbors(c, o->k, o->threads, o->progress, o->progress_user, &nb, &s->duplicates);
  if (st != BSURF_OK) return st;
  s->points = n;
  s->h = nb.h;
  bsurf_error_fields out;
  st = add_fields(c, s->field_count, &out);
  if (st == BSURF_OK)
    st = bsurf_estimate_error(c->xyz, &nb, io->test ? io->test->xyz : NULL, o, &out, &s->report);
  bsurf_neighbors_free(&nb);
  if (st != BSURF_OK) return st;
  for (int f = 0; f < s->field_count; f++)
    s->means[f] = bsurf_jobs_mean(bsurf_cloud_field(c, s->field_names[f])->values, n);
  return BSURF_OK;
}

bsurf_status bsurf_error_job(const bsurf_job_io *io, const bsurf_error_options *opts,
                             bsurf_error_job_summary *summary, bsurf_failure *err) {
  bsurf_error_options o = opts ? *opts : bsurf_error_options_default();
  bsurf_status st = bsurf_jobs_begin(__func__, io, summary, sizeof *summary);
  if (st != BSURF_OK) return st;
  summary->field_count = io->test ? BSURF_ERROR_JOB_FIELDS : BSURF_ERROR_JOB_FIELDS - 2;
  for (int f = 0; f < BSURF_ERROR_JOB_FIELDS; f++)
    summary->field_names[f] = error_field_names[f];
  if (io->cloud) return error_in_memory(io, &o, summary);
  BSURF_REQUIRE(!io->test, "io->test: a test sample is only available in memory");
  return error_tiled(io, &o, summary, err);
}
