/* Benchmark (not a test): points per second of the bootstrap error estimate
 * (K = 50, B = 50, cubic by default) on a noisy sphere, computation only (no
 * file I/O), split into the neighbourhood step and the estimation step.
 * Usage: bench_error [N=1000000] [threads=2] [K=50] [B=50] [degree=3]
 * Prints wall time, CPU time (user + system, all threads) and points/s of each
 * step, then one JSON line with the same numbers and the process's peak RSS
 * (bench/scaling.sh reads it). The sphere (bsurf_generate, random sampling,
 * seed 1) and its noise (0.5 h, seed 1) are made first, untimed. */
#include "bootsurf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double cpu_now(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
         (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
}

int main(int argc, char **argv) {
  size_t n = argc > 1 ? (size_t)atof(argv[1]) : 1000000;
  int threads = argc > 2 ? atoi(argv[2]) : 2;
  bsurf_error_options o = bsurf_error_options_default();
  o.k = argc > 3 ? atoi(argv[3]) : 50;
  o.bootstrap = argc > 4 ? atoi(argv[4]) : 50;
  o.degree = argc > 5 ? atoi(argv[5]) : 3;
  o.threads = threads;
  bsurf_cloud c;
  if (bsurf_generate(&c, BSURF_SHAPE_SPHERE, n, BSURF_SAMPLING_RANDOM, 1, 0) != BSURF_OK) return 1;
  double h;
  bsurf_mean_spacing(c.xyz, c.point_count, threads, &h);
  bsurf_add_noise(c.xyz, c.normals, c.point_count, BSURF_NOISE_GAUSSIAN, 0.5, h, 1);
  double c0 = cpu_now(), t0 = now();
  bsurf_neighbors nb;
  if (bsurf_neighbors_build(&nb, c.xyz, c.point_count, o.k, threads, NULL, NULL) != BSURF_OK)
    return 1;
  double c1 = cpu_now(), t1 = now();
  double *v = malloc(sizeof(double) * c.point_count * 8);
  bsurf_error_fields out;
  memset(&out, 0, sizeof out);
  out.err_train = v;
  out.err_boot = v + c.point_count;
  out.err_loo = v + 2 * c.point_count;
  out.err_loo_center = v + 3 * c.point_count;
  out.err_632 = v + 4 * c.point_count;
  out.err_632plus = v + 5 * c.point_count;
  out.gamma = v + 6 * c.point_count;
  out.overfit_rate = v + 7 * c.point_count;
  if (bsurf_estimate_error(c.xyz, &nb, NULL, &o, &out, NULL) != BSURF_OK) return 1;
  double c2 = cpu_now(), t2 = now();
  double total = t2 - t0;
  printf("bench_error: N=%zu K=%d B=%d degree=%d threads=%d\n", c.point_count, o.k, o.bootstrap,
         o.degree, bsurf_threads_resolve(threads));
  printf("  neighbourhoods  %8.3f s  %12.0f points/s  CPU %8.3f s\n", t1 - t0,
         c.point_count / (t1 - t0), c1 - c0);
  printf("  estimation      %8.3f s  %12.0f points/s  CPU %8.3f s\n", t2 - t1,
         c.point_count / (t2 - t1), c2 - c1);
  printf("  total           %8.3f s  %12.0f points/s  CPU %8.3f s\n", total, c.point_count / total,
         c2 - c0);
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  printf("{\"points\":%zu,\"k\":%d,\"bootstrap\":%d,\"degree\":%d,\"threads\":%d,"
         "\"seconds_neighbors\":%.6f,\"seconds_estimate\":%.6f,\"seconds\":%.6f,"
         "\"cpu_neighbors\":%.6f,\"cpu_estimate\":%.6f,\"cpu_seconds\":%.6f,\"peak_rss_kb\":%ld}\n",
         c.point_count, o.k, o.bootstrap, o.degree, bsurf_threads_resolve(threads), t1 - t0,
         t2 - t1, total, c1 - c0, c2 - c1, c2 - c0, ru.ru_maxrss);
  free(v);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&c);
  return 0;
}
