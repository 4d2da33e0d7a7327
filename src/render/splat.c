/* The point renderer: orthographic projection, z-buffered splats, shading by
 * normals or colour by a field, colour bar, 2x2 grids of views.
 *
 * Determinism: every splat writes a 64-bit key per pixel, depth in the high
 * half and the complement of the point index in the low half, with an atomic
 * maximum. The maximum does not depend on the order in which points arrive,
 * so the nearest point (ties: the lowest index) wins for any thread count. */
#include "draw.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

bsurf_render_options bsurf_render_options_default(void) {
  bsurf_render_options o = {.width = 1024,
                            .height = 768,
                            .azimuth = 45.0,
                            .elevation = 35.26,
                            .views = 1,
                            .point_size = 2.0,
                            .round_splats = 1,
                            .supersample = 2,
                            .up_axis = 2,
                            .colormap = BSURF_COLORMAP_VIRIDIS,
                            .range_lo = NAN,
                            .range_hi = NAN,
                            .percentile_lo = 1.0,
                            .percentile_hi = 99.0,
                            .shade = 1,
                            .colorbar = 1,
                            .background = {255, 255, 255}};
  return o;
}

int bsurf_view_from_name(const char *name, double *azimuth, double *elevation) {
  static const struct {
    const char *name;
    double az, el;
  } views[] = {{"front", 0, 0}, {"back", 180, 0},   {"left", -90, 0},  {"right", 90, 0},
               {"top", 0, 90},  {"bottom", 0, -90}, {"iso", 45, 35.26}};
  for (size_t i = 0; i < sizeof views / sizeof views[0]; i++)
    if (name && strcmp(name, views[i].name) == 0) {
      *azimuth = views[i].az;
      *elevation = views[i].el;
      return 0;
    }
  return -1;
}

bsurf_status bsurf_render_range(const double *values, size_t count, double percentile_lo,
                                double percentile_hi, double *lo, double *hi) {
  BSURF_REQUIRE(values && lo && hi, "values, lo or hi is NULL");
  double *v = bsurf_alloc_array(count ? count : 1, sizeof *v);
  if (!v) return BSURF_ERR_NOMEM;
  size_t n = 0;
  for (size_t i = 0; i < count; i++)
    if (isfinite(values[i])) v[n++] = values[i];
  if (!n) {
    free(v);
    return BSURF_ERR_INVALID_VALUE;
  }
  double pl = percentile_lo < 0 ? 0 : percentile_lo > 100 ? 100 : percentile_lo;
  double ph = percentile_hi < 0 ? 0 : percentile_hi > 100 ? 100 : percentile_hi;
  /* nearest rank: the value with pl% of the others at or below it */
  size_t a = (size_t)floor(pl / 100.0 * (double)(n - 1) + 0.5);
  size_t b = (size_t)floor(ph / 100.0 * (double)(n - 1) + 0.5);
  if (a > b) {
    size_t t = a;
    a = b;
    b = t;
  }
  *lo = bsurf_kth_smallest(v, n, a);
  *hi = bsurf_kth_smallest(v, n, b);
  free(v);
  return BSURF_OK;
}

/* ---- the view ---- */
typedef struct {
  double eye[3], right[3], up[3]; /* eye: unit vector towards the camera */
  double light[3];
} view_frame;

/* A vector of the z-up view frame in world coordinates when `up` (0 x,
 * 1 y, 2 z) points up: the inverse of a rotation taking `up` to z. */
static void to_world(double v[3], int up) {
  double a = v[0], b = v[1], c = v[2];
  if (up == 1)
    v[0] = a, v[1] = c, v[2] = -b; /* p' = (x, -z, y) */
  else if (up == 0)
    v[0] = c, v[1] = a, v[2] = b; /* p' = (y, z, x) */
}

static void make_frame(view_frame *f, double az_deg, double el_deg, int up_axis) {
  double az = az_deg * PI / 180.0, el = el_deg * PI / 180.0;
  double ce = cos(el), se = sin(el), ca = cos(az), sa = sin(az);
  f->eye[0] = sa * ce, f->eye[1] = -ca * ce, f->eye[2] = se;
  f->right[0] = ca, f->right[1] = sa, f->right[2] = 0;
  /* up = right x forward, forward = -eye */
  double fw[3] = {-f->eye[0], -f->eye[1], -f->eye[2]};
  f->up[0] = f->right[1] * fw[2] - f->right[2] * fw[1];
  f->up[1] = f->right[2] * fw[0] - f->right[0] * fw[2];
  f->up[2] = f->right[0] * fw[1] - f->right[1] * fw[0];
  /* a light from above-left of the camera */
  double l[3];
  for (int t = 0; t < 3; t++)
    l[t] = f->eye[t] + 0.45 * f->up[t] - 0.35 * f->right[t];
  double n = sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  for (int t = 0; t < 3; t++)
    f->light[t] = l[t] / n;
  to_world(f->eye, up_axis);
  to_world(f->right, up_axis);
  to_world(f->up, up_axis);
  to_world(f->light, up_axis);
}

/* Depth as an unsigned integer whose order is the float order. */
static uint32_t depth_key(float d) {
  uint32_t u;
  memcpy(&u, &d, sizeof u);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}
static float key_depth(uint32_t k) {
  uint32_t u = (k & 0x80000000u) ? (k & 0x7FFFFFFFu) : ~k;
  float d;
  memcpy(&d, &u, sizeof d);
  return d;
}

static void atomic_max_u64(uint64_t *p, uint64_t v) {
#if defined(__GNUC__)
  uint64_t cur = __atomic_load_n(p, __ATOMIC_RELAXED);
  while (v > cur &&
         !__atomic_compare_exchange_n(p, &cur, v, 1, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
#else
  if (v > *p) *p = v; /* single-threaded builds only */
#endif
}

/* A rough spacing estimate without a neighbour search (render depends on
 * common only): the surface area from the cells of a 3D grid that hold points,
 * with cells coarse enough to hold several points each, h ~ sqrt(area / n).
 * At most 65536 points are looked at (a regular subsample). Used only when
 * the caller does not give h (the CLI passes the exact mean spacing). */
static double estimate_spacing(const double *xyz, size_t n, const double lo[3], double extent) {
  if (n < 2 || !(extent > 0)) return extent > 0 ? extent / 100 : 1.0;
  size_t stride = n > 65536 ? n / 65536 : 1;
  size_t m = (n + stride - 1) / stride;
  uint64_t *keys = bsurf_alloc_array(m, sizeof *keys);
  if (!keys) return extent / sqrt((double)n);
  double area = 0;
  for (double cell = extent / 1024.0; cell <= extent * 2; cell *= 2) {
    for (size_t j = 0; j < m; j++) {
      const double *p = xyz + 3 * (j * stride);
      uint64_t k = 0;
      for (int t = 0; t < 3; t++) {
        double c = floor((p[t] - lo[t]) / cell);
        if (c < 0) c = 0;
        if (c > 1048575) c = 1048575;
        k = (k << 20) | (uint64_t)c;
      }
      keys[j] = k;
    }
    qsort(keys, m, sizeof *keys, bsurf_cmp_u64);
    size_t occ = 1;
    for (size_t j = 1; j < m; j++)
      occ += keys[j] != keys[j - 1];
    /* a surface crosses on average 1.5 cells per cell^2 of its area */
    area = (double)occ * cell * cell / 1.5;
    if ((double)m / (double)occ >= 6.0) break;
  }
  free(keys);
  /* mean nearest-neighbour distance: ~0.5 / sqrt(density) for random
   * samples, ~1.07 / sqrt(density) for even ones */
  return 0.8 * sqrt(area / (double)m) / sqrt((double)stride);
}

/* ---- colour bar ---- */
void bsurf_render_text(uint8_t *rgb, int width, int height, int x, int y, const char *text,
                       int scale, const uint8_t color[3]) {
  canvas c = {rgb, width, height};
  bsurf_draw_text(&c, x, y, text, scale < 1 ? 1 : scale, color);
}

void bsurf_render_colorbar(uint8_t *rgb, int width, int height, int x, int y, int w, int h,
                           bsurf_colormap cmap, double lo, double hi, const char *label,
                           const uint8_t background[3]) {
  canvas c = {rgb, width, height};
  uint8_t ink[3];
  bsurf_draw_ink_for(background, ink);
  int s = (h >= 220 && w >= 120) ? 2 : 1;
  int line = (FONT_H + 4) * s;
  int top = y + (label ? line + 4 * s : 4 * s) + FONT_H * s / 2;
  int bottom = y + h - FONT_H * s / 2 - 4 * s;
  int barw = 12 * s;
  int bx = x + 4 * s;
  if (bottom - top < 10) return;
  if (label) {
    /* the caption, shortened to the box */
    char buf[128];
    snprintf(buf, sizeof buf, "%s", label);
    while (strlen(buf) > 1 && bsurf_draw_text_width(buf, s) > w - 4 * s)
      buf[strlen(buf) - 1] = 0;
    bsurf_draw_text(&c, x + 2 * s, y + 2 * s, buf, s, ink);
  }
  for (int yy = top; yy <= bottom; yy++) {
    double t = (double)(bottom - yy) / (double)(bottom - top);
    uint8_t col[3];
    bsurf_colormap_rgb(cmap, t, col);
    bsurf_draw_hline(&c, bx, bx + barw - 1, yy, col);
  }
  /* frame */
  bsurf_draw_hline(&c, bx - 1, bx + barw, top - 1, ink);
  bsurf_draw_hline(&c, bx - 1, bx + barw, bottom + 1, ink);
  bsurf_draw_vline(&c, bx - 1, top - 1, bottom + 1, ink);
  bsurf_draw_vline(&c, bx + barw, top - 1, bottom + 1, ink);
  if (!isfinite(lo) || !isfinite(hi)) return;
  double ticks[16];
  int nt;
  if (hi > lo) {
    nt = bsurf_draw_nice_ticks(lo, hi, 5, ticks, 16);
  } else {
    ticks[0] = lo;
    nt = 1;
  }
  double step = nt > 1 ? ticks[1] - ticks[0] : fabs(lo) / 10;
  for (int k = 0; k < nt; k++) {
    double t = hi > lo ? (ticks[k] - lo) / (hi - lo) : 0.5;
    int yy = bottom - (int)floor(t * (bottom - top) + 0.5);
    bsurf_draw_hline(&c, bx + barw, bx + barw + 4 * s, yy, ink);
    char buf[32];
    bsurf_draw_format_value(ticks[k], step, buf, sizeof buf);
    bsurf_draw_text(&c, bx + barw + 7 * s, yy - FONT_H * s / 2, buf, s, ink);
  }
}

/* ---- one view into a panel of the image ---- */
typedef struct {
  const double *xyz, *normals, *values;
  size_t n;
  const bsurf_render_options *opt;
  double lo, hi; /* value range */
  double h;      /* spacing */
  double center[3];
  int threads;
} render_job;

static bsurf_status render_view(const render_job *job, canvas *img, int px, int py, int pw, int ph,
                                double az, double el, size_t *covered) {
  const bsurf_render_options *opt = job->opt;
  if (pw < 4 || ph < 4) return BSURF_OK;
  view_frame f;
  make_frame(&f, az, el, opt->up_axis);
  const size_t n = job->n;
  const double *xyz = job->xyz;
  /* projected extent (serial min/max: exact, order-independent) */
  double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  for (size_t i = 0; i < n; i++) {
    double d[3] = {xyz[3 * i] - job->center[0], xyz[3 * i + 1] - job->center[1],
                   xyz[3 * i + 2] - job->center[2]};
    double sx = d[0] * f.right[0] + d[1] * f.right[1] + d[2] * f.right[2];
    double sy = d[0] * f.up[0] + d[1] * f.up[1] + d[2] * f.up[2];
    if (sx < xmin) xmin = sx;
    if (sx > xmax) xmax = sx;
    if (sy < ymin) ymin = sy;
    if (sy > ymax) ymax = sy;
  }
  double margin = 0.06;
  double spanx = xmax - xmin, spany = ymax - ymin;
  double span = fmax(spanx / pw, spany / ph);
  if (!(span > 0)) span = (job->h > 0 ? job->h : 1.0) / 4;
  /* splats go to a buffer ss times finer, averaged down (antialiasing) */
  const int ss = opt->supersample;
  const int sw = pw * ss, sh = ph * ss;
  double scale = (1.0 - 2 * margin) / span * ss; /* sub-pixels per unit */
  double cx = 0.5 * (xmin + xmax), cy = 0.5 * (ymin + ymax);
  const double radius_h = 0.5 * opt->point_size * scale; /* radius per unit of spacing */
  const double radius_max = 64.0 * ss;
  const double *pspace = opt->point_spacing;

  size_t npix = (size_t)sw * (size_t)sh;
  uint64_t *zbuf = bsurf_calloc_array(npix, sizeof *zbuf);
  if (!zbuf) return BSURF_ERR_NOMEM;
  const uint32_t idx_cap = 0xFFFFFFFFu;
  const int round = opt->round_splats;
  long long nn = (long long)n;
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(job->threads)
#endif
  for (long long ii = 0; ii < nn; ii++) {
    size_t i = (size_t)ii;
    double d[3] = {xyz[3 * i] - job->center[0], xyz[3 * i + 1] - job->center[1],
                   xyz[3 * i + 2] - job->center[2]};
    double sx = (d[0] * f.right[0] + d[1] * f.right[1] + d[2] * f.right[2] - cx) * scale + 0.5 * sw;
    double sy = 0.5 * sh - (d[0] * f.up[0] + d[1] * f.up[1] + d[2] * f.up[2] - cy) * scale;
    float depth = (float)(d[0] * f.eye[0] + d[1] * f.eye[1] + d[2] * f.eye[2]);
    uint64_t key = ((uint64_t)depth_key(depth) << 32) |
                   (uint64_t)(idx_cap - (uint32_t)(i < idx_cap ? i : idx_cap - 1));
    double radius = radius_h * (pspace && pspace[i] > 0 ? pspace[i] : job->h);
    if (!(radius >= 0.5)) radius = 0.5;
    if (radius > radius_max) radius = radius_max;
    const double r2 = radius * radius;
    int x0 = (int)floor(sx - radius), x1 = (int)floor(sx + radius);
    int y0 = (int)floor(sy - radius), y1 = (int)floor(sy + radius);
    const int cx0 = (int)floor(sx), cy0 = (int)floor(sy);
    if (x0 < 0) x0 = 0;
    if (y0 < 0) y0 = 0;
    if (x1 >= sw) x1 = sw - 1;
    if (y1 >= sh) y1 = sh - 1;
    for (int y = y0; y <= y1; y++) {
      double dy = y + 0.5 - sy;
      for (int x = x0; x <= x1; x++) {
        double dx = x + 0.5 - sx;
        /* the pixel under the centre is always drawn, even for tiny splats */
        if (round && dx * dx + dy * dy > r2 && (x != cx0 || y != cy0)) continue;
        atomic_max_u64(&zbuf[(size_t)y * sw + x], key);
      }
    }
  }

  /* depth range for depth shading */
  float dmin = INFINITY, dmax = -INFINITY;
  for (size_t p = 0; p < npix && !job->normals; p++)
    if (zbuf[p]) {
      float dd = key_depth((uint32_t)(zbuf[p] >> 32));
      if (dd < dmin) dmin = dd;
      if (dd > dmax) dmax = dd;
    }
  static const uint8_t surface[3] = {205, 208, 220};
  static const uint8_t nan_color[3] = {150, 150, 150};
  size_t cov = 0;
  const double inv = 1.0 / (ss * ss);
  /* every output pixel depends only on its own samples: rows in parallel */
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(job->threads) reduction(+ : cov)
#endif
  for (int y = 0; y < ph; y++)
    for (int x = 0; x < pw; x++) {
      double acc[3] = {0, 0, 0};
      int hit = 0;
      for (int yy = y * ss; yy < (y + 1) * ss; yy++)
        for (int xx = x * ss; xx < (x + 1) * ss; xx++) {
          uint64_t k = zbuf[(size_t)yy * sw + xx];
          if (!k) {
            for (int t = 0; t < 3; t++)
              acc[t] += opt->background[t];
            continue;
          }
          hit = 1;
          size_t i = (size_t)(idx_cap - (uint32_t)(k & 0xFFFFFFFFu));
          double shade = 1.0;
          if (job->normals) {
            const double *nv = job->normals + 3 * i;
            double len = sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
            double lam =
                len > 0 ? fabs(nv[0] * f.light[0] + nv[1] * f.light[1] + nv[2] * f.light[2]) / len
                        : 1.0;
            shade = 0.22 + 0.78 * lam;
          } else if (dmax > dmin) {
            float dd = key_depth((uint32_t)(k >> 32));
            shade = 0.45 + 0.55 * (dd - dmin) / (dmax - dmin);
          }
          uint8_t col[3];
          double mod = shade;
          if (job->values) {
            double v = job->values[i];
            if (isfinite(v)) {
              double t = job->hi > job->lo ? (v - job->lo) / (job->hi - job->lo) : 0.5;
              bsurf_colormap_rgb(opt->colormap, t, col);
            } else {
              memcpy(col, nan_color, 3);
            }
            mod = opt->shade ? 0.45 + 0.55 * shade : 1.0;
          } else {
            memcpy(col, surface, 3);
          }
          for (int t = 0; t < 3; t++)
            acc[t] += col[t] * mod;
        }
      if (!hit) continue;
      cov++;
      uint8_t *o = img->rgb + 3 * ((size_t)(py + y) * (size_t)img->width + (size_t)(px + x));
      for (int t = 0; t < 3; t++) {
        double c = acc[t] * inv;
        o[t] = (uint8_t)(c > 255 ? 255 : c + 0.5);
      }
    }
  free(zbuf);
  if (covered) *covered += cov;
  return BSURF_OK;
}

bsurf_status bsurf_render_options_check(const bsurf_render_options *o) {
  /* the view's numbers, in the words both front ends print (the command
   * line as --azimuth, --elevation, --point-size) */
  if (!o) return bsurf_set_message(BSURF_ERR_INVALID_ARG, "options are NULL");
  if (!(o->azimuth >= -360 && o->azimuth <= 360))
    return bsurf_set_message(BSURF_ERR_INVALID_ARG, "azimuth %g: must be from -360 to 360 degrees",
                             o->azimuth);
  if (!(o->elevation >= -90 && o->elevation <= 90))
    return bsurf_set_message(BSURF_ERR_INVALID_ARG,
                             "elevation %g: must be from -90 to 90 degrees (90 looks down)",
                             o->elevation);
  /* below 0.05 h a splat covers no pixel of a cloud; above 50 h one point
   * hides its neighbourhood's */
  if (!(o->point_size >= 0.05 && o->point_size <= 50))
    return bsurf_set_message(BSURF_ERR_INVALID_ARG,
                             "point_size %g: must be from 0.05 to 50 (splat diameters in h)",
                             o->point_size);
  return BSURF_OK;
}

bsurf_status bsurf_render(uint8_t *rgb, const double *xyz, const double *normals,
                          size_t point_count, const double *values,
                          const bsurf_render_options *opt_in, bsurf_render_info *info) {
  bsurf_render_options opt = opt_in ? *opt_in : bsurf_render_options_default();
  BSURF_REQUIRE(rgb, "rgb is NULL");
  BSURF_REQUIRE(xyz || !point_count, "xyz is NULL");
  /* indices are 32-bit in the z-buffer */
  BSURF_REQUIRE(point_count < 0xFFFFFFFFu, "point_count = %zu: must be below 2^32 - 1",
                point_count);
  BSURF_REQUIRE(opt.width >= 16 && opt.height >= 16 && opt.width <= 16384 && opt.height <= 16384,
                "width x height = %d x %d: each must be in [16, 16384]", opt.width, opt.height);
  BSURF_REQUIRE(opt.views == 1 || opt.views == 4, "views = %d: must be 1 or 4", opt.views);
  BSURF_REQUIRE(opt.supersample >= 1 && opt.supersample <= 4, "supersample = %d: must be in [1, 4]",
                opt.supersample);
  BSURF_REQUIRE(opt.up_axis >= 0 && opt.up_axis <= 2, "up_axis = %d: must be 0, 1 or 2",
                opt.up_axis);
  /* the view's numbers (NaN and infinities included) */
  if (bsurf_render_options_check(&opt) != BSURF_OK) {
    char m[256];
    snprintf(m, sizeof m, "%s", bsurf_last_message());
    return bsurf_invalid("bsurf_render", "%s", m);
  }
  canvas img = {rgb, opt.width, opt.height};
  bsurf_draw_fill(&img, opt.background);
  uint8_t ink[3];
  bsurf_draw_ink_for(opt.background, ink);

  render_job job;
  memset(&job, 0, sizeof job);
  job.xyz = xyz;
  job.normals = normals;
  job.values = values;
  job.n = point_count;
  job.opt = &opt;
  job.threads = bsurf_threads_resolve(opt.threads);
  job.lo = opt.range_lo;
  job.hi = opt.range_hi;
  if (values && (!isfinite(job.lo) || !isfinite(job.hi))) {
    double lo = NAN, hi = NAN;
    bsurf_status st =
        bsurf_render_range(values, point_count, opt.percentile_lo, opt.percentile_hi, &lo, &hi);
    if (st == BSURF_ERR_NOMEM) return st;
    if (!isfinite(job.lo)) job.lo = lo;
    if (!isfinite(job.hi)) job.hi = hi;
  }
  double lo3[3], hi3[3];
  bsurf_bounding_box(xyz, point_count, lo3, hi3);
  double extent = 0;
  if (point_count) {
    for (int t = 0; t < 3; t++) {
      job.center[t] = 0.5 * (lo3[t] + hi3[t]);
      extent = fmax(extent, hi3[t] - lo3[t]);
    }
  }
  job.h = opt.spacing > 0 ? opt.spacing : estimate_spacing(xyz, point_count, lo3, extent);

  int s = bsurf_draw_font_scale(opt.height);
  int bar_w = (values && opt.colorbar) ? (s == 2 ? 150 : 80) : 0;
  if (bar_w > opt.width / 3) bar_w = 80; /* a narrower bar (its font is then 1x) */
  if (bar_w > opt.width / 3) bar_w = 0;
  int title_h = opt.title ? (FONT_H + 8) * s : 0;
  int plot_w = opt.width - bar_w, plot_h = opt.height - title_h;
  size_t covered = 0;
  bsurf_status st = BSURF_OK;
  if (opt.views == 1) {
    st = render_view(&job, &img, 0, title_h, plot_w, plot_h, opt.azimuth, opt.elevation, &covered);
  } else {
    static const char *const names[4] = {"front", "right", "top", "iso"};
    int hw = plot_w / 2, hh = plot_h / 2;
    for (int v = 0; v < 4 && st == BSURF_OK; v++) {
      double az = 0, el = 0;
      bsurf_view_from_name(names[v], &az, &el);
      int px = (v % 2) * hw, py = title_h + (v / 2) * hh;
      st = render_view(&job, &img, px, py, hw, hh, az, el, &covered);
      bsurf_draw_text(&img, px + 4 * s, py + 4 * s, names[v], s, ink);
    }
    if (st == BSURF_OK) {
      uint8_t sep[3] = {(uint8_t)((opt.background[0] + 2 * ink[0]) / 3),
                        (uint8_t)((opt.background[1] + 2 * ink[1]) / 3),
                        (uint8_t)((opt.background[2] + 2 * ink[2]) / 3)};
      bsurf_draw_vline(&img, hw, title_h, title_h + 2 * hh - 1, sep);
      bsurf_draw_hline(&img, 0, 2 * hw - 1, title_h + hh, sep);
    }
  }
  if (st != BSURF_OK) return st;
  if (opt.title) {
    int tw = bsurf_draw_text_width(opt.title, s);
    bsurf_draw_text(&img, (plot_w - tw) / 2 > 2 ? (plot_w - tw) / 2 : 2, 4 * s, opt.title, s, ink);
  }
  if (bar_w) {
    int bh = plot_h * 3 / 4;
    bsurf_render_colorbar(rgb, opt.width, opt.height, plot_w, title_h + (plot_h - bh) / 2,
                          bar_w - 4, bh, opt.colormap, job.lo, job.hi, opt.label, opt.background);
  }
  if (info) {
    info->range_lo = values ? job.lo : NAN;
    info->range_hi = values ? job.hi : NAN;
    info->spacing = job.h;
    info->covered_pixels = covered;
  }
  return BSURF_OK;
}
