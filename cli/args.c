/* Option parsing and --help: defaults shown are the values the options hold
 * before parsing, which come from the library's *_default() constructors,
 * so help and behaviour cannot drift apart. */
#include "cli.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

int cli_usage_error(const cli_command *cmd, const char *fmt, ...) {
  va_list ap;
  fprintf(stderr, "bootsurf %s: ", cmd->name);
  va_start(ap, fmt);
  vfprintf(stderr, fmt, ap);
  va_end(ap);
  fprintf(stderr, "\nTry 'bootsurf %s --help'.\n", cmd->name);
  return CLI_USAGE;
}

volatile sig_atomic_t cli_error_reported = 0;

int cli_error(const char *fmt, ...) {
  va_list ap;
  cli_error_reported = 1;
  fprintf(stderr, "bootsurf: error: ");
  va_start(ap, fmt);
  vfprintf(stderr, fmt, ap);
  va_end(ap);
  fputc('\n', stderr);
  return 1;
}

/* -q silences warnings too (set by cli_parse when a command's --quiet is on) */
static int quiet_warnings = 0;

void cli_warn(const char *fmt, ...) {
  if (quiet_warnings) return;
  va_list ap;
  fprintf(stderr, "bootsurf: warning: ");
  va_start(ap, fmt);
  vfprintf(stderr, fmt, ap);
  va_end(ap);
  fputc('\n', stderr);
}

int cli_choice(const char *value, const char *const *names, int count) {
  for (int i = 0; i < count; i++)
    if (strcmp(value, names[i]) == 0) return i;
  return -1;
}

int cli_parse_one(const cli_command *cmd, const cli_option *opts, int nopts, int argc, char **argv,
                  char **arg, const char *what) {
  int npos;
  int rc = cli_parse(cmd, opts, nopts, argc, argv, arg, 1, &npos);
  if (rc != CLI_PARSED) return rc;
  if (npos != 1) return cli_usage_error(cmd, "expected one %s", what);
  return CLI_PARSED;
}

int cli_parse_input(const cli_command *cmd, const cli_option *opts, int nopts, int argc,
                    char **argv, char **input) {
  return cli_parse_one(cmd, opts, nopts, argc, argv, input, "INPUT file");
}

int cli_pca_center(const cli_command *cmd, const char *text, bsurf_pca_center *out) {
  static const char *const centers[] = {"centroid", "point"};
  int pc = cli_choice(text, centers, 2);
  if (pc < 0) return cli_usage_error(cmd, "--pca-center must be centroid or point, not '%s'", text);
  *out = (bsurf_pca_center)pc;
  return 0;
}

int cli_gamma(const cli_command *cmd, const char *text, bsurf_gamma_mode *out) {
  static const char *const gammas[] = {"fit", "mean", "max"};
  int g = cli_choice(text, gammas, 3);
  if (g < 0) return cli_usage_error(cmd, "--gamma must be fit, mean or max, not '%s'", text);
  *out = (bsurf_gamma_mode)g;
  return 0;
}

int cli_check_terms(const cli_command *cmd, int k, int degree) {
  int terms = bsurf_poly_terms(degree);
  if (k < terms)
    return cli_usage_error(cmd, "K = %d is too small for degree %d: a fit needs at least %d points",
                           k, degree, terms);
  return 0;
}

static int in_range(const cli_option *o, double v) {
  return o->min > o->max || (v >= o->min && v <= o->max);
}

static void range_text(const cli_option *o, char *buf, size_t n) {
  if (o->min > o->max) {
    buf[0] = 0;
  } else if (o->max >= 1e300) {
    snprintf(buf, n, " (at least %g)", o->min);
  } else {
    snprintf(buf, n, " (%g to %g)", o->min, o->max);
  }
}

static int set_value(const cli_command *cmd, const cli_option *o, const char *name,
                     const char *arg) {
  char *end = NULL;
  char range[64];
  range_text(o, range, sizeof range);
  errno = 0;
  switch (o->kind) {
  case ARG_FLAG: *(int *)o->target = 1; return 0;
  case ARG_STRING: *(const char **)o->target = arg; return 0;
  case ARG_INT: {
    long v = strtol(arg, &end, 10);
    if (end == arg || *end || errno || v < -2147483647L || v > 2147483647L ||
        !in_range(o, (double)v))
      return cli_usage_error(cmd, "option %s needs a whole number%s, not '%s'", name, range, arg);
    *(int *)o->target = (int)v;
    return 0;
  }
  case ARG_U64: {
    /* strtoull skips white space and negates a '-' after it: only digits */
    if (arg[0] < '0' || arg[0] > '9')
      return cli_usage_error(cmd, "option %s needs a non-negative whole number, not '%s'", name,
                             arg);
    unsigned long long v = strtoull(arg, &end, 10);
    if (end == arg || *end || errno)
      return cli_usage_error(cmd, "option %s needs a non-negative whole number, not '%s'", name,
                             arg);
    *(uint64_t *)o->target = (uint64_t)v;
    return 0;
  }
  case ARG_SIZE: {
    if (!(arg[0] >= '0' && arg[0] <= '9') && arg[0] != '.')
      return cli_usage_error(cmd, "option %s needs a positive whole number, not '%s'", name, arg);
    double v = strtod(arg, &end); /* accepts 1e6 */
    if (end == arg || *end || errno || !(v >= 0) || v != floor(v) || v > 4294967295.0 ||
        !in_range(o, v))
      return cli_usage_error(cmd, "option %s needs a whole number%s, not '%s'", name, range, arg);
    *(size_t *)o->target = (size_t)v;
    return 0;
  }
  case ARG_DOUBLE: {
    double v = strtod(arg, &end);
    if (end == arg || *end || errno || !isfinite(v) || !in_range(o, v))
      return cli_usage_error(cmd, "option %s needs a number%s, not '%s'", name, range, arg);
    *(double *)o->target = v;
    return 0;
  }
  }
  return 0;
}

int cli_parse(const cli_command *cmd, const cli_option *opts, int nopts, int argc, char **argv,
              char **pos, int maxpos, int *npos) {
  *npos = 0;
  int only_positional = 0;
  for (int i = 1; i < argc; i++) {
    char *a = argv[i];
    if (only_positional || a[0] != '-' || a[1] == 0) {
      if (*npos >= maxpos) return cli_usage_error(cmd, "unexpected argument '%s'", a);
      pos[(*npos)++] = a;
      continue;
    }
    if (strcmp(a, "--") == 0) {
      only_positional = 1;
      continue;
    }
    if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
      cli_print_help(stdout, cmd, opts, nopts);
      return CLI_HELP_SHOWN;
    }
    const cli_option *o = NULL;
    const char *inline_val = NULL;
    char name[96];
    if (a[1] == '-') {
      const char *eq = strchr(a + 2, '=');
      size_t len = eq ? (size_t)(eq - (a + 2)) : strlen(a + 2);
      for (int k = 0; k < nopts; k++)
        if (opts[k].long_name && strlen(opts[k].long_name) == len &&
            strncmp(opts[k].long_name, a + 2, len) == 0)
          o = &opts[k];
      if (eq) inline_val = eq + 1;
      snprintf(name, sizeof name, "--%.*s", (int)(len < 80 ? len : 80), a + 2);
    } else {
      for (int k = 0; k < nopts; k++)
        if (opts[k].short_name && opts[k].short_name == a[1]) o = &opts[k];
      if (a[2]) inline_val = a + 2;
      snprintf(name, sizeof name, "-%c", a[1]);
    }
    if (!o) return cli_usage_error(cmd, "unknown option '%s'", a);
    if (o->kind == ARG_FLAG) {
      if (inline_val) return cli_usage_error(cmd, "option %s takes no value", name);
      *(int *)o->target = 1;
      continue;
    }
    const char *val = inline_val;
    if (!val) {
      if (i + 1 >= argc)
        return cli_usage_error(cmd, "option %s needs a value (%s)", name, o->metavar);
      val = argv[++i];
    }
    int rc = set_value(cmd, o, name, val);
    if (rc) return rc;
  }
  for (int k = 0; k < nopts; k++)
    if (opts[k].kind == ARG_FLAG && strcmp(opts[k].long_name, "quiet") == 0 &&
        *(int *)opts[k].target)
      quiet_warnings = 1;
  /* --format, --las-version and --ply-names are usage: refused before any
   * work is done, not after the computation when the file is written */
  if (cli_write_options_check(cmd)) return CLI_USAGE;
  const char *output = NULL;
  int ascii = 0;
  for (int k = 0; k < nopts; k++) {
    if (opts[k].kind == ARG_FLAG && strcmp(opts[k].long_name, "ascii") == 0)
      ascii = *(int *)opts[k].target;
    if (opts[k].kind == ARG_STRING && strcmp(opts[k].long_name, "output") == 0)
      output = *(const char **)opts[k].target;
  }
  if (cli_ascii_check(cmd, output, ascii)) return CLI_USAGE;
  return CLI_PARSED;
}

void cli_print_help(FILE *f, const cli_command *cmd, const cli_option *opts, int nopts) {
  fprintf(f, "Usage: bootsurf %s %s\n\n%s\n", cmd->name, cmd->usage, cmd->summary);
  if (cmd->description && cmd->description[0]) fprintf(f, "\n%s\n", cmd->description);
  fprintf(f, "\nOptions:\n");
  for (int k = 0; k < nopts; k++) {
    const cli_option *o = &opts[k];
    char left[64], def[96] = "", shortpart[8] = "    ";
    if (o->short_name) snprintf(shortpart, sizeof shortpart, "-%c, ", o->short_name);
    if (o->kind == ARG_FLAG)
      snprintf(left, sizeof left, "%s--%s", shortpart, o->long_name);
    else
      snprintf(left, sizeof left, "%s--%s %s", shortpart, o->long_name, o->metavar);
    switch (o->kind) {
    case ARG_FLAG: break;
    case ARG_INT: snprintf(def, sizeof def, " (default: %d)", *(int *)o->target); break;
    case ARG_U64:
      snprintf(def, sizeof def, " (default: %" PRIu64 ")", *(uint64_t *)o->target);
      break;
    case ARG_SIZE: snprintf(def, sizeof def, " (default: %zu)", *(size_t *)o->target); break;
    case ARG_DOUBLE: /* NaN: not set unless given (the help says what happens then) */
      if (!isnan(*(double *)o->target))
        snprintf(def, sizeof def, " (default: %g)", *(double *)o->target);
      break;
    case ARG_STRING:
      if (*(const char **)o->target)
        snprintf(def, sizeof def, " (default: %s)", *(const char **)o->target);
      break;
    }
    fprintf(f, "  %-26s %s%s\n", left, o->help, def);
  }
  fprintf(f, "  -h, --help                 show this help\n");
}
