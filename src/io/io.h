/* Internal interface of the file layer: the per-format readers and writers
 * and the helpers they share (bounded text scanning, number parsing, type
 * conversion, triangle lists, checked output). Nothing here is public API.
 *
 * Every reader works on a buffer that is NOT NUL-terminated (fuzzers pass
 * arbitrary bytes): nothing may read past data + size. */
#ifndef BSURF_IO_H
#define BSURF_IO_H

#include "common/common.h"

#include <stdio.h>

/* The library exports no unprefixed global symbol (a program linking the
 * static library may have its own io_*): the short names below stay in the
 * sources and the linker sees them as bsurf_i_io_*. A new non-static io_
 * function gets its line here (tests/cli/library.sh checks the archive). */
#define io_count_tokens bsurf_i_io_count_tokens
#define io_i64_exact bsurf_i_io_i64_exact
#define io_las_attr bsurf_i_io_las_attr
#define io_las_has_attr bsurf_i_io_las_has_attr
#define io_nomem bsurf_i_io_nomem
#define io_pcd_parse_header bsurf_i_io_pcd_parse_header
#define io_las_record_size bsurf_i_io_las_record_size
#define io_le16 bsurf_i_io_le16
#define io_le32 bsurf_i_io_le32
#define io_le64 bsurf_i_io_le64
#define io_le_f32 bsurf_i_io_le_f32
#define io_le_f64 bsurf_i_io_le_f64
#define io_le_value bsurf_i_io_le_value
#define io_ply_elem_plural bsurf_i_io_ply_elem_plural
#define io_ply_elem_word bsurf_i_io_ply_elem_word
#define io_ply_nomem bsurf_i_io_ply_nomem
#define io_ply_parse_header bsurf_i_io_ply_parse_header
#define io_ply_setup bsurf_i_io_ply_setup
#define io_ply_shape_name_ok bsurf_i_io_ply_shape_name_ok
#define io_ply_too_short bsurf_i_io_ply_too_short
#define io_ply_probe bsurf_i_io_ply_probe
#define io_put_le bsurf_i_io_put_le
#define io_put_le_bytes bsurf_i_io_put_le_bytes
#define io_u64_exact bsurf_i_io_u64_exact
#define io_names_init bsurf_i_io_names_init
#define io_names_add bsurf_i_io_names_add
#define io_names_find bsurf_i_io_names_find
#define io_names_commit bsurf_i_io_names_commit
#define io_names_free bsurf_i_io_names_free
#define io_cursor_init bsurf_i_io_cursor_init
#define io_dvec_push bsurf_i_io_dvec_push
#define io_dvec_take bsurf_i_io_dvec_take
#define io_faces_begin bsurf_i_io_faces_begin
#define io_faces_corner bsurf_i_io_faces_corner
#define io_faces_free bsurf_i_io_faces_free
#define io_faces_init bsurf_i_io_faces_init
#define io_faces_move bsurf_i_io_faces_move
#define io_format_value bsurf_i_io_format_value
#define io_next_token bsurf_i_io_next_token
#define io_obuf_char bsurf_i_io_obuf_char
#define io_obuf_done bsurf_i_io_obuf_done
#define io_obuf_flush bsurf_i_io_obuf_flush
#define io_obuf_init bsurf_i_io_obuf_init
#define io_obuf_point bsurf_i_io_obuf_point
#define io_obuf_str bsurf_i_io_obuf_str
#define io_obuf_uint bsurf_i_io_obuf_uint
#define io_obuf_value bsurf_i_io_obuf_value
#define io_parse_double bsurf_i_io_parse_double
#define io_parse_u64 bsurf_i_io_parse_u64
#define io_ply_decode bsurf_i_io_ply_decode
#define io_ply_encode bsurf_i_io_ply_encode
#define io_ply_layout_free bsurf_i_io_ply_layout_free
#define io_ply_map bsurf_i_io_ply_map
#define io_ply_write_header bsurf_i_io_ply_write_header
#define io_ply_xyz bsurf_i_io_ply_xyz
#define io_strip_comment bsurf_i_io_strip_comment
#define io_text_init bsurf_i_io_text_init
#define io_text_next_line bsurf_i_io_text_next_line
#define io_token_is bsurf_i_io_token_is
#define io_token_repr bsurf_i_io_token_repr
#define io_type_convert bsurf_i_io_type_convert
#define io_type_is_integer bsurf_i_io_type_is_integer
#define io_type_name bsurf_i_io_type_name
#define io_type_parse bsurf_i_io_type_parse
#define io_type_size bsurf_i_io_type_size
#define io_write_bytes bsurf_i_io_write_bytes
#define io_write_fmt bsurf_i_io_write_fmt
#define io_write_str bsurf_i_io_write_str

/* ---- bounded text scanning ---------------------------------------------- */

typedef struct io_text {
  const char *data;
  size_t size;
  size_t pos; /* offset of the next unread byte */
  long line;  /* 1-based number of the line last returned (0 before any) */
} io_text;

void io_text_init(io_text *t, const char *data, size_t size);
/* The next line without its '\n' (and without a trailing '\r'). Returns 0 at
 * the end of the data. */
int io_text_next_line(io_text *t, const char **line, size_t *len);

typedef struct io_token {
  const char *s;
  size_t len;
} io_token;

/* Token separators. */
enum { IO_SEP_SPACE = 0, IO_SEP_XYZ = 1 /* whitespace, ',' and ';' */ };

typedef struct io_cursor {
  const char *p;
  const char *end;
  int seps;
} io_cursor;

void io_cursor_init(io_cursor *c, const char *s, size_t len, int seps);
/* The next token; 0 when the line has no more. */
int io_next_token(io_cursor *c, io_token *tok);
/* Number of tokens left (does not move the cursor). */
size_t io_count_tokens(const io_cursor *c);
/* 1 if the token equals the NUL-terminated word. */
int io_token_is(io_token tok, const char *word);
/* A printable, shortened copy of a token for messages (out: 48 bytes). */
const char *io_token_repr(io_token tok, char out[48]);
/* Removes a '#' comment: returns the length of the part before it. */
size_t io_strip_comment(const char *line, size_t len);

/* ---- numbers ---------------------------------------------------------------- */

/* Parses a whole token as a double (decimal, exponent, inf, nan; correctly
 * rounded, independent of the C locale). Returns 1 on success. */
int io_parse_double(const char *s, size_t len, double *out);
/* Parses a whole token as an unsigned decimal integer. Returns 1 on success. */
int io_parse_u64(const char *s, size_t len, unsigned long long *out);

/* ---- value types ------------------------------------------------------------ */

size_t io_type_size(bsurf_type type);
/* The PLY 1.0 name (char uchar short ushort int uint float double). */
const char *io_type_name(bsurf_type type);
/* Accepts the PLY 1.0 names and the int8 ... float64 aliases. */
int io_type_parse(const char *s, size_t len, bsurf_type *type);
int io_type_is_integer(bsurf_type type);
/* The value a file of `type` stores for v: integers are rounded to nearest
 * (halves away from zero) and clamped to the type's range (NaN -> 0);
 * FLOAT32 is converted to float. */
double io_type_convert(double v, bsurf_type type);
/* Formats v as stored in `type`: FLOAT64 %.17g, FLOAT32 %.9g of the float,
 * integers exactly. Always uses '.' as decimal point. Returns the length. */
size_t io_format_value(char *buf, size_t cap, double v, bsurf_type type);

/* ---- triangle lists ------------------------------------------------------- */

typedef struct io_faces {
  uint32_t *tri; /* count x 3 */
  size_t count;
  size_t cap;
  /* streaming fan triangulation of the current polygon */
  uint32_t first, prev;
  size_t corners;
} io_faces;

void io_faces_init(io_faces *f);
void io_faces_free(io_faces *f);
/* Starts a polygon; then every io_faces_corner() adds one corner, emitting
 * the triangle (first, previous, this) from the third corner on. Polygons
 * with fewer than 3 corners thus add nothing. */
void io_faces_begin(io_faces *f);
bsurf_status io_faces_corner(io_faces *f, uint32_t index);
/* Moves the triangles into the cloud (shrinking the array). */
void io_faces_move(io_faces *f, bsurf_cloud *cloud);

/* "out of memory" in *err; returns BSURF_ERR_NOMEM. */
bsurf_status io_nomem(bsurf_failure *err);

/* ---- growable arrays of doubles ---------------------------------------------- */

typedef struct io_dvec {
  double *v;
  size_t n, cap;
} io_dvec;

bsurf_status io_dvec_push(io_dvec *d, const double *values, size_t count);
/* Shrinks to n and hands the array over (NULL when empty). */
double *io_dvec_take(io_dvec *d);

/* ---- checked output ------------------------------------------------------- */

typedef struct io_writer {
  FILE *f;
  int failed; /* set by the first failed write */
  int err_no; /* errno of that failure */
} io_writer;

void io_write_bytes(io_writer *w, const void *p, size_t n);
void io_write_str(io_writer *w, const char *s);
void io_write_fmt(io_writer *w, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Buffered text output on top of an io_writer (text writers format values
 * straight into it; one fwrite per ~64 KiB). */
typedef struct io_obuf {
  io_writer *w;
  char *buf;
  size_t n, cap;
} io_obuf;

bsurf_status io_obuf_init(io_obuf *b, io_writer *w);
void io_obuf_flush(io_obuf *b);
/* Flushes and frees the buffer. */
void io_obuf_done(io_obuf *b);
void io_obuf_str(io_obuf *b, const char *s);
void io_obuf_char(io_obuf *b, char c);
/* One value formatted as io_format_value does. */
void io_obuf_value(io_obuf *b, double v, bsurf_type type);
/* Point i's x y z (and nx ny nz when the cloud has normals), exactly (17
 * digits), separated by sep; no line break. */
void io_obuf_point(io_obuf *b, const bsurf_cloud *cloud, size_t i, char sep);
void io_obuf_uint(io_obuf *b, unsigned long long v);

/* ---- readers: fill an initialised cloud; on failure may leave it partly
 * filled (the caller frees it) and fill err -------------------------------- */

typedef bsurf_status bsurf_io_reader(const char *data, size_t size, bsurf_cloud *cloud,
                                     bsurf_failure *err);
/* .xyz/.txt/.pts and .csv/.asc: one reader, bsurf_io_read_xyz (a header
 * line naming the columns is used when present). */
bsurf_io_reader bsurf_io_read_ply, bsurf_io_read_off, bsurf_io_read_obj, bsurf_io_read_xyz,
    bsurf_io_read_pcd, bsurf_io_read_las;

/* ---- shared by the binary readers ----------------------------------------- */

/* Little-endian loads from unaligned bytes. */
uint16_t io_le16(const unsigned char *p);
uint32_t io_le32(const unsigned char *p);
uint64_t io_le64(const unsigned char *p);
double io_le_f64(const unsigned char *p);
float io_le_f32(const unsigned char *p);
/* The value of `type` stored little-endian at p. */
double io_le_value(const unsigned char *p, bsurf_type type);
/* Stores v as `type` little-endian (rounded and clamped as io_type_convert);
 * returns p + the type's size. */
unsigned char *io_put_le(unsigned char *p, double v, bsurf_type type);
/* The n low bytes of u, least significant first; returns p + n. */
unsigned char *io_put_le_bytes(unsigned char *p, uint64_t u, size_t n);
/* A 64-bit integer as a double, or 0 when a double cannot hold it exactly
 * (beyond 2^53): *ok is cleared then. */
double io_i64_exact(int64_t v, int *ok);
double io_u64_exact(uint64_t v, int *ok);
/* The fields a reader adds, named and added in time linear in their number
 * (binary.c): a name set of the cloud's names and the new ones, and one
 * bsurf_cloud_add_fields at the end. io_names_init: room for cap names;
 * io_names_add: `name` made unique ("name_1", "name_2", ..., shortened to
 * fit), returns the index its field will have in the cloud
 * (BSURF_NAMESET_FULL: more than cap); io_names_find: the index of a name
 * (the cloud's or added) or BSURF_NAMESET_NONE; io_names_commit adds the
 * fields (zero-filled) and frees the set, as io_names_free does. */
typedef struct io_names {
  bsurf_nameset set;
  char *buf; /* cap names of BSURF_FIELD_NAME_MAX bytes */
  const char **names;
  bsurf_type *types;
  size_t n, cap, base; /* base: the cloud's field count at init */
} io_names;
bsurf_status io_names_init(io_names *b, const bsurf_cloud *cloud, size_t cap);
size_t io_names_add(io_names *b, const char *name, bsurf_type type);
size_t io_names_find(const io_names *b, const char *name);
bsurf_status io_names_commit(io_names *b, bsurf_cloud *cloud);
void io_names_free(io_names *b);

/* ---- binary PLY by offset (the tiled runs of src/tile) ------------------ */

/* One vertex property: where it is in a record and where it goes in a cloud
 * with the schema's arrays (array 0: xyz, 1: normals, 2: field `at`, 3:
 * nowhere). */
typedef struct io_ply_column {
  size_t offset;
  bsurf_type type;
  size_t stride;
  int array;
  size_t at;
} io_ply_column;

typedef struct io_ply_layout {
  size_t body;   /* offset of vertex 0 */
  size_t record; /* bytes per vertex */
  size_t count;  /* vertices */
  int big_endian;
  size_t nprops;
  io_ply_column *props;
} io_ply_layout;

/* Checks a PLY header as bsurf_io_read_ply does before reading any value
 * (syntax, the vertex layout, every declared count against the bytes that
 * follow: binary exactly, ascii at two bytes per value) without the data:
 * `data` holds the first `size` bytes of a file of `file_size` bytes, the
 * whole header among them. *vertices: the declared vertex count;
 * *ascii_short: the error is ascii data too short for the header (reading it
 * all, as bsurf_io_read_ply does, finds the line). */
bsurf_status io_ply_probe(const char *data, size_t size, unsigned long long file_size,
                          unsigned long long *vertices, int *ascii_short, bsurf_failure *err);
/* Validates a whole binary PLY file (little- or big-endian) exactly as
 * bsurf_io_read_ply does, with the same messages, but stores no vertex: it
 * locates them (layout) and fills `schema`, a one-point cloud (point 0) with
 * the properties, types and shape bsurf_io_read_ply would give. ascii files
 * and meshes (faces) are BSURF_ERR_UNSUPPORTED. */
bsurf_status io_ply_map(const char *data, size_t size, io_ply_layout *layout, bsurf_cloud *schema,
                        bsurf_failure *err);
void io_ply_layout_free(io_ply_layout *layout);
/* Vertex i of the mapped file into point j of c (a cloud with the schema's
 * properties). */
void io_ply_decode(const io_ply_layout *layout, const char *data, size_t i, bsurf_cloud *c,
                   size_t j);
/* x y z of vertex i. */
void io_ply_xyz(const io_ply_layout *layout, const char *data, size_t i, double p[3]);
/* The header bsurf_io_write_ply (binary) writes for a cloud with `schema`'s
 * properties and point_count points, and its record size. */
bsurf_status io_ply_write_header(io_writer *w, const bsurf_cloud *schema, size_t point_count,
                                 size_t *record);
/* The binary records of every point of `cloud`, as bsurf_io_write_ply. */
bsurf_status io_ply_encode(const bsurf_cloud *cloud, unsigned char *out);

/* ---- writers: the cloud has been validated (faces in range, arrays present);
 * write errors are recorded in w and reported by the caller ---------------- */

/* Checks that the fields can be named in a PLY header. */
bsurf_status bsurf_io_ply_check(const bsurf_cloud *cloud, bsurf_failure *err);
/* names: the fields' names were made for a viewer (write_view in io.c): a
 * header comment says so, and the reader takes them back. */
bsurf_status bsurf_io_write_ply(io_writer *w, const bsurf_cloud *cloud, int ascii,
                                bsurf_ply_names names, bsurf_failure *err);
bsurf_status bsurf_io_write_off(io_writer *w, const bsurf_cloud *cloud, bsurf_failure *err);
bsurf_status bsurf_io_write_obj(io_writer *w, const bsurf_cloud *cloud, bsurf_failure *err);
bsurf_status bsurf_io_write_xyz(io_writer *w, const bsurf_cloud *cloud, bsurf_failure *err);
/* A header line then comma-separated rows; cloudcompare: "//X,Y,Z,Nx,..." as
 * CloudCompare's ASCII export, else "x,y,z,nx,...". */
bsurf_status bsurf_io_write_csv(io_writer *w, const bsurf_cloud *cloud, int cloudcompare,
                                bsurf_failure *err);
bsurf_status bsurf_io_write_pcd(io_writer *w, const bsurf_cloud *cloud, int ascii,
                                bsurf_failure *err);
/* Checks before anything is written: finite coordinates, names that fit. */
bsurf_status bsurf_io_las_check(const bsurf_cloud *cloud, bsurf_failure *err);
/* legacy: LAS 1.2, point format 1 or 3 (else 1.4, 6-8) */
bsurf_status bsurf_io_write_las(io_writer *w, const bsurf_cloud *cloud, int legacy,
                                bsurf_failure *err);

#endif
