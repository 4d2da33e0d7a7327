/* bench_render — times bsurf_render on N points (a sphere coloured by a
 * field) at W x H, and the PNG encoding.
 *
 * usage: bench_render [N=1000000] [THREADS=2] [W=1024] [H=768] */
#include "bootsurf.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
  const size_t n = argc > 1 ? (size_t)strtoull(argv[1], NULL, 10) : 1000000;
  const int threads = argc > 2 ? atoi(argv[2]) : 2;
  const int w = argc > 3 ? atoi(argv[3]) : 1024, h = argc > 4 ? atoi(argv[4]) : 768;
  double *xyz = malloc(n * 3 * sizeof *xyz), *nrm = malloc(n * 3 * sizeof *nrm),
         *val = malloc(n * sizeof *val);
  uint8_t *rgb = malloc((size_t)w * h * 3);
  if (!xyz || !nrm || !val || !rgb) return 1;
  bsurf_rng rng;
  bsurf_rng_init(&rng, 1, 0, 0);
  for (size_t i = 0; i < n; i++) {
    double z = 2 * bsurf_rng_uniform(&rng) - 1, phi = 6.283185307179586 * bsurf_rng_uniform(&rng);
    double r = sqrt(1 - z * z);
    nrm[3 * i] = xyz[3 * i] = r * cos(phi);
    nrm[3 * i + 1] = xyz[3 * i + 1] = r * sin(phi);
    nrm[3 * i + 2] = xyz[3 * i + 2] = z;
    val[i] = z;
  }
  bsurf_render_options o = bsurf_render_options_default();
  o.width = w;
  o.height = h;
  o.threads = threads;
  o.spacing =
      sqrt(4 * 3.141592653589793 / (double)n) * 0.55; /* ~ mean nearest-neighbour distance */
  bsurf_render_info info;
  double best = 1e30, t0, t1;
  for (int rep = 0; rep < 3; rep++) {
    t0 = now();
    if (bsurf_render(rgb, xyz, nrm, n, val, &o, &info) != BSURF_OK) return 1;
    t1 = now();
    if (t1 - t0 < best) best = t1 - t0;
  }
  o.spacing = 0; /* the library's own estimate of h */
  t0 = now();
  if (bsurf_render(rgb, xyz, nrm, n, val, &o, &info) != BSURF_OK) return 1;
  double est = now() - t0;
  t0 = now();
  if (bsurf_write_png("bench_render.png", rgb, w, h, NULL) != BSURF_OK) return 1;
  double png = now() - t0;
  remove("bench_render.png");
  printf("render %zu points at %dx%d, %d threads: %.3f s (best of 3; %.3f s with h estimated, h = "
         "%.4g); PNG %.3f s\n",
         n, w, h, threads, best, est, info.spacing, png);
  free(xyz), free(nrm), free(val), free(rgb);
  return 0;
}
