/* Creation of bootstrap sets (thesis 4.1.1, Eqs. 4.1-4.2): a sample S_b of
 * the same size K as the neighbourhood, drawn with replacement. We store it
 * as multiplicities (how often each neighbour was drawn), which is all a
 * least-squares fit and the leave-one-out bookkeeping (b in C_j iff the
 * count of j is 0) need. */
#include "bootstrap/bootstrap.h"
#include "common/common.h"

#include <string.h>

/* Draws from 16-bit chunks: Lemire's multiply-shift m = c k of a chunk c
 * (k <= 65535, so m < 2^32), index m >> 16, exact with rejection of the
 * chunks whose low half (m & 0xffff) is below 2^16 mod k. The first k
 * chunks of the stream (four per 64-bit output, bits 0-15 first) are the
 * draws; each one rejected is replaced by the next accepted chunk after
 * them, starting with the output that follows (the counts do not depend on
 * which draw a replacement stands for). */
static uint32_t chunk_threshold(int k) {
  return 65536u % (uint32_t)k;
}

/* The replacements of `rejected` draws, continuing the stream rng; the
 * indices drawn are appended at draws[n..] (draws may be NULL). Point j's
 * count is counts[j sc] (sc: 1, or 4 in the interleaved layout). */
static void boot_replace(bsurf_rng *rng, int k, int rejected, uint16_t *counts, int sc,
                         uint16_t *draws, int n) {
  const uint32_t threshold = chunk_threshold(k);
  while (rejected > 0) {
    const uint64_t x = bsurf_rng_next(rng);
    for (int c = 0; c < 4 && rejected > 0; c++) {
      const uint32_t m = (uint32_t)(x >> (16 * c) & 0xffffu) * (uint32_t)k;
      if ((m & 0xffffu) < threshold) continue;
      counts[(m >> 16) * (uint32_t)sc]++;
      if (draws) draws[n++] = (uint16_t)(m >> 16);
      rejected--;
    }
  }
}

/* bsurf_boot_counts, and the k indices in the order drawn (draws may be
 * NULL): the accepted chunks among the first k, then the replacements. */
static void boot_counts_draws(uint64_t seed, uint64_t point, uint32_t replicate, int k,
                              uint16_t *counts, int sc, uint16_t *draws) {
  bsurf_rng rng;
  bsurf_rng_init(&rng, seed, point, replicate);
  for (int j = 0; j < k; j++)
    counts[(size_t)j * sc] = 0;
  const uint32_t threshold = chunk_threshold(k);
  int rejected = 0, n = 0;
  for (int t = 0; t < k; t += 4) {
    const uint64_t x = bsurf_rng_next(&rng);
    for (int c = 0; c < 4 && t + c < k; c++) {
      const uint32_t m = (uint32_t)(x >> (16 * c) & 0xffffu) * (uint32_t)k;
      if ((m & 0xffffu) < threshold) {
        rejected++;
      } else {
        counts[(m >> 16) * (uint32_t)sc]++;
        if (draws) draws[n++] = (uint16_t)(m >> 16);
      }
    }
  }
  boot_replace(&rng, k, rejected, counts, sc, draws, n);
}

void bsurf_boot_counts(uint64_t seed, uint64_t point, uint32_t replicate, int k, uint16_t *counts) {
  boot_counts_draws(seed, point, replicate, k, counts, 1, NULL);
}

#if defined(__GNUC__)
typedef uint64_t v4u __attribute__((vector_size(32)));
typedef uint32_t v8u __attribute__((vector_size(32)));

/* xoshiro256** (common/rng.c) in four independent lanes. */
#define ROTL4(x, r) (((x) << (r)) | ((x) >> (64 - (r))))
#endif

/* bsurf_boot_counts4 (il = 0: replicate l's counts at counts[l k + j]) and
 * bsurf_boot_counts4_lanes (il = 1: at counts[4 j + l]). */
static inline __attribute__((always_inline)) void counts4(uint64_t seed, uint64_t point,
                                                          uint32_t replicate, int nrep, int k,
                                                          uint16_t *counts, uint16_t *draws,
                                                          int il) {
  const int sc = il ? 4 : 1;
  const size_t ls = il ? 1 : (size_t)k;
#if defined(__GNUC__)
  if (nrep == 4) {
    /* The streams of four replicates side by side in vector lanes; each
     * lane runs exactly the scalar generator and takes the same chunks, 16
     * draws a step (32-bit element 2 l + h of lane l holds chunks 2 h and
     * 2 h + 1: each times k, separately). A lane that meets a rejection
     * (below k / 2^16 per draw) is redone by the scalar code at the end, so
     * the counts are always those of bsurf_boot_counts. */
    bsurf_rng r[4];
    bsurf_rng_init4(r, seed, point, replicate);
    v4u s0 = {r[0].s[0], r[1].s[0], r[2].s[0], r[3].s[0]};
    v4u s1 = {r[0].s[1], r[1].s[1], r[2].s[1], r[3].s[1]};
    v4u s2 = {r[0].s[2], r[1].s[2], r[2].s[2], r[3].s[2]};
    v4u s3 = {r[0].s[3], r[1].s[3], r[2].s[3], r[3].s[3]};
    memset(counts, 0, 4 * (size_t)k * sizeof *counts);
    uint16_t *const c[4] = {counts, counts + ls, counts + 2 * ls, counts + 3 * ls};
    uint16_t *d[4] = {NULL, NULL, NULL, NULL};
    if (draws)
      for (int l = 0; l < 4; l++)
        d[l] = draws + l * (size_t)k;
    const uint32_t kk = (uint32_t)k, th = chunk_threshold(k), f = 0xffffu;
    const v8u K = {kk, kk, kk, kk, kk, kk, kk, kk}, thr = {th, th, th, th, th, th, th, th};
    const v8u lo = {f, f, f, f, f, f, f, f};
    v8u reject = {0, 0, 0, 0, 0, 0, 0, 0};
    for (int t = 0; t < k; t += 4) {
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
      const v8u x = (v8u)res, ma = (x & lo) * K, mb = (x >> 16) * K;
      /* the four indices of lane l in its 16-bit quarters, chunk order */
      const v4u idx = (v4u)((ma >> 16) | (mb & ~lo));
      /* (in a last, partial step also chunks not drawn: a needless redo) */
      reject |= (v8u)((ma & lo) < thr) | (v8u)((mb & lo) < thr);
      if (k - t >= 4) {
        for (int l = 0; l < 4; l++) {
          const uint64_t u = idx[l];
          c[l][(u & 0xffffu) * sc]++;
          c[l][(u >> 16 & 0xffffu) * sc]++;
          c[l][(u >> 32 & 0xffffu) * sc]++;
          c[l][(u >> 48) * sc]++;
          if (draws) {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
            memcpy(&d[l][t], &u, sizeof u); /* the four in chunk order */
#else
            for (int ch = 0; ch < 4; ch++)
              d[l][t + ch] = (uint16_t)(u >> (16 * ch) & 0xffffu);
#endif
          }
        }
      } else { /* the first k - t chunks */
        for (int l = 0; l < 4; l++)
          for (int ch = 0; ch < k - t; ch++) {
            const uint16_t j = (uint16_t)(idx[l] >> (16 * ch) & 0xffffu);
            c[l][(size_t)j * sc]++;
            if (draws) d[l][t + ch] = j;
          }
      }
    }
    for (int l = 0; l < 4; l++)
      if (reject[2 * l] | reject[2 * l + 1])
        boot_counts_draws(seed, point, replicate + (uint32_t)l, k, c[l], sc, draws ? d[l] : NULL);
    return;
  }
#endif
  if (il) memset(counts, 0, 4 * (size_t)k * sizeof *counts);
  for (int l = 0; l < nrep; l++)
    boot_counts_draws(seed, point, replicate + (uint32_t)l, k, counts + l * ls, sc,
                      draws ? draws + l * (size_t)k : NULL);
}

BSURF_CLONES
void bsurf_boot_counts4(uint64_t seed, uint64_t point, uint32_t replicate, int nrep, int k,
                        uint16_t *counts, uint16_t *draws) {
  counts4(seed, point, replicate, nrep, k, counts, draws, 0);
}

BSURF_CLONES
void bsurf_boot_counts4_lanes(uint64_t seed, uint64_t point, uint32_t replicate, int nrep, int k,
                              uint16_t *counts) {
  counts4(seed, point, replicate, nrep, k, counts, NULL, 1);
}

BSURF_CLONES
int bsurf_boot_distinct(int k, const uint16_t *counts) {
  int distinct = 0;
  for (int j = 0; j < k; j++)
    distinct += counts[j] != 0;
  return distinct;
}

int bsurf_boot_rows(int B) {
  return (B + 1 + 3) / 4 * 4;
}

void bsurf_boot_weight_lanes(uint64_t seed, uint64_t point, int B, int k, uint16_t *counts,
                             double *Wt) {
  for (int b0 = 0; b0 < B; b0 += 4) {
    const int nrep = B - b0 < 4 ? B - b0 : 4;
    bsurf_boot_counts4_lanes(seed, point, (uint32_t)b0, nrep, k, counts);
    double *w = Wt + b0;
    if (nrep == 4) /* four contiguous counts to four contiguous weights */
      for (int j = 0; j < k; j++)
        for (int l = 0; l < 4; l++)
          w[(size_t)j * B + l] = counts[4 * j + l];
    else
      for (int j = 0; j < k; j++)
        for (int l = 0; l < nrep; l++)
          w[(size_t)j * B + l] = counts[4 * j + l];
  }
}

void bsurf_boot_draw_rows(uint64_t seed, uint64_t point, int B, int k, int min_distinct,
                          uint16_t *counts, uint16_t *draws, unsigned char *valid) {
  for (int b0 = 0; b0 < B; b0 += 4) {
    const int nrep = B - b0 < 4 ? B - b0 : 4;
    bsurf_boot_counts4(seed, point, (uint32_t)b0, nrep, k, &counts[(size_t)b0 * k],
                       &draws[(size_t)b0 * k]);
    for (int b = b0; b < b0 + nrep; b++)
      valid[b] = bsurf_boot_distinct(k, &counts[(size_t)b * k]) >= min_distinct;
  }
}

/* Poisson(1) bootstrap weights (docs/normals.md, "Nested neighbourhoods").
 * P(X <= m) = e^-1 sum_{i <= m} 1 / i!, times 2^32 and rounded, m = 0..11:
 * a uniform 32-bit u gives X = #{m : u >= T[m]} (inversion; X = 12 stands
 * for X >= 12, probability 9.3e-10). */
static const uint32_t poisson1_cdf[12] = {1580030169u, 3160060337u, 3950075422u, 4213413783u,
                                          4279248374u, 4292415292u, 4294609778u, 4294923276u,
                                          4294962463u, 4294966817u, 4294967253u, 4294967292u};

/* In place: u[j] becomes its count. 32-bit counts, not bytes, so that the
 * vector loop's lanes are 32 bits wide (16 in AVX-512): byte outputs made
 * GCC take 64 lanes, and a kmax below or between multiples of 64 ran in its
 * scalar epilogue. */
BSURF_CLONES
static void poisson_invert(int k, uint32_t *restrict u) {
  for (int j = 0; j < k; j++) {
    uint32_t c = 0;
    for (int m = 0; m < 12; m++)
      c += u[j] >= poisson1_cdf[m];
    u[j] = c;
  }
}

void bsurf_boot_poisson_rows(uint64_t seed, uint64_t point, int B, int kmax, uint32_t *u,
                             double *Wt) {
  for (int b = 0; b < B; b++) {
    bsurf_rng rng;
    bsurf_rng_init(&rng, seed, point, (uint64_t)b);
    bsurf_rng_fill_u32(&rng, kmax, u);
    poisson_invert(kmax, u);
    for (int j = 0; j < kmax; j++)
      Wt[(size_t)j * B + b] = u[j];
  }
}
