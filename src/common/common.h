/* Internal helpers shared by every layer: allocation, error records, OpenMP. */
#ifndef BSURF_COMMON_H
#define BSURF_COMMON_H

#include "bootsurf.h"

#include <stdarg.h>
#include <stddef.h>

#ifdef _OPENMP
#include <omp.h>
#endif

/* malloc of n * size bytes with an overflow check; NULL on failure or n == 0. */
void *bsurf_alloc_array(size_t n, size_t size);
void *bsurf_calloc_array(size_t n, size_t size);

/* Fills an optional error record (printf-style message). Returns `status`. */
bsurf_status bsurf_fail(bsurf_error *err, bsurf_status status, long line,
                        long long byte, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/* Number of points processed between two progress callbacks; also the unit
 * of cancellation. */
#define BSURF_PROGRESS_CHUNK 16384

#endif
