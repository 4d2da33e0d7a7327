/* Tiled (out-of-core) and distributed runs from the command line: the
 * --tile-points / --memory-limit decision, the run with messages that name
 * the file and the place, and MPI when the tool is built with it
 * (docs/scaling.md). */
#include "cli.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* "8G", "512M", "1.5T", "100000" (bytes); 0 on a bad value. */
static double parse_bytes(const char *s) {
  char *end;
  errno = 0;
  double v = strtod(s, &end);
  if (end == s || errno || !(v > 0)) return 0;
  double unit = 1;
  switch (toupper((unsigned char)*end)) {
  case 0: break;
  case 'K':
    unit = 1024.0;
    end++;
    break;
  case 'M':
    unit = 1024.0 * 1024;
    end++;
    break;
  case 'G':
    unit = 1024.0 * 1024 * 1024;
    end++;
    break;
  case 'T':
    unit = 1024.0 * 1024 * 1024 * 1024;
    end++;
    break;
  default: return 0;
  }
  if (*end == 'B' || *end == 'b') end++;
  return *end ? 0 : v * unit;
}

size_t cli_range_points = 0;

int cli_tiles_plan(const cli_command *cmd, const char *input, const char *output, int ascii,
                   size_t tile_points, const char *memory_limit, int k, int out_fields,
                   size_t *plan) {
  return cli_tiles_plan_bytes(cmd, input, output, ascii, tile_points, memory_limit, k, out_fields,
                              0, 0, plan);
}

int cli_memory_limit(const cli_command *cmd, const char *memory_limit, double *limit) {
  if (strcmp(memory_limit, "auto") == 0) {
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    *limit = pages > 0 && page > 0 ? 0.75 * (double)pages * (double)page : 0;
  } else if (strcmp(memory_limit, "none") == 0) {
    *limit = 0;
  } else if (!(*limit = parse_bytes(memory_limit))) {
    return cli_usage_error(cmd, "--memory-limit needs a size like 8G, 512M, auto or none, not '%s'",
                           memory_limit);
  }
  return 0;
}

double cli_memory_need(const char *input, uint64_t n, int k, int out_fields, double point_bytes) {
  /* the whole cloud in memory: the file, its values as doubles, the
   * neighbourhoods (4 K bytes), the k-d tree and the new fields */
  struct stat sb;
  double size = stat(input, &sb) == 0 ? (double)sb.st_size : 0;
  return 3 * size + (double)n * (4.0 * k + 40 + 8.0 * out_fields + point_bytes);
}

int cli_tiles_plan_bytes(const cli_command *cmd, const char *input, const char *output, int ascii,
                         size_t tile_points, const char *memory_limit, int k, int out_fields,
                         double point_bytes, double cloud_bytes, size_t *plan) {
  return cli_tiles_plan_split(cmd, input, output, ascii, tile_points, memory_limit, k, out_fields,
                              point_bytes, out_fields, point_bytes, cloud_bytes, plan);
}

int cli_tiles_plan_split(const cli_command *cmd, const char *input, const char *output, int ascii,
                         size_t tile_points, const char *memory_limit, int k, int out_fields,
                         double point_bytes, int tile_fields, double tile_bytes, double cloud_bytes,
                         size_t *plan) {
  *plan = 0;
  double limit;
  if (cli_memory_limit(cmd, memory_limit, &limit)) return CLI_USAGE;
  /* the header first: counts a file cannot hold are its fault, named as
   * such, never the basis of an estimate */
  uint64_t n = 0;
  if (cli_read_header(input, &n)) return 1;
  double need = cli_memory_need(input, n, k, out_fields, point_bytes);
  int distributed = cli_mpi_ranks() > 1;
  int automatic = !tile_points && !distributed && limit > 0 && need > limit;
  if (!tile_points && !automatic && !distributed) return 0;
  if (!output)
    return cli_error("%s: tiled runs write their points to a file: give -o FILE.ply", input);
  if (bsurf_format_from_path(output) != BSURF_FORMAT_PLY || ascii ||
      cli_output_format(output) != BSURF_FORMAT_PLY || cli_float32 || cli_ply_names ||
      cli_las_version)
    return cli_error(
        "%s: tiled runs write binary PLY (not --ascii, --format, --float32, --ply-names, other "
        "formats or -)",
        output);
  if (bsurf_format_from_path(input) != BSURF_FORMAT_PLY)
    return cli_error(
        "%s: tiled runs read binary PLY files (write one with any command's -o FILE.ply)", input);
  if (cli_drop_invalid)
    return cli_error("%s: --drop-invalid is not available in tiled runs", input);
  if (!tile_points) {
    /* tiles well inside the budget: the neighbourhood rows (12 K bytes per
     * point while they are built), the fields, the command's arrays and the
     * halo */
    double budget = limit > 0 ? limit : 4.0 * 1024 * 1024 * 1024;
    /* less what the run holds for the whole cloud beside a tile (beyond the
     * budget: the smallest tiles) */
    budget -= cloud_bytes * (double)n;
    double per = 4.0 * (12.0 * k + 8.0 * tile_fields + tile_bytes + 200);
    tile_points = (size_t)fmin(budget / per, 2e8);
  }
  if (tile_points < 2 * (size_t)k) tile_points = 2 * (size_t)k;
  if (cli_mpi_comm()) {
    /* at least two tiles per rank */
    size_t ranks = (size_t)cli_mpi_ranks(), per = (n + 2 * ranks - 1) / (2 * ranks);
    if (n && per < tile_points) tile_points = per < 2 * (size_t)k ? 2 * (size_t)k : per;
  }
  if (automatic && !cli_mpi_rank())
    cli_warn(
        "%s: needs about %.1f GB in memory, more than --memory-limit %.1f GB: tiles of %zu points",
        input, need / 1e9, limit / 1e9, tile_points);
  *plan = tile_points;
  return 0;
}

/* A failure of the output, not of the input (a full disk, the directory):
 * the messages of the atomic writer and of the tiles' output. */
static int about_output(const char *msg) {
  static const char *const starts[] = {
      "cannot write",         "write failed",     "cannot move the finished file",
      "cannot create a file", "tiled runs write", "interrupted; nothing written"};
  for (size_t i = 0; i < sizeof starts / sizeof starts[0]; i++)
    if (strncmp(msg, starts[i], strlen(starts[i])) == 0) return 1;
  return 0;
}

int cli_check_tiled_input(const char *input) {
  struct stat sb;
  if (stat(input, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size == 0)
    return cli_error("%s: the file is empty", input);
  return 0;
}

int cli_tiles_failed(const char *input, const char *output, bsurf_status st,
                     const bsurf_failure *err) {
  if (cli_mpi_rank() != 0) return 1;
  const char *msg = cli_interrupted()             ? "interrupted"
                    : err->message[0]             ? err->message
                    : st == BSURF_ERR_INVALID_ARG ? bsurf_last_message()
                                                  : bsurf_strerror(st);
  if (st == BSURF_ERR_INVALID_VALUE)
    return cli_error("%s: %s (--drop-invalid, in memory, skips such points)", input, msg);
  if (output && about_output(msg)) return cli_error("%s: %s", output, msg);
  if (err->line > 0) return cli_error("%s:%ld: %s", input, err->line, msg);
  if (err->byte >= 0) return cli_error("%s: byte %lld: %s", input, err->byte, msg);
  return cli_error("%s: %s", input, msg);
}

int cli_job_io(bsurf_job_io *io, const char *input, const char *output, size_t plan, bsurf_cloud *c,
               cli_progress *prog, const char *label, int quiet) {
  memset(io, 0, sizeof *io);
  bsurf_cloud_init(c);
  if (plan) {
    if (cli_check_tiled_input(input)) return 1;
    io->input = input;
    io->output = output;
    io->tile_points = plan;
    io->range_points = cli_range_points;
    io->comm = cli_mpi_comm();
    cli_progress_init(prog, "tiles", quiet || cli_mpi_rank() != 0);
    return 0;
  }
  if (cli_read_cloud(input, c)) return 1;
  io->cloud = c;
  cli_progress_init(prog, label, quiet);
  return 0;
}

int cli_job_failed(const char *input, const char *output, size_t plan, bsurf_status st,
                   const bsurf_failure *err) {
  if (plan) return cli_tiles_failed(input, output, st, err);
  const char *msg = cli_interrupted() ? "interrupted"
                    : st == BSURF_ERR_INVALID_ARG || st == BSURF_ERR_TOO_FEW_POINTS
                        ? bsurf_last_message()
                        : bsurf_strerror(st);
  return cli_error("%s: %s", input, msg);
}

int cli_job_done(cli_progress *prog, const char *input, const char *output, size_t plan,
                 bsurf_status st, const bsurf_failure *err, size_t duplicates) {
  cli_progress_done(prog);
  if (st != BSURF_OK) return cli_job_failed(input, output, plan, st, err);
  cli_set_duplicates(duplicates);
  return 0;
}

/* ---- MPI ---------------------------------------------------------------------- */

#ifdef BSURF_MPI
#include <mpi.h>

static int mpi_on = 0, mpi_rank = 0, mpi_size = 1;

static void mpi_barrier(void *u) {
  (void)u;
  MPI_Barrier(MPI_COMM_WORLD);
}

/* MPI counts are ints: long arrays go in chunks of 2^24 elements */
#define MPI_CHUNK ((size_t)1 << 24)

static void mpi_sum(void *u, double *v, size_t n) {
  (void)u;
  for (size_t i = 0; i < n; i += MPI_CHUNK) {
    size_t m = n - i < MPI_CHUNK ? n - i : MPI_CHUNK;
    MPI_Allreduce(MPI_IN_PLACE, v + i, (int)m, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  }
}

static void mpi_sum_u64(void *u, uint64_t *v, size_t n) {
  (void)u;
  for (size_t i = 0; i < n; i += MPI_CHUNK) {
    size_t m = n - i < MPI_CHUNK ? n - i : MPI_CHUNK;
    MPI_Allreduce(MPI_IN_PLACE, v + i, (int)m, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  }
}

static void mpi_exscan_u64(void *u, uint64_t *v, size_t n) {
  (void)u;
  for (size_t i = 0; i < n; i += MPI_CHUNK) {
    size_t m = n - i < MPI_CHUNK ? n - i : MPI_CHUNK;
    MPI_Exscan(MPI_IN_PLACE, v + i, (int)m, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  }
  /* MPI leaves rank 0's buffer undefined */
  if (mpi_rank == 0) memset(v, 0, n * sizeof *v);
}

static void mpi_allgather(void *u, const void *mine, void *all, size_t bytes) {
  (void)u;
  size_t chunk = MPI_CHUNK / (size_t)mpi_size;
  if (bytes <= chunk) {
    MPI_Allgather(mine, (int)bytes, MPI_BYTE, all, (int)bytes, MPI_BYTE, MPI_COMM_WORLD);
    return;
  }
  /* in chunks (at most 16 MiB gathered at a time), each put in its place of
   * every rank's part */
  char *tmp = malloc((size_t)mpi_size * chunk);
  if (!tmp) {
    fprintf(stderr, "bootsurf: out of memory\n");
    MPI_Abort(MPI_COMM_WORLD, 1);
    return;
  }
  for (size_t i = 0; i < bytes; i += chunk) {
    size_t m = bytes - i < chunk ? bytes - i : chunk;
    MPI_Allgather((const char *)mine + i, (int)m, MPI_BYTE, tmp, (int)m, MPI_BYTE, MPI_COMM_WORLD);
    for (int r = 0; r < mpi_size; r++)
      memcpy((char *)all + (size_t)r * bytes + i, tmp + (size_t)r * m, m);
  }
  free(tmp);
}

static int mpi_max(void *u, int v) {
  (void)u;
  int r = v;
  MPI_Allreduce(&v, &r, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  return r;
}

static void mpi_bcast(void *u, void *data, size_t bytes) {
  (void)u;
  MPI_Bcast(data, (int)bytes, MPI_BYTE, 0, MPI_COMM_WORLD);
}

static bsurf_tile_comm mpi_comm;

void cli_mpi_init(int *argc, char ***argv) {
  /* only when started by mpirun (Open MPI, or a PMI launcher) */
  if (!getenv("OMPI_COMM_WORLD_SIZE") && !getenv("PMI_SIZE") && !getenv("PMIX_RANK")) return;
  MPI_Init(argc, argv);
  mpi_on = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &mpi_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &mpi_size);
  mpi_comm = (bsurf_tile_comm){.rank = mpi_rank,
                               .ranks = mpi_size,
                               .barrier = mpi_barrier,
                               .sum = mpi_sum,
                               .max = mpi_max,
                               .broadcast = mpi_bcast,
                               .allgather = mpi_allgather,
                               .sum_u64 = mpi_sum_u64,
                               .exscan_u64 = mpi_exscan_u64};
  /* one summary: the other ranks say nothing on stdout */
  if (mpi_rank != 0) {
    FILE *quiet = freopen("/dev/null", "w", stdout);
    (void)quiet; /* should it fail, the other ranks' summaries also reach stdout */
  }
}

void cli_mpi_finalize(void) {
  if (mpi_on) MPI_Finalize();
}

const bsurf_tile_comm *cli_mpi_comm(void) {
  return mpi_on ? &mpi_comm : NULL;
}
int cli_mpi_rank(void) {
  return mpi_rank;
}
int cli_mpi_ranks(void) {
  return mpi_on ? mpi_size : 1;
}
#else
void cli_mpi_init(int *argc, char ***argv) {
  (void)argc;
  (void)argv;
}
void cli_mpi_finalize(void) {}
const bsurf_tile_comm *cli_mpi_comm(void) {
  return NULL;
}
int cli_mpi_rank(void) {
  return 0;
}
int cli_mpi_ranks(void) {
  return 1;
}
#endif
