/* bootsurf histogram: a PNG histogram of a field with an optional threshold
 * marker (thesis 7.2 reads feature thresholds off such histograms). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>

int cmd_histogram(const cli_command *cmd, int argc, char **argv) {
  bsurf_histogram_options ho = bsurf_histogram_options_default();
  const char *output = NULL, *field = NULL, *size = NULL, *range = NULL, *title = NULL;
  int json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      CLI_OPT_IMAGE(output),
      {0, "field", ARG_STRING, &field, "NAME",
       "the field to count, or x, y, z, nx, ny, nz (required)", 1, 0},
      {0, "bins", ARG_INT, &ho.bins, "N", "number of bins", 1, 10000},
      {0, "threshold", ARG_DOUBLE, &ho.threshold, "T",
       "draw a marker at T and count the values above (default: no marker)", 1, 0},
      {0, "log", ARG_FLAG, &ho.log_counts, "", "bar heights log10(1 + count)", 1, 0},
      {0, "range", ARG_STRING, &range, "LO:HI", "the x range (default: min to max)", 1, 0},
      {0, "size", ARG_STRING, &size, "WxH", "image size in pixels (default: 800x500)", 1, 0},
      {0, "title", ARG_STRING, &title, "TEXT", "a title at the top", 1, 0},
      CLI_OPTS_END(force, json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
  if (!output) return cli_usage_error(cmd, "-o IMAGE.png is required");
  if (cli_png_name(cmd, output)) return CLI_USAGE;
  if (!field) return cli_usage_error(cmd, "--field NAME is required");
  if (size && render_parse_size(cmd, size, &ho.width, &ho.height)) return CLI_USAGE;
  if (range && render_parse_range(cmd, range, &ho.range_lo, &ho.range_hi)) return CLI_USAGE;
  ho.label = field;
  ho.title = title;
  if (cli_check_writable(output, pos[0], force)) return 1;
  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  if (cli_read_cloud(pos[0], &c)) return 1;
  const bsurf_field *f = render_find_field(&c, pos[0], field);
  if (!f) {
    bsurf_cloud_free(&c);
    return 1;
  }
  uint8_t *rgb = malloc((size_t)ho.width * (size_t)ho.height * 3);
  if (!rgb) {
    bsurf_cloud_free(&c);
    return cli_error("out of memory");
  }
  bsurf_histogram_info info;
  bsurf_status st = bsurf_render_histogram(rgb, f->values, c.point_count, &ho, &info);
  if (st == BSURF_OK) {
    rc = cli_write_png(output, rgb, ho.width, ho.height);
  } else {
    rc = cli_error("%s: histogram: %s", pos[0], bsurf_strerror(st));
  }
  free(rgb);
  double secs = cli_now() - t0;
  if (rc == 0 && json) {
    cli_json j = json_start("histogram", pos[0], output);
    json_str(&j, "field", field);
    json_int(&j, "points", (long long)c.point_count);
    json_int(&j, "bins", ho.bins);
    json_int(&j, "counted", (long long)info.counted);
    json_int(&j, "max_count", (long long)info.max_count);
    if (isfinite(ho.threshold)) {
      json_num(&j, "threshold", ho.threshold);
      json_int(&j, "above_threshold", (long long)info.above_threshold);
    }
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else if (rc == 0 && !quiet) {
    printf("histogram: %s of %zu points, %d bins, fullest bin %zu", field, c.point_count, ho.bins,
           info.max_count);
    if (isfinite(ho.threshold)) printf(", %zu above %g", info.above_threshold, ho.threshold);
    printf("\n");
    cli_print_footer(output);
  }
  bsurf_cloud_free(&c);
  return rc;
}
