/* The command-line tool: shared pieces. cli/ uses only the public header. */
#ifndef BSURF_CLI_H
#define BSURF_CLI_H

#include "bootsurf.h"

#include <signal.h>
#include <stdio.h>

/* ---- options ---- */
typedef enum { ARG_FLAG, ARG_INT, ARG_DOUBLE, ARG_STRING, ARG_U64, ARG_SIZE } cli_arg_kind;

typedef struct cli_option {
  char short_name;       /* 0: none */
  const char *long_name; /* without the dashes */
  cli_arg_kind kind;
  void *target; /* int* (FLAG, INT), double*, const char**, uint64_t*, size_t* */
  const char *metavar;
  const char *help;
  double min, max; /* accepted range of numbers (ignored when min > max) */
} cli_option;

typedef struct cli_command {
  const char *name;
  const char *summary;
  const char *usage; /* after "bootsurf NAME " */
  const char *description;
  int (*run)(const struct cli_command *cmd, int argc, char **argv);
} cli_command;

/* Options shared by the commands, so their names and help never drift. */
#define CLI_OPT_THREADS(var)                                                                       \
  {                                                                                                \
    'j', "threads", ARG_INT, &(var), "N", "threads, 0 = $OMP_NUM_THREADS if set, else all cores",  \
        0, 4096                                                                                    \
  }
#define CLI_OPT_SEED(var)                                                                          \
  { 0, "seed", ARG_U64, &(var), "S", "random seed", 1, 0 }
#define CLI_ASCII_HELP                                                                             \
  "write ascii PLY or PCD (default: binary little-endian; .csv .xyz .off .obj are text anyway; "   \
  ".las has no text form: refused)"
#define CLI_OPTS_OUTPUT(out, ascii, force)                                                         \
  {'o',    "output", ARG_STRING,                                                                   \
   &(out), "FILE",   "output file (.ply .pcd .las .csv keep every field; - = standard output)",    \
   1,      0},                                                                                     \
      {0, "ascii", ARG_FLAG, &(ascii), "", CLI_ASCII_HELP, 1, 0},                                  \
      {0,        "force", ARG_FLAG,                                                                \
       &(force), "",      "allow the output to be the input file, or a read-only file",            \
       1,        0},                                                                               \
      CLI_OPTS_FORMATS
/* --format, --float32, --ply-names (cli/formats.c, docs/formats.md) */
extern const char *cli_out_format;
extern int cli_float32;
extern const char *cli_ply_names;
extern const char *cli_las_version;
#define CLI_OPTS_FORMATS                                                                           \
  {0,                                                                                              \
   "format",                                                                                       \
   ARG_STRING,                                                                                     \
   &cli_out_format,                                                                                \
   "FMT",                                                                                          \
   "output format whatever the extension: ply pcd las csv asc xyz off obj (needed for -)",         \
   1,                                                                                              \
   0},                                                                                             \
      {0,        "float32",                                                                        \
       ARG_FLAG, &cli_float32,                                                                     \
       "",       "write double coordinates, normals and fields as float (PCL's typed loaders)",    \
       1,        0},                                                                               \
      {0,          "ply-names",                                                                    \
       ARG_STRING, &cli_ply_names,                                                                 \
       "NAMES",    "PLY field names: plain, cloudcompare (scalar_ prefix) or meshlab (+ quality)", \
       1,          0},                                                                             \
  {                                                                                                \
    0, "las-version", ARG_STRING, &cli_las_version, "V",                                           \
        "LAS output: 1.4 (point formats 6-8) or 1.2 (formats 1, 3: readers stopping at 1.3)", 1, 0 \
  }
/* -o - anywhere in argv. */
int cli_output_is_stdout(int argc, char **argv);
/* From now on standard output carries a cloud: what is printed for people
 * goes to standard error. */
void cli_stdout_data_begin(void);
/* --ascii with an output that has no text form (LAS): a usage error (2),
 * else 0. */
int cli_ascii_check(const cli_command *cmd, const char *output, int ascii);
/* bsurf_write_options from the options (ascii, --format, ...); 0, or prints
 * and returns 1. */
int cli_write_options(const char *path, int ascii, bsurf_write_options *wo);
/* --format, --las-version and --ply-names checked as usage (cli_parse, before
 * any work): 0, or the usage error printed (CLI_USAGE). */
int cli_write_options_check(const cli_command *cmd);
/* The format a path will be written in (--format, else the extension). */
bsurf_format cli_output_format(const char *path);
/* bsurf_write, "-" to the real standard output. */
bsurf_status cli_write_to(const char *path, const bsurf_cloud *cloud, const bsurf_write_options *wo,
                          bsurf_failure *err);
/* a PNG to PATH; "-" is the real standard output under "-o -" */
bsurf_status cli_write_png_to(const char *path, const uint8_t *rgb, int w, int h,
                              bsurf_failure *err);
/* For every command that reads clouds: cli_read_cloud() then drops points
 * with a NaN or infinite coordinate or normal instead of rejecting the file. */
extern int cli_drop_invalid;
/* option rows that several commands share (one text each) */
#define CLI_OPT_IMAGE(out)                                                                         \
  { 'o', "output", ARG_STRING, &(out), "IMAGE", "output PNG file", 1, 0 }
#define CLI_OPT_COLORMAP(cmap)                                                                     \
  { 0, "colormap", ARG_STRING, &(cmap), "MAP", "viridis, magma, gray or coolwarm", 1, 0 }
#define CLI_OPT_FORCE_SAME(force)                                                                  \
  { 0, "force", ARG_FLAG, &(force), "", "allow the output to be the input file", 1, 0 }
#define CLI_OPT_DROP_INVALID                                                                       \
  {                                                                                                \
    0, "drop-invalid", ARG_FLAG, &cli_drop_invalid, "",                                            \
        "skip points with a NaN or infinite coordinate or normal (default: reject the file)", 1, 0 \
  }
#define CLI_OPTS_REPORT(json, quiet)                                                               \
  {0, "json", ARG_FLAG, &(json), "", "print the summary as one JSON object on stdout", 1, 0}, {    \
    'q', "quiet", ARG_FLAG, &(quiet), "", "no progress bar, summary or warning", 1, 0              \
  }

/* The options a command that reads one cloud and writes one file (image,
 * sample) ends with. */
#define CLI_OPTS_END(force, json, quiet)                                                           \
  CLI_OPT_FORCE_SAME(force), CLI_OPT_DROP_INVALID, CLI_OPTS_REPORT(json, quiet)

/* Tiled runs (cli/tiles.c, docs/scaling.md). */
#define CLI_OPTS_TILES(tile_points, memory_limit)                                                  \
  {0,                                                                                              \
   "tile-points",                                                                                  \
   ARG_SIZE,                                                                                       \
   &(tile_points),                                                                                 \
   "N",                                                                                            \
   "out of core: tiles of about N points with proven halos, same bytes as in memory "              \
   "(binary PLY in and out; 0 = only above --memory-limit)",                                       \
   0,                                                                                              \
   4294967295.0},                                                                                  \
      {0,          "memory-limit",                                                                 \
       ARG_STRING, &(memory_limit),                                                                \
       "SIZE",     "inputs needing more memory (e.g. 8G; auto = 3/4 of RAM; none) are tiled",      \
       1,          0},                                                                             \
  {                                                                                                \
    0, "range-points", ARG_SIZE, &cli_range_points, "N",                                           \
        "tiled runs: the output is assembled at most N points at a time, at least 64 "             \
        "(0 = the larger of the tile size and 32 MiB of rows; with mpirun, at most points / "      \
        "ranks)",                                                                                  \
        0, 4294967295.0                                                                            \
  }

/* The options every job command (error, normals, smooth, features) ends with. */
#define CLI_OPTS_JOB(out, ascii, force, tile_points, memory_limit, json, quiet)                    \
  CLI_OPTS_OUTPUT(out, ascii, force), CLI_OPTS_TILES(tile_points, memory_limit),                   \
      CLI_OPT_DROP_INVALID, CLI_OPTS_REPORT(json, quiet)

#define CLI_PARSED 0
#define CLI_HELP_SHOWN (-1)
#define CLI_USAGE 2

/* Parses argv[1..] (argv[0] is the command name). Positional arguments go to
 * pos (at most maxpos). Returns CLI_PARSED, CLI_HELP_SHOWN or CLI_USAGE (the
 * message was printed). */
int cli_parse(const cli_command *cmd, const cli_option *opts, int nopts, int argc, char **argv,
              char **pos, int maxpos, int *npos);
void cli_print_help(FILE *f, const cli_command *cmd, const cli_option *opts, int nopts);
/* Prints "bootsurf CMD: message" and a hint to --help; returns CLI_USAGE. */
int cli_usage_error(const cli_command *cmd, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Prints "bootsurf: error: message"; returns 1. */
/* Set once an error has been printed: a signal arriving afterwards (mpirun
 * ending the other ranks) then adds no second message. */
extern volatile sig_atomic_t cli_error_reported;
int cli_error(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;
void cli_warn(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;

/* Picks `value` from a list of names; returns its index or -1. */
int cli_choice(const char *value, const char *const *names, int count);
/* cli_parse for a command with exactly one INPUT: *input = it. */
/* cli_parse with exactly one positional argument, WHAT in the message
 * ("expected one WHAT") */
int cli_parse_one(const cli_command *cmd, const cli_option *opts, int nopts, int argc, char **argv,
                  char **arg, const char *what);
int cli_parse_input(const cli_command *cmd, const cli_option *opts, int nopts, int argc,
                    char **argv, char **input);
/* --pca-center (centroid, point) and --gamma (fit, mean, max): 0, or the
 * usage error printed (CLI_USAGE). */
int cli_pca_center(const cli_command *cmd, const char *text, bsurf_pca_center *out);
int cli_gamma(const cli_command *cmd, const char *text, bsurf_gamma_mode *out);
/* K large enough for a fit of the degree: 0, or the usage error printed. */
int cli_check_terms(const cli_command *cmd, int k, int degree);

/* ---- files ---- */
/* Reads a cloud; on failure prints "error: PATH:LINE: message" and returns 1.
 * Rejects an empty file, and NaN/Inf coordinates naming the point (or, with
 * --drop-invalid, drops those points with a warning and counts them). */
int cli_read_cloud(const char *path, bsurf_cloud *cloud);
/* Checks a file's header before anything is estimated from it
 * (bsurf_read_header: PLY counts against the file size); *points = the
 * declared vertex count (0 when the format has none). 0, or prints the
 * message naming the file and the place and returns 1. */
int cli_read_header(const char *path, uint64_t *points);
/* Ground truth carried along under names eval never scores as a result:
 * the normals become true_nx/true_ny/true_nz, feature and feature_dist
 * become true_feature and true_feature_dist (an existing true_* field
 * wins). 0, or 1 (printed) when out of memory. */
int cli_truth_to_fields(bsurf_cloud *c);
/* The reverse, for a truth file: its true_* fields (when present) become
 * its normals, feature and feature_dist. 0 or 1 (printed). */
int cli_truth_from_fields(bsurf_cloud *c);
/* Text summaries: the points dropped by --drop-invalid and the duplicate
 * points the job counted (cli_set_duplicates: the library's count, in
 * memory bsurf_jobs_neighbors, tiled the engine's), when there are any. (JSON summaries get
 * "dropped_invalid" and "duplicate_points" from json_end().) */
void cli_print_input_report(FILE *f);
/* The end of a text summary on stdout: cli_print_input_report, then
 * "  -> OUTPUT" unless output is NULL. */
void cli_print_footer(const char *output);
/* Checks before any work that OUTPUT can be written and is not the input
 * (unless force). Returns 0 or prints and returns 1 (or 2 for usage). */
int cli_check_output(const char *output, const char *input, int force);
/* The same for any file (no format check): not the input, directory writable. */
int cli_check_writable(const char *output, const char *input, int force);
/* Writes atomically; warns about fields the format cannot carry; writes
 * nothing once SIGINT/SIGTERM arrived. 0 or 1. */
int cli_write_cloud(const char *path, const bsurf_cloud *cloud, int ascii);

/* --range-points (bsurf_job_io.range_points; 0: the library's choice) */
extern size_t cli_range_points;

/* --memory-limit as bytes (auto: 3/4 of the physical memory; none: 0);
 * CLI_USAGE (printed) for a bad value, else 0. */
int cli_memory_limit(const cli_command *cmd, const char *memory_limit, double *limit);
/* The bytes a run in memory needs for n points of input: the file, its
 * values, the k-neighbour rows, the tree, out_fields doubles and
 * point_bytes a point. */
double cli_memory_need(const char *input, uint64_t n, int k, int out_fields, double point_bytes);
/* --tile-points / --memory-limit: *plan = the tile size, or 0 for the
 * in-memory run (always tiles under mpirun with several ranks). Checks that a
 * tiled run can write its output. 0, or prints and returns 1 (2: usage). */
int cli_tiles_plan(const cli_command *cmd, const char *input, const char *output, int ascii,
                   size_t tile_points, const char *memory_limit, int k, int out_fields,
                   size_t *plan);
/* The same with point_bytes more bytes a point in memory than the
 * neighbourhoods, the fields and the files count (the command's own arrays,
 * such as the MSE rule's candidates: counted for the whole cloud in memory
 * and for a tile's points when the tile size is chosen), and cloud_bytes a
 * point of the whole cloud that a tiled run holds beside a tile (taken
 * from the budget of the tiles). */
int cli_tiles_plan_bytes(const cli_command *cmd, const char *input, const char *output, int ascii,
                         size_t tile_points, const char *memory_limit, int k, int out_fields,
                         double point_bytes, double cloud_bytes, size_t *plan);
/* The same where a tiled run holds other arrays than the run in memory
 * (smooth: multipass in memory, bilateral in tiles): out_fields and
 * point_bytes for the whole cloud in memory, tile_fields and tile_bytes for
 * a tile's points. */
int cli_tiles_plan_split(const cli_command *cmd, const char *input, const char *output, int ascii,
                         size_t tile_points, const char *memory_limit, int k, int out_fields,
                         double point_bytes, int tile_fields, double tile_bytes, double cloud_bytes,
                         size_t *plan);
/* Before a tiled run: an empty input is refused by name. 0 or 1 (printed). */
int cli_check_tiled_input(const char *input);
/* A failed tiled run's message (rank 0): the file, the line or byte, the
 * reason. Returns 1. */
int cli_tiles_failed(const char *input, const char *output, bsurf_status st,
                     const bsurf_failure *err);
/* A job's io (bsurf_job_io): with a plan, the tiled input and output (an
 * empty input refused by name) and a "tiles" progress bar (rank 0); without,
 * the input read into c (initialised here in any case: free it after) and a
 * progress bar named label. 0, or 1 (printed). */
struct cli_progress;
int cli_job_io(bsurf_job_io *io, const char *input, const char *output, size_t plan, bsurf_cloud *c,
               struct cli_progress *prog, const char *label, int quiet);
/* A failed job's message (tiled: as cli_tiles_failed; in memory: the input,
 * the library's message). Returns 1. */
int cli_job_failed(const char *input, const char *output, size_t plan, bsurf_status st,
                   const bsurf_failure *err);
/* After a job: the progress bar ended; a failure's message (cli_job_failed,
 * returns 1), or the run's duplicate count kept for the summary (returns 0). */
int cli_job_done(struct cli_progress *prog, const char *input, const char *output, size_t plan,
                 bsurf_status st, const bsurf_failure *err, size_t duplicates);
/* The duplicate count a job reported, for the summaries. */
void cli_set_duplicates(size_t count);
/* MPI (a build with BSURF_MPI, started by mpirun); otherwise one rank. */
void cli_mpi_init(int *argc, char ***argv);
void cli_mpi_finalize(void);
const bsurf_tile_comm *cli_mpi_comm(void);
int cli_mpi_rank(void);
int cli_mpi_ranks(void);

/* ---- progress, signals, time ---- */
typedef struct cli_progress {
  const char *label;
  int enabled;
  int last_permille;
} cli_progress;
void cli_progress_init(cli_progress *p, const char *label, int quiet);
int cli_progress_cb(void *user, size_t done, size_t total);
void cli_progress_done(cli_progress *p);
void cli_install_signals(void);
int cli_interrupted(void);
/* The end of every command: `rc`, or, after SIGINT/SIGTERM, death by that
 * signal (the shell sees 130 or 143 and stops a loop). */
int cli_exit_status(int rc);
double cli_now(void);

/* ---- JSON on stdout ---- */
typedef struct cli_json {
  FILE *f;
  int depth;
  int count[16];
} cli_json;
void json_begin(cli_json *j, FILE *f);
/* A command's summary on stdout: json_begin, then "command", and "input"
 * and "output" unless NULL. */
cli_json json_start(const char *command, const char *input, const char *output);
/* "points" and "h" */
void json_points_h(cli_json *j, size_t points, double h);
void json_end(cli_json *j);
void json_obj(cli_json *j, const char *key);
void json_arr(cli_json *j, const char *key);
void json_close_obj(cli_json *j);
void json_close_arr(cli_json *j);
void json_str(cli_json *j, const char *key, const char *v);
void json_num(cli_json *j, const char *key, double v);
void json_int(cli_json *j, const char *key, long long v);
void json_bool(cli_json *j, const char *key, int v);

/* "mean": {field: mean} and "mean_h": {field: mean / h} of the named fields. */
void json_field_means(cli_json *j, const bsurf_cloud *cloud, const char *const *names, int count,
                      double h);
/* The same from means computed elsewhere (tiled runs). */
/* A tiled run's keys: tile_points, tiles, ranks. */
void json_tiles(cli_json *j, size_t tile_points, size_t tiles);
void json_means(cli_json *j, const char *const *names, const double *means, int count, double h);
void print_means(FILE *f, const char *const *names, const double *means, int count, double h);
/* The same as a table on `f` for people. */
void print_field_means(FILE *f, const bsurf_cloud *cloud, const char *const *names, int count,
                       double h);
double cli_field_mean(const bsurf_field *field, size_t n);

/* ---- commands ---- */
int cmd_info(const cli_command *cmd, int argc, char **argv);
int cmd_generate(const cli_command *cmd, int argc, char **argv);
int cmd_noise(const cli_command *cmd, int argc, char **argv);
int cmd_error(const cli_command *cmd, int argc, char **argv);
int cmd_normals(const cli_command *cmd, int argc, char **argv);
int cmd_sample(const cli_command *cmd, int argc, char **argv);
int cmd_eval(const cli_command *cmd, int argc, char **argv);
int cmd_render(const cli_command *cmd, int argc, char **argv);
int cmd_histogram(const cli_command *cmd, int argc, char **argv);
int cmd_compare(const cli_command *cmd, int argc, char **argv);
/* Shared by render, histogram and compare (cmd_render.c): --size WxH and
 * --range LO:HI (0 or CLI_USAGE after the message), a field or an error
 * listing the available ones (NULL), --view or --azimuth/--elevation. */
int render_parse_size(const cli_command *cmd, const char *text, int *w, int *h);
int render_parse_range(const cli_command *cmd, const char *text, double *lo, double *hi);
const bsurf_field *render_find_field(bsurf_cloud *c, const char *path, const char *name);
/* What render and compare share: their view options' values (set the
 * defaults cmap "viridis", up "auto", az and el NAN first), the option rows
 * (RENDER_OPTS_VIEW) and render_args_apply after parsing: -o required,
 * then --colormap, --size, --range, --view/--azimuth/--elevation, --up and
 * --flat into ro; 0, or CLI_USAGE after the message. */
typedef struct render_args {
  const char *output, *field, *cmap, *range, *view, *size, *up;
  double az, el;
  int flat;
} render_args;
#define RENDER_OPTS_VIEW(a, ro)                                                                      \
  CLI_OPT_IMAGE((a).output),                                                                         \
      {0,          "field",                                                                          \
       ARG_STRING, &(a).field,                                                                       \
       "NAME",     "colour by this field, or x, y, z, nx, ny, nz (default: shade by normals)",       \
       1,          0},                                                                               \
      CLI_OPT_COLORMAP((a).cmap),                                                                    \
      {0,         "view", ARG_STRING,                                                                \
       &(a).view, "VIEW", "front, back, left, right, top, bottom or iso (default: iso)",             \
       1,         0},                                                                                \
      {0,       "azimuth", ARG_DOUBLE,                                                               \
       &(a).az, "DEG",     "view azimuth about z, -360 to 360 (0 = front; default: that of --view)", \
       1,       0},                                                                                  \
      {0,          "elevation",                                                                      \
       ARG_DOUBLE, &(a).el,                                                                          \
       "DEG",      "view elevation, -90 to 90 (90 = top; default: that of --view)",                  \
       1,          0},                                                                               \
      {0,          "point-size",                                                                     \
       ARG_DOUBLE, &(ro).point_size,                                                                 \
       "S",        "splat diameter in units of h, 0.05 to 50",                                       \
       1,          0},                                                                               \
  {                                                                                                  \
    0, "flat", ARG_FLAG, &(a).flat, "", "field colours without shading", 1, 0                        \
  }
int render_args_apply(const cli_command *cmd, const render_args *a, bsurf_render_options *ro);
/* --up auto: 2 (z) for a generated shape, else 1 (y). */
int render_auto_up(const bsurf_cloud *c);
/* Writes an RGB image as PNG (atomically); prints the reason and returns 1
 * on failure. */
int cli_write_png(const char *path, const uint8_t *rgb, int w, int h);
/* -o of render, histogram and compare: a name with an extension other than
 * .png (x.jpg, x.ply) is refused (CLI_USAGE after the message) rather than
 * given PNG bytes under another type's name; names without one (-o out,
 * /dev/stdout) are taken. 0 when accepted. */
int cli_png_name(const cli_command *cmd, const char *path);
/* One 7-nearest-neighbour search: the mean spacing h (0 for fewer than 2
 * points) and, returned, each point's splat spacing (malloc'ed, point_count;
 * NULL for fewer than 8 points or on failure, with *status set). */
double *render_spacing(const bsurf_cloud *c, int threads, bsurf_progress_fn progress, void *user,
                       double *h, bsurf_status *status);
int cmd_features(const cli_command *cmd, int argc, char **argv);
int cmd_convert(const cli_command *cmd, int argc, char **argv);
int cmd_smooth(const cli_command *cmd, int argc, char **argv);

#endif
