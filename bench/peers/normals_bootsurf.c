/* normals_bootsurf — bootsurf's normals through the library, timed like the
 * peers: computation only, no file I/O.
 *
 * usage: normals_bootsurf INPUT.ply -o OUTPUT.ply [-k 30] [-j 2] [--fit pca|poly] [-d 2] [-B 0]
 *
 * `bootsurf normals --json` reports "seconds" for the whole command, reading and
 * writing the files included. This driver makes the same library calls as
 * cli/cmd_normals.c for a plain run (no --test-error/--select-k/smoothing/
 * orientation) and times only them: bsurf_neighbors_build (k-d tree, all-kNN,
 * h) + bsurf_estimate_normals. The output must be bit-identical to the CLI's
 * normals (bench/normals_compare.sh checks it once per input).
 *
 * Built by bench/peers/build.sh against a bootsurf build directory
 * (include/bootsurf.h, libbootsurf.a, OpenMP). */
#include "bootsurf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bs_driver.h"

static int usage(void) {
  fprintf(stderr, "usage: normals_bootsurf INPUT.ply -o OUTPUT.ply [-k 30] [-j 2] "
                  "[--fit pca|poly] [-d 2] [-B 0]\n");
  return 2;
}

int main(int argc, char **argv) {
  const char *in = NULL, *out = NULL, *fit = "pca";
  bsurf_normal_options no = bsurf_normal_options_default();
  no.k = 30;
  no.threads = 2;
  no.bootstrap = 0;
  no.degree = 2;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    int has = i + 1 < argc;
    if (!strcmp(a, "-o") && has)
      out = argv[++i];
    else if (!strcmp(a, "-k") && has)
      no.k = atoi(argv[++i]);
    else if (!strcmp(a, "-j") && has)
      no.threads = atoi(argv[++i]);
    else if (!strcmp(a, "-d") && has)
      no.degree = atoi(argv[++i]);
    else if (!strcmp(a, "-B") && has)
      no.bootstrap = atoi(argv[++i]);
    else if (!strcmp(a, "--fit") && has)
      fit = argv[++i];
    else if (a[0] == '-')
      return usage();
    else if (!in)
      in = a;
    else
      return usage();
  }
  if (!in || !out || no.k < 3) return usage();
  if (!strcmp(fit, "pca"))
    no.fit = BSURF_NORMAL_PCA;
  else if (!strcmp(fit, "poly"))
    no.fit = BSURF_NORMAL_POLY;
  else
    return usage();

  bsurf_cloud c;
  if (driver_read("normals_bootsurf", in, &c)) return 1;
  bsurf_failure where;
  memset(&where, 0, sizeof where);
  const size_t n = c.point_count;
  double *normals = malloc(n * 3 * sizeof(double));
  double *var = calloc(n, sizeof(double)); /* the CLI always asks for normal_var */
  if (!normals || !var) {
    fprintf(stderr, "normals_bootsurf: out of memory\n");
    return 1;
  }
  bsurf_neighbors nb;
  memset(&nb, 0, sizeof nb);
  bsurf_normal_report rep;
  memset(&rep, 0, sizeof rep);
  bsurf_normal_fields f = {normals, var, NULL};

  const double c0 = cpu_seconds();
  const double t0 = now();
  bsurf_status st = bsurf_neighbors_build(&nb, c.xyz, n, no.k, no.threads, NULL, NULL);
  const double t1 = now();
  if (st == BSURF_OK) st = bsurf_estimate_normals(c.xyz, &nb, NULL, &no, &f, &rep);
  const double t2 = now();
  const double cpu = cpu_seconds() - c0;
  if (st != BSURF_OK) {
    fprintf(stderr, "normals_bootsurf: %s\n", bsurf_strerror(st));
    return 1;
  }

  /* the output: positions and normals only (the CLI also keeps the input's
   * other fields and adds normal_var; not needed for the angle errors) */
  bsurf_cloud o;
  bsurf_cloud_init(&o);
  if (bsurf_cloud_alloc(&o, n, 1) != BSURF_OK) {
    fprintf(stderr, "normals_bootsurf: out of memory\n");
    return 1;
  }
  memcpy(o.xyz, c.xyz, n * 3 * sizeof(double));
  memcpy(o.normals, normals, n * 3 * sizeof(double));
  o.normal_type = BSURF_FLOAT64;
  if (bsurf_write(out, &o, NULL, &where) != BSURF_OK) {
    fprintf(stderr, "normals_bootsurf: %s: %s\n", out, where.message);
    return 1;
  }
  printf("{\"peer\":\"bootsurf\",\"method\":\"%s\",\"degree\":%d,\"bootstrap\":%d,\"k\":%d,"
         "\"threads\":%d,\"points\":%zu,\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"seconds_"
         "neighbors\":%.6f,"
         "\"seconds_normals\":%.6f,\"peak_rss_kb\":%ld,\"degenerate\":%zu,"
         "\"timed\":\"bsurf_neighbors_build + bsurf_estimate_normals\"}\n",
         fit, no.fit == BSURF_NORMAL_POLY ? no.degree : 1, no.bootstrap, no.k, no.threads, n,
         t2 - t0, cpu, t1 - t0, t2 - t1, peak_rss_kb(), rep.degenerate);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&o);
  bsurf_cloud_free(&c);
  free(normals);
  free(var);
  return 0;
}
