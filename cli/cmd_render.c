/* bootsurf render: a PNG picture of a cloud, shaded by its normals or
 * coloured by a field (the thesis's figures). Also the helpers shared by
 * histogram and compare (declared in cli.h). */
#include "cli.h"

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

const bsurf_field *render_find_field(const bsurf_cloud *c, const char *path, const char *name) {
  const bsurf_field *f = bsurf_cloud_field(c, name);
  if (f) return f;
  char list[1024] = "";
  size_t len = 0;
  for (size_t i = 0; i < c->field_count && len + 80 < sizeof list; i++)
    len +=
        (size_t)snprintf(list + len, sizeof list - len, "%s%s", i ? ", " : "", c->fields[i].name);
  cli_error("%s: no field '%s'; available fields: %s", path, name, c->field_count ? list : "none");
  return NULL;
}

int render_view_option(const cli_command *cmd, const char *view, double az, double el,
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

/* Per-point spacing for the splat size: h times the ratio of the point's
 * distance to its 6th nearest neighbour to the median of those distances,
 * clamped to [1, 4]: evenly sampled regions keep splats of h, sparse regions
 * of a scan get larger ones, so they look closed too. NULL on failure (the
 * renderer then uses h everywhere). */
double *render_spacing(const bsurf_cloud *c, int threads, bsurf_progress_fn progress, void *user,
                       double *h, bsurf_status *status) {
  const int k = 7;
  size_t n = c->point_count;
  *h = 0;
  *status = BSURF_OK;
  if (n < 2) return NULL;
  if (n < (size_t)k + 1) {
    *status = bsurf_mean_spacing_progress(c->xyz, n, threads, h, progress, user);
    return NULL;
  }
  /* one search: the nearest neighbour gives h (as bsurf_mean_spacing), the
   * 7th the local spacing */
  bsurf_neighbors nb;
  *status = bsurf_neighbors_build(&nb, c->xyz, n, k, threads, progress, user);
  if (*status != BSURF_OK) return NULL;
  *h = nb.h;
  double *out = malloc(n * sizeof *out);
  double med = 0, unused = 0;
  int okay = out != NULL && nb.h > 0;
  if (okay) {
    for (size_t i = 0; i < n; i++) {
      const double *p = &c->xyz[3 * i], *q = &c->xyz[3 * (size_t)nb.idx[i * k + k - 1]];
      out[i] = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                    (p[2] - q[2]) * (p[2] - q[2]));
    }
    okay = bsurf_render_range(out, n, 50, 50, &med, &unused) == BSURF_OK && med > 0;
  }
  if (okay)
    for (size_t i = 0; i < n; i++) {
      double r = out[i] / med;
      out[i] = nb.h * (r < 1 ? 1 : r > 4 ? 4 : r);
    }
  bsurf_neighbors_free(&nb);
  if (!okay) {
    free(out);
    return NULL;
  }
  return out;
}

int render_up_option(const cli_command *cmd, const char *up, int *axis) {
  static const char *const axes[] = {"x", "y", "z", "auto"};
  int a = cli_choice(up, axes, 4);
  if (a < 0) return cli_usage_error(cmd, "--up must be x, y, z or auto, not '%s'", up);
  *axis = a == 3 ? -1 : a;
  return 0;
}

int render_auto_up(const bsurf_cloud *c) {
  /* --up auto: bootsurf's generated shapes (a "bootsurf shape" comment)
   * are z-up, like LiDAR and GIS data; scans and meshes from graphics
   * (Stanford's PLY scans, CGAL's OFF data, OBJ) are y-up, OpenGL's
   * convention: the Stanford bunny then stands upright (docs/gallery.md) */
  return c->shape[0] ? 2 : 1;
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
  const char *output = NULL, *field = NULL, *cmap = "viridis", *range = NULL, *view = NULL,
             *size = NULL, *title = NULL, *up = "auto";
  double az = NAN, el = NAN;
  int views = 1, json = 0, quiet = 0, force = 0, flat = 0, square = 0;
  cli_option opts[] = {
      {'o', "output", ARG_STRING, &output, "IMAGE", "output PNG file", 1, 0},
      {0, "field", ARG_STRING, &field, "NAME", "colour by this field (default: shade by normals)",
       1, 0},
      {0, "colormap", ARG_STRING, &cmap, "MAP", "viridis, magma, gray or coolwarm", 1, 0},
      {0, "range", ARG_STRING, &range, "LO:HI",
       "values at the colormap's ends (default: 1st-99th percentile)", 1, 0},
      {0, "view", ARG_STRING, &view, "VIEW",
       "front, back, left, right, top, bottom or iso (default: iso)", 1, 0},
      {0, "azimuth", ARG_DOUBLE, &az, "DEG",
       "view azimuth about z (0 = front; default: that of --view)", -360, 360},
      {0, "elevation", ARG_DOUBLE, &el, "DEG", "view elevation (90 = top; default: that of --view)",
       -90, 90},
      {0, "up", ARG_STRING, &up, "AXIS",
       "the axis that points up in the views: x, y, z or auto (z for bootsurf's generated shapes, "
       "else y: "
       "the convention of scans and meshes)",
       1, 0},
      {0, "views", ARG_INT, &views, "N", "1, or 4 for front, right, top and iso in a 2x2 grid", 1,
       4},
      {0, "size", ARG_STRING, &size, "WxH", "image size in pixels (default: 1024x768)", 1, 0},
      {0, "point-size", ARG_DOUBLE, &ro.point_size, "S", "splat diameter in units of h", 0.05, 50},
      {0, "title", ARG_STRING, &title, "TEXT", "a title at the top", 1, 0},
      {0, "flat", ARG_FLAG, &flat, "", "field colours without shading", 1, 0},
      {0, "square", ARG_FLAG, &square, "", "square splats instead of discs", 1, 0},
      CLI_OPT_THREADS(ro.threads),
      {0, "force", ARG_FLAG, &force, "", "allow the output to be the input file", 1, 0},
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int npos;
  int rc = cli_parse(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, 1, &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos != 1) return cli_usage_error(cmd, "expected one INPUT file");
  if (!output) return cli_usage_error(cmd, "-o IMAGE.png is required");
  if (bsurf_colormap_from_name(cmap, &ro.colormap) != 0)
    return cli_usage_error(cmd, "--colormap must be viridis, magma, gray or coolwarm, not '%s'",
                           cmap);
  if (size && render_parse_size(cmd, size, &ro.width, &ro.height)) return CLI_USAGE;
  if (range && render_parse_range(cmd, range, &ro.range_lo, &ro.range_hi)) return CLI_USAGE;
  if (views != 1 && views != 4)
    return cli_usage_error(cmd, "--views must be 1 or 4, not %d", views);
  if (render_view_option(cmd, view, az, el, &ro.azimuth, &ro.elevation)) return CLI_USAGE;
  if (render_up_option(cmd, up, &ro.up_axis)) return CLI_USAGE;
  ro.views = views;
  ro.shade = !flat;
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
    cli_json j;
    json_begin(&j, stdout);
    json_str(&j, "command", "render");
    json_str(&j, "input", pos[0]);
    json_str(&j, "output", output);
    json_int(&j, "points", (long long)c.point_count);
    json_num(&j, "h", h);
    json_int(&j, "width", ro.width);
    json_int(&j, "height", ro.height);
    json_int(&j, "views", ro.views);
    json_num(&j, "azimuth", ro.azimuth);
    json_num(&j, "elevation", ro.elevation);
    json_num(&j, "point_size", ro.point_size);
    if (f) {
      json_str(&j, "field", field);
      json_str(&j, "colormap", cmap);
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
    if (f) printf(", %s in [%.6g, %.6g] (%s)", field, info.range_lo, info.range_hi, cmap);
    printf(", %.2f s\n", secs);
    cli_print_input_report(stdout);
    printf("  -> %s\n", output);
  }
  bsurf_cloud_free(&c);
  return rc;
}
