/* Benchmark (not a test): points per second of feature detection (thesis
 * chapter 7), both methods with their defaults, on a noisy cube (random
 * sampling, uniform noise 0.5 h), computation only (no file I/O), each split
 * into the neighbourhood step and the detection step. The distance method's
 * detection is further split into the raw map (noise-adapted T_{a/c}:
 * the sampled per-size medians, then the growing PCA) and the rest (bilateral
 * filter passes and the automatic threshold). F1 against the cube's truth
 * labels is printed as a sanity check.
 * Usage: bench_features [N=1000000] [threads=2] [B=50] */
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

/* CPU time (user + system) of all threads so far: with other jobs on the
 * machine, CPU s / wall s shows how many cores the step actually had */
static double cpu(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
         (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
}

static void line(const char *what, double secs, double cpu_secs, size_t n) {
  printf("  %-36s %8.3f s  %12.0f points/s  (CPU %7.2f s)\n", what, secs, (double)n / secs,
         cpu_secs);
}

int main(int argc, char **argv) {
  size_t n = argc > 1 ? (size_t)atof(argv[1]) : 1000000;
  int threads = argc > 2 ? atoi(argv[2]) : 2;
  int B = argc > 3 ? atoi(argv[3]) : 50;
  bsurf_cloud c;
  if (bsurf_generate(&c, BSURF_SHAPE_CUBE, n, BSURF_SAMPLING_RANDOM, 1, 2.0) != BSURF_OK) return 1;
  n = c.point_count;
  double h;
  bsurf_mean_spacing(c.xyz, n, threads, &h);
  bsurf_add_noise(c.xyz, c.normals, n, BSURF_NOISE_UNIFORM, 0.5, h, 1);
  bsurf_field *tf = bsurf_cloud_field(&c, "feature");
  uint8_t *truth = malloc(n), *feat = malloc(n);
  double *score = malloc(n * sizeof(double));
  if (!tf || !truth || !feat || !score) return 1;
  for (size_t i = 0; i < n; i++)
    truth[i] = tf->values[i] != 0;

  bsurf_feature_options o = bsurf_feature_options_default();
  o.method = BSURF_FEATURES_DISTANCE; /* first; variance below */
  o.threads = threads;
  o.normals.bootstrap = B;
  printf("bench_features: cube N=%zu, uniform noise 0.5 h, threads=%d\n", n,
         bsurf_threads_resolve(threads));

  /* distance (7.1), defaults: k 15..60 step 2, noise factor 1.75, 5 filter passes */
  double t0 = now(), c0 = cpu();
  bsurf_neighbors nb;
  if (bsurf_neighbors_build(&nb, c.xyz, n, o.k_max, threads, NULL, NULL) != BSURF_OK) return 1;
  double t1 = now(), c1 = cpu();
  if (bsurf_feature_distance_raw(c.xyz, &nb, &o, score, NULL, NULL, NULL) != BSURF_OK) return 1;
  double t2 = now(), c2 = cpu();
  bsurf_feature_report rep;
  if (bsurf_detect_features(c.xyz, &nb, &o, feat, score, &rep) != BSURF_OK) return 1;
  double t3 = now(), c3 = cpu();
  bsurf_feature_stats s;
  bsurf_eval_features(feat, truth, n, &s);
  printf("distance (k %d..%d step %d, %d filter passes): T_{a/c} at k_min %.3g, F1 %.3f\n", o.k_min,
         o.k_max, o.k_step, o.iterations, rep.ratio_threshold_kmin, s.f1);
  line("neighbourhoods (K = 60)", t1 - t0, c1 - c0, n);
  line("raw map (medians + growing PCA)", t2 - t1, c2 - c1, n);
  line("detection (raw map + filter + T_h)", t3 - t2, c3 - c2, n);
  line("  of which filter + threshold", (t3 - t2) - (t2 - t1), (c3 - c2) - (c2 - c1), n);
  line("total (neighbourhoods + detection)", (t1 - t0) + (t3 - t2), (c1 - c0) + (c3 - c2), n);
  bsurf_neighbors_free(&nb);

  /* variance (7.2), defaults: K 30, B replicates, Otsu */
  o.method = BSURF_FEATURES_VARIANCE;
  t0 = now();
  c0 = cpu();
  if (bsurf_neighbors_build(&nb, c.xyz, n, o.normals.k, threads, NULL, NULL) != BSURF_OK) return 1;
  t1 = now();
  c1 = cpu();
  if (bsurf_detect_features(c.xyz, &nb, &o, feat, score, &rep) != BSURF_OK) return 1;
  t2 = now();
  c2 = cpu();
  bsurf_eval_features(feat, truth, n, &s);
  printf("variance (K %d, B %d, Otsu): F1 %.3f\n", o.normals.k, o.normals.bootstrap, s.f1);
  line("neighbourhoods (K = 30)", t1 - t0, c1 - c0, n);
  line("detection (bootstrap normals + t_h)", t2 - t1, c2 - c1, n);
  line("total", t2 - t0, c2 - c0, n);
  bsurf_neighbors_free(&nb);
  free(truth);
  free(feat);
  free(score);
  bsurf_cloud_free(&c);
  return 0;
}
