/* bootsurf render: a PNG picture of a cloud, shaded by its normals or
 * coloured by a field (the thesis's figures). Also the helpers shared by
 * histogram and compare (declared in cli.h). */
#include "cli.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int render_parse_size(const cli_command *cmd, const char *text, int *w, int *h) {
  char *end = NULL;
  long a = strtol(text, &end, 10);
  if (end == text || (*end != 'x' && *end != 'X'))
    return cli_usage_error(cmd, "--size needs WIDTHxHEIGHT (e.g. 1024x768), not '%s'", text);
  const char *p = end + 1;
  long b = strtol(p, &end, 10);
  if (end == p || *end || a < 64 || b < 64 || a > 8192 || b > 8192)
    return cli_usage_error(cmd, "--size needs WIDTHxHEIGHT with each in 64..8192, not '%s'", text);
  *w = (int)a;
  *h = (int)b;
  return 0;
}

int render_parse_range(const cli_command *cmd, const char *text, double *lo, double *hi) {
  char *end = NULL;
  double a = strtod(text, &end);
  if (end == text || *end != ':')
    return cli_usage_error(cmd, "--range needs LO:HI, not '%s'", text);
  const char *p = end + 1;
  double b = strtod(p, &end);
  if (end == p || *end || !isfinite(a) || !isfinite(b) || !(b > a))
    return cli_usage_error(cmd, "--range needs LO:HI with LO < HI, not '%s'", text);
  *lo = a;
  *hi = b;
  return 0;
}

/* The coordinates and normals by their files' names (x y z, nx ny nz):
 * every number a point carries can colour it, as its fields can. */
static const char *const coordinate_names[6] = {"x", "y", "z", "nx", "ny", "nz"};

const bsurf_field *render_find_field(bsurf_cloud *c, const char *path, const char *name) {
  const bsurf_field *f = bsurf_cloud_field(c, name);
  if (f) return f;
  for (int k = 0; k < 6; k++) {
    const double *src = k < 3 ? c->xyz : c->normals;
    if (strcmp(name, coordinate_names[k]) != 0 || !src) continue;
    /* a field of the cloud read for the picture (never written back) */
    bsurf_field *g = bsurf_cloud_add_field(c, name, BSURF_FLOAT64);
    if (!g) {
      cli_error("out of memory");
      return NULL;
    }
    for (size_t i = 0; i < c->point_count; i++)
      g->values[i] = src[3 * i + (size_t)(k % 3)];
    return g;
  }
  char list[1024] = "";
  size_t len = 0;
  for (int k = 0; k < (c->normals ? 6 : 3); k++)
    len +=
        (size_t)snprintf(list + len, sizeof list - len, "%s%s", k ? ", " : "", coordinate_names[k]);
  for (size_t i = 0; i < c->field_count && len + 80 < sizeof list; i++)
    len += (size_t)snprintf(list + len, sizeof list - len, ", %s", c->fields[i].name);
  cli_error("%s: no field '%s'; available fields: %s", path, name, list);
  return NULL;
}

static int render_view_option(const cli_command *cmd, const char *view, double az, double el,
                              double *out_az, double *out_el) {
  if (view && (!isnan(az) || !isnan(el)))
    return cli_usage_error(cmd, "give --view or --azimuth/--elevation, not both");
  if (view) {
    if (bsurf_view_from_name(view, out_az, out_el) != 0)
      return cli_usage_error(
          cmd, "--view must be front, back, left, right, top, bottom or iso, not '%s'", view);
    return 0;
  }
  if (!isnan(az)) *out_az = az;
  if (!isnan(el)) *out_el = el;
  return 0;
}

/* bsurf_render_spacing into a new array: NULL when the renderer is to use
 * h everywhere (or on failure, *status). */
double *render_spacing(const bsurf_cloud *c, int threads, bsurf_progress_fn progress, void *user,
                       double *h, bsurf_status *status) {
  double *out = c->point_count ? malloc(c->point_count * sizeof *out) : NULL;
  int filled = 0;
  *status = bsurf_render_spacing(c->xyz, c->point_count, threads, progress, user, h, out, &filled);
  if (*status != BSURF_OK || !filled) {
    free(out);
    return NULL;
  }
  return out;
}

static int render_up_option(const cli_command *cmd, const char *up, int *axis) {
  static const char *const axes[] = {"x", "y", "z", "auto"};
  int a = cli_choice(up, axes, 4);
  if (a < 0) return cli_usage_error(cmd, "--up must be x, y, z or auto, not '%s'", up);
  *axis = a == 3 ? -1 : a;
  return 0;
}

int cli_png_name(const cli_command *cmd, const char *path) {
  const char *base = strrchr(path, '/');
  base = base ? base + 1 : path;
  const char *dot = strrchr(base, '.');
  if (!dot || dot == base || !dot[1]) return 0;
  const char *png = ".png";
  for (int i = 0; i < 5; i++)
    if (tolower((unsigned char)dot[i]) != png[i])
      return cli_usage_error(cmd, "-o %s: the output is a PNG image: name it .png", path);
  return 0;
}

int render_args_apply(const cli_command *cmd, const render_args *a, bsurf_render_options *ro) {
  if (!a->output) return cli_usage_error(cmd, "-o IMAGE.png is required");
  if (cli_png_name(cmd, a->output)) return CLI_USAGE;
  if (bsurf_colormap_from_name(a->cmap, &ro->colormap) != 0)
    return cli_usage_error(cmd, "--colormap must be viridis, magma, gray or coolwarm, not '%s'",
                           a->cmap);
  if (a->size && render_parse_size(cmd, a->size, &ro->width, &ro->height)) return CLI_USAGE;
  if (a->range && render_parse_range(cmd, a->range, &ro->range_lo, &ro->range_hi)) return CLI_USAGE;
  if (render_view_option(cmd, a->view, a->az, a->el, &ro->azimuth, &ro->elevation))
    return CLI_USAGE;
  if (render_up_option(cmd, a->up, &ro->up_axis)) return CLI_USAGE;
  if (bsurf_render_options_check(ro) != BSURF_OK) {
    /* the library's words, its option named as the command line spells it
     * ("point_size 100: ..." is --point-size) */
    char m[256];
    snprintf(m, sizeof m, "%s", bsurf_last_message());
    for (char *p = m; *p && *p != ' '; p++)
      if (*p == '_') *p = '-';
    return cli_usage_error(cmd, "--%s", m);
  }
  ro->shade = !a->flat;
  return 0;
}

int render_auto_up(const bsurf_cloud *c) {
  return bsurf_render_auto_up(c->shape);
}

int cli_write_png(const char *path, const uint8_t *rgb, int w, int h) {
  bsurf_failure err = {0, -1, ""};
  if (cli_interrupted()) return cli_error("%s: interrupted; nothing written", path);
  bsurf_status st = cli_write_png_to(path, rgb, w, h, &err);
  if (st != BSURF_OK)
    return cli_error("%s: %s", path, err.message[0] ? err.message : bsurf_strerror(st));
  return 0;
}

int cmd_render(const cli_command *cmd, int argc, char **argv) {
  bsurf_render_options ro = bsurf_render_options_default();
  render_args a = {NULL, NULL, "viridis", NULL, NULL, NULL, "auto", NAN, NAN, 0};
  const char *title = NULL;
  int views = 1, json = 0, quiet = 0, force = 0, square = 0;
  cli_option opts[] = {
      RENDER_OPTS_VIEW(a, ro),
      {0, "range", ARG_STRING, &a.range, "LO:HI",
       "values at the colormap's ends (default: 1st-99th percentile)", 1, 0},
      {0, "up", ARG_STRING, &a.up, "AXIS",
       "the axis that points up in the views: x, y, z or auto (z for bootsurf's generated shapes, "
       "else y: "
       "the convention of scans and meshes)",
       1, 0},
      {0, "views", ARG_INT, &views, "N", "1, or 4 for front, right, top and iso in a 2x2 grid", 1,
       4},
      {0, "size", ARG_STRING, &a.size, "WxH", "image size in pixels (default: 1024x768)", 1, 0},
      {0, "title", ARG_STRING, &title, "TEXT", "a title at the top", 1, 0},
      {0, "square", ARG_FLAG, &square, "", "square splats instead of discs", 1, 0},
      CLI_OPT_THREADS(ro.threads),
      CLI_OPTS_END(force, json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
  if (render_args_apply(cmd, &a, &ro)) return CLI_USAGE;
  if (views != 1 && views != 4)
    return cli_usage_error(cmd, "--views must be 1 or 4, not %d", views);
  const char *output = a.output, *field = a.field;
  ro.views = views;
  ro.round_splats = !square;
  ro.title = title;
  if (cli_check_writable(output, pos[0], force)) return 1;

  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  if (cli_read_cloud(pos[0], &c)) return 1;
  if (ro.up_axis < 0) ro.up_axis = render_auto_up(&c);
  const bsurf_field *f = NULL;
  if (field && !(f = render_find_field(&c, pos[0], field))) {
    bsurf_cloud_free(&c);
    return 1;
  }
  ro.label = field;
  double h = 0;
  cli_progress prog;
  cli_progress_init(&prog, "spacing", quiet || json);
  bsurf_status sst;
  double *local = render_spacing(&c, ro.threads, cli_progress_cb, &prog, &h, &sst);
  cli_progress_done(&prog);
  if (sst != BSURF_OK) {
    bsurf_cloud_free(&c);
    return cli_error("%s: spacing: %s", pos[0],
                     cli_interrupted() ? "interrupted" : bsurf_strerror(sst));
  }
  ro.spacing = h;
  ro.point_spacing = local;
  uint8_t *rgb = malloc((size_t)ro.width * (size_t)ro.height * 3);
  if (!rgb) {
    free(local);
    bsurf_cloud_free(&c);
    return cli_error("out of memory");
  }
  bsurf_render_info info;
  bsurf_status st =
      bsurf_render(rgb, c.xyz, c.normals, c.point_count, f ? f->values : NULL, &ro, &info);
  if (st == BSURF_OK) {
    rc = cli_write_png(output, rgb, ro.width, ro.height);
  } else {
    rc = cli_error("%s: render: %s", pos[0], bsurf_strerror(st));
  }
  free(rgb);
  free(local);
  double secs = cli_now() - t0;
  if (rc == 0 && json) {
    cli_json j = json_start("render", pos[0], output);
    json_points_h(&j, c.point_count, h);
    json_int(&j, "width", ro.width);
    json_int(&j, "height", ro.height);
    json_int(&j, "views", ro.views);
    json_num(&j, "azimuth", ro.azimuth);
    json_num(&j, "elevation", ro.elevation);
    json_num(&j, "point_size", ro.point_size);
    if (f) {
      json_str(&j, "field", field);
      json_str(&j, "colormap", a.cmap);
      json_arr(&j, "range");
      json_num(&j, NULL, info.range_lo);
      json_num(&j, NULL, info.range_hi);
      json_close_arr(&j);
    }
    json_int(&j, "covered_pixels", (long long)info.covered_pixels);
    json_int(&j, "threads", bsurf_threads_resolve(ro.threads));
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (rc == 0 && !quiet) {
    printf("render: %zu points, h = %.6g, %dx%d", c.point_count, h, ro.width, ro.height);
    if (f) printf(", %s in [%.6g, %.6g] (%s)", field, info.range_lo, info.range_hi, a.cmap);
    printf(", %.2f s\n", secs);
    cli_print_footer(output);
  }
  bsurf_cloud_free(&c);
  return rc;
}
