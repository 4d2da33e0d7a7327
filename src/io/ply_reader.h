/* The PLY reader's state, shared by its header parser (ply_header.c) and its
 * data readers (ply_read.c); private to src/io/ply_*.c. */
#ifndef BSURF_IO_PLY_READER_H
#define BSURF_IO_PLY_READER_H

#include "io/io.h"

enum { PLY_ASCII, PLY_LE, PLY_BE };
enum { ELEM_OTHER, ELEM_VERTEX, ELEM_FACE };

typedef struct ply_prop {
  io_token name;
  int is_list;
  bsurf_type type;       /* scalar type, or the type of a list's items */
  bsurf_type count_type; /* list only */
  long line;
  size_t offset; /* binary: offset inside a fixed-size record */
  double *dst;   /* vertex element: where the values go */
  size_t stride;
  int is_index; /* face element: the vertex index list */
  size_t field; /* vertex element: its field in the cloud, or (size_t)-1 */
} ply_prop;

typedef struct ply_elem {
  io_token name;
  unsigned long long count;
  long line;
  int kind;
  ply_prop *props;
  size_t nprops, cap;
  int has_list;
  size_t min_record; /* smallest record: binary bytes, or ascii values */
} ply_elem;

typedef struct ply_reader {
  const char *data;
  size_t size;
  int format;
  ply_elem *elems;
  size_t nelems, cap;
  size_t body;    /* offset of the first byte after the header */
  long body_line; /* number of the first line after the header */
  unsigned long long nv;
  io_faces faces;
  bsurf_failure *err;
  int dry;                          /* ascii data too short for the header: validate only */
  bsurf_failure dry_err;            /* the error to report if validation finds nothing */
  char shape[BSURF_FIELD_NAME_MAX]; /* from "comment bootsurf shape NAME" */
  io_ply_layout *layout;            /* io_ply_map: vertices are located, not stored */
  int probe;                        /* io_ply_probe: the header only, checked */
  int names;                        /* bsurf_ply_names from "comment bootsurf ply-names ..." */
} ply_reader;

/* "vertex", "face" or the element's own name, printable. */
const char *io_ply_elem_word(const ply_elem *e, char out[48]);
/* "vertices", "faces", "elements 'material'" */
const char *io_ply_elem_plural(const ply_elem *e, char out[64]);
bsurf_status io_ply_nomem(ply_reader *r);
/* A shape name a header line can carry: one printable word that fits. */
int io_ply_shape_name_ok(const char *s, size_t len);
/* Binary: the records of `e` starting at `offset` need more than the `left`
 * bytes that follow. */
bsurf_status io_ply_too_short(ply_reader *r, const ply_elem *e, unsigned long long offset,
                              unsigned long long left);
/* Parses the header into r->elems (r->body: the first byte after it). */
bsurf_status io_ply_parse_header(ply_reader *r);
/* Checks the layout, checks the declared counts against the data size and
 * allocates the cloud. */
bsurf_status io_ply_setup(ply_reader *r, bsurf_cloud *cloud);

#endif
