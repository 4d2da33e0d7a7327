/* Creation of bootstrap sets (thesis 4.1.1, Eqs. 4.1-4.2): a sample S_b of
 * the same size K as the neighbourhood, drawn with replacement. We store it
 * as multiplicities (how often each neighbour was drawn), which is all a
 * least-squares fit and the leave-one-out bookkeeping (b in C_j iff the
 * count of j is 0) need. */
#include "bootstrap/bootstrap.h"

#include <string.h>

void bsurf_boot_counts(uint64_t seed, uint64_t point, uint32_t replicate, int k,
                       uint16_t *counts) {
  bsurf_rng rng;
  bsurf_rng_init(&rng, seed, point, replicate);
  memset(counts, 0, (size_t)k * sizeof *counts);
  /* Two draws from each 64-bit output: Lemire's multiply-shift on each
   * 32-bit half, exact with rejection (a rejected half is replaced by the
   * high half of a fresh output). */
  const uint64_t n = (uint64_t)k;
  const uint32_t threshold = (uint32_t)(-(uint32_t)k) % (uint32_t)k;
  int t = 0;
  while (t < k) {
    uint64_t x = bsurf_rng_next(&rng);
    for (int half = 0; half < 2 && t < k; half++) {
      uint64_t m = (half ? (x & 0xffffffffu) : (x >> 32)) * n;
      while ((uint32_t)m < threshold) m = (bsurf_rng_next(&rng) >> 32) * n;
      counts[m >> 32]++;
      t++;
    }
  }
}
