/* Creation of bootstrap sets (thesis 4.1.1, Eqs. 4.1-4.2): a sample S_b of
 * the same size K as the neighbourhood, drawn with replacement. We store it
 * as multiplicities (how often each neighbour was drawn), which is all a
 * least-squares fit and the leave-one-out bookkeeping (b in C_j iff the
 * count of j is 0) need. */
#include "bootstrap/bootstrap.h"
#include "common/common.h"

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

#if defined(__GNUC__)
typedef uint64_t v4u __attribute__((vector_size(32)));

/* xoshiro256** (common/rng.c) in four independent lanes. */
#define ROTL4(x, r) (((x) << (r)) | ((x) >> (64 - (r))))
#endif

BSURF_CLONES
void bsurf_boot_counts4(uint64_t seed, uint64_t point, uint32_t replicate, int nrep, int k,
                        uint16_t *counts) {
#if defined(__GNUC__)
  if (nrep == 4) {
    /* The streams of four replicates side by side in vector lanes; each
     * lane runs exactly the scalar generator and the same two draws per
     * output. A lane that meets a rejection (probability below k / 2^32 per
     * draw) is redone by the scalar code at the end, so the counts are
     * always those of bsurf_boot_counts. */
    bsurf_rng r[4];
    for (int l = 0; l < 4; l++) bsurf_rng_init(&r[l], seed, point, replicate + (uint32_t)l);
    v4u s0 = {r[0].s[0], r[1].s[0], r[2].s[0], r[3].s[0]};
    v4u s1 = {r[0].s[1], r[1].s[1], r[2].s[1], r[3].s[1]};
    v4u s2 = {r[0].s[2], r[1].s[2], r[2].s[2], r[3].s[2]};
    v4u s3 = {r[0].s[3], r[1].s[3], r[2].s[3], r[3].s[3]};
    memset(counts, 0, 4 * (size_t)k * sizeof *counts);
    uint16_t *c0 = counts, *c1 = counts + k, *c2 = counts + 2 * (size_t)k,
             *c3 = counts + 3 * (size_t)k;
    const uint64_t kk = (uint64_t)k, threshold = (uint32_t)(-(uint32_t)k) % (uint32_t)k;
    const v4u K = {kk, kk, kk, kk}, lo = {0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu};
    const v4u thr = {threshold, threshold, threshold, threshold};
    v4u reject = {0, 0, 0, 0};
    for (int t = 0; t < k; t += 2) {
      const v4u x1 = (s1 << 2) + s1; /* s1 * 5 */
      const v4u x2 = ROTL4(x1, 7);
      const v4u res = (x2 << 3) + x2; /* * 9 */
      const v4u tt = s1 << 17;
      s2 ^= s0;
      s3 ^= s1;
      s1 ^= s2;
      s0 ^= s3;
      s2 ^= tt;
      s3 = ROTL4(s3, 45);
      const v4u mh = (res >> 32) * K;
      reject |= (v4u)((mh & lo) < thr);
      c0[mh[0] >> 32]++;
      c1[mh[1] >> 32]++;
      c2[mh[2] >> 32]++;
      c3[mh[3] >> 32]++;
      if (t + 1 < k) {
        const v4u ml = (res & lo) * K;
        reject |= (v4u)((ml & lo) < thr);
        c0[ml[0] >> 32]++;
        c1[ml[1] >> 32]++;
        c2[ml[2] >> 32]++;
        c3[ml[3] >> 32]++;
      }
    }
    for (int l = 0; l < 4; l++)
      if (reject[l]) bsurf_boot_counts(seed, point, replicate + (uint32_t)l, k, counts + l * (size_t)k);
    return;
  }
#endif
  for (int l = 0; l < nrep; l++)
    bsurf_boot_counts(seed, point, replicate + (uint32_t)l, k, counts + l * (size_t)k);
}

/* A replicate's multiplicities as fit weights (w) and, if missing is not
 * NULL, 1.0 where a point was not drawn; the number of distinct points. */
BSURF_CLONES
static int boot_weights(int k, const uint16_t *restrict counts, double *restrict w,
                        double *restrict missing) {
  int distinct = 0;
  for (int j = 0; j < k; j++) {
    w[j] = counts[j];
    distinct += counts[j] != 0;
  }
  if (missing)
    for (int j = 0; j < k; j++) missing[j] = counts[j] == 0;
  return distinct;
}

int bsurf_boot_rows(int B) { return (B + 1 + 3) / 4 * 4; }

void bsurf_boot_weight_rows(uint64_t seed, uint64_t point, int B, int k, int min_distinct,
                            uint16_t *counts, double *W, double *missing, unsigned char *valid) {
  for (int b0 = 0; b0 < B; b0 += 4) {
    const int nrep = B - b0 < 4 ? B - b0 : 4;
    bsurf_boot_counts4(seed, point, (uint32_t)b0, nrep, k, counts);
    for (int b = b0; b < b0 + nrep; b++)
      valid[b] = boot_weights(k, &counts[(size_t)(b - b0) * k], &W[(size_t)b * k],
                              missing ? &missing[(size_t)b * k] : NULL) >= min_distinct;
  }
  for (int j = 0; j < k; j++) W[(size_t)B * k + j] = 1.0;
  for (size_t t = (size_t)(B + 1) * k; t < (size_t)bsurf_boot_rows(B) * k; t++) W[t] = 0.0;
}
