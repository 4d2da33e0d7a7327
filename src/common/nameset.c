/* A set of names (not NUL-terminated: a pointer and a length) with a value
 * each, by open addressing with linear probing and FNV-1a hashes: the PLY
 * header's duplicate-name check and the cloud's bulk field lookup take time
 * linear in the number of names instead of quadratic (a 100,000-property
 * header; docs/robustness.md). The table does not grow: it is sized for the
 * number of names given at init. */
#include "common/common.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint64_t name_hash(const char *s, size_t len) {
  uint64_t h = 1469598103934665603ULL;
  for (size_t i = 0; i < len; i++) {
    h ^= (unsigned char)s[i];
    h *= 1099511628211ULL;
  }
  return h;
}

bsurf_status bsurf_nameset_init(bsurf_nameset *set, size_t expected) {
  memset(set, 0, sizeof *set);
  size_t cap = 16;
  while (cap < 2 * expected + 16) {
    if (cap > (size_t)-1 / 4) return BSURF_ERR_NOMEM;
    cap *= 2;
  }
  set->slots = bsurf_calloc_array(cap, sizeof *set->slots);
  if (!set->slots) return BSURF_ERR_NOMEM;
  set->cap = cap;
  return BSURF_OK;
}

void bsurf_nameset_free(bsurf_nameset *set) {
  free(set->slots);
  memset(set, 0, sizeof *set);
}

/* The slot holding the name, or the empty slot where it would go. */
static bsurf_nameset_slot *slot_of(const bsurf_nameset *set, const char *name, size_t len) {
  size_t mask = set->cap - 1, i = (size_t)name_hash(name, len) & mask;
  for (;;) {
    bsurf_nameset_slot *s = &set->slots[i];
    if (!s->name || (s->len == len && memcmp(s->name, name, len) == 0)) return s;
    i = (i + 1) & mask;
  }
}

size_t bsurf_nameset_find(const bsurf_nameset *set, const char *name, size_t len) {
  if (!set->cap) return BSURF_NAMESET_NONE;
  const bsurf_nameset_slot *s = slot_of(set, name, len);
  return s->name ? s->value : BSURF_NAMESET_NONE;
}

size_t bsurf_nameset_insert(bsurf_nameset *set, const char *name, size_t len, size_t value) {
  bsurf_nameset_slot *s = slot_of(set, name, len);
  if (s->name) return s->value;
  if (2 * (set->n + 1) > set->cap) return BSURF_NAMESET_FULL; /* init was told fewer names */
  s->name = name;
  s->len = len;
  s->value = value;
  set->n++;
  return BSURF_NAMESET_NONE;
}
