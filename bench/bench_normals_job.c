/* Benchmark (not a test): the C side of bench/python_overhead.py. Times one
 * bsurf_normals_job call in memory (the call bootsurf.normals makes) on a
 * noisy random sphere, untimed generation first.
 * Usage: bench_normals_job [N=1000000] [threads=2] [K=30] [B=10] [progress=1]
 *        [hugepages=0]
 * progress 1: a progress callback that never cancels, as the CLI's progress
 * bar and the Python package's Ctrl-C check are (the library then works in
 * chunks of 4096 points between callbacks); 0: none (one parallel region).
 * hugepages 1: the points are copied into memory advised for transparent
 * huge pages (madvise MADV_HUGEPAGE), as numpy allocates every array of
 * 4 MiB or more on Linux: bench/python_overhead.py then compares the call on
 * the same kind of memory as the Python array's (random reads of the points
 * cost differently on huge pages, by 10-40% either way depending on the
 * machine; docs/python.md, "Overhead").
 * Prints one JSON line: {"points", "seconds" (wall), "cpu_seconds" (every
 * thread's), "minor_faults" (pages first touched during the call),
 * "mean_normal_var"}. */
#define _DEFAULT_SOURCE /* madvise */
#include "bootsurf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <time.h>

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU time of the process (every thread), and its minor page faults */
static double cpu_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static long minor_faults(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_minflt;
}

static int keep_going(void *user, size_t done, size_t total) {
  (void)user;
  (void)done;
  (void)total;
  return 0;
}

int main(int argc, char **argv) {
  size_t n = argc > 1 ? (size_t)atof(argv[1]) : 1000000;
  bsurf_normals_job_options o = bsurf_normals_job_options_default();
  o.normals.threads = argc > 2 ? atoi(argv[2]) : 2;
  o.normals.k = argc > 3 ? atoi(argv[3]) : 30;
  o.normals.bootstrap = argc > 4 ? atoi(argv[4]) : 10;
  if (argc <= 5 || atoi(argv[5])) o.normals.progress = keep_going;
  bsurf_cloud c;
  if (bsurf_generate(&c, BSURF_SHAPE_SPHERE, n, BSURF_SAMPLING_RANDOM, 1, 0) != BSURF_OK) return 1;
  bsurf_noise_options no = bsurf_noise_options_default();
  if (bsurf_noise_points(c.xyz, c.normals, c.point_count, &no, NULL) != BSURF_OK) return 1;
  /* bootsurf.normals hands the job a cloud of points only */
  free(c.normals);
  c.normals = NULL;
  while (c.field_count)
    bsurf_cloud_remove_field(&c, c.fields[0].name);
  double *own = c.xyz, *huge = NULL;
  size_t bytes = c.point_count * 3 * sizeof(double), align = (size_t)2 << 20;
  if (argc > 6 && atoi(argv[6])) {
    if (posix_memalign((void **)&huge, align, (bytes + align - 1) / align * align)) return 1;
    madvise(huge, (bytes + align - 1) / align * align, MADV_HUGEPAGE);
    memcpy(huge, own, bytes);
    c.xyz = huge;
  }
  bsurf_job_io io = {0};
  io.cloud = &c;
  bsurf_normals_job_summary s;
  long f0 = minor_faults();
  double c0 = cpu_now(), t0 = now();
  bsurf_status st = bsurf_normals_job(&io, &o, &s, NULL);
  double secs = now() - t0, cpu = cpu_now() - c0;
  long faults = minor_faults() - f0;
  if (st != BSURF_OK) {
    fprintf(stderr, "bench_normals_job: %s\n", bsurf_last_message());
    return 1;
  }
  printf("{\"points\": %zu, \"seconds\": %.6f, \"cpu_seconds\": %.6f, \"minor_faults\": %ld, "
         "\"mean_normal_var\": %.17g}\n",
         s.points, secs, cpu, faults, s.means[0]);
  c.xyz = own;
  free(huge);
  bsurf_cloud_free(&c);
  return 0;
}
