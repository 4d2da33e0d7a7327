/* Status codes, their messages and error records; the allocation helpers. */
#if defined(__linux__) && !defined(_DEFAULT_SOURCE)
#define _DEFAULT_SOURCE /* madvise */
#endif
#include "common/common.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(__linux__)
#include <sys/mman.h>
#endif

const char *bsurf_strerror(bsurf_status status) {
  switch (status) {
  case BSURF_OK: return "success";
  case BSURF_ERR_NOMEM: return "out of memory";
  case BSURF_ERR_IO: return "input/output error";
  case BSURF_ERR_PARSE: return "malformed file";
  case BSURF_ERR_UNSUPPORTED: return "unsupported file feature";
  case BSURF_ERR_INVALID_ARG: return "invalid argument";
  case BSURF_ERR_TOO_FEW_POINTS: return "too few points";
  case BSURF_ERR_NO_NORMALS: return "the input has no normals";
  case BSURF_ERR_INVALID_VALUE: return "NaN or infinite value";
  case BSURF_ERR_RANK_DEFICIENT: return "rank-deficient least-squares system";
  case BSURF_ERR_CANCELLED: return "cancelled";
  }
  return "unknown status";
}

/* The message of the last failed call on each thread (bsurf_last_message):
 * thread-local, so concurrent calls on other threads never overwrite it. */
static _Thread_local char last_message[512];

const char *bsurf_last_message(void) {
  return last_message;
}

bsurf_status bsurf_set_message(bsurf_status status, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(last_message, sizeof last_message, fmt, ap);
  va_end(ap);
  return status;
}

bsurf_status bsurf_invalid(const char *func, const char *fmt, ...) {
  int n = snprintf(last_message, sizeof last_message, "%s: ", func);
  if (n < 0 || (size_t)n >= sizeof last_message) return BSURF_ERR_INVALID_ARG;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(last_message + n, sizeof last_message - (size_t)n, fmt, ap);
  va_end(ap);
  return BSURF_ERR_INVALID_ARG;
}

bsurf_status bsurf_fail(bsurf_failure *err, bsurf_status status, long line, long long byte,
                        const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(last_message, sizeof last_message, fmt, ap);
  va_end(ap);
  if (err) {
    err->line = line;
    err->byte = byte;
    size_t len = strlen(last_message);
    if (len >= sizeof err->message) len = sizeof err->message - 1;
    memcpy(err->message, last_message, len);
    err->message[len] = '\0';
  }
  return status;
}

/* Large arrays (a million points' coordinates, neighbour lists, outputs,
 * file buffers) in transparent huge pages where the kernel offers them on
 * request (THP "madvise" mode, Debian's default): each first touch of a 4 KiB
 * page is a page fault, and under a hypervisor a costly one (about a tenth of
 * a `normals -k 30 -B 0` run at 200k points was page faults, perf); one 2 MiB
 * page takes 512 of them, and fewer TLB misses follow. Arrays from HUGE_MIN
 * bytes are placed on a 2 MiB boundary and the whole 2 MiB pages inside them
 * marked MADV_HUGEPAGE (a hint: ignored where not supported). */
#define HUGE_PAGE ((size_t)2 << 20)
#define HUGE_MIN ((size_t)4 << 20)

static void *huge_hint(void *p, size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (p && bytes >= HUGE_MIN) {
    const uintptr_t a = ((uintptr_t)p + HUGE_PAGE - 1) & ~(uintptr_t)(HUGE_PAGE - 1);
    const uintptr_t e = ((uintptr_t)p + bytes) & ~(uintptr_t)(HUGE_PAGE - 1);
    if (e > a) (void)madvise((void *)a, e - a, MADV_HUGEPAGE);
  }
#else
  (void)bytes;
#endif
  return p;
}

void *bsurf_alloc_array(size_t n, size_t size) {
  if (n == 0 || size == 0 || n > (size_t)-1 / size) return NULL;
  const size_t bytes = n * size;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (bytes >= HUGE_MIN && bytes <= (size_t)-1 - HUGE_PAGE)
    return huge_hint(aligned_alloc(HUGE_PAGE, (bytes + HUGE_PAGE - 1) / HUGE_PAGE * HUGE_PAGE),
                     bytes);
#endif
  return malloc(bytes);
}

void *bsurf_alloc_aligned(size_t n, size_t size) {
  if (n == 0 || size == 0 || n > ((size_t)-1 - 63) / size) return NULL;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (n * size >= HUGE_MIN) return bsurf_alloc_array(n, size); /* 2 MiB is a multiple of 64 */
#endif
  return aligned_alloc(64, (n * size + 63) / 64 * 64); /* C11: a multiple of the alignment */
}

void *bsurf_calloc_array(size_t n, size_t size) {
  if (n == 0 || size == 0 || n > (size_t)-1 / size) return NULL;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (n * size >= HUGE_MIN) { /* whole huge pages (a calloc's unaligned ends were 4 KiB pages) */
    void *p = bsurf_alloc_array(n, size);
    if (p) memset(p, 0, n * size);
    return p;
  }
#endif
  return calloc(n, size);
}

int bsurf_threads_resolve(int threads) {
#ifdef _OPENMP
  /* 0: OMP_NUM_THREADS when it is set (the OpenMP convention, e.g. a batch
   * system's share of the machine), else every core */
  if (threads <= 0) {
    const char *env = getenv("OMP_NUM_THREADS");
    return env && *env ? omp_get_max_threads() : omp_get_num_procs();
  }
  return threads;
#else
  (void)threads;
  return 1;
#endif
}

unsigned bsurf_version(void) {
  return (unsigned)BSURF_VERSION_NUMBER;
}

const char *bsurf_version_string(void) {
  return BSURF_VERSION_STRING;
}
