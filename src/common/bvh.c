/* The bounding-volume hierarchy of bvh.h: build and nearest-primitive query. */
#include "common/bvh.h"

#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The search stack: a median-split tree of n primitives is log2(n) + 1 deep,
 * and the search holds at most one pending sibling per level (plus one). */
#define BVH_STACK 128

typedef struct build_ctx {
  const double *box, *center;
  bsurf_bvh *t;
} build_ctx;

static int center_less(const build_ctx *b, size_t i, size_t j, int axis) {
  double x = b->center[3 * i + (size_t)axis], y = b->center[3 * j + (size_t)axis];
  return x < y || (x == y && i < j);
}

static void swap_sz(size_t *a, size_t *b) {
  size_t t = *a;
  *a = *b;
  *b = t;
}

/* Quickselect: afterwards ord[0..k) are the k smallest by (centre on axis,
 * index), a total order, so the split does not depend on the input order. */
static void select_kth(const build_ctx *b, size_t *ord, size_t n, size_t k, int axis) {
  size_t lo = 0, hi = n - 1;
  while (hi > lo) {
    size_t mid = lo + (hi - lo) / 2;
    /* median of three as the pivot, moved to hi */
    if (center_less(b, ord[mid], ord[lo], axis)) swap_sz(&ord[mid], &ord[lo]);
    if (center_less(b, ord[hi], ord[lo], axis)) swap_sz(&ord[hi], &ord[lo]);
    if (center_less(b, ord[mid], ord[hi], axis)) swap_sz(&ord[mid], &ord[hi]);
    size_t pivot = ord[hi], store = lo;
    for (size_t i = lo; i < hi; i++)
      if (center_less(b, ord[i], pivot, axis)) swap_sz(&ord[i], &ord[store++]);
    swap_sz(&ord[hi], &ord[store]);
    if (store == k) return;
    if (store < k)
      lo = store + 1;
    else
      hi = store - 1;
  }
}

static size_t build_node(build_ctx *b, size_t first, size_t count) {
  bsurf_bvh *t = b->t;
  size_t id = t->node_count++;
  bsurf_bvh_node *nd = &t->nodes[id];
  double clo[3], chi[3];
  for (int k = 0; k < 3; k++) {
    nd->lo[k] = clo[k] = INFINITY;
    nd->hi[k] = chi[k] = -INFINITY;
  }
  for (size_t i = first; i < first + count; i++) {
    size_t f = t->order[i];
    const double *bx = &b->box[6 * f], *c = &b->center[3 * f];
    for (int k = 0; k < 3; k++) {
      if (bx[k] < nd->lo[k]) nd->lo[k] = bx[k];
      if (bx[3 + k] > nd->hi[k]) nd->hi[k] = bx[3 + k];
      if (c[k] < clo[k]) clo[k] = c[k];
      if (c[k] > chi[k]) chi[k] = c[k];
    }
  }
  nd->first = first;
  nd->count = count;
  nd->left = nd->right = 0;
  if (count <= BSURF_BVH_LEAF) return id;
  int axis = 0;
  for (int k = 1; k < 3; k++)
    if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
  size_t half = count / 2;
  select_kth(b, &t->order[first], count, half, axis);
  size_t left = build_node(b, first, half); /* nodes never move: allocated up front */
  size_t right = build_node(b, first + half, count - half);
  nd = &t->nodes[id];
  nd->first = 0;
  nd->count = 0;
  nd->left = left;
  nd->right = right;
  return id;
}

void bsurf_bvh_free(bsurf_bvh *t) {
  if (!t) return;
  free(t->order);
  free(t->nodes);
  memset(t, 0, sizeof *t);
}

bsurf_status bsurf_bvh_build(bsurf_bvh *t, const double *box, const double *center, size_t count) {
  memset(t, 0, sizeof *t);
  if (count == 0 || !box || !center) return BSURF_ERR_INVALID_ARG;
  t->order = bsurf_alloc_array(count, sizeof(size_t));
  /* a binary tree whose leaves hold >= 1 primitive has < 2 count nodes */
  t->nodes = bsurf_alloc_array(count, 2 * sizeof(bsurf_bvh_node));
  if (!t->order || !t->nodes) {
    bsurf_bvh_free(t);
    return BSURF_ERR_NOMEM;
  }
  double extent2 = 0;
  for (size_t i = 0; i < count; i++) {
    double e2 = 0;
    for (int k = 0; k < 3; k++) {
      double e = box[6 * i + 3 + (size_t)k] - box[6 * i + (size_t)k];
      e2 += e * e;
    }
    if (e2 > extent2) extent2 = e2;
    t->order[i] = i;
  }
  t->count = count;
  t->extent2 = extent2;
  build_ctx b = {box, center, t};
  build_node(&b, 0, count);
  return BSURF_OK;
}

static double box_dist2(const double *p, const bsurf_bvh_node *nd) {
  double s = 0;
  for (int k = 0; k < 3; k++) {
    double d = p[k] < nd->lo[k] ? nd->lo[k] - p[k] : p[k] > nd->hi[k] ? p[k] - nd->hi[k] : 0.0;
    s += d * d;
  }
  return s;
}

double bsurf_bvh_nearest(const bsurf_bvh *t, const double p[3], bsurf_bvh_dist2_fn dist2,
                         const void *ctx, size_t *slot) {
  size_t stack[BVH_STACK];
  double sd[BVH_STACK];
  int top = 0;
  double best = INFINITY, bound = INFINITY;
  size_t best_i = 0;
  stack[top] = 0;
  sd[top++] = box_dist2(p, &t->nodes[0]);
  while (top > 0) {
    --top;
    if (sd[top] > bound) continue;
    const bsurf_bvh_node *nd = &t->nodes[stack[top]];
    if (nd->count) {
      for (size_t i = nd->first; i < nd->first + nd->count; i++) {
        double d = dist2(ctx, i, p);
        if (d < best || (d == best && t->order[i] < t->order[best_i])) {
          best = d;
          best_i = i;
          bound = best + 1e-9 * (best + t->extent2);
        }
      }
      continue;
    }
    double dl = box_dist2(p, &t->nodes[nd->left]), dr = box_dist2(p, &t->nodes[nd->right]);
    size_t near = nd->left, far = nd->right;
    double dn = dl, df = dr;
    if (dr < dl) {
      near = nd->right, far = nd->left;
      dn = dr, df = dl;
    }
    /* the farther child below the nearer one: the nearer is searched first */
    if (df <= bound) {
      stack[top] = far;
      sd[top++] = df;
    }
    if (dn <= bound) {
      stack[top] = near;
      sd[top++] = dn;
    }
  }
  if (slot) *slot = best_i;
  return best;
}
