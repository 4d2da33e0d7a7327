/* libFuzzer target: the command line's whole read path, as `error`,
 * `normals`, `smooth` and `features` run it (cli/util.c and cli/tiles.c,
 * compiled into this target): the header check and the memory estimate of
 * cli_tiles_plan (with --memory-limit 1K, so that every header that passes
 * reaches the estimate and the tiling decision), then cli_read_cloud.
 *
 * Input: byte 0 picks the file type (bits 0-1: .ply .off .obj .xyz); the
 * rest is the file, written to a scratch directory ($TMPDIR or /tmp) since
 * the path is what the CLI reads. Inputs may be far longer than libFuzzer's
 * default 4096 bytes (fuzz/run.sh passes -max_len=1048576 for this target):
 * headers of thousands of properties are in the seeds.
 *
 * Checked after every call (abort() when broken):
 *   - cli_tiles_plan and cli_read_cloud return 0 or 1;
 *   - a file whose header check fails is never read successfully (the check
 *     rejects only what the reader rejects);
 *   - a PLY file read successfully has as many points as its header declares.
 * Messages go to /dev/null (BSURF_FUZZ_VERBOSE=1 shows them). */
#include "cli.h"

#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define FUZZ_CHECK(cond)                                                                           \
  do {                                                                                             \
    if (!(cond)) {                                                                                 \
      fprintf(stderr, "%s:%d: read path contract broken: %s\n", __FILE__, __LINE__, #cond);        \
      abort();                                                                                     \
    }                                                                                              \
  } while (0)

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char g_dir[4096];

int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc;
  (void)argv;
  const char *tmp = getenv("TMPDIR");
  snprintf(g_dir, sizeof g_dir, "%s/bsurf-fuzz-read-%ld", tmp && *tmp ? tmp : "/tmp",
           (long)getpid());
  mkdir(g_dir, 0700);
  const char *verbose = getenv("BSURF_FUZZ_VERBOSE");
  if (!verbose || !*verbose) {
    int null = open("/dev/null", O_WRONLY);
    if (null >= 0) {
      fflush(stdout);
      dup2(null, STDOUT_FILENO);
      close(null);
    }
  }
  return 0;
}

/* The CLI's messages (stderr) are silenced around the calls only, so that
 * sanitizer reports and FUZZ_CHECK still reach the terminal. */
static void quiet(int on) {
  static int saved = -1;
  const char *verbose = getenv("BSURF_FUZZ_VERBOSE");
  if (verbose && *verbose) return;
  fflush(stderr);
  if (on) {
    int null = open("/dev/null", O_WRONLY);
    if (null < 0) return;
    saved = dup(STDERR_FILENO);
    dup2(null, STDERR_FILENO);
    close(null);
  } else if (saved >= 0) {
    dup2(saved, STDERR_FILENO);
    close(saved);
    saved = -1;
  }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static const char *const ext[4] = {"ply", "off", "obj", "xyz"};
  if (size < 1) return 0;
  char path[4200], out[4200];
  snprintf(path, sizeof path, "%s/in.%s", g_dir, ext[data[0] & 3]);
  snprintf(out, sizeof out, "%s/out.ply", g_dir);
  FILE *f = fopen(path, "wb");
  if (!f) return 0;
  size_t wrote = size > 1 ? fwrite(data + 1, 1, size - 1, f) : 0;
  if (fclose(f) != 0 || wrote != size - 1) {
    unlink(path);
    return 0;
  }
  static const cli_command cmd = {"error", "fuzz", "INPUT", "", NULL};
  size_t plan = 0;
  uint64_t declared = 0;
  quiet(1);
  int header = cli_read_header(path, &declared);
  int planned = cli_tiles_plan(&cmd, path, out, 0, 0, "1K", 20, 8, &plan);
  bsurf_cloud c;
  bsurf_cloud_init(&c);
  int read = cli_read_cloud(path, &c);
  quiet(0);
  FUZZ_CHECK(header == 0 || header == 1);
  FUZZ_CHECK(planned == 0 || planned == 1);
  FUZZ_CHECK(read == 0 || read == 1);
  if (header) FUZZ_CHECK(read == 1);
  if (header) FUZZ_CHECK(planned == 1);
  if (!read && (data[0] & 3) == 0) FUZZ_CHECK(c.point_count == declared);
  bsurf_cloud_free(&c);
  unlink(path);
  return 0;
}
