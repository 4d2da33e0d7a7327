/* Command-line plumbing: reading and writing with messages that name the
 * file and the place, progress bar, signals, JSON summaries. */
#define _XOPEN_SOURCE 700 /* realpath */
#include "cli.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

/* ---- files ---- */

/* the input being read or processed, for the signal handler's message */
static const char *volatile current_input = NULL;

/* --drop-invalid (CLI_OPT_DROP_INVALID) and what reading and the
 * neighbourhoods found; json_end() and cli_print_input_report() report them. */
int cli_drop_invalid = 0;
static size_t input_dropped = 0;
static int input_duplicates_known = 0;
static size_t input_duplicates = 0;

static int point_is_finite(const bsurf_cloud *c, size_t i) {
  const double *p = c->xyz + 3 * i, *q = c->normals ? c->normals + 3 * i : NULL;
  return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]) &&
         (!q || (isfinite(q[0]) && isfinite(q[1]) && isfinite(q[2])));
}

/* Removes the points with a NaN or infinite coordinate or normal, with their
 * field values and the faces that use them; keeps the order of the rest.
 * Returns the number removed, or (size_t)-1 when out of memory. */
static size_t drop_invalid_points(bsurf_cloud *c) {
  const size_t n = c->point_count;
  uint32_t *map = NULL;
  if (c->face_count && !(map = malloc(n * sizeof *map))) return (size_t)-1;
  size_t m = 0;
  for (size_t i = 0; i < n; i++) {
    int ok = point_is_finite(c, i);
    if (map) map[i] = ok ? (uint32_t)m : UINT32_MAX;
    if (!ok) continue;
    if (m != i) {
      memcpy(c->xyz + 3 * m, c->xyz + 3 * i, 3 * sizeof(double));
      if (c->normals) memcpy(c->normals + 3 * m, c->normals + 3 * i, 3 * sizeof(double));
      for (size_t f = 0; f < c->field_count; f++)
        c->fields[f].values[m] = c->fields[f].values[i];
    }
    m++;
  }
  if (map) {
    size_t kept = 0;
    for (size_t t = 0; t < c->face_count; t++) {
      const uint32_t *f = c->faces + 3 * t;
      if (map[f[0]] == UINT32_MAX || map[f[1]] == UINT32_MAX || map[f[2]] == UINT32_MAX) continue;
      uint32_t a = map[f[0]], b = map[f[1]], d = map[f[2]];
      c->faces[3 * kept] = a;
      c->faces[3 * kept + 1] = b;
      c->faces[3 * kept + 2] = d;
      kept++;
    }
    c->face_count = kept;
    free(map);
  }
  c->point_count = m;
  return n - m;
}

/* "PATH:LINE: message", "PATH: byte B: message" or "PATH: message"; 1. */
static int read_error(const char *path, bsurf_status st, const bsurf_failure *err) {
  const char *msg = err->message[0] ? err->message : bsurf_strerror(st);
  if (err->line > 0) return cli_error("%s:%ld: %s", path, err->line, msg);
  if (err->byte >= 0) return cli_error("%s: byte %lld: %s", path, err->byte, msg);
  return cli_error("%s: %s", path, msg);
}

/* The checks every read starts with: not empty (a file, or standard input,
 * "-"). The format is the content's signature, else the extension
 * (bsurf_read, docs/formats.md). */
static int check_input_file(const char *path) {
  struct stat sb;
  if (!strcmp(path, "-")) { /* one byte looked at and put back for the reader */
    int ch = getc(stdin);
    if (ch == EOF) return cli_error("-: standard input is empty");
    ungetc(ch, stdin);
    return 0;
  }
  if (stat(path, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size == 0)
    return cli_error("%s: the file is empty", path);
  return 0;
}

int cli_read_header(const char *path, uint64_t *points) {
  *points = 0;
  current_input = path;
  if (check_input_file(path)) return 1;
  bsurf_failure err = {0, -1, ""};
  bsurf_status st = bsurf_read_header(path, points, &err);
  return st == BSURF_OK ? 0 : read_error(path, st, &err);
}

int cli_read_cloud(const char *path, bsurf_cloud *cloud) {
  bsurf_failure err = {0, -1, ""};
  if (!current_input) current_input = path;
  if (check_input_file(path)) return 1;
  bsurf_status st = bsurf_read(path, cloud, &err);
  if (st != BSURF_OK) return read_error(path, st, &err);
  size_t bad = 0;
  if (bsurf_cloud_check_finite(cloud, &bad) != BSURF_OK) {
    if (!cli_drop_invalid) {
      bsurf_cloud_free(cloud);
      return cli_error("%s: point %zu (0-based) has a NaN or infinite coordinate or normal "
                       "(--drop-invalid skips such points)",
                       path, bad);
    }
    size_t dropped = drop_invalid_points(cloud);
    if (dropped == (size_t)-1) {
      bsurf_cloud_free(cloud);
      return cli_error("%s: out of memory", path);
    }
    input_dropped += dropped;
    cli_warn("%s: dropped %zu point(s) with a NaN or infinite coordinate or normal (the first: "
             "point %zu, 0-based); %zu left",
             path, dropped, bad, cloud->point_count);
  }
  return 0;
}

/* ---- ground truth carried along (docs/robustness.md, "Honest truth") ---- */

static const char *const truth_plain[5] = {"nx", "ny", "nz", "feature", "feature_dist"};
static const char *const truth_named[5] = {"true_nx", "true_ny", "true_nz", "true_feature",
                                           "true_feature_dist"};

/* Renames field `from` to `to`; when `to` exists already, `from` is dropped. */
static void rename_field(bsurf_cloud *c, const char *from, const char *to) {
  bsurf_field *f = bsurf_cloud_field(c, from);
  if (!f) return;
  if (bsurf_cloud_field(c, to))
    bsurf_cloud_remove_field(c, from);
  else
    snprintf(f->name, sizeof f->name, "%s", to);
}

int cli_truth_to_fields(bsurf_cloud *c) {
  if (c->normals) {
    if (!bsurf_cloud_field(c, truth_named[0])) {
      for (int k = 0; k < 3; k++) {
        bsurf_field *f = bsurf_cloud_add_field(c, truth_named[k], c->normal_type);
        if (!f) return cli_error("out of memory");
        for (size_t i = 0; i < c->point_count; i++)
          f->values[i] = c->normals[3 * i + (size_t)k];
      }
    }
    free(c->normals);
    c->normals = NULL;
  }
  rename_field(c, "feature", "true_feature");
  rename_field(c, "feature_dist", "true_feature_dist");
  return 0;
}

int cli_truth_from_fields(bsurf_cloud *c) {
  const bsurf_field *t[3];
  for (int k = 0; k < 3; k++)
    t[k] = bsurf_cloud_field(c, truth_named[k]);
  if (t[0] && t[1] && t[2]) {
    double *n = c->normals ? c->normals : malloc(c->point_count * 3 * sizeof(double) + 1);
    if (!n) return cli_error("out of memory");
    for (size_t i = 0; i < c->point_count; i++)
      for (int k = 0; k < 3; k++)
        n[3 * i + (size_t)k] = t[k]->values[i];
    c->normal_type = t[0]->type;
    c->normals = n;
  }
  for (int k = 3; k < 5; k++)
    if (bsurf_cloud_field(c, truth_named[k])) {
      bsurf_cloud_remove_field(c, truth_plain[k]);
      rename_field(c, truth_named[k], truth_plain[k]);
    }
  return 0;
}

void cli_print_input_report(FILE *f) {
  if (input_dropped)
    fprintf(f, "  %zu input points with a NaN or infinite coordinate or normal were dropped\n",
            input_dropped);
  if (input_duplicates)
    fprintf(f, "  %zu points coincide with another point (duplicates)\n", input_duplicates);
}

void cli_print_footer(const char *output) {
  cli_print_input_report(stdout);
  if (output) printf("  -> %s\n", output);
}

int cli_check_output(const char *output, const char *input, int force) {
  if (!strcmp(output, "-"))
    return cli_out_format ? 0 : cli_error("-: standard output needs --format");
  struct stat sd;
  if (stat(output, &sd) == 0 && S_ISDIR(sd.st_mode)) return cli_error("%s: is a directory", output);
  /* a FIFO or device (-o /dev/null) takes PLY whatever its name */
  if (cli_output_format(output) == BSURF_FORMAT_UNKNOWN && !bsurf_output_is_stream(output))
    return cli_error(
        "%s: unknown output file type (use .ply, .pcd, .las, .csv, .asc, .off, .obj, .xyz or .txt, "
        "or --format)",
        output);
  return cli_check_writable(output, input, force);
}

int cli_check_writable(const char *output, const char *input, int force) {
  struct stat so, si;
  if (input && !force && stat(output, &so) == 0 && stat(input, &si) == 0 &&
      so.st_dev == si.st_dev && so.st_ino == si.st_ino)
    return cli_error("%s: the output is the input file; refusing to overwrite it (use --force)",
                     output);
  /* the policy of docs/robustness.md: directories refused, read-only files
   * only with --force, FIFOs and devices written directly */
  bsurf_failure err = {0, -1, ""};
  if (bsurf_output_check(output, force, &err) != BSURF_OK)
    return cli_error("%s: %s", output, err.message);
  if (bsurf_output_is_stream(output)) return 0;
  /* the directory must exist and be writable (the file goes to a temporary
   * name there first): the directory of a symbolic link's target */
  char resolved[PATH_MAX];
  const char *target = realpath(output, resolved) ? resolved : output;
  char dir[4096];
  const char *slash = strrchr(target, '/');
  if (!slash) {
    strcpy(dir, ".");
  } else if (slash == target) {
    strcpy(dir, "/");
  } else {
    size_t n = (size_t)(slash - target);
    if (n >= sizeof dir) return cli_error("%s: path too long", output);
    memcpy(dir, target, n);
    dir[n] = 0;
  }
  if (access(dir, W_OK) != 0)
    return cli_error("%s: cannot write in directory '%s': %s", output, dir, strerror(errno));
  struct stat sd;
  if (stat(dir, &sd) != 0 || !S_ISDIR(sd.st_mode))
    return cli_error("%s: cannot write in directory '%s': %s", output, dir, strerror(ENOTDIR));
  return 0;
}

int cli_write_cloud(const char *path, const bsurf_cloud *cloud, int ascii) {
  bsurf_write_options wo;
  if (cli_write_options(path, ascii, &wo)) return 1;
  bsurf_format fmt = wo.format ? wo.format : bsurf_format_from_path(path);
  if (!bsurf_format_keeps_fields(fmt) && cloud->field_count > 0) {
    cli_warn("%s: this format cannot store the %zu scalar field(s) (first: %s); write .ply, .pcd, "
             ".las or .csv "
             "to keep them",
             path, cloud->field_count, cloud->fields[0].name);
  }
  if (cli_interrupted()) return cli_error("%s: interrupted; nothing written", path);
  bsurf_failure err = {0, -1, ""};
  bsurf_status st = cli_write_to(path, cloud, &wo, &err);
  if (st != BSURF_OK)
    return cli_error("%s: %s", path, err.message[0] ? err.message : bsurf_strerror(st));
  return 0;
}

/* ---- progress and signals ---- */

/* SIGINT and SIGTERM (docs/robustness.md, "Signals"): the first one sets
 * the flag every progress callback returns (the computation stops within one
 * chunk of points), makes writes still open discard their temporary files,
 * and arms a watchdog; the command then ends by cli_exit_status() dying of
 * the same signal (exit status 130 or 143 to the shell, which then stops a
 * loop, as it does for programs without a handler). If the command has not
 * ended 0.3 s after the signal (a step that cannot be cancelled: reading a
 * large file, a write), or at a second signal, the handler removes the
 * temporary files itself and dies at once. */
static volatile sig_atomic_t interrupted = 0;

static void say(const char *s) {
  size_t n = 0;
  while (s[n])
    n++;
  ssize_t w = write(STDERR_FILENO, s, n); /* async-signal-safe */
  (void)w;
}

static void die_of(int sig) {
  bsurf_atomic_remove_temporaries();
  const char *in = current_input;
  /* one message from a distributed run (a plain read of an int), and none
   * after the run's own error (mpirun then ends every rank) */
  if (cli_mpi_rank() == 0 && !cli_error_reported) {
    say("bootsurf: error: ");
    if (in) {
      say(in);
      say(": ");
    }
    say("interrupted\n");
  }
  signal(sig, SIG_DFL);
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, sig);
  sigprocmask(SIG_UNBLOCK, &set, NULL);
  raise(sig);
  _exit(128 + sig);
}

static void on_watchdog(int sig) {
  (void)sig;
  die_of(interrupted ? (int)interrupted : SIGINT);
}

static void on_signal(int sig) {
  if (interrupted) die_of(sig); /* a second signal */
  interrupted = sig;
  bsurf_atomic_interrupt();
  struct itimerval t;
  memset(&t, 0, sizeof t);
  t.it_value.tv_usec = 300000;
  setitimer(ITIMER_REAL, &t, NULL);
}

void cli_install_signals(void) {
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
  sa.sa_handler = on_watchdog;
  sigaction(SIGALRM, &sa, NULL);
}

int cli_exit_status(int rc) {
  if (!interrupted) return rc;
  fflush(stdout);
  fflush(stderr);
  die_of((int)interrupted);
  return 128 + (int)interrupted;
}

int cli_interrupted(void) {
  return interrupted != 0;
}

void cli_progress_init(cli_progress *p, const char *label, int quiet) {
  p->label = label;
  p->enabled = !quiet && isatty(STDERR_FILENO);
  p->last_permille = -1;
}

int cli_progress_cb(void *user, size_t done, size_t total) {
  cli_progress *p = user;
  if (p && p->enabled && total > 0) {
    int permille = (int)(1000.0 * (double)done / (double)total);
    if (permille != p->last_permille) {
      p->last_permille = permille;
      int width = 30, filled = permille * width / 1000;
      fprintf(stderr, "\r%-10s [", p->label);
      for (int i = 0; i < width; i++)
        fputc(i < filled ? '#' : '.', stderr);
      fprintf(stderr, "] %5.1f%%", permille / 10.0);
      fflush(stderr);
    }
  }
  return interrupted ? 1 : 0;
}

void cli_progress_done(cli_progress *p) {
  if (p->enabled && p->last_permille >= 0) fprintf(stderr, "\n");
  p->last_permille = -1;
}

double cli_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- JSON ---- */

static void json_sep(cli_json *j, const char *key) {
  if (j->count[j->depth]++) fputc(',', j->f);
  if (key) {
    fputc('"', j->f);
    for (const char *c = key; *c; c++) {
      if (*c == '"' || *c == '\\') fputc('\\', j->f);
      fputc(*c, j->f);
    }
    fputs("\":", j->f);
  }
}

void json_begin(cli_json *j, FILE *f) {
  memset(j, 0, sizeof *j);
  j->f = f;
  fputc('{', f);
}

cli_json json_start(const char *command, const char *input, const char *output) {
  cli_json j;
  json_begin(&j, stdout);
  json_str(&j, "command", command);
  if (input) json_str(&j, "input", input);
  if (output) json_str(&j, "output", output);
  return j;
}

void json_points_h(cli_json *j, size_t points, double h) {
  json_int(j, "points", (long long)points);
  json_num(j, "h", h);
}

void json_end(cli_json *j) {
  json_str(j, "version", BSURF_VERSION_STRING);
  if (cli_drop_invalid) json_int(j, "dropped_invalid", (long long)input_dropped);
  if (input_duplicates_known) json_int(j, "duplicate_points", (long long)input_duplicates);
  fputs("}\n", j->f);
  fflush(j->f);
}

void json_obj(cli_json *j, const char *key) {
  json_sep(j, key);
  fputc('{', j->f);
  j->count[++j->depth] = 0;
}

void json_arr(cli_json *j, const char *key) {
  json_sep(j, key);
  fputc('[', j->f);
  j->count[++j->depth] = 0;
}

void json_close_obj(cli_json *j) {
  fputc('}', j->f);
  j->depth--;
}

void json_close_arr(cli_json *j) {
  fputc(']', j->f);
  j->depth--;
}

void json_str(cli_json *j, const char *key, const char *v) {
  json_sep(j, key);
  fputc('"', j->f);
  for (const unsigned char *c = (const unsigned char *)v; *c; c++) {
    if (*c == '"' || *c == '\\') {
      fputc('\\', j->f);
      fputc(*c, j->f);
    } else if (*c < 0x20) {
      fprintf(j->f, "\\u%04x", *c);
    } else {
      fputc(*c, j->f);
    }
  }
  fputc('"', j->f);
}

void json_num(cli_json *j, const char *key, double v) {
  json_sep(j, key);
  if (isfinite(v))
    fprintf(j->f, "%.10g", v);
  else
    fputs("null", j->f);
}

void json_int(cli_json *j, const char *key, long long v) {
  json_sep(j, key);
  fprintf(j->f, "%lld", v);
}

void json_bool(cli_json *j, const char *key, int v) {
  json_sep(j, key);
  fputs(v ? "true" : "false", j->f);
}

double cli_field_mean(const bsurf_field *field, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++)
    s += field->values[i];
  return n ? s / (double)n : 0.0;
}

/* Fields that are not lengths (rates, angles, labels, counts) have no
 * meaning in units of h and are left out of "mean_h". */
static int is_length_field(const char *name) {
  static const char *const not_lengths[] = {"overfit_rate", "normal_var", "normal_err",
                                            "feature",      "k_selected", "two_sheet"};
  for (size_t i = 0; i < sizeof not_lengths / sizeof not_lengths[0]; i++)
    if (strcmp(name, not_lengths[i]) == 0) return 0;
  return 1;
}

void cli_set_duplicates(size_t count) {
  input_duplicates_known = 1;
  input_duplicates = count;
}

/* means[t] is NAN for a field the cloud lacks */
static void field_means(const bsurf_cloud *cloud, const char *const *names, int count,
                        double *means) {
  for (int t = 0; t < count && t < 64; t++) {
    const bsurf_field *f = bsurf_cloud_field(cloud, names[t]);
    means[t] = f ? cli_field_mean(f, cloud->point_count) : NAN;
  }
}

void json_tiles(cli_json *j, size_t tile_points, size_t tiles) {
  json_int(j, "tile_points", (long long)tile_points);
  json_int(j, "tiles", (long long)tiles);
  json_int(j, "ranks", cli_mpi_ranks());
}

void json_means(cli_json *j, const char *const *names, const double *means, int count, double h) {
  json_obj(j, "mean");
  for (int t = 0; t < count && t < 64; t++)
    if (!isnan(means[t])) json_num(j, names[t], means[t]);
  json_close_obj(j);
  json_obj(j, "mean_h");
  for (int t = 0; t < count && t < 64; t++)
    if (!isnan(means[t]) && is_length_field(names[t]))
      json_num(j, names[t], h > 0 ? means[t] / h : NAN);
  json_close_obj(j);
}

void json_field_means(cli_json *j, const bsurf_cloud *cloud, const char *const *names, int count,
                      double h) {
  double means[64];
  field_means(cloud, names, count, means);
  json_means(j, names, means, count, h);
}

void print_field_means(FILE *f, const bsurf_cloud *cloud, const char *const *names, int count,
                       double h) {
  double means[64];
  field_means(cloud, names, count, means);
  print_means(f, names, means, count, h);
}

void print_means(FILE *f, const char *const *names, const double *means, int count, double h) {
  fprintf(f, "  %-16s %14s %12s\n", "field", "mean", "mean / h");
  for (int t = 0; t < count && t < 64; t++) {
    double m = means[t];
    if (isnan(m)) continue;
    if (is_length_field(names[t]) && h > 0) /* h = 0: every point has a duplicate */
      fprintf(f, "  %-16s %14.6g %12.4f\n", names[t], m, m / h);
    else
      fprintf(f, "  %-16s %14.6g %12s\n", names[t], m, "-");
  }
}
