/* libFuzzer target: the command-line option parser, cli_parse (cli/args.c,
 * compiled into this target).
 *
 * Input: byte 0 picks an option table (bits 0-1: tables modelled on the
 * commands error, render, sample and compare, which together use every
 * option kind and range) and the number of positional arguments allowed
 * (bits 2-4: 0..7). The rest, split at NUL bytes, is argv[1..] (at most
 * FUZZ_MAX_ARGS arguments); each argument is copied to its own allocation of
 * exactly its length + 1, so that reading past an argument is an ASan
 * report. argv[0] is the command name, argv[argc] is NULL as in main().
 *
 * cli_parse never exits; it prints usage errors on stderr and --help on
 * stdout. While it runs, stdout and stderr point to /dev/null (set
 * BSURF_FUZZ_VERBOSE=1 to see the messages, e.g. when reproducing a crash);
 * libFuzzer's own output and the sanitizers' reports are not affected. If
 * the parser ever called exit(), libFuzzer would report it ("fuzz target
 * exited") and keep the input.
 *
 * Checked after every call (abort() when broken): the return code is one of
 * CLI_PARSED, CLI_HELP_SHOWN, CLI_USAGE; 0 <= npos <= maxpos and every
 * positional argument is one of the argv strings; every string option points
 * into an argv string (or is still its default); every number stored lies in
 * its option's range. */
#include "cli.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FUZZ_MAX_ARGS 64
#define FUZZ_MAX_POS 8

#define FUZZ_CHECK(cond)                                                                           \
  do {                                                                                             \
    if (!(cond)) {                                                                                 \
      fprintf(stderr, "%s:%d: parser contract broken: %s\n", __FILE__, __LINE__, #cond);           \
      abort();                                                                                     \
    }                                                                                              \
  } while (0)

/* Option targets, reset before every input. */
static struct {
  int k, degree, bootstrap, threads, views, flag[8];
  double az, el, point_size, sharp, width;
  uint64_t seed;
  size_t points;
  const char *str[8];
} v;

static const char k_default_str[] = "default";

static void reset_values(void) {
  memset(&v, 0, sizeof v);
  v.k = 50;
  v.degree = 3;
  v.bootstrap = 50;
  v.views = 1;
  v.az = NAN;
  v.el = NAN;
  v.point_size = 1.5;
  v.sharp = 30;
  v.width = 1;
  v.seed = 1;
  for (int i = 0; i < 8; i++)
    v.str[i] = i % 2 ? k_default_str : NULL;
}

/* Tables modelled on cli/cmd_error.c, cmd_render.c, cmd_sample.c and cmd_compare.c. */
static const cli_option k_error[] = {
    {'k', "neighbors", ARG_INT, &v.k, "K", "neighbourhood size", 2, 65535},
    {'d', "degree", ARG_INT, &v.degree, "M", "degree", 1, 4},
    {'B', "bootstrap", ARG_INT, &v.bootstrap, "B", "replicates", 0, 100000},
    {0, "gamma", ARG_STRING, &v.str[1], "MODE", "fit, mean or max", 1, 0},
    {0, "pca-center", ARG_STRING, &v.str[3], "C", "centroid or point", 1, 0},
    CLI_OPT_SEED(v.seed),
    CLI_OPT_THREADS(v.threads),
    {0, "test-sample", ARG_STRING, &v.str[0], "FILE", "test sample", 1, 0},
    CLI_OPTS_OUTPUT(v.str[2], v.flag[0], v.flag[1]),
    CLI_OPTS_REPORT(v.flag[2], v.flag[3]),
};

static const cli_option k_render[] = {
    {'o', "output", ARG_STRING, &v.str[0], "IMAGE", "output PNG file", 1, 0},
    {0, "field", ARG_STRING, &v.str[2], "NAME", "colour by this field", 1, 0},
    {0, "colormap", ARG_STRING, &v.str[1], "MAP", "colormap", 1, 0},
    {0, "range", ARG_STRING, &v.str[4], "LO:HI", "range", 1, 0},
    {0, "azimuth", ARG_DOUBLE, &v.az, "DEG", "azimuth", -360, 360},
    {0, "elevation", ARG_DOUBLE, &v.el, "DEG", "elevation", -90, 90},
    {0, "views", ARG_INT, &v.views, "N", "1 or 4", 1, 4},
    {0, "point-size", ARG_DOUBLE, &v.point_size, "S", "splat diameter", 0.05, 50},
    {0, "flat", ARG_FLAG, &v.flag[4], "", "no shading", 1, 0},
    CLI_OPT_THREADS(v.threads),
    {0, "force", ARG_FLAG, &v.flag[1], "", "allow the output to be the input", 1, 0},
    CLI_OPTS_REPORT(v.flag[2], v.flag[3]),
};

static const cli_option k_sample[] = {
    {0, "vertices", ARG_FLAG, &v.flag[5], "", "the mesh's vertices", 1, 0},
    {'n', "points", ARG_SIZE, &v.points, "N", "points by area", 0, 4e9},
    {0, "sharp-angle", ARG_DOUBLE, &v.sharp, "DEG", "sharp edge angle", 0, 180},
    {0, "feature-width", ARG_DOUBLE, &v.width, "W", "feature width", 0, 1e300},
    {0, "seed", ARG_U64, &v.seed, "S", "random seed", 1, 0},
    CLI_OPT_THREADS(v.threads),
    CLI_OPTS_OUTPUT(v.str[2], v.flag[0], v.flag[1]),
    CLI_OPTS_REPORT(v.flag[2], v.flag[3]),
};

/* No ranges at all, and options whose names share prefixes. */
static const cli_option k_compare[] = {
    {'o', "output", ARG_STRING, &v.str[0], "IMAGE", "output", 1, 0},
    {0, "titles", ARG_STRING, &v.str[5], "A,B", "titles", 1, 0},
    {0, "title", ARG_STRING, &v.str[6], "T", "title", 1, 0},
    {'s', "size", ARG_SIZE, &v.points, "N", "size", 1, 0},
    {'x', "x", ARG_DOUBLE, &v.width, "X", "unbounded number", 1, 0},
    {'i', "i", ARG_INT, &v.k, "I", "unbounded integer", 1, 0},
    {'f', "f", ARG_FLAG, &v.flag[6], "", "flag", 1, 0},
    {0, "", ARG_FLAG, &v.flag[7], "", "empty long name", 1, 0},
};

static const struct {
  cli_command cmd;
  const cli_option *opts;
  int nopts;
} k_tables[4] = {
    {{"error", "bootstrap test-error estimates", "[OPTIONS] INPUT", "", NULL},
     k_error,
     (int)(sizeof k_error / sizeof k_error[0])},
    {{"render", "PNG picture", "[OPTIONS] INPUT -o IMAGE.png", NULL, NULL},
     k_render,
     (int)(sizeof k_render / sizeof k_render[0])},
    {{"sample", "points from a mesh", "[OPTIONS] MESH", "a description", NULL},
     k_sample,
     (int)(sizeof k_sample / sizeof k_sample[0])},
    {{"compare", "clouds side by side", "[OPTIONS] A B ...", NULL, NULL},
     k_compare,
     (int)(sizeof k_compare / sizeof k_compare[0])},
};

static FILE *g_null;
static int g_verbose;

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc;
  (void)argv;
  const char *e = getenv("BSURF_FUZZ_VERBOSE");
  g_verbose = e && e[0] && strcmp(e, "0") != 0;
  if (!g_verbose) g_null = fopen("/dev/null", "w");
  return 0;
}

/* p points into one of the argv strings (its terminating NUL included). */
static int in_some_arg(const char *p, char **argv, int argc) {
  for (int i = 1; i < argc; i++) {
    size_t n = strlen(argv[i]);
    if (p >= argv[i] && p <= argv[i] + n) return 1;
  }
  return 0;
}

static void check_ranges(const cli_option *opts, int nopts, char **argv, int argc) {
  for (int k = 0; k < nopts; k++) {
    const cli_option *o = &opts[k];
    int ranged = o->min <= o->max;
    switch (o->kind) {
    case ARG_FLAG: FUZZ_CHECK(*(int *)o->target == 0 || *(int *)o->target == 1); break;
    case ARG_INT: {
      int x = *(int *)o->target;
      if (ranged) FUZZ_CHECK(x >= o->min && x <= o->max);
      break;
    }
    case ARG_DOUBLE: {
      double x = *(double *)o->target;
      /* NaN: the untouched default of --azimuth / --elevation */
      if (!isnan(x)) FUZZ_CHECK(isfinite(x) && (!ranged || (x >= o->min && x <= o->max)));
      break;
    }
    case ARG_SIZE: {
      size_t x = *(size_t *)o->target;
      FUZZ_CHECK(x <= 4294967295u);
      if (ranged) FUZZ_CHECK((double)x >= o->min && (double)x <= o->max);
      break;
    }
    case ARG_U64: break;
    case ARG_STRING: {
      const char *s = *(const char **)o->target;
      FUZZ_CHECK(s == NULL || s == k_default_str || in_some_arg(s, argv, argc));
      break;
    }
    }
  }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size == 0) return 0;
  int table = data[0] & 3, maxpos = (data[0] >> 2) & 7;
  data++;
  size--;

  char *argv[FUZZ_MAX_ARGS + 2];
  int argc = 0;
  static char name[] = "fuzz";
  argv[argc++] = name;
  size_t start = 0;
  while (argc <= FUZZ_MAX_ARGS && start < size) {
    const uint8_t *nul = memchr(data + start, 0, size - start);
    size_t len = nul ? (size_t)(nul - (data + start)) : size - start;
    char *a = malloc(len + 1);
    if (!a) break;
    memcpy(a, data + start, len);
    a[len] = '\0';
    argv[argc++] = a;
    start += len + 1;
  }
  argv[argc] = NULL;

  reset_values();
  char *pos[FUZZ_MAX_POS];
  int npos = -1;
  FILE *saved_out = stdout, *saved_err = stderr;
#if defined(__GLIBC__)
  if (g_null) {
    stdout = g_null; /* glibc's stdout and stderr are plain variables */
    stderr = g_null;
  }
#endif
  const cli_command *cmd = &k_tables[table].cmd;
  int rc =
      cli_parse(cmd, k_tables[table].opts, k_tables[table].nopts, argc, argv, pos, maxpos, &npos);
#if defined(__GLIBC__)
  stdout = saved_out;
  stderr = saved_err;
#else
  (void)saved_out;
  (void)saved_err;
#endif

  FUZZ_CHECK(rc == CLI_PARSED || rc == CLI_HELP_SHOWN || rc == CLI_USAGE);
  FUZZ_CHECK(npos >= 0 && npos <= maxpos);
  for (int i = 0; i < npos; i++) {
    int found = 0;
    for (int j = 1; j < argc; j++)
      found |= pos[i] == argv[j];
    FUZZ_CHECK(found);
  }
  check_ranges(k_tables[table].opts, k_tables[table].nopts, argv, argc);

  for (int i = 1; i < argc; i++)
    free(argv[i]);
  return 0;
}
