/* Internal helpers shared by every layer: allocation, error records, OpenMP,
 * the parallel loop over points. */
#ifndef BSURF_COMMON_H
#define BSURF_COMMON_H

#include "bootsurf.h"

#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#if defined(__GNUC__)
#define BSURF_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define BSURF_PRINTF(a, b)
#endif

/* Hot kernels are compiled three times (GCC): for x86-64-v4 (AVX-512), x86-64-v3
 * (AVX2) and a portable default, chosen at load time (clang 14 rejects
 * target_clones beside noinline, so clang builds use the default path only).
 * Kernels avoid floating-point contraction (-std=c11 keeps it off) so every
 * clone gives the same bits (the goldens, made with the AVX2 clones, pass on
 * an AVX-512 machine). The AVX-512 clone halves the time of Eq. 5.10's angle
 * loops on a Zen 5 (twice the lanes and registers, docs/performance.md,
 * "Fourth round"); machines without AVX-512 run the AVX2 clone as before. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) &&                             \
    !defined(__SANITIZE_ADDRESS__)
#define BSURF_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define BSURF_CLONES
#endif

/* bsurf_rng_init of the four streams (seed, a, b + l), l < 4 (rng.c). */
void bsurf_rng_init4(bsurf_rng rng[4], uint64_t seed, uint64_t a, uint64_t b);

/* malloc of n * size bytes with an overflow check; NULL on failure or n == 0. */
void *bsurf_alloc_array(size_t n, size_t size);
void *bsurf_calloc_array(size_t n, size_t size);
/* bsurf_alloc_array on a 64-byte boundary (a cache line), for arrays read
 * by 32-byte vector loads at multiples of 32 bytes from the start: none of
 * them then straddles two lines (a split load costs two). free() frees it. */
void *bsurf_alloc_aligned(size_t n, size_t size);

/* Arrays allocated one by one and freed together (blocks.c): a thread's
 * scratch. Zero-initialise; each call returns the array, or NULL and sets
 * `failed` (as bsurf_alloc_array: also when n == 0); bsurf_blocks_free
 * frees all and zeroes the record. */
#define BSURF_BLOCKS_MAX 24
typedef struct bsurf_blocks {
  void *p[BSURF_BLOCKS_MAX];
  int n, failed;
} bsurf_blocks;
void *bsurf_blocks_array(bsurf_blocks *b, size_t n, size_t size);
void *bsurf_blocks_aligned(bsurf_blocks *b, size_t n, size_t size);
void bsurf_blocks_free(bsurf_blocks *b);
/* BSURF_ERR_NOMEM if an allocation failed, else BSURF_OK. */
bsurf_status bsurf_blocks_status(const bsurf_blocks *b);

/* The best split of the sorted values v[0..n-1] into two groups, each of at
 * least q (>= 1): the smallest within-groups sum of squares over the total
 * (split.c). 1 when n < 2q or the total is not above min_total (nor above
 * 0); *cut (may be NULL): the midpoint of the best split, NAN when none is
 * below 1. */
double bsurf_split_share(const double *v, int n, int q, double min_total, double *cut);
/* 1 when the sorted residuals v[0..n-1] fall in two groups apart (two
 * sheets): the best split with at least max(n/4, 3) a side leaves a share
 * below the 1% quantile of unimodal noise's, 1/4 - 0.635 / sqrt(n)
 * (split.c). Not tested (0) when their sum of squares is not above
 * n tiny^2 (rounding). *cut (may be NULL): the best split's midpoint. */
int bsurf_split_bimodal(const double *v, int n, double tiny, double *cut);

/* Order statistics (order_stats.c): the qsort comparison of doubles
 * (ascending, NaN-free input); the median of n sorted values (the mean of
 * the two middle ones for even n; 0 for n == 0); and the median of v after
 * sorting it in place. */
int bsurf_cmp_double(const void *pa, const void *pb);
/* ascending unsigned keys for qsort */
int bsurf_cmp_u64(const void *pa, const void *pb);
int bsurf_cmp_u32(const void *pa, const void *pb);
double bsurf_median_sorted(const double *v, size_t n);
double bsurf_median(double *v, size_t n);
/* The k-th smallest of n NaN-free values (k < n), without a full sort: v
 * rearranged so that v[k] is the value sorting would put there, v[j] <=
 * v[k] before it and >= after it (deterministic quickselect). */
double bsurf_kth_smallest(double *v, size_t n, size_t k);
/* chi^2_nu / nu at the standard normal quantile z, by Wilson and Hilferty's
 * cube-root approximation (within 1% for nu >= 5 at |z| <= 2.33); 0 where
 * the approximation's cube root falls at or below 0. */
double bsurf_chi2_ratio_wh(double nu, double z);
/* The quantile of F(nu1, nu2) at the standard normal quantile z, by
 * Paulson's cube-root approximation (Wilson and Hilferty's, applied to the
 * ratio; within about 1% of the exact quantile at nu2 >= 7, |z| <= 1.65);
 * INFINITY (z > 0) or 0 where the approximation has no root. */
double bsurf_f_quantile_paulson(double nu1, double nu2, double z);

/* BSURF_ERR_INVALID_ARG with a message for bsurf_last_message(): "FUNC:
 * what is wrong" naming the parameter, its value and the allowed range.
 * BSURF_REQUIRE(cond, fmt, ...) returns it from the calling function when
 * cond is false (func is the public function's name, __func__). */
bsurf_status bsurf_invalid(const char *func, const char *fmt, ...) BSURF_PRINTF(2, 3);
#define BSURF_REQUIRE(cond, ...) BSURF_REQUIRE_IN(__func__, cond, __VA_ARGS__)
/* The same in a check shared by several functions: `what` names the
 * argument checked ("error options", "mesh") instead of the helper. */
#define BSURF_REQUIRE_IN(what, cond, ...)                                                          \
  do {                                                                                             \
    if (!(cond)) return bsurf_invalid(what, __VA_ARGS__);                                          \
  } while (0)
/* Sets the calling thread's last message (printf-style) to any status's
 * explanation; returns `status`. */
bsurf_status bsurf_set_message(bsurf_status status, const char *fmt, ...) BSURF_PRINTF(2, 3);

/* Fills an optional error record (printf-style message). Returns `status`. */
bsurf_status bsurf_fail(bsurf_failure *err, bsurf_status status, long line, long long byte,
                        const char *fmt, ...) BSURF_PRINTF(5, 6);

/* A set of names (pointer and length, not copied: they must outlive the set)
 * with a value each; lookups in constant expected time (nameset.c). */
typedef struct bsurf_nameset_slot {
  const char *name;
  size_t len, value;
} bsurf_nameset_slot;
typedef struct bsurf_nameset {
  bsurf_nameset_slot *slots;
  size_t cap, n;
} bsurf_nameset;
#define BSURF_NAMESET_NONE ((size_t)-1)
#define BSURF_NAMESET_FULL ((size_t)-2)
/* Room for `expected` names. */
bsurf_status bsurf_nameset_init(bsurf_nameset *set, size_t expected);
void bsurf_nameset_free(bsurf_nameset *set);
/* The value of `name`, or BSURF_NAMESET_NONE. */
size_t bsurf_nameset_find(const bsurf_nameset *set, const char *name, size_t len);
/* Adds `name` with `value` and returns BSURF_NAMESET_NONE; when the name is
 * there already, returns its value and changes nothing (BSURF_NAMESET_FULL:
 * more names than init was told). */
size_t bsurf_nameset_insert(bsurf_nameset *set, const char *name, size_t len, size_t value);

/* Adds `count` fields at once (zero-filled, names[i] with types[i]; a name
 * the cloud has already keeps its values and takes the type, as
 * bsurf_cloud_add_field): one allocation of the field array and a name set,
 * so time linear in the number of fields. BSURF_ERR_INVALID_ARG for a name
 * of BSURF_FIELD_NAME_MAX characters or more; BSURF_ERR_NOMEM. */
bsurf_status bsurf_cloud_add_fields(bsurf_cloud *cloud, size_t count, const char *const *names,
                                    const bsurf_type *types);

/* A file written under a temporary name next to its target and renamed
 * over it only when complete (atomic_file.c). */
typedef struct bsurf_atomic_file {
  FILE *f;   /* write here (1 MiB buffer) */
  char *tmp; /* NULL when direct */
  const char *path;
  char *iobuf;
  char *target; /* `path` with every symbolic link followed */
  int direct;   /* a FIFO or device, written as it is (not atomic) */
} bsurf_atomic_file;

/* Creates and opens the temporary file for `path` (beside the target of a
 * symbolic link; a FIFO or device is opened directly), removing first the
 * temporaries that dead processes left in that directory. */
bsurf_status bsurf_atomic_open(bsurf_atomic_file *af, const char *path, bsurf_failure *err);
/* Finishes: with status == BSURF_OK and write_errno == 0 (no write error seen
 * by the caller) flushes, fsyncs, closes and renames over the target;
 * otherwise, or if any of that fails, closes and removes the temporary.
 * Returns `status` if it was an error, else the outcome (err filled). */
bsurf_status bsurf_atomic_close(bsurf_atomic_file *af, bsurf_status status, int write_errno,
                                bsurf_failure *err);

/* Number of points processed between two progress callbacks; also the unit
 * of cancellation: 4096 points of `error` with the defaults (K 50, B 50) take
 * about 0.25-0.5 s on two busy cores, so Ctrl-C (the CLI's handler, the
 * Python package's KeyboardInterrupt) is answered within a second. Heavier
 * settings take proportionally fewer points a chunk (bsurf_progress_chunk).
 * Results never depend on it (each point's work is its own). */
#define BSURF_PROGRESS_CHUNK 4096

/* The work of one point of that reference job, in the unit of
 * bsurf_progress_chunk: K x (B + 1) x the cubic's 10 terms. */
#define BSURF_PROGRESS_REF_WORK (50.0 * 51.0 * 10.0)

/* Points a chunk for a loop whose points cost `work` units each (neighbours
 * x (replicates + 1) x fitted terms, summed over the candidates a point
 * assesses): BSURF_PROGRESS_CHUNK up to BSURF_PROGRESS_REF_WORK, then
 * proportionally fewer, at least 16, so that a chunk takes about as long
 * whatever the settings (`error -B 1000`: 205 points). A function of the
 * settings only, never of timing: the progress calls stay the same from
 * run to run and for any thread count. */
size_t bsurf_progress_chunk(double work);

/* Work on point i by thread `thread` (0 .. threads-1). */
typedef void (*bsurf_point_fn)(void *ctx, int thread, size_t i);

/* Runs fn for every point 0..n-1 with bsurf_threads_resolve(threads) threads
 * (see parallel.c), calling progress after every BSURF_PROGRESS_CHUNK points. */
bsurf_status bsurf_parallel_points(size_t n, int threads, bsurf_point_fn fn, void *ctx,
                                   bsurf_progress_fn progress, void *progress_user);
/* The same with progress after every `chunk` points (bsurf_progress_chunk). */
bsurf_status bsurf_parallel_points_chunk(size_t n, size_t chunk, int threads, bsurf_point_fn fn,
                                         void *ctx, bsurf_progress_fn progress,
                                         void *progress_user);

/* A progress callback for a step reported within its caller's progress:
 * its own (d, t) goes to fn as (done + d span / t, total), and fn's answer
 * is returned. span 0 (a step that does not advance the caller's progress
 * but must stay cancellable, as the K selection's noise passes) reports
 * the fixed position (done, total) whatever it is told; span = t maps the
 * step's count one to one. user: a bsurf_progress_hold. */
typedef struct bsurf_progress_hold {
  bsurf_progress_fn fn;
  void *user;
  size_t done, total;
  size_t span; /* 0: held at done */
} bsurf_progress_hold;
int bsurf_progress_hold_cb(void *user, size_t done, size_t total);

/* The same, visiting point order[r] at step r (order: a permutation of
 * 0..n-1, e.g. bsurf_spatial_order's; NULL = index order). Progress counts
 * steps. */
bsurf_status bsurf_parallel_points_ordered(size_t n, const uint32_t *order, int threads,
                                           bsurf_point_fn fn, void *ctx, bsurf_progress_fn progress,
                                           void *progress_user);

/* The same in one parallel region, without progress or cancellation: for
 * short sweeps repeated many times (the smoothing passes). */
bsurf_status bsurf_parallel_sweep(size_t n, int threads, bsurf_point_fn fn, void *ctx);
/* The same with OpenMP's dynamic chunks of `chunk` steps (512 above): for
 * steps that are blocks of points. */
bsurf_status bsurf_parallel_sweep_chunk(size_t n, int threads, int chunk, bsurf_point_fn fn,
                                        void *ctx);

/* n 32-bit draws of the stream: the low then the high half of each
 * bsurf_rng_next output in turn (an odd n drops the last high half). */
void bsurf_rng_fill_u32(bsurf_rng *rng, int n, uint32_t *u);

#endif
