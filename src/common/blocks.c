/* A scratch made of several arrays, allocated one by one and freed together
 * (bsurf_blocks in common.h): the owner lists each array once, where it
 * allocates it, instead of again in a free list and a NULL check. */
#include "common/common.h"

#include <stdlib.h>
#include <string.h>

static void *blocks_keep(bsurf_blocks *b, void *p) {
  if (!p || b->n == BSURF_BLOCKS_MAX) {
    free(p);
    b->failed = 1;
    return NULL;
  }
  b->p[b->n++] = p;
  return p;
}

void *bsurf_blocks_array(bsurf_blocks *b, size_t n, size_t size) {
  return blocks_keep(b, bsurf_alloc_array(n, size));
}

void *bsurf_blocks_aligned(bsurf_blocks *b, size_t n, size_t size) {
  return blocks_keep(b, bsurf_alloc_aligned(n, size));
}

void bsurf_blocks_free(bsurf_blocks *b) {
  for (int t = 0; t < b->n; t++)
    free(b->p[t]);
  memset(b, 0, sizeof *b);
}

bsurf_status bsurf_blocks_status(const bsurf_blocks *b) {
  return b->failed ? BSURF_ERR_NOMEM : BSURF_OK;
}
