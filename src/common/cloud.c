/* The point-cloud container: positions, optional normals, named fields, faces. */
#include "common/common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void bsurf_cloud_init(bsurf_cloud *cloud) {
  memset(cloud, 0, sizeof *cloud);
  cloud->xyz_type = BSURF_FLOAT64;
  cloud->normal_type = BSURF_FLOAT32;
}

bsurf_status bsurf_cloud_alloc(bsurf_cloud *cloud, size_t n, int with_normals) {
  bsurf_cloud_init(cloud);
  if (n == 0) return BSURF_OK;
  cloud->xyz = bsurf_calloc_array(n, 3 * sizeof(double));
  if (!cloud->xyz) return BSURF_ERR_NOMEM;
  if (with_normals) {
    cloud->normals = bsurf_calloc_array(n, 3 * sizeof(double));
    if (!cloud->normals) {
      free(cloud->xyz);
      cloud->xyz = NULL;
      return BSURF_ERR_NOMEM;
    }
  }
  cloud->point_count = n;
  return BSURF_OK;
}

void bsurf_cloud_free(bsurf_cloud *cloud) {
  if (!cloud) return;
  free(cloud->xyz);
  free(cloud->normals);
  for (size_t i = 0; i < cloud->field_count; i++)
    free(cloud->fields[i].values);
  free(cloud->fields);
  free(cloud->faces);
  bsurf_cloud_init(cloud);
}

static void *dup_array(const void *src, size_t n, size_t size) {
  if (!src || n == 0) return NULL;
  void *p = bsurf_alloc_array(n, size);
  if (p) memcpy(p, src, n * size);
  return p;
}

bsurf_status bsurf_cloud_copy(bsurf_cloud *dst, const bsurf_cloud *src) {
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  c.point_count = src->point_count;
  c.xyz_type = src->xyz_type;
  c.normal_type = src->normal_type;
  memcpy(c.shape, src->shape, sizeof c.shape);
  c.xyz = dup_array(src->xyz, src->point_count, 3 * sizeof(double));
  c.normals = dup_array(src->normals, src->point_count, 3 * sizeof(double));
  c.faces = dup_array(src->faces, src->face_count, 3 * sizeof(uint32_t));
  c.face_count = c.faces ? src->face_count : 0;
  if ((src->point_count && !c.xyz) || (src->normals && src->point_count && !c.normals) ||
      (src->face_count && !c.faces))
    goto nomem;
  if (src->field_count) {
    c.fields = bsurf_calloc_array(src->field_count, sizeof(bsurf_field));
    if (!c.fields) goto nomem;
    c.field_count = src->field_count;
    for (size_t i = 0; i < src->field_count; i++) {
      c.fields[i] = src->fields[i];
      c.fields[i].values = dup_array(src->fields[i].values, src->point_count, sizeof(double));
      if (src->point_count && !c.fields[i].values) goto nomem;
    }
  }
  *dst = c;
  return BSURF_OK;
nomem:
  bsurf_cloud_free(&c);
  return BSURF_ERR_NOMEM;
}

bsurf_field *bsurf_cloud_field(const bsurf_cloud *cloud, const char *name) {
  for (size_t i = 0; i < cloud->field_count; i++)
    if (strcmp(cloud->fields[i].name, name) == 0) return &cloud->fields[i];
  return NULL;
}

bsurf_field *bsurf_cloud_add_field(bsurf_cloud *cloud, const char *name, bsurf_type type) {
  bsurf_field *f = bsurf_cloud_field(cloud, name);
  if (f) {
    f->type = type;
    return f;
  }
  if (strlen(name) >= BSURF_FIELD_NAME_MAX) return NULL;
  double *values = NULL;
  if (cloud->point_count) {
    values = bsurf_calloc_array(cloud->point_count, sizeof(double));
    if (!values) return NULL;
  }
  bsurf_field *fields = realloc(cloud->fields, (cloud->field_count + 1) * sizeof *fields);
  if (!fields) {
    free(values);
    return NULL;
  }
  cloud->fields = fields;
  f = &fields[cloud->field_count++];
  memset(f, 0, sizeof *f);
  strcpy(f->name, name);
  f->type = type;
  f->values = values;
  return f;
}

bsurf_status bsurf_cloud_add_fields(bsurf_cloud *cloud, size_t count, const char *const *names,
                                    const bsurf_type *types) {
  if (count == 0) return BSURF_OK;
  for (size_t i = 0; i < count; i++)
    if (strlen(names[i]) >= BSURF_FIELD_NAME_MAX) return BSURF_ERR_INVALID_ARG;
  const size_t old = cloud->field_count;
  if (count > (size_t)-1 / 4 - old) return BSURF_ERR_NOMEM;
  bsurf_nameset set;
  if (bsurf_nameset_init(&set, old + count) != BSURF_OK) return BSURF_ERR_NOMEM;
  /* every name once, with its index in the field array to be */
  for (size_t f = 0; f < old; f++)
    bsurf_nameset_insert(&set, cloud->fields[f].name, strlen(cloud->fields[f].name), f);
  size_t fresh = 0;
  for (size_t i = 0; i < count; i++)
    if (bsurf_nameset_insert(&set, names[i], strlen(names[i]), old + fresh) == BSURF_NAMESET_NONE)
      fresh++;
  bsurf_status st = BSURF_OK;
  /* the set's keys of the old fields point into the old array: it is freed
   * only after the set */
  bsurf_field *retired = NULL;
  if (fresh) {
    bsurf_field *fields = bsurf_alloc_array(old + fresh, sizeof *fields);
    if (!fields) {
      bsurf_nameset_free(&set);
      return BSURF_ERR_NOMEM;
    }
    if (old) memcpy(fields, cloud->fields, old * sizeof *fields);
    retired = cloud->fields;
    cloud->fields = fields;
  }
  for (size_t i = 0; i < count && st == BSURF_OK; i++) {
    size_t at = bsurf_nameset_find(&set, names[i], strlen(names[i]));
    if (at < cloud->field_count) { /* there already (or earlier in the list) */
      cloud->fields[at].type = types[i];
      continue;
    }
    double *values = NULL;
    if (cloud->point_count && !(values = bsurf_calloc_array(cloud->point_count, sizeof(double)))) {
      st = BSURF_ERR_NOMEM;
      break;
    }
    bsurf_field *f = &cloud->fields[cloud->field_count++];
    memset(f, 0, sizeof *f);
    strcpy(f->name, names[i]);
    f->type = types[i];
    f->values = values;
  }
  bsurf_nameset_free(&set);
  free(retired);
  return st;
}

void bsurf_cloud_remove_field(bsurf_cloud *cloud, const char *name) {
  for (size_t i = 0; i < cloud->field_count; i++) {
    if (strcmp(cloud->fields[i].name, name) == 0) {
      free(cloud->fields[i].values);
      memmove(&cloud->fields[i], &cloud->fields[i + 1],
              (cloud->field_count - i - 1) * sizeof(bsurf_field));
      cloud->field_count--;
      return;
    }
  }
}

bsurf_status bsurf_cloud_check_finite(const bsurf_cloud *cloud, size_t *bad_index) {
  for (size_t i = 0; i < cloud->point_count; i++) {
    int ok = isfinite(cloud->xyz[3 * i]) && isfinite(cloud->xyz[3 * i + 1]) &&
             isfinite(cloud->xyz[3 * i + 2]);
    if (ok && cloud->normals)
      ok = isfinite(cloud->normals[3 * i]) && isfinite(cloud->normals[3 * i + 1]) &&
           isfinite(cloud->normals[3 * i + 2]);
    if (!ok) {
      if (bad_index) *bad_index = i;
      return BSURF_ERR_INVALID_VALUE;
    }
  }
  return BSURF_OK;
}

double bsurf_bounding_box(const double *xyz, size_t point_count, double lo[3], double hi[3]) {
  double l[3] = {INFINITY, INFINITY, INFINITY}, h[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < point_count; i++)
    for (int t = 0; t < 3; t++) {
      const double v = xyz[3 * i + t];
      if (v < l[t]) l[t] = v;
      if (v > h[t]) h[t] = v;
    }
  if (lo) memcpy(lo, l, sizeof l);
  if (hi) memcpy(hi, h, sizeof h);
  double s = 0;
  for (int t = 0; t < 3; t++)
    s += (h[t] - l[t]) * (h[t] - l[t]);
  return point_count ? sqrt(s) : 0.0;
}
