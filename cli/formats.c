/* Output formats on the command line (docs/formats.md): --format,
 * --float32 and --ply-names for every command that writes a cloud, and
 * standard output as a file ("-o -"): the cloud's bytes go to the real
 * standard output while everything the command prints for people (summaries,
 * JSON) goes to standard error, so a pipe carries only the data. */
#include "cli.h"

#include <string.h>
#include <unistd.h>

const char *cli_out_format = NULL;
int cli_float32 = 0;
const char *cli_ply_names = NULL;
const char *cli_las_version = NULL;

/* the real standard output while it carries data; -1: not redirected */
static int data_fd = -1;

void cli_stdout_data_begin(void) {
  if (data_fd >= 0) return;
  fflush(stdout);
  data_fd = dup(STDOUT_FILENO);
  if (data_fd >= 0) dup2(STDERR_FILENO, STDOUT_FILENO);
}

int cli_output_is_stdout(int argc, char **argv) {
  for (int i = 1; i < argc; i++) {
    if ((!strcmp(argv[i], "-o") || !strcmp(argv[i], "--output")) && i + 1 < argc &&
        !strcmp(argv[i + 1], "-"))
      return 1;
    if (!strcmp(argv[i], "--output=-") || !strcmp(argv[i], "-o-")) return 1;
  }
  return 0;
}

static const char *const k_ply_names[] = {"plain", "cloudcompare", "meshlab"};

/* What is wrong with --format, --las-version or --ply-names (written into
 * msg), or 0. */
static int write_options_problem(char *msg, size_t n) {
  if (cli_out_format && bsurf_format_from_name(cli_out_format) == BSURF_FORMAT_UNKNOWN) {
    snprintf(msg, n, "--format %s: unknown format (ply, pcd, las, csv, asc, xyz, off, obj)",
             cli_out_format);
    return 1;
  }
  if (cli_las_version && strcmp(cli_las_version, "1.2") != 0 &&
      strcmp(cli_las_version, "1.4") != 0) {
    snprintf(msg, n, "--las-version %s: expected 1.2 or 1.4", cli_las_version);
    return 1;
  }
  if (cli_ply_names && cli_choice(cli_ply_names, k_ply_names, 3) < 0) {
    snprintf(msg, n, "--ply-names %s: expected plain, cloudcompare or meshlab", cli_ply_names);
    return 1;
  }
  return 0;
}

int cli_write_options_check(const cli_command *cmd) {
  char msg[512];
  return write_options_problem(msg, sizeof msg) ? cli_usage_error(cmd, "%s", msg) : 0;
}

int cli_ascii_check(const cli_command *cmd, const char *output, int ascii) {
  /* --ascii asks for a text file: PLY and PCD have one (the default is
   * binary); CSV, XYZ, OFF and OBJ are text whatever it says, so it is met;
   * LAS has no text form: the request cannot be met and is refused */
  if (ascii && output && cli_output_format(output) == BSURF_FORMAT_LAS)
    return cli_usage_error(cmd, "--ascii: LAS is a binary format, it has no text form (write .ply "
                                "or .pcd for ascii with every field, .csv for a table)");
  return 0;
}

int cli_write_options(const char *path, int ascii, bsurf_write_options *wo) {
  memset(wo, 0, sizeof *wo);
  wo->ascii = ascii;
  wo->float32 = cli_float32;
  char msg[512];
  if (write_options_problem(msg, sizeof msg)) return cli_error("%s", msg);
  if (cli_out_format) {
    wo->format = bsurf_format_from_name(cli_out_format);
  } else if (path && !strcmp(path, "-")) {
    return cli_error(
        "-: writing to standard output needs --format (ply, pcd, las, csv, xyz, off, obj)");
  }
  wo->las_legacy = cli_las_version && !strcmp(cli_las_version, "1.2");
  if (cli_ply_names) wo->ply_names = (bsurf_ply_names)cli_choice(cli_ply_names, k_ply_names, 3);
  return 0;
}

bsurf_format cli_output_format(const char *path) {
  if (cli_out_format) return bsurf_format_from_name(cli_out_format);
  return bsurf_format_from_path(path);
}

/* The data to the real standard output while "-o -" has text going to
 * standard error: returns the descriptor to restore (or -1). */
static int data_stdout_enter(const char *path) {
  if (strcmp(path, "-") != 0 || data_fd < 0) return -1;
  fflush(stdout);
  int text_fd = dup(STDOUT_FILENO);
  dup2(data_fd, STDOUT_FILENO);
  return text_fd;
}

static void data_stdout_leave(int text_fd) {
  fflush(stdout);
  if (text_fd >= 0) {
    dup2(text_fd, STDOUT_FILENO);
    close(text_fd);
  }
}

bsurf_status cli_write_to(const char *path, const bsurf_cloud *cloud, const bsurf_write_options *wo,
                          bsurf_failure *err) {
  bsurf_format f = wo && wo->format ? wo->format : bsurf_format_from_path(path);
  if (cloud->face_count && f != BSURF_FORMAT_PLY && f != BSURF_FORMAT_OFF && f != BSURF_FORMAT_OBJ)
    cli_warn("%s: %s holds points only: the %zu faces are not written (use .ply, .off or .obj)",
             path, bsurf_format_name(f), cloud->face_count);
  int text_fd = data_stdout_enter(path);
  bsurf_status st = bsurf_write(path, cloud, wo, err);
  data_stdout_leave(text_fd);
  return st;
}

bsurf_status cli_write_png_to(const char *path, const uint8_t *rgb, int w, int h,
                              bsurf_failure *err) {
  int text_fd = data_stdout_enter(path);
  bsurf_status st = bsurf_write_png(path, rgb, w, h, err);
  data_stdout_leave(text_fd);
  return st;
}
