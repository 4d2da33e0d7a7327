/* Consistent normal orientation (the thesis's normals are unoriented, 3.3;
 * it refers to [67] for orientation). We follow Hoppe et al. 1992 as CGAL's
 * mst_orient_normals does: a minimum spanning tree of the symmetric
 * K-neighbour graph with edge weights 1 - |n_i . n_j| (nearly parallel
 * normals first), built by Prim's algorithm from the highest point of each
 * connected component (its normal is turned to +z, outward for a closed
 * surface's top), and each normal is flipped to agree with its tree parent.
 * Ties in the heap are broken by point index, so the result is unique. */
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct heap_item {
  double w;
  uint32_t node, parent;
} heap_item;

static int item_less(const heap_item *a, const heap_item *b) {
  if (a->w != b->w) return a->w < b->w;
  if (a->node != b->node) return a->node < b->node;
  return a->parent < b->parent;
}

typedef struct heap {
  heap_item *a;
  size_t n, cap;
} heap;

static int heap_push(heap *h, heap_item it) {
  if (h->n == h->cap) {
    size_t cap = h->cap ? 2 * h->cap : 1024;
    heap_item *a = realloc(h->a, cap * sizeof *a);
    if (!a) return -1;
    h->a = a;
    h->cap = cap;
  }
  size_t i = h->n++;
  while (i > 0) {
    size_t p = (i - 1) / 2;
    if (!item_less(&it, &h->a[p])) break;
    h->a[i] = h->a[p];
    i = p;
  }
  h->a[i] = it;
  return 0;
}

static heap_item heap_pop(heap *h) {
  heap_item top = h->a[0], last = h->a[--h->n];
  size_t i = 0;
  for (;;) {
    size_t l = 2 * i + 1, r = l + 1, m = i;
    const heap_item *best = &last;
    if (l < h->n && item_less(&h->a[l], best)) {
      m = l;
      best = &h->a[l];
    }
    if (r < h->n && item_less(&h->a[r], best)) m = r;
    if (m == i) break;
    h->a[i] = h->a[m];
    i = m;
  }
  if (h->n) h->a[i] = last;
  return top;
}

bsurf_status bsurf_orient_normals(const double *xyz, const bsurf_neighbors *nb, int k,
                                  double *normals) {
  BSURF_REQUIRE(xyz && normals, "xyz or normals is NULL");
  BSURF_REQUIRE(nb && nb->idx, "nb is %s: build it with bsurf_neighbors_build",
                nb ? "empty" : "NULL");
  BSURF_REQUIRE(k >= 2 && k <= nb->k, "k = %d: must be in [2, nb->k = %d]", k, nb->k);
  const size_t n = nb->point_count;
  BSURF_REQUIRE(n <= UINT32_MAX, "nb->point_count = %zu: at most 2^32 - 1 points", n);
  /* symmetric adjacency (CSR): i -> j for j in N_i, and j -> i */
  size_t *start = calloc(n + 1, sizeof *start);
  uint32_t *adj = bsurf_alloc_array(2 * n * (size_t)(k - 1), sizeof *adj);
  unsigned char *seen = calloc(n, 1); /* 1 = in a found component, 2 = oriented */
  uint32_t *stack = bsurf_alloc_array(n, sizeof *stack);
  heap h = {NULL, 0, 0};
  bsurf_status st = BSURF_OK;
  if (!start || !adj || !seen || !stack) {
    st = BSURF_ERR_NOMEM;
    goto out;
  }
  for (size_t i = 0; i < n; i++)
    for (int j = 1; j < k; j++) {
      start[i + 1]++;
      start[nb->idx[i * nb->k + j] + 1]++;
    }
  for (size_t i = 0; i < n; i++)
    start[i + 1] += start[i];
  {
    size_t *fill = bsurf_alloc_array(n, sizeof *fill);
    if (!fill) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    memcpy(fill, start, n * sizeof *fill);
    for (size_t i = 0; i < n; i++)
      for (int j = 1; j < k; j++) {
        uint32_t q = nb->idx[i * nb->k + j];
        adj[fill[i]++] = q;
        adj[fill[q]++] = (uint32_t)i;
      }
    free(fill);
  }
  /* components in order of their smallest index; each starts at its highest point */
  for (size_t s0 = 0; s0 < n; s0++) {
    if (seen[s0]) continue;
    size_t top = 0, root = s0;
    stack[top++] = (uint32_t)s0;
    seen[s0] = 1;
    /* depth-first search marks the component and finds its highest point */
    while (top) {
      uint32_t v = stack[--top];
      if (xyz[3 * (size_t)v + 2] > xyz[3 * root + 2] ||
          (xyz[3 * (size_t)v + 2] == xyz[3 * root + 2] && v < root))
        root = v;
      for (size_t e = start[v]; e < start[v + 1]; e++)
        if (!seen[adj[e]]) {
          seen[adj[e]] = 1;
          stack[top++] = adj[e];
        }
    }
    if (normals[3 * root + 2] < 0)
      for (int t = 0; t < 3; t++)
        normals[3 * root + t] = -normals[3 * root + t];
    /* Prim from root */
    h.n = 0;
    if (heap_push(&h, (heap_item){0.0, (uint32_t)root, (uint32_t)root})) {
      st = BSURF_ERR_NOMEM;
      goto out;
    }
    while (h.n) {
      heap_item it = heap_pop(&h);
      if (seen[it.node] == 2) continue;
      seen[it.node] = 2;
      double *nv = &normals[3 * (size_t)it.node];
      const double *np = &normals[3 * (size_t)it.parent];
      if (it.node != it.parent && nv[0] * np[0] + nv[1] * np[1] + nv[2] * np[2] < 0)
        for (int t = 0; t < 3; t++)
          nv[t] = -nv[t];
      for (size_t e = start[it.node]; e < start[it.node + 1]; e++) {
        uint32_t q = adj[e];
        if (seen[q] == 2) continue;
        const double *nq = &normals[3 * (size_t)q];
        double w = 1.0 - fabs(nv[0] * nq[0] + nv[1] * nq[1] + nv[2] * nq[2]);
        if (heap_push(&h, (heap_item){w, q, it.node})) {
          st = BSURF_ERR_NOMEM;
          goto out;
        }
      }
    }
  }
out:
  free(start);
  free(adj);
  free(seen);
  free(stack);
  free(h.a);
  return st;
}
