/* bs_driver.h — what the C drivers that time bootsurf's library like a peer
 * (normals_bootsurf.c, knn_bootsurf.c, error_bootsurf.c) share: a monotonic
 * clock, CPU time of all threads, the peak RSS, and the per-row check file of
 * the kNN comparison, reading the input. Header-only (static functions), C11;
 * include it after bootsurf.h. */
#ifndef BS_DRIVER_H
#define BS_DRIVER_H

#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

static inline double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* user + system time of all threads of this process so far, seconds */
static inline double cpu_seconds(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
         (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
}

/* peak resident set size of this process so far, kB (Linux) */
static inline long peak_rss_kb(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss;
}

/* Reads `path` into c (initialised here); on failure prints "prog: path: why"
 * and returns -1. Untimed in every driver. */
static inline int driver_read(const char *prog, const char *path, bsurf_cloud *c) {
  bsurf_failure where;
  memset(&where, 0, sizeof where);
  bsurf_cloud_init(c);
  if (bsurf_read(path, c, &where) == BSURF_OK) return 0;
  fprintf(stderr, "%s: %s: %s\n", prog, path, where.message);
  return -1;
}

/* The kNN comparison's check file: per row of the n x k squared distances
 * (row-major), their sum and their largest, as n x 2 little-endian doubles
 * (x86). Equal rows mean equal neighbour distances whatever the tie order.
 * Returns 0 on success. */
static inline int write_knn_check(const char *path, const double *dist2, size_t n, int k) {
  FILE *f = fopen(path, "wb");
  if (!f) return -1;
  int bad = 0;
  for (size_t i = 0; i < n && !bad; i++) {
    double row[2] = {0.0, 0.0};
    for (int j = 0; j < k; j++) {
      const double d = dist2[i * (size_t)k + (size_t)j];
      row[0] += d;
      if (d > row[1]) row[1] = d;
    }
    bad = fwrite(row, sizeof row, 1, f) != 1;
  }
  return fclose(f) != 0 || bad ? -1 : 0;
}

#endif
