/* error_bootsurf — `bootsurf error` through the library, timed like the peers:
 * computation only, no file I/O.
 *
 * usage: error_bootsurf INPUT.ply -o OUTPUT.ply [-k 50] [-B 50] [-d 3] [-j 2]
 *
 * `bootsurf error --json` reports "seconds" for the whole command, reading and
 * writing included. This driver makes the library calls of cli/cmd_error.c for
 * a plain run (no --test-sample) and times only them: bsurf_neighbors_build
 * (k-d tree, all-kNN, h; "seconds_neighbors") + bsurf_estimate_error with all
 * eight per-point outputs ("seconds_estimate"). Not timed: reading, writing.
 * The output holds x y z and err_632plus (float32, as the CLI writes it), so
 * bench/peers/kernels.py can check it against the CLI's. */
#include "bootsurf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bs_driver.h"

static int usage(void) {
  fprintf(stderr, "usage: error_bootsurf INPUT.ply -o OUTPUT.ply [-k 50] [-B 50] [-d 3] [-j 2]\n");
  return 2;
}

int main(int argc, char **argv) {
  const char *in = NULL, *out = NULL;
  bsurf_error_options eo = bsurf_error_options_default();
  eo.threads = 2;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    const int has = i + 1 < argc;
    if (!strcmp(a, "-o") && has)
      out = argv[++i];
    else if (!strcmp(a, "-k") && has)
      eo.k = atoi(argv[++i]);
    else if (!strcmp(a, "-B") && has)
      eo.bootstrap = atoi(argv[++i]);
    else if (!strcmp(a, "-d") && has)
      eo.degree = atoi(argv[++i]);
    else if (!strcmp(a, "-j") && has)
      eo.threads = atoi(argv[++i]);
    else if (a[0] == '-' || in)
      return usage();
    else
      in = a;
  }
  if (!in || !out || eo.k < 3 || eo.threads < 1) return usage();

  bsurf_cloud c;
  if (driver_read("error_bootsurf", in, &c)) return 1;
  bsurf_failure where;
  memset(&where, 0, sizeof where);
  const size_t n = c.point_count;
  double *v = malloc(n * 8 * sizeof *v); /* the CLI's eight fields */
  if (!v) {
    fprintf(stderr, "error_bootsurf: out of memory\n");
    return 1;
  }
  bsurf_error_fields f;
  memset(&f, 0, sizeof f);
  double **slot[8] = {&f.err_train, &f.err_boot,    &f.err_loo, &f.err_loo_center,
                      &f.err_632,   &f.err_632plus, &f.gamma,   &f.overfit_rate};
  for (int i = 0; i < 8; i++)
    *slot[i] = v + (size_t)i * n;
  bsurf_neighbors nb;
  memset(&nb, 0, sizeof nb);
  bsurf_error_report rep;
  memset(&rep, 0, sizeof rep);

  const double c0 = cpu_seconds();
  const double t0 = now();
  bsurf_status st = bsurf_neighbors_build(&nb, c.xyz, n, eo.k, eo.threads, NULL, NULL);
  const double t1 = now();
  if (st == BSURF_OK) st = bsurf_estimate_error(c.xyz, &nb, NULL, &eo, &f, &rep);
  const double t2 = now();
  const double cpu = cpu_seconds() - c0;
  if (st != BSURF_OK) {
    fprintf(stderr, "error_bootsurf: %s\n", bsurf_strerror(st));
    return 1;
  }
  double mean = 0.0;
  for (size_t i = 0; i < n; i++)
    mean += f.err_632plus[i];
  mean /= (double)n;

  bsurf_cloud o;
  bsurf_cloud_init(&o);
  bsurf_field *fo = NULL;
  if (bsurf_cloud_alloc(&o, n, 0) != BSURF_OK ||
      !(fo = bsurf_cloud_add_field(&o, "err_632plus", BSURF_FLOAT32))) {
    fprintf(stderr, "error_bootsurf: out of memory\n");
    return 1;
  }
  memcpy(o.xyz, c.xyz, n * 3 * sizeof(double));
  memcpy(fo->values, f.err_632plus, n * sizeof(double));
  if (bsurf_write(out, &o, NULL, &where) != BSURF_OK) {
    fprintf(stderr, "error_bootsurf: %s: %s\n", out, where.message);
    return 1;
  }
  printf("{\"peer\":\"bootsurf\",\"method\":\"error\",\"degree\":%d,\"bootstrap\":%d,\"k\":%d,"
         "\"threads\":%d,\"points\":%zu,\"seconds\":%.6f,\"cpu_seconds\":%.6f,"
         "\"seconds_neighbors\":%.6f,\"seconds_estimate\":%.6f,\"h\":%.10g,"
         "\"mean_err_632plus_h\":%.6f,\"peak_rss_kb\":%ld,"
         "\"timed\":\"bsurf_neighbors_build + bsurf_estimate_error\"}\n",
         eo.degree, eo.bootstrap, eo.k, bsurf_threads_resolve(eo.threads), n, t2 - t0, cpu, t1 - t0,
         t2 - t1, nb.h, mean / nb.h, peak_rss_kb());
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&o);
  bsurf_cloud_free(&c);
  free(v);
  return 0;
}
