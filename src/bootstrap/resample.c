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
  for (int t = 0; t < k; t++) counts[bsurf_rng_below(&rng, (uint32_t)k)]++;
}
