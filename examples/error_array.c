/* Test error of an array of points in memory (thesis Algorithm 1): samples a
 * paraboloid z = (x^2 + y^2) / 2 with Gaussian noise of standard deviation
 * sigma along z, and prints the mean bootstrap estimates next to sigma.
 * Usage: error_array [POINTS [SIGMA]] (10000, 0.01) */
#include <bootsurf.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
  size_t n = argc > 1 ? (size_t)strtoul(argv[1], NULL, 10) : 10000;
  double sigma = argc > 2 ? atof(argv[2]) : 0.01;
  if (bsurf_version() != BSURF_VERSION_NUMBER)
    fprintf(stderr, "note: compiled with bootsurf %s, running with %s\n", BSURF_VERSION_STRING,
            bsurf_version_string());

  double *xyz = malloc(n * 3 * sizeof *xyz);
  double *err_train = malloc(n * sizeof *err_train), *err_632plus = malloc(n * sizeof *err_632plus);
  if (!xyz || !err_train || !err_632plus) return 1;
  bsurf_rng rng;
  bsurf_rng_init(&rng, 7, 0, 0); /* any generator would do: the library's is at hand */
  for (size_t i = 0; i < n; i++) {
    double x = 2 * bsurf_rng_uniform(&rng) - 1, y = 2 * bsurf_rng_uniform(&rng) - 1;
    xyz[3 * i] = x;
    xyz[3 * i + 1] = y;
    xyz[3 * i + 2] = 0.5 * (x * x + y * y) + sigma * bsurf_rng_normal(&rng);
  }

  bsurf_error_options opt = bsurf_error_options_default(); /* K = 50, cubic, B = 50 */
  bsurf_neighbors nb;
  bsurf_status st = bsurf_neighbors_build(&nb, xyz, n, opt.k, 0, NULL, NULL);
  if (st == BSURF_OK) {
    bsurf_error_fields out = {0}; /* outputs not wanted stay NULL */
    out.err_train = err_train;
    out.err_632plus = err_632plus;
    bsurf_error_report rep;
    st = bsurf_estimate_error(xyz, &nb, NULL, &opt, &out, &rep);
    bsurf_neighbors_free(&nb);
  }
  if (st != BSURF_OK) {
    fprintf(stderr, "error_array: %s\n", bsurf_strerror(st));
    return 1;
  }
  double train = 0, plus = 0;
  for (size_t i = 0; i < n; i++) {
    train += err_train[i];
    plus += err_632plus[i];
  }
  /* for Gaussian noise the mean absolute error of a point is sigma sqrt(2/pi) */
  printf("%zu points, sigma = %g: mean err_train = %.4g, err_632plus = %.4g, "
         "sigma sqrt(2/pi) = %.4g\n",
         n, sigma, train / (double)n, plus / (double)n, sigma * sqrt(2 / acos(-1.0)));
  free(xyz);
  free(err_train);
  free(err_632plus);
  return 0;
}
