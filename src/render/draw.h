/* Internal drawing helpers of the render layer: an RGB canvas, a 5x7 bitmap
 * font, lines, rectangles, tick values, the colour bar. */
#ifndef BSURF_RENDER_DRAW_H
#define BSURF_RENDER_DRAW_H

#include "common/common.h"

#include <stdint.h>

typedef struct {
  uint8_t *rgb; /* height x width x 3 */
  int width, height;
} canvas;

#define FONT_W 5
#define FONT_H 7
/* Advance of one character at scale s: (FONT_W + 1) * s. */
int bsurf_draw_text_width(const char *text, int scale);
/* Text with its top-left corner at (x, y); clipped to the canvas. */
void bsurf_draw_text(canvas *c, int x, int y, const char *text, int scale, const uint8_t color[3]);
/* Text rotated by 90 degrees counter-clockwise (reads bottom to top), its
 * bottom-left corner at (x, y). */
void bsurf_draw_text_up(canvas *c, int x, int y, const char *text, int scale,
                        const uint8_t color[3]);
void bsurf_draw_rect(canvas *c, int x0, int y0, int x1, int y1,
                     const uint8_t color[3]); /* filled, inclusive */
void bsurf_draw_hline(canvas *c, int x0, int x1, int y, const uint8_t color[3]);
void bsurf_draw_vline(canvas *c, int x, int y0, int y1, const uint8_t color[3]);
void bsurf_draw_fill(canvas *c, const uint8_t color[3]);
/* Text or ink colour that reads on `bg`. */
void bsurf_draw_ink_for(const uint8_t bg[3], uint8_t ink[3]);
/* "Nice" tick values covering [lo, hi]: returns their count (<= max) in ticks. */
int bsurf_draw_nice_ticks(double lo, double hi, int target, double *ticks, int max);
/* A short label of a tick value (%.3g, with trailing zeros trimmed). */
void bsurf_draw_format_value(double v, double step, char *buf, size_t size);
/* Font scale that suits an image of this height. */
int bsurf_draw_font_scale(int height);

#endif
