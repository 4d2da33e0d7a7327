/* bootsurf info: what is in a file. */
#include "cli.h"

#include <math.h>

static const char *type_name(bsurf_type t) {
  static const char *names[] = {"int8",  "uint8",  "int16",   "uint16",
                                "int32", "uint32", "float32", "float64"};
  return (unsigned)t < 8 ? names[t] : "?";
}

int cmd_info(const cli_command *cmd, int argc, char **argv) {
  int threads = 0, json = 0, quiet = 0;
  cli_option opts[] = {
      CLI_OPT_THREADS(threads),
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int rc = cli_parse_input(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos);
  if (rc != CLI_PARSED) return rc;
  double t0 = cli_now();
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  if (cli_read_cloud(pos[0], &c)) return 1;
  double lo[3], hi[3];
  const double diag = bsurf_bounding_box(c.xyz, c.point_count, lo, hi);
  double h = NAN;
  cli_progress prog;
  cli_progress_init(&prog, "spacing", quiet || json);
  if (!quiet && c.point_count >= 2 &&
      bsurf_mean_spacing_progress(c.xyz, c.point_count, threads, &h, cli_progress_cb, &prog) !=
          BSURF_OK)
    h = NAN;
  cli_progress_done(&prog);
  if (cli_interrupted()) {
    bsurf_cloud_free(&c);
    return cli_error("%s: interrupted", pos[0]);
  }
  if (quiet) { /* -q: the exit status says whether the file reads */
    bsurf_cloud_free(&c);
    return 0;
  }
  double secs = cli_now() - t0;
  if (json) {
    cli_json j = json_start("info", pos[0], NULL);
    json_int(&j, "points", (long long)c.point_count);
    json_int(&j, "faces", (long long)c.face_count);
    json_bool(&j, "normals", c.normals != NULL);
    json_arr(&j, "fields");
    for (size_t f = 0; f < c.field_count; f++)
      json_str(&j, NULL, c.fields[f].name);
    json_close_arr(&j);
    if (c.point_count) {
      json_obj(&j, "bbox");
      json_arr(&j, "min");
      for (int t = 0; t < 3; t++)
        json_num(&j, NULL, lo[t]);
      json_close_arr(&j);
      json_arr(&j, "max");
      for (int t = 0; t < 3; t++)
        json_num(&j, NULL, hi[t]);
      json_close_arr(&j);
      json_num(&j, "diagonal", diag);
      json_close_obj(&j);
    }
    json_num(&j, "h", h);
    json_int(&j, "threads", bsurf_threads_resolve(threads));
    json_num(&j, "seconds", secs);
    json_end(&j);
  } else {
    printf("%s\n", pos[0]);
    printf("  points     %zu\n", c.point_count);
    printf("  faces      %zu\n", c.face_count);
    printf("  normals    %s\n", c.normals ? "yes" : "no");
    printf("  fields    ");
    for (size_t f = 0; f < c.field_count; f++)
      printf(" %s(%s)", c.fields[f].name, type_name(c.fields[f].type));
    printf("%s\n", c.field_count ? "" : " none");
    if (c.point_count)
      printf("  bbox       [%g %g %g] .. [%g %g %g], diagonal %g\n", lo[0], lo[1], lo[2], hi[0],
             hi[1], hi[2], diag);
    if (c.point_count < 2)
      printf("  h          - (no spacing: fewer than 2 points)\n");
    else
      printf("  h          %.6g (mean nearest-neighbour distance)\n", h);
    cli_print_input_report(stdout);
  }
  bsurf_cloud_free(&c);
  return 0;
}
