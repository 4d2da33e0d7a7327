/* The PCD reader's header (pcd_header.c parses it, pcd_read.c reads the data
 * it describes); private to src/io/pcd_*.c. */
#ifndef BSURF_IO_PCD_H
#define BSURF_IO_PCD_H

#include "io/io.h"

#define PCD_MAX_FIELDS 4096
#define PCD_MAX_COLUMNS 65536
#define PCD_MAX_COUNT_OUT 64 /* COUNT of a field written from name_0 .. name_63 */

typedef struct pcd_field {
  io_token name;
  size_t size;   /* bytes of one element: 1 2 4 8 */
  char kind;     /* 'I' 'U' 'F' */
  size_t count;  /* elements */
  size_t offset; /* in a binary record */
} pcd_field;

typedef struct pcd_header {
  pcd_field *fields;
  size_t nfields;
  unsigned long long width, height, points;
  int have_width, have_height, have_points, have_size, have_type;
  int data;       /* 0 ascii, 1 binary, 2 binary_compressed */
  size_t body;    /* offset of the first byte after the DATA line */
  long body_line; /* its line number */
  size_t record;  /* binary bytes per point */
  char shape[BSURF_FIELD_NAME_MAX];
} pcd_header;

/* Parses and checks the header: every keyword, the counts against each
 * other, POINTS x record against the bytes that follow (binary). */
bsurf_status io_pcd_parse_header(const char *data, size_t size, pcd_header *h, bsurf_failure *err);

#endif
