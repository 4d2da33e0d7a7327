/* knn_bootsurf — bootsurf's all-K-nearest-neighbour search through the library,
 * timed like the kNN peers (knn_nanoflann.cpp, knn_open3d.py): no file I/O.
 *
 * usage: knn_bootsurf INPUT.ply -o CHECK.f64 [-k 50] [-j 2]
 *
 * Timed (monotonic clock): bsurf_knn_build (the k-d tree, sequential) as
 * "seconds_build", bsurf_knn_all (every point's K nearest, the point itself
 * first, sorted; K x 4-byte indices and K x 8-byte squared distances per point
 * into arrays allocated, untouched, before the clock starts) as
 * "seconds_search"; "seconds" is their sum. This is the search every bootsurf
 * command runs (bsurf_neighbors_build adds h from the same lists).
 *
 * CHECK.f64: per point the sum and the largest of its K squared distances
 * (bs_driver.h); bench/peers/kernels.py compares it with the peers'. */
#include "bootsurf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bs_driver.h"

static int usage(void) {
  fprintf(stderr, "usage: knn_bootsurf INPUT.ply -o CHECK.f64 [-k 50] [-j 2]\n");
  return 2;
}

int main(int argc, char **argv) {
  const char *in = NULL, *out = NULL;
  int k = 50, threads = 2;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    const int has = i + 1 < argc;
    if (!strcmp(a, "-o") && has)
      out = argv[++i];
    else if (!strcmp(a, "-k") && has)
      k = atoi(argv[++i]);
    else if (!strcmp(a, "-j") && has)
      threads = atoi(argv[++i]);
    else if (a[0] == '-' || in)
      return usage();
    else
      in = a;
  }
  if (!in || !out || k < 1 || threads < 1) return usage();
  bsurf_cloud c;
  if (driver_read("knn_bootsurf", in, &c)) return 1;
  const size_t n = c.point_count;
  if ((size_t)k > n) {
    fprintf(stderr, "knn_bootsurf: K = %d > %zu points\n", k, n);
    return 2;
  }
  uint32_t *idx = malloc(n * (size_t)k * sizeof *idx);
  double *dist2 = malloc(n * (size_t)k * sizeof *dist2);
  if (!idx || !dist2) {
    fprintf(stderr, "knn_bootsurf: out of memory\n");
    return 1;
  }
  bsurf_knn_index *index = NULL;
  const double c0 = cpu_seconds();
  const double t0 = now();
  bsurf_status st = bsurf_knn_build(&index, c.xyz, n);
  const double t1 = now();
  if (st == BSURF_OK) st = bsurf_knn_all(index, k, threads, idx, dist2, NULL, NULL);
  const double t2 = now();
  const double cpu = cpu_seconds() - c0;
  if (st != BSURF_OK) {
    fprintf(stderr, "knn_bootsurf: %s\n", bsurf_strerror(st));
    return 1;
  }
  if (write_knn_check(out, dist2, n, k)) {
    fprintf(stderr, "knn_bootsurf: %s: cannot write\n", out);
    return 1;
  }
  printf(
      "{\"peer\":\"bootsurf\",\"method\":\"bsurf_knn_all\",\"k\":%d,\"threads\":%d,\"points\":%zu,"
      "\"seconds\":%.6f,\"seconds_build\":%.6f,\"seconds_search\":%.6f,\"cpu_seconds\":%.6f,"
      "\"peak_rss_kb\":%ld,\"timed\":\"bsurf_knn_build + bsurf_knn_all\"}\n",
      k, bsurf_threads_resolve(threads), n, t2 - t0, t1 - t0, t2 - t1, cpu, peak_rss_kb());
  bsurf_knn_free(index);
  free(idx);
  free(dist2);
  bsurf_cloud_free(&c);
  return 0;
}
