/* bench_knn — times the k-d tree build and the all-K-nearest-neighbour search.
 *
 * usage: bench_knn [N=1000000] [K=50] [THREADS=2]
 * N points uniform on the unit sphere surface (a scanned surface is what the
 * library sees), from the library's counter-based generator (seed 1). */
#include "bootsurf.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double clock_s(clockid_t id) {
  struct timespec ts;
  clock_gettime(id, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double now(void) {
  return clock_s(CLOCK_MONOTONIC);
}

/* CPU time of all the process's threads: on a shared machine the wall time
 * also counts the time other jobs held the cores. */
static double cpu(void) {
  return clock_s(CLOCK_PROCESS_CPUTIME_ID);
}

int main(int argc, char **argv) {
  const size_t n = argc > 1 ? (size_t)strtoull(argv[1], NULL, 10) : 1000000;
  const int k = argc > 2 ? atoi(argv[2]) : 50;
  const int threads = argc > 3 ? atoi(argv[3]) : 2;
  double *xyz, t0, t1, t2, c0, c1, c2, checksum = 0.0;
  uint32_t *idx;
  double *dist2;
  bsurf_knn_index *index = NULL;
  bsurf_rng rng;
  bsurf_status st;

  if (n == 0 || k < 1 || (size_t)k > n) {
    fprintf(stderr, "usage: bench_knn [N>0] [1<=K<=N] [THREADS]\n");
    return 2;
  }
  xyz = malloc(n * 3 * sizeof *xyz);
  idx = malloc(n * (size_t)k * sizeof *idx);
  dist2 = malloc(n * (size_t)k * sizeof *dist2);
  if (!xyz || !idx || !dist2) {
    fprintf(stderr, "bench_knn: out of memory\n");
    return 1;
  }
  /* Touch the outputs first: the timing is the search's, not page faults'. */
  memset(idx, 0, n * (size_t)k * sizeof *idx);
  memset(dist2, 0, n * (size_t)k * sizeof *dist2);
  bsurf_rng_init(&rng, 1, 0, 0);
  for (size_t i = 0; i < n; i++) {
    const double z = 2.0 * bsurf_rng_uniform(&rng) - 1.0;
    const double phi = 6.283185307179586 * bsurf_rng_uniform(&rng);
    const double s = sqrt(1.0 - z * z);
    xyz[3 * i] = s * cos(phi);
    xyz[3 * i + 1] = s * sin(phi);
    xyz[3 * i + 2] = z;
  }

  c0 = cpu();
  t0 = now();
  st = bsurf_knn_build(&index, xyz, n);
  t1 = now();
  c1 = cpu();
  if (st != BSURF_OK) {
    fprintf(stderr, "bench_knn: build: %s\n", bsurf_strerror(st));
    return 1;
  }
  printf("knn build: %zu points in %.3f s (cpu %.3f s)\n", n, t1 - t0, c1 - c0);
  fflush(stdout);

  st = bsurf_knn_all(index, k, threads, idx, dist2, NULL, NULL);
  t2 = now();
  c2 = cpu();
  if (st != BSURF_OK) {
    fprintf(stderr, "bench_knn: all: %s\n", bsurf_strerror(st));
    return 1;
  }
  for (size_t i = 0; i < n; i++)
    checksum += dist2[i * (size_t)k + (size_t)k - 1];
  printf("knn all K=%d threads=%d: %.3f s, %.0f points/s (cpu %.3f s)\n", k,
         bsurf_threads_resolve(threads), t2 - t1, (double)n / (t2 - t1), c2 - c1);
  printf("mean K-th neighbour distance^2: %.6g\n", checksum / (double)n);

  bsurf_knn_free(index);
  free(xyz);
  free(idx);
  free(dist2);
  return 0;
}
