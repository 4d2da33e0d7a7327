/* PNG output through libpng: 8-bit RGB, no time stamp or text chunks (same
 * image, same bytes), written to a temporary file that is renamed at the end
 * like every other output (src/io/io.c). */
#include "common/common.h"

#include <errno.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static void png_error_fn(png_structp png, png_const_charp msg) {
  char *buf = png_get_error_ptr(png);
  if (buf) snprintf(buf, 200, "%s", msg);
  png_longjmp(png, 1);
}
static void png_warning_fn(png_structp png, png_const_charp msg) {
  (void)png;
  (void)msg;
}

/* Everything libpng touches across its longjmp lives in this struct. */
typedef struct {
  FILE *f;
  const uint8_t *rgb;
  int width, height;
  char message[200];
} png_job;

static int encode(png_job *job) {
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, job->message, png_error_fn, png_warning_fn);
  if (!png) return -1;
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, NULL);
    return -1;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return -1;
  }
  png_init_io(png, job->f);
  png_set_IHDR(png, info, (png_uint_32)job->width, (png_uint_32)job->height, 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, 6);
  png_write_info(png, info);
  for (int y = 0; y < job->height; y++)
    png_write_row(png, (png_const_bytep)(job->rgb + (size_t)y * (size_t)job->width * 3));
  png_write_end(png, NULL);
  png_destroy_write_struct(&png, &info);
  return 0;
}

bsurf_status bsurf_write_png(const char *path, const uint8_t *rgb, int width, int height,
                             bsurf_failure *err) {
  if (err) {
    err->line = 0;
    err->byte = -1;
    err->message[0] = 0;
  }
  if (!path || !rgb || width < 1 || height < 1)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "no path or no image given");
  bsurf_atomic_file af;
  bsurf_status st = bsurf_atomic_open(&af, path, err);
  if (st != BSURF_OK) return st;
  png_job job;
  memset(&job, 0, sizeof job);
  job.f = af.f;
  job.rgb = rgb;
  job.width = width;
  job.height = height;
  if (encode(&job) != 0)
    st = job.message[0] ? bsurf_fail(err, BSURF_ERR_IO, 0, -1, "PNG: %s", job.message)
                        : bsurf_fail(err, BSURF_ERR_IO, 0, -1, "PNG encoding failed");
  return bsurf_atomic_close(&af, st, 0, err);
}
