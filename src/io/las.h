/* The LAS reader's and writer's shared tables (las_attrs.c): header sizes,
 * record sizes and the standard attributes of the point formats; private to
 * src/io/las_*.c. */
#ifndef BSURF_IO_LAS_H
#define BSURF_IO_LAS_H

#include "io/io.h"

#define LAS_HEADER_12 227
#define LAS_HEADER_13 235
#define LAS_HEADER_14 375
#define LAS_VLR_HEADER 54
#define LAS_EVLR_HEADER 60
#define LAS_EB_SIZE 192
#define LAS_NAME_MAX 32

/* Bytes of a point record of formats 0-10, without extra bytes. */
extern const size_t io_las_record_size[11];

/* ---- the standard attributes ---- */
enum {
  A_INTENSITY,
  A_RETURN,
  A_NRETURNS,
  A_SYNTHETIC,
  A_KEYPOINT,
  A_WITHHELD,
  A_OVERLAP,
  A_CHANNEL,
  A_SCANDIR,
  A_EDGE,
  A_CLASS,
  A_USERDATA,
  A_ANGLE_RANK,
  A_ANGLE,
  A_SOURCE,
  A_GPS,
  A_RED,
  A_GREEN,
  A_BLUE,
  A_NIR,
  A_WP_INDEX,
  A_WP_OFFSET,
  A_WP_SIZE,
  A_WP_LOCATION,
  A_WP_XT,
  A_WP_YT,
  A_WP_ZT,
  A_COUNT
};

typedef struct io_las_attr_info {
  const char *name; /* the field's name */
  bsurf_type type;  /* the field's type */
} io_las_attr_info;
extern const io_las_attr_info io_las_attr[A_COUNT];

/* Which attributes format f has. */
int io_las_has_attr(int f, int a);

#endif
