/* Colormaps for pictures of per-point fields.
 *
 * viridis and magma are perceptually uniform maps by S. van der Walt and
 * N. Smith (matplotlib 1.5+, CC0); the control points below are entries
 * 0, 16, 32, ..., 240 and 255 of matplotlib's published 256-entry tables
 * (lib/matplotlib/_cm_listed.py: _viridis_data, _magma_data), interpolated
 * linearly in between (the tables are smooth: the error is below 1/255).
 * coolwarm is K. Moreland's diverging map ("Diverging Color Maps for
 * Scientific Visualization", 2009), five of its published control points.
 * gray is linear. */
#include "draw.h"

#include <math.h>
#include <string.h>

typedef struct {
  float t, r, g, b;
} cmap_point;

#define P16(i, r, g, b)                                                                            \
  { (float)(i) / 255.0f, r, g, b }
static const cmap_point viridis[] = {
    P16(0, 0.267004f, 0.004874f, 0.329415f),   P16(16, 0.282327f, 0.094955f, 0.417331f),
    P16(32, 0.278826f, 0.175490f, 0.483397f),  P16(48, 0.258965f, 0.251537f, 0.524736f),
    P16(64, 0.229739f, 0.322361f, 0.545706f),  P16(80, 0.199430f, 0.387607f, 0.554642f),
    P16(96, 0.172719f, 0.448791f, 0.557885f),  P16(112, 0.149039f, 0.508051f, 0.557250f),
    P16(128, 0.127568f, 0.566949f, 0.550556f), P16(144, 0.120638f, 0.625828f, 0.533488f),
    P16(160, 0.157851f, 0.683765f, 0.501686f), P16(176, 0.246070f, 0.738910f, 0.452024f),
    P16(192, 0.369214f, 0.788888f, 0.382914f), P16(208, 0.515992f, 0.831158f, 0.294279f),
    P16(224, 0.678489f, 0.863742f, 0.189503f), P16(240, 0.845561f, 0.887322f, 0.099702f),
    P16(255, 0.993248f, 0.906157f, 0.143936f),
};
static const cmap_point magma[] = {
    P16(0, 0.001462f, 0.000466f, 0.013866f),   P16(16, 0.039608f, 0.031090f, 0.133515f),
    P16(32, 0.113094f, 0.065492f, 0.276784f),  P16(48, 0.211718f, 0.061992f, 0.418647f),
    P16(64, 0.316654f, 0.071690f, 0.485380f),  P16(80, 0.414709f, 0.110431f, 0.504662f),
    P16(96, 0.512831f, 0.148179f, 0.507648f),  P16(112, 0.613617f, 0.181811f, 0.498536f),
    P16(128, 0.716387f, 0.214982f, 0.475290f), P16(144, 0.816914f, 0.255895f, 0.436461f),
    P16(160, 0.904281f, 0.319610f, 0.388137f), P16(176, 0.960949f, 0.418323f, 0.359630f),
    P16(192, 0.986700f, 0.535582f, 0.382210f), P16(208, 0.996096f, 0.653659f, 0.446213f),
    P16(224, 0.996898f, 0.769591f, 0.534892f), P16(240, 0.992440f, 0.884330f, 0.640099f),
    P16(255, 0.987053f, 0.991438f, 0.749504f),
};
static const cmap_point coolwarm[] = {
    {0.00f, 0.2298f, 0.2987f, 0.7537f}, {0.25f, 0.5543f, 0.6901f, 0.9955f},
    {0.50f, 0.8654f, 0.8654f, 0.8654f}, {0.75f, 0.9567f, 0.5980f, 0.4773f},
    {1.00f, 0.7057f, 0.0156f, 0.1502f},
};
static const cmap_point gray[] = {{0.0f, 0.0f, 0.0f, 0.0f}, {1.0f, 1.0f, 1.0f, 1.0f}};

static const char *const cmap_names[] = {"viridis", "magma", "gray", "coolwarm"};

int bsurf_colormap_from_name(const char *name, bsurf_colormap *cmap) {
  for (int i = 0; i < 4; i++)
    if (name && strcmp(name, cmap_names[i]) == 0) {
      *cmap = (bsurf_colormap)i;
      return 0;
    }
  return -1;
}

const char *bsurf_colormap_name(bsurf_colormap cmap) {
  return (unsigned)cmap < 4 ? cmap_names[cmap] : "?";
}

static uint8_t to_byte(float v) {
  float x = v * 255.0f + 0.5f;
  if (x < 0.0f) x = 0.0f;
  if (x > 255.0f) x = 255.0f;
  return (uint8_t)x;
}

void bsurf_colormap_rgb(bsurf_colormap cmap, double t, uint8_t rgb[3]) {
  const cmap_point *p;
  int n;
  switch (cmap) {
  case BSURF_COLORMAP_MAGMA: p = magma, n = (int)(sizeof magma / sizeof *magma); break;
  case BSURF_COLORMAP_GRAY: p = gray, n = 2; break;
  case BSURF_COLORMAP_COOLWARM: p = coolwarm, n = (int)(sizeof coolwarm / sizeof *coolwarm); break;
  case BSURF_COLORMAP_VIRIDIS:
  default: p = viridis, n = (int)(sizeof viridis / sizeof *viridis); break;
  }
  if (!(t > 0.0)) t = 0.0; /* NaN too */
  if (t > 1.0) t = 1.0;
  float tf = (float)t;
  int k = 0;
  while (k < n - 2 && tf > p[k + 1].t)
    k++;
  float w = (tf - p[k].t) / (p[k + 1].t - p[k].t);
  if (w < 0.0f) w = 0.0f;
  if (w > 1.0f) w = 1.0f;
  rgb[0] = to_byte(p[k].r + w * (p[k + 1].r - p[k].r));
  rgb[1] = to_byte(p[k].g + w * (p[k + 1].g - p[k].g));
  rgb[2] = to_byte(p[k].b + w * (p[k + 1].b - p[k].b));
}
