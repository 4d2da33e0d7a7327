/* Status codes, their messages and error records. */
#include "common/common.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

void *bsurf_alloc_array(size_t n, size_t size) {
  if (n == 0 || size == 0 || n > (size_t)-1 / size) return NULL;
  return malloc(n * size);
}

void *bsurf_alloc_aligned(size_t n, size_t size) {
  if (n == 0 || size == 0 || n > ((size_t)-1 - 63) / size) return NULL;
  return aligned_alloc(64, (n * size + 63) / 64 * 64); /* C11: a multiple of the alignment */
}

void *bsurf_calloc_array(size_t n, size_t size) {
  if (n == 0 || size == 0 || n > (size_t)-1 / size) return NULL;
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
