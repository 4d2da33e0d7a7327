/* order.c — a spatially coherent order of a cloud's points.
 *
 * Per-point passes read the positions of each point's neighbourhood; in input
 * order (often random: scans interleave lines, generated clouds are random)
 * each read is a cache miss. Visiting the points in Morton (Z-curve) order of
 * their coordinates, quantised to 21 bits per axis over the bounding box
 * (ties by index), keeps consecutive neighbourhoods in cache. The order is a
 * pure function of the coordinates; it changes which point a thread works on
 * when, never a result. */
#include "search/search.h"

#include <math.h>
#include <stdlib.h>

typedef struct morton_key {
  uint64_t code;
  uint32_t index;
} morton_key;

static uint64_t spread3(uint64_t x) { /* 21 bits -> every third of 63 */
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

static int morton_cmp(const void *a, const void *b) {
  const morton_key *x = a, *y = b;
  if (x->code != y->code) return x->code < y->code ? -1 : 1;
  return x->index < y->index ? -1 : (x->index > y->index);
}

bsurf_status bsurf_spatial_order(const double *xyz, size_t n, uint32_t **perm_out,
                                 uint32_t **rank_out) {
  morton_key *keys = bsurf_alloc_array(n ? n : 1, sizeof *keys);
  uint32_t *perm = bsurf_alloc_array(n ? n : 1, sizeof *perm);
  uint32_t *rank = rank_out ? bsurf_alloc_array(n ? n : 1, sizeof *rank) : NULL;
  if (!keys || !perm || (rank_out && !rank)) {
    free(keys);
    free(perm);
    free(rank);
    return BSURF_ERR_NOMEM;
  }
  double lo[3], hi[3];
  bsurf_bounding_box(xyz, n, lo, hi);
  double ext = 0;
  for (int t = 0; t < 3; t++)
    if (hi[t] - lo[t] > ext) ext = hi[t] - lo[t];
  const double scale = ext > 0 ? 2097151.0 / ext : 0.0;
  for (size_t i = 0; i < n; i++) {
    uint64_t q[3];
    for (int t = 0; t < 3; t++) {
      double v = (xyz[3 * i + t] - lo[t]) * scale;
      q[t] = v > 0 ? (uint64_t)(v < 2097151.0 ? v : 2097151.0) : 0;
    }
    keys[i].code = spread3(q[0]) | spread3(q[1]) << 1 | spread3(q[2]) << 2;
    keys[i].index = (uint32_t)i;
  }
  qsort(keys, n, sizeof *keys, morton_cmp);
  for (size_t r = 0; r < n; r++) {
    perm[r] = keys[r].index;
    if (rank) rank[keys[r].index] = (uint32_t)r;
  }
  free(keys);
  *perm_out = perm;
  if (rank_out) *rank_out = rank;
  return BSURF_OK;
}

const uint32_t *bsurf_visit_order(const bsurf_neighbors *nb, const double *xyz, uint32_t **owned) {
  *owned = NULL;
  if (nb->order) return nb->order;
  if (bsurf_spatial_order(xyz, nb->point_count, owned, NULL) != BSURF_OK) return NULL;
  return *owned;
}
