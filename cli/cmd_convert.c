/* bootsurf convert: any supported format to any other (docs/formats.md).
 * The conversion is the library's read and write: every field the output
 * format can carry is kept with its values (PLY, PCD, LAS, CSV keep them all;
 * LAS coordinates within their scale). */
#include "cli.h"

#include <string.h>

int cmd_convert(const cli_command *cmd, int argc, char **argv) {
  int ascii = 0, force = 0, json = 0, quiet = 0;
  cli_option opts[] = {
      {0, "ascii", ARG_FLAG, &ascii, "", CLI_ASCII_HELP, 1, 0},
      {0, "force", ARG_FLAG, &force, "",
       "allow the output to be the input file, or a read-only file", 1, 0},
      CLI_OPTS_FORMATS,
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[2];
  int npos;
  int rc = cli_parse(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, 2, &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos != 2)
    return cli_usage_error(cmd, "expected INPUT and OUTPUT (- for standard input or output)");
  const char *input = pos[0], *output = pos[1];
  if (cli_ascii_check(cmd, output, ascii)) return CLI_USAGE;
  bsurf_write_options wo;
  if (cli_write_options(output, ascii, &wo)) return CLI_USAGE;
  if (!strcmp(output, "-")) {
    cli_stdout_data_begin();
  } else if (cli_check_output(output, strcmp(input, "-") ? input : NULL, force)) {
    return 1;
  }
  double t0 = cli_now();
  bsurf_cloud c;
  if (cli_read_cloud(input, &c)) return 1;
  bsurf_format out_fmt = wo.format ? wo.format : bsurf_format_from_path(output);
  rc = cli_write_cloud(output, &c, ascii);
  if (rc == 0 && (json || !quiet)) {
    if (json) {
      /* a conversion searches no neighbours: no "h" (as sample) */
      cli_json j = json_start("convert", input, output);
      json_str(&j, "format", bsurf_format_name(out_fmt));
      json_int(&j, "points", (long long)c.point_count);
      json_int(&j, "fields", (long long)c.field_count);
      json_bool(&j, "normals", c.normals != NULL);
      json_int(&j, "faces", (long long)c.face_count);
      json_num(&j, "seconds", cli_now() - t0);
      json_end(&j);
    } else {
      printf("convert: %zu points%s, %zu field(s)%s: %s -> %s (%s)\n", c.point_count,
             c.normals ? " with normals" : "", c.field_count, c.face_count ? ", with faces" : "",
             input, output, bsurf_format_name(out_fmt));
    }
  }
  bsurf_cloud_free(&c);
  return rc;
}
