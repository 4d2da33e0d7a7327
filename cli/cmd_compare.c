/* bootsurf compare: several clouds side by side in one PNG, same view, same
 * colour range (so colours compare across panels), with titles. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define COMPARE_MAX 16

int cmd_compare(const cli_command *cmd, int argc, char **argv) {
  bsurf_render_options ro = bsurf_render_options_default();
  render_args a = {NULL, NULL, "viridis", NULL, NULL, NULL, "auto", NAN, NAN, 0};
  const char *titles = NULL;
  int json = 0, quiet = 0, force = 0;
  ro.width = 512;
  ro.height = 512;
  cli_option opts[] = {
      RENDER_OPTS_VIEW(a, ro),
      {0, "range", ARG_STRING, &a.range, "LO:HI",
       "values at the colormap's ends (default: 1st-99th percentile of all inputs)", 1, 0},
      {0, "titles", ARG_STRING, &titles, "A,B,...", "panel titles (default: the file names)", 1, 0},
      {0, "up", ARG_STRING, &a.up, "AXIS",
       "the axis that points up in the views: x, y, z or auto (from the first input, as render)", 1,
       0},
      {0, "size", ARG_STRING, &a.size, "WxH", "size of each panel in pixels (default: 512x512)", 1,
       0},
      CLI_OPT_THREADS(ro.threads),
      {0, "force", ARG_FLAG, &force, "", "allow the output to be an input file", 1, 0},
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[COMPARE_MAX];
  int npos;
  int rc = cli_parse(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, COMPARE_MAX,
                     &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos < 1) return cli_usage_error(cmd, "expected one or more INPUT files");
  if (render_args_apply(cmd, &a, &ro)) return CLI_USAGE;
  const char *output = a.output, *field = a.field;
  ro.colorbar = 0;
  /* titles: split a copy at commas */
  char *tcopy = NULL;
  const char *tnames[COMPARE_MAX];
  for (int i = 0; i < npos; i++) {
    const char *slash = strrchr(pos[i], '/');
    tnames[i] = slash ? slash + 1 : pos[i];
  }
  if (titles) {
    tcopy = malloc(strlen(titles) + 1);
    if (!tcopy) return cli_error("out of memory");
    strcpy(tcopy, titles);
    int k = 0;
    for (char *p = tcopy, *tok; k < npos && (tok = p) != NULL; k++) {
      char *comma = strchr(p, ',');
      if (comma) *comma = 0;
      tnames[k] = tok;
      p = comma ? comma + 1 : NULL;
      if (!p) {
        k++;
        break;
      }
    }
  }
  for (int i = 0; i < npos; i++)
    if (cli_check_writable(output, pos[i], force)) {
      free(tcopy);
      return 1;
    }

  double t0 = cli_now();
  bsurf_cloud clouds[COMPARE_MAX];
  const double *vals[COMPARE_MAX];
  double hs[COMPARE_MAX];
  double *locals[COMPARE_MAX] = {NULL};
  int loaded = 0;
  rc = 0;
  for (int i = 0; i < npos && rc == 0; i++) {
    bsurf_cloud_init(&clouds[i]);
    if (cli_read_cloud(pos[i], &clouds[i])) {
      rc = 1;
      break;
    }
    loaded++;
    if (i == 0 && ro.up_axis < 0) ro.up_axis = render_auto_up(&clouds[0]);
    vals[i] = NULL;
    if (field) {
      const bsurf_field *f = render_find_field(&clouds[i], pos[i], field);
      if (!f) {
        rc = 1;
        break;
      }
      vals[i] = f->values;
    }
    bsurf_status sst;
    locals[i] = render_spacing(&clouds[i], ro.threads, NULL, NULL, &hs[i], &sst);
    if (sst != BSURF_OK) rc = cli_error("%s: spacing: %s", pos[i], bsurf_strerror(sst));
  }
  /* one colour range for every panel */
  if (rc == 0 && field && (!isfinite(ro.range_lo) || !isfinite(ro.range_hi))) {
    size_t total = 0;
    for (int i = 0; i < npos; i++)
      total += clouds[i].point_count;
    double *all = malloc((total ? total : 1) * sizeof *all);
    if (!all) {
      rc = cli_error("out of memory");
    } else {
      size_t o = 0;
      for (int i = 0; i < npos; i++) {
        memcpy(all + o, vals[i], clouds[i].point_count * sizeof *all);
        o += clouds[i].point_count;
      }
      double lo = NAN, hi = NAN;
      if (bsurf_render_range(all, total, ro.percentile_lo, ro.percentile_hi, &lo, &hi) ==
          BSURF_OK) {
        ro.range_lo = lo;
        ro.range_hi = hi;
      }
      free(all);
    }
  }
  int pw = ro.width, ph = ro.height;
  int bar =
      field ? (ph * 3 / 4 >= 220 ? 150 : 90) : 0; /* the colour bar's font doubles from 220 px */
  int W = pw * npos + bar, H = ph;
  uint8_t *img = NULL, *panel = NULL;
  if (rc == 0) {
    img = malloc((size_t)W * (size_t)H * 3);
    panel = malloc((size_t)pw * (size_t)ph * 3);
    if (!img || !panel) rc = cli_error("out of memory");
  }
  if (rc == 0) {
    memset(img, 255, (size_t)W * (size_t)H * 3);
    for (int i = 0; i < npos && rc == 0; i++) {
      bsurf_render_options o = ro;
      o.title = tnames[i];
      o.spacing = hs[i];
      o.point_spacing = locals[i];
      bsurf_status st = bsurf_render(panel, clouds[i].xyz, clouds[i].normals, clouds[i].point_count,
                                     vals[i], &o, NULL);
      if (st != BSURF_OK) {
        rc = cli_error("%s: render: %s", pos[i], bsurf_strerror(st));
        break;
      }
      for (int y = 0; y < ph; y++)
        memcpy(img + ((size_t)y * W + (size_t)i * pw) * 3, panel + (size_t)y * pw * 3,
               (size_t)pw * 3);
    }
    if (rc == 0 && field)
      bsurf_render_colorbar(img, W, H, pw * npos, H / 8, bar - 4, H * 3 / 4, ro.colormap,
                            ro.range_lo, ro.range_hi, field, ro.background);
    if (rc == 0) rc = cli_write_png(output, img, W, H);
  }
  double secs = cli_now() - t0;
  if (rc == 0 && json) {
    cli_json j = json_start("compare", NULL, NULL);
    json_arr(&j, "inputs");
    for (int i = 0; i < npos; i++)
      json_str(&j, NULL, pos[i]);
    json_close_arr(&j);
    json_str(&j, "output", output);
    json_int(&j, "width", W);
    json_int(&j, "height", H);
    if (field) {
      json_str(&j, "field", field);
      json_arr(&j, "range");
      json_num(&j, NULL, ro.range_lo);
      json_num(&j, NULL, ro.range_hi);
      json_close_arr(&j);
    }
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (rc == 0 && !quiet) {
    printf("compare: %d clouds, %dx%d", npos, W, H);
    if (field) printf(", %s in [%.6g, %.6g]", field, ro.range_lo, ro.range_hi);
    printf("\n");
    cli_print_footer(output);
  }
  free(img);
  free(panel);
  for (int i = 0; i < loaded; i++) {
    bsurf_cloud_free(&clouds[i]);
    free(locals[i]);
  }
  free(tcopy);
  return rc;
}
