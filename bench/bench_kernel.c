/* Benchmark (not a test): the floating-point rate of the bootstrap fit
 * kernel against this CPU's peak, one thread, data in L1.
 *
 * One neighbourhood of K points (a noisy quadric patch) is analysed again and
 * again as `bootsurf error` analyses every point (bsurf_error_point: frame,
 * setup, B resamples, the (B + 1)-row normal-equation product, the solves, the
 * residual sums, the estimators), and each kernel is also timed alone, in CPU
 * time of the thread (so that other jobs on a shared machine do not count). The
 * floating-point operations are counted from the sizes (a multiply and an add
 * are two operations; square roots and divisions count one), so the rates are
 * useful work per second. The clock is measured with a chain of dependent
 * integer additions (one per cycle), and the peak is 16 double-precision
 * operations per cycle (two 4-wide multiplies and two 4-wide adds, or two
 * 4-wide FMAs, per cycle: AVX2 on AMD Zen 3 and Intel since Haswell).
 *
 * Usage: bench_kernel [K=50] [B=50] [degree=3] [seconds per kernel=1] */
#include "algo/algo.h"
#include "bootstrap/bootstrap.h"
#include "local/local.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* CPU time of this thread: other jobs on a shared machine do not count */
static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* cycles per CPU second: 2^28 dependent additions, one cycle each */
static double clock_hz(void) {
  double best = 0;
  for (int rep = 0; rep < 3; rep++) {
    unsigned long x = 0, n = 1ul << 22;
    double t0 = now();
    for (unsigned long i = 0; i < n; i++) {
#if defined(__x86_64__)
      __asm__ volatile(".rept 64\n\tadd $1, %0\n\t.endr" : "+r"(x));
#else
      x += 64;
#endif
    }
    double hz = (double)x / (now() - t0);
    if (hz > best) best = hz;
  }
  return best;
}

/* flops of one LDL^T solve of m unknowns as ldl_solve8 does it */
static double ldl_flops(int m) {
  double f = 0;
  for (int j = 0; j < m; j++) {
    f += 2.0 * j + 1;                         /* pivot: j multiply-subtracts, reciprocal */
    f += (double)(m - 1 - j) * (2.0 * j + 1); /* column below the pivot */
  }
  f += 2.0 * (double)m * m - m; /* forward and back substitution, D^-1 */
  return f;
}

typedef struct timing {
  const char *name;
  double seconds_per_call, flops_per_call;
} timing;

static void report(const timing *t, double hz) {
  double rate = t->flops_per_call / t->seconds_per_call;
  printf("  %-34s %10.3f us %12.0f flop %8.2f GFLOP/s %6.1f%% of peak\n", t->name,
         1e6 * t->seconds_per_call, t->flops_per_call, 1e-9 * rate, 100.0 * rate / (16.0 * hz));
}

int main(int argc, char **argv) {
  const int K = argc > 1 ? atoi(argv[1]) : 50;
  const int B = argc > 2 ? atoi(argv[2]) : 50;
  const int D = argc > 3 ? atoi(argv[3]) : 3;
  const double budget = argc > 4 ? atof(argv[4]) : 1.0;
  if (K < 10 || B < 1 || D < 1 || D > BSURF_DEGREE_MAX || K < bsurf_poly_terms(D)) {
    fprintf(stderr, "usage: bench_kernel [K>=10] [B>=1] [degree 1..4] [seconds]\n");
    return 2;
  }
  /* a noisy quadric patch, the centre first */
  double *xyz = malloc(sizeof(double) * 3 * (size_t)K);
  uint32_t *idx = malloc(sizeof(uint32_t) * (size_t)K);
  bsurf_rng rng;
  bsurf_rng_init(&rng, 7, 1, 2);
  for (int j = 0; j < K; j++) {
    double x = j ? bsurf_rng_uniform(&rng) * 2 - 1 : 0, y = j ? bsurf_rng_uniform(&rng) * 2 - 1 : 0;
    xyz[3 * j] = x;
    xyz[3 * j + 1] = y;
    xyz[3 * j + 2] =
        0.3 * x * x - 0.2 * x * y + 0.1 * y * y + 0.02 * (bsurf_rng_uniform(&rng) - 0.5);
    idx[j] = (uint32_t)j;
  }
  bsurf_error_options o = bsurf_error_options_default();
  o.k = K;
  o.bootstrap = B;
  o.degree = D;
  bsurf_error_scratch s;
  if (bsurf_error_scratch_alloc(&s, K, B, D) != BSURF_OK) return 1;
  double fields[8];
  bsurf_error_fields out;
  memset(&out, 0, sizeof out);
  out.err_train = &fields[0];
  out.err_boot = &fields[1];
  out.err_loo = &fields[2];
  out.err_loo_center = &fields[3];
  out.err_632 = &fields[4];
  out.err_632plus = &fields[5];
  out.gamma = &fields[6];
  out.overfit_rate = &fields[7];
  const double hz = clock_hz();
  const int m = bsurf_poly_terms(D), R = bsurf_boot_rows(B);

  /* the whole per-point analysis */
  bsurf_error_point(xyz, idx, NULL, &o, 0, &s, &out, NULL);
  const bsurf_localfit *lf = &s.lf;
  const int nc = lf->ncols;
  /* the dense product counts a multiply and an add per weight; the draws'
   * sums (what bsurf_error_point runs) one add per draw, plus row B */
  const double f_gemm = 2.0 * R * K * nc, f_draws = (B + 1.0) * K * nc, f_ldl = B * ldl_flops(m);
  const double f_resid = (double)B * K * (2.0 * m + 5);
  const double f_setup = K * (15.0 + bsurf_poly_terms(2 * D) + m);
  size_t calls = 0;
  double t0 = now();
  while (now() - t0 < budget)
    for (int r = 0; r < 100; r++, calls++)
      bsurf_error_point(xyz, idx, NULL, &o, 0, &s, &out, NULL);
  timing whole = {"bsurf_error_point (all of it)", (now() - t0) / (double)calls,
                  f_draws + f_ldl + f_resid + f_setup};

  /* each kernel alone, on the state the last point left; the dense
   * product (normals with PCA, tests) on that point's counts as weights */
  double *W = calloc((size_t)R * K, sizeof(double));
  if (!W) return 1;
  for (int b = 0; b <= B; b++)
    for (int j = 0; j < K; j++)
      W[(size_t)b * K + j] = b < B ? s.counts[(size_t)b * K + j] : 1.0;
  timing t_gemm = {"normal equations (gemm_lanes)", 0, f_gemm};
  calls = 0;
  t0 = now();
  while (now() - t0 < budget)
    for (int r = 0; r < 100; r++, calls++)
      bsurf_localfit_normal_eq_lanes(lf, R, W, s.rows);
  t_gemm.seconds_per_call = (now() - t0) / (double)calls;

  /* the error pass's product: one add per draw and column (half the flop) */
  timing t_draws = {"normal equations from draws", 0, f_draws};
  calls = 0;
  t0 = now();
  while (now() - t0 < budget)
    for (int r = 0; r < 100; r++, calls++)
      bsurf_localfit_normal_eq_draws(lf, B, s.draws, s.rows);
  t_draws.seconds_per_call = (now() - t0) / (double)calls;

  timing t_ldl = {"LDL^T solves (solve_lanes)", 0, f_ldl};
  unsigned char *valid = malloc((size_t)B);
  calls = 0;
  t0 = now();
  while (now() - t0 < budget)
    for (int r = 0; r < 100; r++, calls++) {
      memset(valid, 1, (size_t)B);
      bsurf_localfit_solve_lanes(lf, D, B, s.rows, valid, s.coefs);
    }
  t_ldl.seconds_per_call = (now() - t0) / (double)calls;

  timing t_res = {"predictions + residual sums", 0, f_resid};
  double *sums = malloc(sizeof(double) * 3 * (size_t)K);
  calls = 0;
  t0 = now();
  while (now() - t0 < budget)
    for (int r = 0; r < 100; r++, calls++)
      bsurf_localfit_residual_sums(lf, D, B, s.coefs, valid, s.counts, sums, sums + K,
                                   sums + 2 * K);
  t_res.seconds_per_call = (now() - t0) / (double)calls;

  timing t_counts = {"resampling (counts + draws)", 0, 0};
  calls = 0;
  t0 = now();
  while (now() - t0 < budget)
    for (int r = 0; r < 100; r++, calls++)
      bsurf_boot_draw_rows(1, calls, B, K, m, s.counts, s.draws, valid);
  t_counts.seconds_per_call = (now() - t0) / (double)calls;

  printf("bench_kernel: K=%d B=%d degree=%d (m=%d terms, %d normal-equation columns, %d rows)\n", K,
         B, D, m, nc, R);
  printf("  clock %.3f GHz (dependent adds); peak %.1f GFLOP/s per core (16 flop/cycle)\n",
         1e-9 * hz, 16e-9 * hz);
  report(&whole, hz);
  report(&t_gemm, hz);
  report(&t_draws, hz);
  report(&t_ldl, hz);
  report(&t_res, hz);
  printf("  %-34s %10.3f us (%d draws, integer work)\n", t_counts.name,
         1e6 * t_counts.seconds_per_call, B * K);
  printf("  points/s per core at this rate: %.0f (error pass without kNN, frames in L1)\n",
         1.0 / whole.seconds_per_call);
  free(sums);
  free(valid);
  free(W);
  bsurf_error_scratch_free(&s);
  free(xyz);
  free(idx);
  return 0;
}
