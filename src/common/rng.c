/* Counter-based random numbers.
 *
 * The bootstrap (thesis 4.1.1) draws, for point i and replicate b, K indices
 * with replacement. To make results independent of thread count and order,
 * the stream for (seed, i, b) is a pure function of those three numbers: they
 * are mixed by SplitMix64 into the 256-bit state of xoshiro256** (Blackman &
 * Vigna), which then produces the draws. No state is shared between streams. */
#include "common/common.h"

#include <math.h>

static uint64_t splitmix64(uint64_t *x) {
  uint64_t z = (*x += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) {
  return (x << k) | (x >> (64 - k));
}

/* The first two mixing steps of bsurf_rng_init: (seed, a) only. */
static uint64_t rng_key(uint64_t seed, uint64_t a) {
  uint64_t x = seed;
  uint64_t k = splitmix64(&x);
  x = k ^ (a * 0xD1B54A32D192ED03ull);
  return splitmix64(&x);
}

void bsurf_rng_init(bsurf_rng *rng, uint64_t seed, uint64_t a, uint64_t b) {
  /* Mix the three keys one after the other so that (seed, a, b) and any
   * permutation of them give unrelated streams. */
  uint64_t x = rng_key(seed, a) ^ (b * 0x8CB92BA72F3D8DD7ull);
  for (int i = 0; i < 4; i++)
    rng->s[i] = splitmix64(&x);
  if ((rng->s[0] | rng->s[1] | rng->s[2] | rng->s[3]) == 0) rng->s[0] = 1;
}

/* The streams (seed, a, b + l), l < 4, as bsurf_rng_init: the keys' common
 * steps once, the last four in lanes (the bootstrap's four replicates at a
 * time; 50 initialisations a point were 4% of `normals -B 50`). */
BSURF_CLONES
void bsurf_rng_init4(bsurf_rng rng[4], uint64_t seed, uint64_t a, uint64_t b) {
  const uint64_t k = rng_key(seed, a);
  uint64_t x[4], s[4][4];
  for (int l = 0; l < 4; l++)
    x[l] = k ^ ((b + (uint64_t)l) * 0x8CB92BA72F3D8DD7ull);
  for (int i = 0; i < 4; i++)
    for (int l = 0; l < 4; l++)
      s[i][l] = splitmix64(&x[l]);
  for (int l = 0; l < 4; l++) {
    for (int i = 0; i < 4; i++)
      rng[l].s[i] = s[i][l];
    if ((rng[l].s[0] | rng[l].s[1] | rng[l].s[2] | rng[l].s[3]) == 0) rng[l].s[0] = 1;
  }
}

uint64_t bsurf_rng_next(bsurf_rng *rng) {
  uint64_t *s = rng->s;
  const uint64_t result = rotl(s[1] * 5, 7) * 9;
  const uint64_t t = s[1] << 17;
  s[2] ^= s[0];
  s[3] ^= s[1];
  s[1] ^= s[2];
  s[0] ^= s[3];
  s[2] ^= t;
  s[3] = rotl(s[3], 45);
  return result;
}

void bsurf_rng_fill_u32(bsurf_rng *rng, int n, uint32_t *u) {
  for (int j = 0; j < n; j += 2) { /* bsurf_rng_next inlined here */
    const uint64_t r = bsurf_rng_next(rng);
    u[j] = (uint32_t)r;
    if (j + 1 < n) u[j + 1] = (uint32_t)(r >> 32);
  }
}

double bsurf_rng_uniform(bsurf_rng *rng) {
  return (double)(bsurf_rng_next(rng) >> 11) * 0x1.0p-53;
}

uint32_t bsurf_rng_below(bsurf_rng *rng, uint32_t n) {
  /* Lemire's multiply-shift with rejection: exact and unbiased. */
  uint64_t m = (bsurf_rng_next(rng) >> 32) * (uint64_t)n;
  uint32_t low = (uint32_t)m;
  if (low < n) {
    uint32_t threshold = (uint32_t)(-n) % n;
    while (low < threshold) {
      m = (bsurf_rng_next(rng) >> 32) * (uint64_t)n;
      low = (uint32_t)m;
    }
  }
  return (uint32_t)(m >> 32);
}

double bsurf_rng_normal(bsurf_rng *rng) {
  /* Box-Muller; u1 in (0, 1] so the logarithm is finite. */
  double u1 = 1.0 - bsurf_rng_uniform(rng);
  double u2 = bsurf_rng_uniform(rng);
  return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}
