/* Histogram pictures of a per-point field (thesis 7.2 chooses feature
 * thresholds from such histograms): bars, axes with ticks and labels, an
 * optional threshold marker, optional log10(1 + count) bar heights. */
#include "draw.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

bsurf_histogram_options bsurf_histogram_options_default(void) {
  bsurf_histogram_options o = {
      .width = 800, .height = 500, .bins = 50, .range_lo = NAN, .range_hi = NAN, .threshold = NAN};
  return o;
}

bsurf_status bsurf_render_histogram(uint8_t *rgb, const double *values, size_t count,
                                    const bsurf_histogram_options *opt_in,
                                    bsurf_histogram_info *info) {
  bsurf_histogram_options opt = opt_in ? *opt_in : bsurf_histogram_options_default();
  BSURF_REQUIRE(rgb, "rgb is NULL");
  BSURF_REQUIRE(values || !count, "values is NULL");
  BSURF_REQUIRE(opt.width >= 64 && opt.height >= 64 && opt.width <= 16384 && opt.height <= 16384,
                "width x height = %d x %d: each must be in [64, 16384]", opt.width, opt.height);
  BSURF_REQUIRE(opt.bins >= 1 && opt.bins <= 100000, "bins = %d: must be in [1, 100000]", opt.bins);
  double lo = opt.range_lo, hi = opt.range_hi;
  if (!isfinite(lo) || !isfinite(hi)) {
    double mn = INFINITY, mx = -INFINITY;
    for (size_t i = 0; i < count; i++)
      if (isfinite(values[i])) {
        if (values[i] < mn) mn = values[i];
        if (values[i] > mx) mx = values[i];
      }
    if (!isfinite(lo)) lo = mn;
    if (!isfinite(hi)) hi = mx;
  }
  if (!isfinite(lo) || !isfinite(hi)) lo = 0, hi = 1; /* no finite value: an empty plot */
  if (hi < lo) {
    double t = lo;
    lo = hi, hi = t;
  }
  if (hi == lo) {
    double d = fabs(lo) > 0 ? fabs(lo) * 0.05 : 0.5;
    lo -= d, hi += d;
  }
  size_t *bins = bsurf_calloc_array((size_t)opt.bins, sizeof *bins);
  if (!bins) return BSURF_ERR_NOMEM;
  size_t counted = 0, above = 0, maxc = 0;
  for (size_t i = 0; i < count; i++) {
    double v = values[i];
    if (!isfinite(v)) continue;
    if (isfinite(opt.threshold) && v > opt.threshold) above++;
    if (v < lo || v > hi) continue;
    long b = (long)floor((v - lo) / (hi - lo) * opt.bins);
    if (b >= opt.bins) b = opt.bins - 1;
    if (b < 0) b = 0;
    bins[b]++;
    counted++;
  }
  for (int b = 0; b < opt.bins; b++)
    if (bins[b] > maxc) maxc = bins[b];

  canvas c = {rgb, opt.width, opt.height};
  static const uint8_t white[3] = {255, 255, 255}, ink[3] = {20, 20, 20}, bar[3] = {68, 114, 168},
                       grid[3] = {225, 225, 225}, mark[3] = {200, 30, 30};
  bsurf_draw_fill(&c, white);
  int s = bsurf_draw_font_scale(opt.height);
  int left = 10 * s + 7 * (FONT_W + 1) * s + 8 * s; /* room for count labels and the y caption */
  int right = opt.width - 16 * s;
  int top = (opt.title ? (FONT_H + 10) * s : 6 * s) + FONT_H * s +
            (isfinite(opt.threshold) ? (FONT_H + 4) * s : 0);
  int bottom = opt.height - (FONT_H * 2 + 16) * s;
  if (right - left < 20 || bottom - top < 20) {
    free(bins);
    return bsurf_invalid(__func__, "width x height = %d x %d: too small for the axes and labels",
                         opt.width, opt.height);
  }
  double ymax = opt.log_counts ? log10(1.0 + (double)maxc) : (double)maxc;
  if (!(ymax > 0)) ymax = 1;
  /* y ticks and grid */
  double ticks[32];
  int nt;
  double step;
  if (opt.log_counts) {
    /* counts 0, 1, 10, 100, ... at log10(1 + count) */
    ticks[0] = 0;
    nt = 1;
    for (double c = 1; nt < 32 && log10(1.0 + c) <= ymax; c *= 10)
      ticks[nt++] = log10(1.0 + c);
    step = 1;
  } else {
    nt = bsurf_draw_nice_ticks(0, ymax, 5, ticks, 32);
    step = nt > 1 ? ticks[1] - ticks[0] : 1;
    if (step < 1) nt = bsurf_draw_nice_ticks(0, ymax < 2 ? 2 : ymax, 2, ticks, 32);
  }
  for (int k = 0; k < nt; k++) {
    int y = bottom - (int)floor(ticks[k] / ymax * (bottom - top) + 0.5);
    if (y < top) continue;
    bsurf_draw_hline(&c, left + 1, right, y, grid);
    bsurf_draw_hline(&c, left - 4 * s, left - 1, y, ink);
    char buf[32];
    if (opt.log_counts)
      snprintf(buf, sizeof buf, "%.0f", pow(10.0, ticks[k]) - 1.0);
    else
      bsurf_draw_format_value(ticks[k], ticks[k] == floor(ticks[k]) ? 1.0 : step, buf, sizeof buf);
    bsurf_draw_text(&c, left - 6 * s - bsurf_draw_text_width(buf, s), y - FONT_H * s / 2, buf, s,
                    ink);
  }
  /* bars */
  double bw = (double)(right - left) / opt.bins;
  for (int b = 0; b < opt.bins; b++) {
    if (!bins[b]) continue;
    double hgt = opt.log_counts ? log10(1.0 + (double)bins[b]) : (double)bins[b];
    int y = bottom - (int)floor(hgt / ymax * (bottom - top) + 0.5);
    int x0 = left + (int)floor(b * bw + 0.5), x1 = left + (int)floor((b + 1) * bw + 0.5) - 1;
    if (bw >= 4 && x1 > x0) x1--;    /* a gap between bars */
    if (y >= bottom) y = bottom - 1; /* a non-empty bin is never invisible */
    bsurf_draw_rect(&c, x0, y, x1 < x0 ? x0 : x1, bottom - 1, bar);
  }
  /* axes */
  bsurf_draw_hline(&c, left, right, bottom, ink);
  bsurf_draw_vline(&c, left, top, bottom, ink);
  /* as many x ticks as their labels leave room for */
  for (int target = 8; target >= 2; target--) {
    nt = bsurf_draw_nice_ticks(lo, hi, target, ticks, 32);
    step = nt > 1 ? ticks[1] - ticks[0] : (hi - lo);
    int widest = 0;
    for (int k = 0; k < nt; k++) {
      char buf[32];
      bsurf_draw_format_value(ticks[k], step, buf, sizeof buf);
      int tw = bsurf_draw_text_width(buf, s);
      if (tw > widest) widest = tw;
    }
    if (nt * (widest + 6 * (FONT_W + 1) * s / 2) <= right - left) break;
  }
  for (int k = 0; k < nt; k++) {
    int x = left + (int)floor((ticks[k] - lo) / (hi - lo) * (right - left) + 0.5);
    bsurf_draw_vline(&c, x, bottom + 1, bottom + 4 * s, ink);
    char buf[32];
    bsurf_draw_format_value(ticks[k], step, buf, sizeof buf);
    bsurf_draw_text(&c, x - bsurf_draw_text_width(buf, s) / 2, bottom + 7 * s, buf, s, ink);
  }
  /* captions */
  const char *xl = opt.label ? opt.label : "value";
  bsurf_draw_text(&c, left + (right - left - bsurf_draw_text_width(xl, s)) / 2,
                  opt.height - (FONT_H + 4) * s, xl, s, ink);
  const char *yl = opt.log_counts ? "count (log)" : "count";
  bsurf_draw_text_up(&c, 4 * s, top + (bottom - top + bsurf_draw_text_width(yl, s)) / 2, yl, s,
                     ink);
  if (opt.title)
    bsurf_draw_text(&c, (opt.width - bsurf_draw_text_width(opt.title, s)) / 2, 5 * s, opt.title, s,
                    ink);
  /* threshold */
  if (isfinite(opt.threshold) && opt.threshold >= lo && opt.threshold <= hi) {
    int x = left + (int)floor((opt.threshold - lo) / (hi - lo) * (right - left) + 0.5);
    for (int d = -s / 2; d <= s / 2; d++)
      bsurf_draw_vline(&c, x + d, top - 2 * s, bottom - 1, mark);
    char buf[64], v[32];
    snprintf(v, sizeof v, "%.4g", opt.threshold);
    snprintf(buf, sizeof buf, "t=%s: %zu above", v, above);
    int tw = bsurf_draw_text_width(buf, s);
    int tx = x + 4 * s;
    if (tx + tw > right) tx = x - 4 * s - tw;
    bsurf_draw_text(&c, tx, top - (FONT_H + 6) * s, buf, s, mark);
  }
  free(bins);
  if (info) {
    info->counted = counted;
    info->above_threshold = above;
    info->max_count = maxc;
  }
  return BSURF_OK;
}
