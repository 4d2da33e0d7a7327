/*
 * bootsurf.h — the public API of libbootsurf.
 *
 * bootsurf brings statistics to point-cloud processing: bootstrap test-error
 * estimates of local polynomial fits (thesis "Bootstrap Based Surface
 * Reconstruction", chapters 3-4), normals with a confidence value (chapter 5),
 * denoising (chapter 6) and feature detection (chapter 7).
 *
 * Conventions (see docs/architecture.md):
 *  - every fallible call returns a bsurf_status; bsurf_strerror() names it;
 *  - arrays are owned by the caller and come with explicit counts; shapes are
 *    written libigl-style, e.g. `xyz  in: point_count x 3` (row-major);
 *  - optional outputs may be NULL;
 *  - the library never prints and never exits; progress is reported through a
 *    callback that may also cancel the computation;
 *  - results depend only on the inputs and the seed, never on the thread count.
 *
 * Ownership and lifetimes (tests/test_api.c checks each rule):
 *  - A struct the library fills (bsurf_cloud, bsurf_neighbors, an index) is
 *    an OUT parameter: it is overwritten without being read, so it may be
 *    uninitialised. A cloud or neighbourhoods that already hold data must be
 *    freed first (bsurf_cloud_free, bsurf_neighbors_free), or their arrays
 *    leak; reading into a cloud that holds data is therefore `free, then
 *    read`. A failed read leaves the cloud empty (freeing it is harmless).
 *  - Every *_free accepts NULL and, for structs (cloud, neighbourhoods), may
 *    be called twice: the first call leaves an empty struct.
 *  - Arrays inside a cloud belong to the cloud. A field's `values` array
 *    stays at the same address until that field is removed or the cloud is
 *    freed: adding other fields never moves it. The bsurf_field pointer
 *    returned by bsurf_cloud_field/bsurf_cloud_add_field points into the
 *    cloud's table of fields and is valid only until the next add or remove
 *    (the table grows by realloc): keep `values`, or look the field up again.
 *  - Arrays passed in are only read and never kept, except where a function
 *    says so (bsurf_knn_build keeps `xyz`).
 *  - NULL for a required pointer, an unknown enum value, a NaN or
 *    out-of-range option and k larger than the neighbourhoods give
 *    BSURF_ERR_INVALID_ARG and a message (bsurf_last_message()); too few
 *    points for k gives BSURF_ERR_TOO_FEW_POINTS; NaN or infinite coordinates
 *    given to a neighbour search give BSURF_ERR_INVALID_VALUE. Zero counts are
 *    valid where a function can give a meaningful empty result (statistics,
 *    noise, rendering) and BSURF_ERR_TOO_FEW_POINTS where it cannot
 *    (neighbourhoods). Never a crash.
 */
#ifndef BOOTSURF_H
#define BOOTSURF_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The version of this header. CMakeLists.txt reads these three lines: they
 * are the project's version (project(), the shared library's VERSION; its
 * SONAME libbootsurf.so.MAJOR changes when the ABI does). */
#define BSURF_VERSION_MAJOR 0
#define BSURF_VERSION_MINOR 1
#define BSURF_VERSION_PATCH 0
#define BSURF_VERSION_STRING "0.1.0"
/* MAJOR * 10000 + MINOR * 100 + PATCH, as bsurf_version() returns it. */
#define BSURF_VERSION_NUMBER                                                                       \
  (BSURF_VERSION_MAJOR * 10000 + BSURF_VERSION_MINOR * 100 + BSURF_VERSION_PATCH)

/* Every function of this header is marked BSURF_API: the only symbols the
 * shared library exports (it is built with -fvisibility=hidden). */
#if defined(__GNUC__) && __GNUC__ >= 4
#define BSURF_API __attribute__((visibility("default")))
#else
#define BSURF_API
#endif

/* The library's version at run time (BSURF_VERSION_NUMBER of the header it
 * was built from), to compare with the header a program was compiled with. */
BSURF_API unsigned bsurf_version(void);
/* The same as "MAJOR.MINOR.PATCH" (static storage). */
BSURF_API const char *bsurf_version_string(void);

/* ------------------------------------------------------------------------ */
/* Status codes                                                              */
/* ------------------------------------------------------------------------ */

typedef enum bsurf_status {
  BSURF_OK = 0,
  BSURF_ERR_NOMEM,          /* an allocation failed */
  BSURF_ERR_IO,             /* a file could not be opened, read or written */
  BSURF_ERR_PARSE,          /* a file's content is malformed */
  BSURF_ERR_UNSUPPORTED,    /* a valid file uses a feature we do not read */
  BSURF_ERR_INVALID_ARG,    /* a parameter is out of range */
  BSURF_ERR_TOO_FEW_POINTS, /* fewer points than the computation needs */
  BSURF_ERR_NO_NORMALS,     /* the input has no normals but they are needed */
  BSURF_ERR_INVALID_VALUE,  /* NaN or infinite coordinates */
  BSURF_ERR_RANK_DEFICIENT, /* a least-squares system is singular */
  BSURF_ERR_CANCELLED       /* the progress callback asked to stop */
} bsurf_status;

/* A static, human-readable name of a status code. */
BSURF_API const char *bsurf_strerror(bsurf_status status);

/* What the last call that failed on the calling thread said was wrong, as
 * text a program can print: always set when a call returns
 * BSURF_ERR_INVALID_ARG ("bsurf_estimate_error: opts->k = 80 exceeds nb->k
 * = 50: K must be in [2, nb->k]" -- the function, the parameter, its value,
 * the allowed range) and when a reader or writer fails (the message of its
 * bsurf_failure); other failures may leave an earlier message. "" before any.
 * Thread-local: a failure on another thread never overwrites it. The string
 * stays valid until the thread's next failing call. */
BSURF_API const char *bsurf_last_message(void);

/* Where a reader or writer failed. `line` is 1-based (0 when unknown or for
 * binary data), `byte` the offset from the start of the file (-1 when unknown).
 * `message` says what is wrong in words a user understands. */
typedef struct bsurf_failure {
  long line;
  long long byte;
  char message[256];
} bsurf_failure;

/* Progress callback: `done` of `total` work items are finished. Called from
 * the calling thread only. Return non-zero to cancel (the call then returns
 * BSURF_ERR_CANCELLED and its outputs are unspecified). */
typedef int (*bsurf_progress_fn)(void *user, size_t done, size_t total);

/* ------------------------------------------------------------------------ */
/* Point clouds                                                              */
/* ------------------------------------------------------------------------ */

/* Storage type of a value in a file (PLY property types). In memory every
 * value is a double, which represents all of them exactly. */
typedef enum bsurf_type {
  BSURF_INT8 = 0,
  BSURF_UINT8,
  BSURF_INT16,
  BSURF_UINT16,
  BSURF_INT32,
  BSURF_UINT32,
  BSURF_FLOAT32,
  BSURF_FLOAT64
} bsurf_type;

#define BSURF_FIELD_NAME_MAX 64

/* A named per-point scalar (a PLY vertex property other than x y z nx ny nz). */
typedef struct bsurf_field {
  char name[BSURF_FIELD_NAME_MAX];
  bsurf_type type; /* type used when written to a file */
  double *values;  /* point_count */
} bsurf_field;

/* A point cloud, optionally with triangles (a mesh). All arrays are owned by
 * the cloud and released by bsurf_cloud_free(). */
typedef struct bsurf_cloud {
  size_t point_count;
  double *xyz;            /* point_count x 3 */
  double *normals;        /* point_count x 3, or NULL */
  bsurf_type xyz_type;    /* how x y z are written (default FLOAT64) */
  bsurf_type normal_type; /* how nx ny nz are written (default FLOAT32) */
  size_t field_count;
  bsurf_field *fields; /* field_count */
  size_t face_count;
  uint32_t *faces;                  /* face_count x 3 (polygons are fan-triangulated) */
  char shape[BSURF_FIELD_NAME_MAX]; /* the generated shape the points sample
                                       (bsurf_shape_name; set by bsurf_generate)
                                       or "": PLY keeps it as the header line
                                       "comment bootsurf shape NAME" */
} bsurf_cloud;

/* An empty cloud (all zero / NULL). */
BSURF_API void bsurf_cloud_init(bsurf_cloud *cloud);
/* Allocates xyz for n points (zeroed); normals when with_normals. */
BSURF_API bsurf_status bsurf_cloud_alloc(bsurf_cloud *cloud, size_t n, int with_normals);
BSURF_API void bsurf_cloud_free(bsurf_cloud *cloud);
/* Deep copy. */
BSURF_API bsurf_status bsurf_cloud_copy(bsurf_cloud *dst, const bsurf_cloud *src);
/* The field called `name`, or NULL. */
BSURF_API bsurf_field *bsurf_cloud_field(const bsurf_cloud *cloud, const char *name);
/* The field called `name`, created (zero-filled, with `type`) if missing; an
 * existing field keeps its values and takes `type`. NULL on allocation failure. */
BSURF_API bsurf_field *bsurf_cloud_add_field(bsurf_cloud *cloud, const char *name, bsurf_type type);
/* Removes the field called `name` if present. */
BSURF_API void bsurf_cloud_remove_field(bsurf_cloud *cloud, const char *name);
/* BSURF_OK if every coordinate (and normal) is finite; otherwise
 * BSURF_ERR_INVALID_VALUE and *bad_index (if not NULL) is the first bad point. */
BSURF_API bsurf_status bsurf_cloud_check_finite(const bsurf_cloud *cloud, size_t *bad_index);
/* The axis-aligned bounding box of point_count points (xyz: point_count x 3)
 * into lo and hi (either may be NULL; +inf and -inf when there are none);
 * returns the length of its diagonal (0 when there are none). */
BSURF_API double bsurf_bounding_box(const double *xyz, size_t point_count, double lo[3],
                                    double hi[3]);

/* ------------------------------------------------------------------------ */
/* Files                                                                     */
/* ------------------------------------------------------------------------ */

typedef enum bsurf_format {
  BSURF_FORMAT_UNKNOWN = 0,
  BSURF_FORMAT_PLY,
  BSURF_FORMAT_OFF,
  BSURF_FORMAT_OBJ,
  BSURF_FORMAT_XYZ, /* .xyz, .txt, .pts: x y z [nx ny nz] per line */
  BSURF_FORMAT_PCD, /* .pcd: PCL's point cloud data v0.7 */
  BSURF_FORMAT_LAS, /* .las: ASPRS LAS 1.0-1.4, point formats 0-10 */
  BSURF_FORMAT_CSV  /* .csv, .asc: text with a header line naming the columns */
} bsurf_format;

/* The format named by a path's extension (case-insensitive). */
BSURF_API bsurf_format bsurf_format_from_path(const char *path);
/* The format called `name` ("ply", "pcd", "las", "csv", "xyz", "off", "obj";
 * also "txt", "pts", "asc"), or BSURF_FORMAT_UNKNOWN. */
BSURF_API bsurf_format bsurf_format_from_name(const char *name);
/* The lower-case name of a format ("ply", ...; "" for UNKNOWN). */
BSURF_API const char *bsurf_format_name(bsurf_format format);
/* The format a file's first bytes declare: PLY ("ply"), PCD ("# .PCD" or a
 * "VERSION" line), LAS ("LASF"), OFF (a first word ending in "OFF"); else
 * BSURF_FORMAT_UNKNOWN (text formats have no signature). bsurf_read() trusts
 * it over the extension, so a missing or wrong extension still reads. */
BSURF_API bsurf_format bsurf_format_detect(const void *data, size_t size);

/* Reads a cloud or mesh; the format comes from the content when it declares
 * one (bsurf_format_detect), else from the extension, else (no extension)
 * text is read as CSV/XYZ and "v ..." lines as OBJ. "-" reads standard input.
 * `cloud` is an OUT parameter (overwritten, never freed: free a cloud holding
 * data first). On failure the cloud is left empty and `err` (optional) and
 * bsurf_last_message() say where and why. */
BSURF_API bsurf_status bsurf_read(const char *path, bsurf_cloud *cloud, bsurf_failure *err);
/* The same from a buffer already in memory (used by the fuzzers). */
BSURF_API bsurf_status bsurf_read_buffer(const void *data, size_t size, bsurf_format format,
                                         bsurf_cloud *cloud, bsurf_failure *err);

/* PLY property names for the fields (docs/formats.md): as they are, with
 * CloudCompare's "scalar_" prefix (which it loads and strips), or as they are
 * plus a float "quality" copy of the first field (MeshLab's one scalar). */
typedef enum bsurf_ply_names {
  BSURF_PLY_NAMES_PLAIN = 0,
  BSURF_PLY_NAMES_CLOUDCOMPARE,
  BSURF_PLY_NAMES_MESHLAB
} bsurf_ply_names;

/* Reads only the header of a file and checks it as bsurf_read would before
 * reading any value: for PLY the syntax, the vertex layout and every declared
 * count against the size of the file (binary: the smallest records must fit;
 * ascii: at least two bytes per value). Tools call it before estimating
 * resources from the declared counts. *points: the declared vertex count (0
 * for formats without a header count, which are not checked here). */
BSURF_API bsurf_status bsurf_read_header(const char *path, uint64_t *points, bsurf_failure *err);

/* The output-path policy of every writer (docs/robustness.md): BSURF_OK for
 * a new file, a writable regular file, a FIFO or a device (written directly,
 * not atomically); BSURF_ERR_INVALID_ARG with a message for a directory and,
 * unless `force`, for a file without write permission. Symbolic links are
 * followed (their target is written). */
BSURF_API bsurf_status bsurf_output_check(const char *path, int force, bsurf_failure *err);
/* 1 when `path` exists and is a FIFO, device or socket (written directly). */
BSURF_API int bsurf_output_is_stream(const char *path);
/* For a SIGINT/SIGTERM handler (both async-signal-safe):
 * bsurf_atomic_interrupt makes every write still open discard its temporary
 * file when it closes instead of renaming it into place;
 * bsurf_atomic_remove_temporaries removes the temporary files open now (the
 * handler then ends the process). */
BSURF_API void bsurf_atomic_interrupt(void);
BSURF_API void bsurf_atomic_remove_temporaries(void);

typedef struct bsurf_write_options {
  int ascii;           /* PLY, PCD: write ascii instead of binary little-endian */
  bsurf_format format; /* BSURF_FORMAT_UNKNOWN (0): from the path's extension */
  int float32;         /* float64 coordinates, normals and fields as float32 */
  bsurf_ply_names ply_names;
  int las_legacy; /* LAS 1.2 (point format 1 or 3) instead of 1.4 (6-8) */
} bsurf_write_options;

/* Writes a cloud; the format comes from opts->format, else the extension. The
 * data go to a temporary file in the same directory which is renamed to `path`
 * only when everything was written: a failed write leaves no partial file.
 * "-" writes standard output (opts->format required). `opts` may be NULL
 * (binary PLY). Formats that cannot carry every field (OFF, OBJ, XYZ) write
 * what they can; see bsurf_format_keeps_fields(). LAS: the header's creation
 * day and year are 0, or the UTC date of $SOURCE_DATE_EPOCH when it is set
 * (a malformed value: BSURF_ERR_INVALID_ARG, nothing written). */
BSURF_API bsurf_status bsurf_write(const char *path, const bsurf_cloud *cloud,
                                   const bsurf_write_options *opts, bsurf_failure *err);
/* 1 if the format stores named scalar fields (PLY, PCD, LAS, CSV). */
BSURF_API int bsurf_format_keeps_fields(bsurf_format format);

/* ------------------------------------------------------------------------ */
/* Neighbourhoods                                                            */
/* ------------------------------------------------------------------------ */

/* An exact k-d tree over a set of points (for the K-nearest-neighbour search). */
typedef struct bsurf_knn_index bsurf_knn_index;

/* Builds the index over `xyz` (point_count x 3), which must outlive it. */
BSURF_API bsurf_status bsurf_knn_build(bsurf_knn_index **index, const double *xyz,
                                       size_t point_count);
BSURF_API void bsurf_knn_free(bsurf_knn_index *index);

/* The k nearest indexed points of one query point, sorted by (squared
 * distance, index). `idx` out: k; `dist2` out: k, may be NULL. k must not
 * exceed the number of indexed points. */
BSURF_API bsurf_status bsurf_knn_query(const bsurf_knn_index *index, const double query[3], int k,
                                       uint32_t *idx, double *dist2);

/* All-K-nearest neighbours of the indexed points themselves: row i lists point
 * i first, then the k-1 nearest other points sorted by (squared distance,
 * index) — so duplicates of a point never displace the point itself.
 * `idx` out: point_count x k; `dist2` out: point_count x k (may be NULL).
 * threads: 0 = all cores. Parallel, deterministic for any thread count. */
BSURF_API bsurf_status bsurf_knn_all(const bsurf_knn_index *index, int k, int threads,
                                     uint32_t *idx, double *dist2, bsurf_progress_fn progress,
                                     void *progress_user);

/* Reference O(N^2 K) implementation of bsurf_knn_all (same order and ties),
 * used by the tests; only for small inputs. */
BSURF_API bsurf_status bsurf_knn_all_brute(const double *xyz, size_t point_count, int k,
                                           uint32_t *idx, double *dist2);

/* Neighbourhoods of every point, computed once and shared by every stage. */
typedef struct bsurf_neighbors {
  size_t point_count;
  int k;           /* neighbours per point, the point itself first */
  uint32_t *idx;   /* point_count x k */
  double h;        /* mean nearest-neighbour distance (the thesis's unit) */
  uint32_t *order; /* point_count: the points in k-d tree (spatially coherent)
                      order, in which per-point passes visit them for cache
                      locality; may be NULL (then a Morton order is made) */
} bsurf_neighbors;

/* Builds the neighbourhoods (kd-tree + all-kNN) and h. k >= 2. */
BSURF_API bsurf_status bsurf_neighbors_build(bsurf_neighbors *nb, const double *xyz,
                                             size_t point_count, int k, int threads,
                                             bsurf_progress_fn progress, void *progress_user);
BSURF_API void bsurf_neighbors_free(bsurf_neighbors *nb);

/* Mean distance from each point to its nearest other point (h). Builds its own
 * index; threads: 0 = all cores. Needs at least 2 points. */
BSURF_API bsurf_status bsurf_mean_spacing(const double *xyz, size_t point_count, int threads,
                                          double *h);
/* The same with a progress callback (which may cancel). */
BSURF_API bsurf_status bsurf_mean_spacing_progress(const double *xyz, size_t point_count,
                                                   int threads, double *h,
                                                   bsurf_progress_fn progress, void *progress_user);

/* ------------------------------------------------------------------------ */
/* Local analysis (thesis 3.3)                                               */
/* ------------------------------------------------------------------------ */

/* The local frame of a neighbourhood: rows of `rot` are X', Y', n (Eq. 3.4),
 * `origin` is the neighbourhood's point d_i; a point p has local coordinates
 * p' = rot (p - origin). eigenvalues are ascending (lambda0 <= lambda1 <= lambda2);
 * n is the eigenvector of lambda0, X' that of lambda2. */
typedef struct bsurf_frame {
  double origin[3];
  double rot[3][3];
  double eigenvalues[3];
} bsurf_frame;

typedef enum bsurf_pca_center {
  BSURF_PCA_CENTROID = 0, /* second moments about the centroid */
  BSURF_PCA_POINT         /* about the point itself (thesis Eq. 2.1) */
} bsurf_pca_center;

/* PCA frame of the k points xyz[idx[0..k-1]] centred at xyz[idx[0]]. */
BSURF_API void bsurf_local_frame(const double *xyz, const uint32_t *idx, int k,
                                 bsurf_pca_center center, bsurf_frame *frame);

/* Number of coefficients of a bivariate polynomial of total degree `degree`:
 * (degree+1)(degree+2)/2. */
BSURF_API int bsurf_poly_terms(int degree);

/* ------------------------------------------------------------------------ */
/* Bootstrap test-error estimation (thesis chapter 4)                         */
/* ------------------------------------------------------------------------ */

typedef enum bsurf_gamma_mode {
  BSURF_GAMMA_FIT = 0, /* gamma of the fit to the whole neighbourhood (Eq. 4.10) */
  BSURF_GAMMA_MEAN,    /* mean of the replicates' gammas (section 4.2.1) */
  BSURF_GAMMA_MAX      /* maximum of the replicates' gammas (section 4.2.1) */
} bsurf_gamma_mode;

typedef struct bsurf_error_options {
  int k;                       /* neighbourhood size K, the point included (50) */
  int degree;                  /* polynomial degree M, 1..4 (3) */
  int bootstrap;               /* replicates B (50) */
  uint64_t seed;               /* random seed (1) */
  bsurf_gamma_mode gamma;      /* no-information rate (FIT) */
  bsurf_pca_center pca_center; /* frame's PCA centre (CENTROID) */
  int threads;                 /* 0 = all cores */
  bsurf_progress_fn progress;
  void *progress_user;
  /* NULL, or point_count global indices: row i of the neighbourhoods is the
   * point point_index[i] of a larger cloud, and its random draws are keyed by
   * that index instead of i (tiled and distributed runs, bsurf_tiles_run:
   * the same draws as the whole cloud in memory). */
  const uint64_t *point_index;
} bsurf_error_options;

BSURF_API bsurf_error_options bsurf_error_options_default(void);

/* Per-point outputs, each point_count long or NULL when not wanted. */
typedef struct bsurf_error_fields {
  double *err_train;      /* Eq. 4.6 */
  double *err_boot;       /* Eq. 4.3 */
  double *err_loo;        /* Eq. 4.4 */
  double *err_loo_center; /* Eq. 4.11 */
  double *err_632;        /* Eq. 4.5 */
  double *err_632plus;    /* Eqs. 4.7-4.10 */
  double *gamma;          /* Eq. 4.10, or its mean/max over replicates */
  double *overfit_rate;   /* R of Eq. 4.9, clipped to [0, 1] */
  /* Filled only when a test sample is given to bsurf_estimate_error: the
   * mean |f(x_j) - y_j| of the full fit over the test sample's copy of the
   * neighbourhood, and the same at the centre point only. */
  double *err_test;
  double *err_test_center;
} bsurf_error_fields;

typedef struct bsurf_error_report {
  size_t replicates_total;   /* point_count x B */
  size_t replicates_skipped; /* rank-deficient replicate fits, not used */
  size_t degree_reduced;     /* points whose full fit was rank-deficient at
                                the asked degree and used a lower one */
  size_t center_unestimated; /* points whose centre was in every replicate:
                                err_loo_center falls back to err_loo */
} bsurf_error_report;

/* Bootstrap test-error estimates of the local polynomial fits (Algorithm 1).
 * xyz in: point_count x 3; nb: neighbourhoods with nb->k >= opts->k (the first
 * opts->k of each row are used); test_xyz in: point_count x 3 or NULL — an
 * independent sample of the same surface points (same order) on which the
 * full fits are evaluated (err_test). Deterministic for a given seed. */
BSURF_API bsurf_status bsurf_estimate_error(const double *xyz, const bsurf_neighbors *nb,
                                            const double *test_xyz, const bsurf_error_options *opts,
                                            bsurf_error_fields *out, bsurf_error_report *report);

/* ------------------------------------------------------------------------ */
/* Normals with bootstrap confidence (thesis chapter 5)                       */
/* ------------------------------------------------------------------------ */

typedef enum bsurf_normal_fit {
  BSURF_NORMAL_PCA = 0, /* plane of the principal components (2.2, 5.2) */
  BSURF_NORMAL_POLY     /* gradient of a height polynomial at the point (Eq. 5.9) */
} bsurf_normal_fit;

typedef struct bsurf_normal_options {
  bsurf_normal_fit fit;        /* PCA */
  bsurf_pca_center pca_center; /* CENTROID (PCA about the point: Eq. 2.1) */
  int k;                       /* neighbourhood size, the point included (30) */
  int degree;                  /* polynomial degree for POLY, 1..4 (2) */
  int bootstrap;               /* B; 0 = a single fit (50) */
  uint64_t seed;               /* (1) */
  int threads;                 /* 0 = all cores */
  bsurf_progress_fn progress;
  void *progress_user;
  const uint64_t *point_index; /* NULL, or the global index of each row (as
                                  bsurf_error_options.point_index) */
} bsurf_normal_options;

BSURF_API bsurf_normal_options bsurf_normal_options_default(void);

/* Per-point outputs, point_count long (x 3 for vectors) or NULL. */
typedef struct bsurf_normal_fields {
  double *normals;    /* unit, unoriented (Eq. 5.4: normalised mean of the
                         bootstrap normals, each oriented to the whole
                         neighbourhood's normal; the single fit when B = 0) */
  double *normal_var; /* Eq. 5.5: variance of the angles (rad) between the
                         first bootstrap normal and the others; 0 when B < 2 */
  double *normal_err; /* Eq. 5.10: bootstrap test error of the normal (rad);
                         needs reference normals */
} bsurf_normal_fields;

typedef struct bsurf_normal_report {
  size_t replicates_total;
  size_t replicates_skipped; /* degenerate resamples (rank-deficient fits) */
  size_t degree_reduced;     /* POLY points that used a lower degree */
  size_t degenerate;         /* points whose neighbourhood is collinear or
                                repeated: the plane, hence the normal, is not
                                determined (a perpendicular is returned) */
} bsurf_normal_report;

/* Normals (and their confidence and test error) of every point from its
 * first opts->k neighbours (nb->k >= opts->k). ref_normals in: point_count x 3
 * or NULL — the reference normals n_j of Eq. 5.10 (Algorithm 3), e.g. PCA
 * normals of a fixed neighbourhood size; normal_err is computed only when
 * they are given. Deterministic for a given seed, any thread count. */
BSURF_API bsurf_status bsurf_estimate_normals(const double *xyz, const bsurf_neighbors *nb,
                                              const double *ref_normals,
                                              const bsurf_normal_options *opts,
                                              bsurf_normal_fields *out,
                                              bsurf_normal_report *report);

/* Per-point choice of the neighbourhood size K (docs/normals.md, "Choosing
 * K"). BSURF_KSELECT_TEST_ERROR is the thesis's rule (5.5, Eq. 5.10): per
 * point the candidate whose bootstrap test error against reference normals
 * is smallest (bsurf_estimate_normals with ref_normals, once per candidate,
 * compared by the caller). BSURF_KSELECT_MSE minimises an estimate of the
 * PCA normal's mean squared angle error, variance + squared bias, with the
 * noise and the curvature from local quadrics, the candidates within the
 * estimate's scatter of the minimum told apart by the neighbours' agreement
 * (bsurf_select_k).
 * BSURF_KSELECT_AUTO (bsurf_normals_job's default): MSE where it applies
 * (select_k with candidates >= 7, or select_degree alone with k >= 7, PCA or
 * POLY fit, no curve; in memory and tiled), TEST_ERROR otherwise; MSE was the nearer to the best
 * fixed K on the development benchmark (docs/normals.md, "What the benchmark says"). */
typedef enum bsurf_kselect_rule {
  BSURF_KSELECT_TEST_ERROR = 0,
  BSURF_KSELECT_MSE,
  BSURF_KSELECT_AUTO
} bsurf_kselect_rule;

/* Where BSURF_KSELECT_MSE pools its noise estimate (docs/normals.md,
 * "Choosing K"): GLOBAL, the median over the cloud of the points' local
 * estimates (one noise level, the default: assumes the noise's level does
 * not vary over the cloud); LOCAL, each point's own (the lower quartile
 * over its largest candidate's neighbourhood). */
typedef enum bsurf_noise_pool {
  BSURF_NOISE_POOL_GLOBAL = 0,
  BSURF_NOISE_POOL_LOCAL
} bsurf_noise_pool;

typedef struct bsurf_kselect_options {
  bsurf_kselect_rule rule;     /* MSE (bsurf_select_k accepts only MSE) */
  const int *ks;               /* candidate K, strictly ascending, each >= 7 */
  int nk;                      /* number of candidates */
  int noise_k;                 /* the quadric noise fits' smallest neighbourhood
                                  (12; >= 12); the noise is pooled over the
                                  largest candidate's */
  bsurf_noise_pool noise_pool; /* GLOBAL (default) or LOCAL */
  int threads;                 /* 0 = all cores */
  bsurf_progress_fn progress;  /* bsurf_select_k: over twice the points, the
                                  noise fits' pass in the first half and the
                                  selection's in the second (the passes between
                                  and after hold their position) */
  void *progress_user;
  /* With nd >= 1: the candidates are the pairs (K, degree) of polynomial
   * height fits of degrees ds[0..nd-1] (each in [1, 4]) instead of PCA
   * planes, and the estimated mean squared error is that of the fit's
   * normal at the point (docs/normals.md, "Choosing K and the degree");
   * NULL, 0: PCA. */
  const int *ds;
  int nd;
} bsurf_kselect_options;

BSURF_API bsurf_kselect_options bsurf_kselect_options_default(void);

/* Per-point outputs, point_count long (x 3 for normals) or NULL. */
typedef struct bsurf_kselect_fields {
  double *normals; /* unit, unoriented: the PCA normal (about the
                      centroid, single fit) of the chosen K */
  int *k_selected; /* the chosen K */
  double *rmse;    /* the estimated root mean squared angle error of
                      that normal (rad): sqrt(variance + bias^2);
                      pi / 2 where no candidate could be assessed
                      (among them the points whose K_max neighbours
                      sample a curve, not a surface: docs/normals.md,
                      "Curve-sampled neighbourhoods") */
  double *noise;   /* the estimated noise standard deviation along the
                      normal (length) */
  int *two_sheet;  /* 1 where the chosen neighbourhood mixes two sheets
                      (a thin part's faces, or two surfaces): its heights
                      about a quadric split into two groups beyond what one
                      sheet with any unimodal noise gives at level 0.001
                      (docs/normals.md, "Two sheets"); else 0 */
  /* with opts->nd >= 1: the chosen degree (the normals are then the
   * chosen fit's, in the frame of the K_max neighbours) */
  int *degree_selected;
} bsurf_kselect_fields;

typedef struct bsurf_kselect_report {
  size_t unassessed; /* points where no candidate could be assessed (the
                        noise exceeds the tangent spread of every K, the
                        quadrics are rank-deficient, the K_max
                        neighbours sample a curve, or every candidate's
                        plane is thinner than the noise and may be a
                        cross-section's -- not a surface patch's own
                        plane: docs/normals.md, "Planes thinner than the
                        noise"): the largest K */
} bsurf_kselect_report;

/* K selection by BSURF_KSELECT_MSE for every point; nb->k must be at least
 * the largest candidate and noise_k. Deterministic, any thread count. */
BSURF_API bsurf_status bsurf_select_k(const double *xyz, const bsurf_neighbors *nb,
                                      const bsurf_kselect_options *opts, bsurf_kselect_fields *out,
                                      bsurf_kselect_report *report);

/* Per-point K selection (5.5, Algorithm 3): outputs of the chosen
 * candidate (point_count long, x 3 for vectors) and, for --curve style
 * summaries, every candidate's (NULL when not wanted). */
typedef struct bsurf_normal_select_fields {
  double *normals, *normal_var, *normal_err; /* as bsurf_normal_fields */
  int *k_selected;                           /* the chosen K */
  double *cand_err, *cand_var; /* point_count x nk: candidate c of point i at [i nk + c] */
  double *cand_normals;        /* point_count x nk x 3 */
} bsurf_normal_select_fields;

/* PCA normals with every K of ks[0..nk) (strictly increasing, ks[0] >= 3,
 * ks[nk - 1] <= nb->k; opts->k is ignored) and, per point, the K whose
 * bootstrap test error (Eq. 5.10 against ref_normals, required) is the
 * smallest (ties: the smaller K). The candidates are nested (each the first
 * K of one sorted neighbour list) and share their resamples: Poisson(1)
 * counts per neighbour, drawn once per point and replicate, restricted to
 * each candidate's first K (docs/normals.md explains the scheme): the
 * estimator of bsurf_estimate_normals at each K, on Poisson instead of
 * multinomial resamples (the numbers differ at O(1/K)). With
 * opts->bootstrap = 0 the single fits and their training errors. PCA only
 * (opts->fit); deterministic for a given seed, any thread count. */
BSURF_API bsurf_status bsurf_select_normals_k(const double *xyz, const bsurf_neighbors *nb,
                                              const double *ref_normals,
                                              const bsurf_normal_options *opts, const int *ks,
                                              int nk, bsurf_normal_select_fields *out,
                                              bsurf_normal_report *report);

/* Bilateral normal smoothing (5.3, Eqs. 5.6-5.8), `iterations` Jacobi-style
 * passes (every point from the previous pass's normals, so order-free):
 *   n_i <- (1 - alpha) n_i + alpha / c_i sum_{p in N_i} G(nu_p, sigma_nu)
 *          G(|d_i - p|, sigma_d) n_p,   G(a, b) = exp(-a^2 / b^2),
 * then normalised; neighbours' normals are flipped to agree with n_i first.
 * normals in/out: point_count x 3; normal_var in: point_count (NULL or
 * sigma_nu = INFINITY: the single Gaussian filter). */
BSURF_API bsurf_status bsurf_smooth_normals(const double *xyz, const bsurf_neighbors *nb, int k,
                                            double *normals, const double *normal_var,
                                            int iterations, double alpha, double sigma_d,
                                            double sigma_nu, int threads);

/* Consistent orientation by propagation along a minimum spanning tree of the
 * neighbour graph with weights 1 - |n_i . n_j| (Hoppe et al. 1992). Each
 * connected component starts at its highest point (largest z), whose normal
 * is turned to +z. normals in/out: point_count x 3. */
BSURF_API bsurf_status bsurf_orient_normals(const double *xyz, const bsurf_neighbors *nb, int k,
                                            double *normals);

/* ------------------------------------------------------------------------ */
/* Smoothing driven by the bootstrap error (thesis chapter 6)                 */
/* ------------------------------------------------------------------------ */

typedef enum bsurf_smooth_method {
  BSURF_SMOOTH_NAIVE = 0, /* 6.2, Eq. 6.1: projection to the mean bootstrap fit */
  BSURF_SMOOTH_BILATERAL, /* 6.3, Algorithm 4, Eq. 6.2 */
  BSURF_SMOOTH_MULTIPASS, /* 6.4, Algorithm 5, Eqs. 6.3-6.5 */
  /* the default: MULTIPASS in memory (at its defaults it is below BILATERAL
   * on 35 of the 38 development cases, docs/smoothing.md), BILATERAL in
   * tiled runs, where MULTIPASS is refused (its passes reach one ring
   * further each); bsurf_smooth_job_summary.method says which ran */
  BSURF_SMOOTH_AUTO
} bsurf_smooth_method;

typedef enum bsurf_smooth_order {
  BSURF_ORDER_PARALLEL = 0, /* every neighbourhood's fit from the same positions;
                               a point's moves are combined (order-independent) */
  BSURF_ORDER_SEQUENTIAL    /* the thesis's in-place sweep i = 1..N (one thread) */
} bsurf_smooth_order;

typedef enum bsurf_smooth_estimator {
  BSURF_SMOOTH_EST_DEFAULT = 0, /* .632+ for naive (6.2), .632 otherwise (6.1, Eq. 4.5) */
  BSURF_SMOOTH_EST_632,
  BSURF_SMOOTH_EST_632PLUS
} bsurf_smooth_estimator;

typedef struct bsurf_smooth_options {
  bsurf_smooth_method method;       /* AUTO */
  bsurf_error_options error;        /* K, degree, B, seed, gamma, PCA centre,
                                       threads, progress of the bootstrap pass */
  bsurf_smooth_estimator estimator; /* which error is W_i (DEFAULT) */
  /* naive: project where W_i < threshold. NAN = auto (the mean of W_i over
   * the cloud, the thesis's reference value of 6.2); INFINITY = every point. */
  double threshold;
  /* bilateral: theta_1 = G(., h1) and theta_2 = G(., h2) of Eq. 6.2, with
   * G(a, b) = exp(-a^2/b^2) (Eq. 5.7). h1 <= 0: sqrt(h^2 + 2 sigma^2), h
   * the mean spacing and sigma the guard's noise estimate (h without the
   * guard; docs/smoothing.md, "The distance sigma"). h2 <= 0:
   * h2_fraction x |W|, the mean of W_i; multipass with both <= 0: 2 W_n, W_n
   * the median W_i (docs/smoothing.md). */
  double h1, h2;
  double h2_fraction;       /* <= 0: the default, 2 (the thesis shows 0.5-1 for
                               bilateral, Figs. 6.4-6.6, and uses 0.3 for multipass,
                               6.4.1, where its points barely move; see
                               docs/smoothing.md) */
  bsurf_smooth_order order; /* bilateral and multipass (PARALLEL) */
  /* multipass: h1 = a d_L (Eq. 6.5); a < 0 (default): a = 1.5 sqrt(pi / K_i),
   * the local spacing, and with the guard h1 = sqrt((a d_L)^2 + 2 sigma^2),
   * sigma its noise estimate (as bilateral's h1 auto; the thesis's a is
   * 0.1). iterations passes; -1
   * (default): until the first pass whose mean squared move is below
   * sigma^2 mean(p_i / K_i), at most 300 (the thesis: 300). K_i = max{k_min,
   * y} with y the linear map of Eq. 6.4 from (0, K) to (k_error, k_min);
   * k_error <= 0: k_error_fraction x |W|; both <= 0 (default): K_i = K (the
   * thesis's is 1 |W|). */
  double a;                /* -1 (auto) */
  int iterations;          /* -1 (auto) */
  int k_min;               /* 10; at least 3 (a plane fit), at most error.k */
  double k_error;          /* 0 */
  double k_error_fraction; /* 0 (none) */
  /* every method: a neighbourhood whose fit is biased at its centre (two
   * sheets, a sharp edge: a t test on its nearest points' residuals) is
   * fitted again from fewer points, or moves nothing (docs/smoothing.md,
   * "The guard"). 1 (on) by default; 0: the thesis's methods as written. */
  int guard;
  /* with the guard: 1 = each sheet fit takes the degree, from error.degree
   * down to a plane, of least estimated prediction error (Mallows' C_p);
   * 0 = the degree of error.degree (with two points per coefficient);
   * -1 (default, auto) = 1 for bilateral and multipass, 0 for naive
   * (docs/smoothing.md, "The degree test"). */
  int degree_test;
  /* multipass with the guard: the largest K the noise may widen the
   * neighbourhood to. Where the guard's noise estimate is heavy against the
   * error.k-ball (the ball then holds only the points near its centre's
   * height, and its fit keeps the centre's own noise), K grows to the
   * smallest size whose ball drops no more of the noise variance (1 - kappa)
   * than its fit's own prediction variance holds (p / K; docs/smoothing.md,
   * "The neighbourhood's scale"), and the
   * method runs again on the K-neighbourhoods. 0 (default): 8 error.k;
   * error.k: K stays error.k. */
  int k_max;
} bsurf_smooth_options;

BSURF_API bsurf_smooth_options bsurf_smooth_options_default(void);

/* Per-point outputs, point_count long or NULL when not wanted. */
typedef struct bsurf_smooth_fields {
  double *err_632;     /* Eq. 4.5 of the bootstrap pass */
  double *err_632plus; /* Eqs. 4.7-4.10 of the bootstrap pass */
  double *moved;       /* distance from the input position */
  double *k_hat;       /* multipass: K_i of Eq. 6.3 */
  double *d_local;     /* multipass: d_L, the mean nearest-neighbour distance
                          over the K_i neighbourhood */
} bsurf_smooth_fields;

typedef struct bsurf_smooth_report {
  bsurf_error_report error;     /* of the bootstrap pass */
  double h;                     /* mean spacing (nb->h) */
  double mean_error;            /* |W|: mean of the W_i used */
  double threshold;             /* naive: the threshold applied */
  double h1, h2;                /* the sigmas applied (multipass: h1 = 0, per point) */
  double k_error;               /* multipass: the error mapped to k_min */
  size_t projected;             /* naive: points under the threshold */
  size_t moved_points;          /* points whose position changed */
  double moved_mean, moved_max; /* displacement over all points */
  int iterations;               /* multipass: passes run */
  double noise;                 /* the guard's noise estimate sigma (NAN: guard off):
                                   noise_fits, or the larger of the two below where
                                   the fits are blind to the noise, more than 5% of
                                   the points' neighbourhoods cross-sections
                                   (section_share); docs/smoothing.md, "Two readings
                                   of the noise" */
  double noise_fits;            /* sigma read by the sheet fits (their residual
                                   variances' lower decile; NAN: guard off) */
  double noise_select;          /* sigma read by the K selection's noise passes
                                   (bsurf_select_k's level; NAN: guard off, 80
                                   points or fewer, or not needed: section_share at
                                   most 5% by the section test alone) */
  double section_share;         /* the share of points whose 80 nearest the selection
                                   found section-sampled; where noise_select is NAN
                                   an upper bound from the section test alone (NAN:
                                   guard off; 0: 80 points or fewer) */
  size_t misfit_fits;           /* the guard's misfit test: fits of the first stage
                                   with more misfit than noise (they move nothing) */
  int k;                        /* the neighbourhood size used (error.k, or the scale
                                   rule's, bsurf_smooth_options.k_max) */
} bsurf_smooth_report;

/* Moves the points of a cloud towards the bootstrap fits (chapter 6).
 * xyz in: point_count x 3; nb: neighbourhoods with nb->k >= opts->error.k;
 * out_xyz out: point_count x 3 (may not alias xyz). Deterministic for a given
 * seed, whatever the thread count (the sequential order runs its sweep on one
 * thread). */
BSURF_API bsurf_status bsurf_smooth(const double *xyz, const bsurf_neighbors *nb,
                                    const bsurf_smooth_options *opts, double *out_xyz,
                                    bsurf_smooth_fields *fields, bsurf_smooth_report *report);

/* ------------------------------------------------------------------------ */
/* Feature detection (thesis chapter 7)                                      */
/* ------------------------------------------------------------------------ */

typedef enum bsurf_feature_method {
  BSURF_FEATURES_DISTANCE = 0, /* distance to the nearest feature from PCA of
                                  growing neighbourhoods (7.1) */
  BSURF_FEATURES_VARIANCE      /* normal_var > t_h (7.2, Eq. 7.2) */
} bsurf_feature_method;

/* Automatic threshold rules for a score whose bulk is "non-feature" and whose
 * upper tail is the feature area (7.2: "the start of the tail"). */
typedef enum bsurf_tail_rule {
  BSURF_TAIL_OTSU = 0, /* Otsu's two-class split of log(value) (256 bins);
                          the default: best on the cube and Fandisk (see
                          src/algo/features.c) */
  BSURF_TAIL_MAD,      /* median + 3 x 1.4826 x MAD of log(value) */
  BSURF_TAIL_NULL      /* features --method variance only, the default: a
                          test against the variance of a flat patch at the
                          measured noise level, at the false-positive rate
                          false_positive_rate (src/algo/features_variance.c,
                          docs/features.md); needs the geometry, so
                          bsurf_tail_threshold refuses it */
} bsurf_tail_rule;

/* The start of the upper tail of a distribution of non-negative values.
 * Values <= 1e-12 x max (rounding-level zeros, e.g. a noise-free flat area)
 * are bulk and left out; the rule runs on the logs of the others (if fewer
 * than 2 remain, the threshold is 1e-12 x max).
 * values in: count. *threshold out: points with value > threshold are the
 * tail. BSURF_ERR_INVALID_VALUE for NaN, BSURF_ERR_TOO_FEW_POINTS for
 * count < 2. */
BSURF_API bsurf_status bsurf_tail_threshold(const double *values, size_t count,
                                            bsurf_tail_rule rule, double *threshold);

typedef struct bsurf_feature_options {
  bsurf_feature_method method; /* VARIANCE (issue 22: the null test; DISTANCE is 7.1) */
  /* distance (7.1) */
  int k_min, k_max, k_step; /* neighbourhood sizes k_min, k_min + k_step,
                               ... <= k_max, the point included (15, 60, 2;
                               k_min 15 beat 10 and 20 on the cube and
                               Fandisk at noise 0 and 0.5) */
  double ratio_threshold;   /* T_{a/c}: stop when f = lambda0/lambda2 (or
                               f + d f') exceeds it (0.1) */
  double noise_factor;      /* c > 0: at each size K the threshold is
                               max(T_{a/c}, c x the median of f(K) over
                               the points), so that noise alone (which
                               raises f everywhere) does not stop the
                               growth; at low noise c x median < T_{a/c}
                               and nothing changes. 0 = T_{a/c} alone, the
                               thesis (1.75, see src/algo/features.c) */
  double derivative;        /* d of f + d f' (f' per step); 0 = f alone (0) */
  double alpha;             /* bilateral filter strength, Eq. 7.1 (0.5) */
  int iterations;           /* bilateral filter passes (5) */
  int filter_k;             /* neighbours of the filter, point included
                               (0 = k_min) */
  double sigma_range;       /* range sigma of g_b as a fraction of
                               max(radius) (0.05; the thesis's 0.01 is
                               absolute on a unit-size model) */
  /* threshold: distance: feature_dist <= threshold x max(feature_dist),
   * threshold in [0, 1] (0: the thesis's T_h = 0 of Fig. 7.5, the points the accentuated,
   * filtered map keeps at or below zero); NAN = auto: the points <= 0 and
   * those below Otsu's split of the positive values that exceeded T_{a/c}
   * at some size (the band that met a feature before k_max, apart from the
   * plateau near max radius of those that met none).
   * variance: normal_var > threshold (at least 0); NAN = auto
   * (tail_rule). */
  double threshold;          /* NAN */
  bsurf_tail_rule tail_rule; /* NULL (variance) */
  /* variance, tail_rule NULL: the score is z = nu d / s^2 (d = 4 / (1 /
   * lambda1 + 1 / lambda2) of the covariance of the normals.k-neighbourhood,
   * s^2 the median of its smallest eigenvalue over the cloud; 0 where the
   * neighbourhood is two parallel flat sheets), median-filtered over the first
   * variance_filter_k neighbours; a point is a feature when it exceeds the
   * (1 - false_positive_rate) quantile of the same score on a simulated flat
   * patch with the cloud's noise level, or when its border score zb (k
   * |tangential offset of the neighbourhood's centroid|^2 / (lambda1 +
   * lambda2), median-filtered likewise) exceeds that patch's (1 -
   * false_positive_rate) quantile of zb: a border, e.g. a thin part's rim
   * (docs/features.md). */
  double false_positive_rate; /* in (0, 1) (0.01) */
  int variance_filter_k;      /* 1 = no filter; 0 = normals.k / 2 (0) */
  /* variance, tail_rule NULL: the neighbourhood grows from normals.k (x 2
   * each step, at most variance_k_max) until the test detects a simulated
   * edge whose faces' normals differ by feature_angle degrees, at the
   * cloud's measured noise, at half its points or more (power >= 1/2):
   * noise comparable to the neighbourhood's radius hides edges from the test
   * at small K (docs/features.md). 0 = normals.k always (the thesis). 90:
   * a right-angle edge, the commonest in machined parts; lower angles grow K
   * sooner (a wider detected band), higher ones later. */
  double feature_angle; /* degrees, in [0, 180) (90) */
  int variance_k_max;   /* the largest K tried; 0 = 8 normals.k (0) */
  /* variance, tail_rule NULL: the quadric check. A point the variance test
   * flags stays a feature only where a quadric does not explain its
   * neighbourhood: the residual variance of the least-squares quadric of
   * its K_q nearest, median-filtered like z, over the cloud's noise
   * variance (the K selection's reading, bsurf_select_k's noise passes)
   * exceeds the (1 - false_positive_rate) quantile of the same statistic
   * on the flat null patch. K_q is the first of k, 2 k, 4 k (at most the
   * K choice's cap and nb->k) at which a simulated crease whose faces'
   * normals differ by quadric_angle degrees, at the cloud's noise, keeps
   * at least 9 in 10 of its points within a spacing of the crease; where
   * none does (heavy noise), with no noise (s^2 = 0), 80 points or fewer or
   * nb->k < 80, no check. A smooth bend tighter
   * than the cloud's curvature raises nu as an edge does, but a quadric
   * fits it (docs/features.md). 0 = off (the test alone). The border
   * test's flags are not checked. */
  double quadric_angle;         /* degrees, in [0, 180) (45) */
  bsurf_normal_options normals; /* variance: the bootstrap normals (defaults) */
  int threads;                  /* 0 = all cores (also used for normals) */
  bsurf_progress_fn progress;
  void *progress_user;
} bsurf_feature_options;

BSURF_API bsurf_feature_options bsurf_feature_options_default(void);
/* bsurf_feature_options.threshold's range for a method, in the words every
 * front end prints: distance a fraction of max(feature_dist) in [0, 1],
 * variance a normal_var >= 0, NaN auto. BSURF_OK, or BSURF_ERR_INVALID_ARG
 * with the message ("threshold 1.5: method distance takes a fraction of
 * max(feature_dist), 0 to 1, or auto"; bsurf_last_message()). */
BSURF_API bsurf_status bsurf_feature_threshold_check(bsurf_feature_method method, double threshold);

typedef struct bsurf_feature_report {
  double threshold;            /* the absolute threshold applied to the score */
  size_t feature_points;       /* points with feature = 1 */
  double max_radius;           /* distance: the largest neighbourhood radius */
  size_t immediate;            /* distance: points whose k_min neighbourhood
                                  already exceeded T_{a/c} (set to -max_radius) */
  double ratio_threshold_kmin; /* distance: the T_{a/c} applied at k_min
                                  (above ratio_threshold when noise_factor
                                  raised it); NAN for VARIANCE */
  int k;                       /* variance: the normals' neighbourhood used
                                  (feature_angle: the chosen one) */
  double edge_power;           /* variance, feature_angle > 0: the simulated
                                  edge's detected share at k; else NAN */
  double noise_level;          /* variance, rule NULL: sqrt of the median
                                  smallest PCA eigenvalue (the noise sigma
                                  the null patch is given); else NAN */
  double border_threshold;     /* variance, rule NULL: the border test's
                                  threshold on the filtered border score zb
                                  (a point is also a feature when zb exceeds
                                  it); else NAN */
  int quadric_k;               /* variance, rule NULL: the quadric check's
                                  K_q; 0 when it did not run */
  double quadric_threshold;    /* its threshold on the filtered residual
                                  variance over quadric_noise^2; else NAN */
  double quadric_power;        /* the simulated crease's share kept at K_q
                                  (or the largest tried); else NAN */
  double quadric_noise;        /* the cloud's noise sigma it reads (also
                                  where it then finds no K_q); else NAN */
  size_t quadric_cleared;      /* points the variance test flagged that the
                                  check cleared */
  size_t border_points;        /* variance, rule NULL: feature points that the
                                  border test alone flags (zb above its
                                  threshold, the variance test's flag not
                                  standing): on an open scan its rims, on a
                                  mesh's own vertices also the vertex density's
                                  gradient (docs/features.md, step 6) */
} bsurf_feature_report;

/* Feature detection. nb: neighbourhoods with nb->k >= k_max (distance) or
 * >= normals.k (variance; the quadric check needs nb->k >= 80 and reads K_q
 * up to min(4 K, the K cap, nb->k): bsurf_features_job_neighbors gives the
 * table the job builds). feature out: point_count, 0/1; score out:
 * point_count (feature_dist for DISTANCE, normal_var for VARIANCE with the
 * OTSU or MAD rule, the filtered score z for VARIANCE with the NULL rule),
 * may be NULL. Deterministic for any thread count. */
BSURF_API bsurf_status bsurf_detect_features(const double *xyz, const bsurf_neighbors *nb,
                                             const bsurf_feature_options *opts, uint8_t *feature,
                                             double *score, bsurf_feature_report *report);

/* The raw distance map of 7.1 (before filtering): for each point the radius
 * of the first neighbourhood size whose a/c (or a/c + d (a/c)') exceeds the
 * ratio threshold (with noise_factor: the raised threshold of that size;
 * k_max's radius when none does); points that exceed it at
 * k_min get -max(radius). dist out: point_count. Also returns, per point,
 * the neighbourhood size it stopped at (ksel out, may be NULL). */
BSURF_API bsurf_status bsurf_feature_distance_raw(const double *xyz, const bsurf_neighbors *nb,
                                                  const bsurf_feature_options *opts, double *dist,
                                                  int *ksel, double *max_radius, size_t *immediate);

/* Incremental PCA along a sorted neighbour list (internal to 7.1, public
 * for the tests): for m = 1..k the ratio lambda0/lambda2 of the covariance
 * (about the centroid) of the first m points xyz[idx[0..m-1]], from running
 * sums. ratio out: k (0 where lambda2 = 0). */
BSURF_API void bsurf_incremental_pca_ratios(const double *xyz, const uint32_t *idx, int k,
                                            double *ratio);

/* ------------------------------------------------------------------------ */
/* Generated shapes and noise                                                 */
/* ------------------------------------------------------------------------ */

typedef enum bsurf_shape {
  BSURF_SHAPE_SPHERE = 0, /* radius 1, centred at 0 */
  BSURF_SHAPE_CUBE,       /* edge 2, centred at 0; sharp edges */
  BSURF_SHAPE_TORUS,      /* radii 1 and 0.35 around the z axis */
  BSURF_SHAPE_PLANE       /* the square [-1,1]^2 at z = 0 */
} bsurf_shape;

typedef enum bsurf_sampling {
  BSURF_SAMPLING_REGULAR = 0, /* even, deterministic (Fibonacci / grids) */
  BSURF_SAMPLING_RANDOM       /* uniform by area, from the seed */
} bsurf_sampling;

/* Parses "sphere", "cube", ... Returns 0 on success. */
BSURF_API int bsurf_shape_from_name(const char *name, bsurf_shape *shape);
BSURF_API const char *bsurf_shape_name(bsurf_shape shape);

/* Generates about `n` points on a shape with exact normals and, for shapes
 * with sharp edges, the fields `feature_dist` (distance to the nearest sharp
 * edge) and `feature` (1 where feature_dist <= feature_width * s, with s =
 * sqrt(area / point count) the nominal point spacing). Regular sampling
 * rounds n to the nearest count its pattern allows. */
BSURF_API bsurf_status bsurf_generate(bsurf_cloud *cloud, bsurf_shape shape, size_t n,
                                      bsurf_sampling sampling, uint64_t seed, double feature_width);

/* Exact distance from a point to a generated shape's surface. */
BSURF_API double bsurf_shape_distance(bsurf_shape shape, const double p[3]);

typedef enum bsurf_noise_model {
  BSURF_NOISE_GAUSSIAN = 0, /* t ~ N(0, level^2) */
  BSURF_NOISE_UNIFORM       /* t ~ U[-level, level] (thesis 4.2's text) */
} bsurf_noise_model;

/* Displaces every point along its (unit) normal by t * scale: xyz is updated
 * in place. t is drawn from the model with the given level, from a generator
 * keyed by (seed, point index). normals in: point_count x 3. */
BSURF_API bsurf_status bsurf_add_noise(double *xyz, const double *normals, size_t point_count,
                                       bsurf_noise_model model, double level, double scale,
                                       uint64_t seed);

/* `bootsurf noise` as one call: the thesis's protocol (4.2), t * h with h
 * the points' mean nearest-neighbour distance, or PCPNet's (gaussian with
 * sigma = sigma_diag x the bounding-box diagonal). */
typedef struct bsurf_noise_options {
  bsurf_noise_model model; /* GAUSSIAN */
  double level;            /* xi in units of h (0.5) */
  double sigma_diag;       /* > 0: instead of level, gaussian noise of sigma =
                              sigma_diag x the bounding-box diagonal (0) */
  uint64_t seed;           /* (1) */
  int threads;             /* for measuring h; 0 = all cores */
  bsurf_progress_fn progress;
  void *progress_user;
} bsurf_noise_options;

BSURF_API bsurf_noise_options bsurf_noise_options_default(void);

typedef struct bsurf_noise_report {
  double h;        /* mean nearest-neighbour distance before the noise */
  double diagonal; /* of the bounding box */
  double level;    /* the level applied: opts->level, or 1 with sigma_diag */
  double scale;    /* its unit: h, or sigma_diag x diagonal (gaussian sigma =
                      level x scale; uniform half-width the same) */
} bsurf_noise_report;

/* Measures h (bsurf_mean_spacing_progress, cancellable) and the bounding
 * box, then displaces the points along their normals (bsurf_add_noise with
 * level x scale). xyz in/out: point_count x 3 (at least 2 points); normals
 * in: point_count x 3, non-zero. opts NULL: defaults; report may be NULL.
 * BSURF_ERR_INVALID_VALUE (message naming the point) for a zero normal. */
BSURF_API bsurf_status bsurf_noise_points(double *xyz, const double *normals, size_t point_count,
                                          const bsurf_noise_options *opts,
                                          bsurf_noise_report *report);

/* ------------------------------------------------------------------------ */
/* Pictures                                                                  */
/* ------------------------------------------------------------------------ */

/* Colormaps: viridis and magma (matplotlib's perceptually uniform maps),
 * gray, coolwarm (Moreland's diverging map). */
typedef enum bsurf_colormap {
  BSURF_COLORMAP_VIRIDIS = 0,
  BSURF_COLORMAP_MAGMA,
  BSURF_COLORMAP_GRAY,
  BSURF_COLORMAP_COOLWARM
} bsurf_colormap;

/* Parses "viridis", "magma", "gray", "coolwarm". Returns 0 on success. */
BSURF_API int bsurf_colormap_from_name(const char *name, bsurf_colormap *cmap);
BSURF_API const char *bsurf_colormap_name(bsurf_colormap cmap);
/* The colour at t in [0, 1] (clamped; NaN gives the low end). */
BSURF_API void bsurf_colormap_rgb(bsurf_colormap cmap, double t, uint8_t rgb[3]);
/* Named views: front (looking along +y, z up), back, left, right, top,
 * bottom, iso. Returns 0 and the angles in degrees, or -1. */
BSURF_API int bsurf_view_from_name(const char *name, double *azimuth, double *elevation);

typedef struct bsurf_render_options {
  int width, height;                   /* pixels of the whole image (1024 x 768) */
  double azimuth, elevation;           /* view direction in degrees (iso: 45, 35.26) */
  int views;                           /* 1, or 4: front, right, top and iso in a 2x2 grid */
  double point_size;                   /* splat diameter in units of the spacing h (2) */
  double spacing;                      /* h; 0: estimated from the points */
  const double *point_spacing;         /* point_count local spacings (sparse regions get
                                          larger splats) or NULL: h everywhere */
  int up_axis;                         /* 0, 1, 2: x, y or z points up in named views (2) */
  int round_splats;                    /* 1: discs (default), 0: squares */
  int supersample;                     /* 1..4: samples per pixel side, averaged (2) */
  bsurf_colormap colormap;             /* viridis */
  double range_lo, range_hi;           /* field values mapped to the colormap's ends;
                                          NaN: the percentiles below */
  double percentile_lo, percentile_hi; /* in percent (1, 99); values outside are capped */
  int shade;                           /* 1: field colours modulated by Lambert shading
                                          when normals are given */
  int colorbar;                        /* 1: a colour bar with ticks when values are given */
  const char *label;                   /* colour-bar caption (e.g. the field name) or NULL */
  const char *title;                   /* text at the top or NULL */
  uint8_t background[3];               /* white */
  int threads;                         /* 0 = all cores; the image never depends on it */
} bsurf_render_options;

BSURF_API bsurf_render_options bsurf_render_options_default(void);
/* The view's ranges, shared by every front end (bsurf_render checks them
 * too): azimuth from -360 to 360 degrees, elevation from -90 to 90,
 * point_size from 0.05 to 50. BSURF_OK, or BSURF_ERR_INVALID_ARG with a
 * message naming the option and its value ("azimuth 1000: must be from
 * -360 to 360 degrees"; bsurf_last_message()). */
BSURF_API bsurf_status bsurf_render_options_check(const bsurf_render_options *opts);

typedef struct bsurf_render_info {
  double range_lo, range_hi; /* the value range used (NaN without values) */
  double spacing;            /* h used for the splat size */
  size_t covered_pixels;     /* pixels showing a point */
} bsurf_render_info;

/* Renders points to an RGB image: orthographic view, z-buffered splats of
 * diameter point_size * h (nearest point wins, ties by the lower index, so
 * the image is the same for any thread count). Without values the surface is
 * shaded by its normals (two-sided Lambert + ambient) or, without normals, by
 * depth; with values, coloured through the colormap.
 *   rgb      out: height x width x 3 bytes, rows top to bottom
 *   xyz      in: point_count x 3
 *   normals  in: point_count x 3 or NULL
 *   values   in: point_count or NULL (NaN values are drawn gray)
 *   point_count  below 2^32 - 1
 *   info     out, may be NULL */
BSURF_API bsurf_status bsurf_render(uint8_t *rgb, const double *xyz, const double *normals,
                                    size_t point_count, const double *values,
                                    const bsurf_render_options *opt, bsurf_render_info *info);

/* The spacings `bootsurf render` draws with: *h, the mean nearest-neighbour
 * distance, and per point h times the ratio of its distance to its 6th
 * nearest other point to the median of those distances, clamped to [1, 4]
 * (sparse regions of a scan get larger splats, so they look closed).
 * point_spacing out: point_count or NULL; *filled = 1 when it was filled
 * (pass it as bsurf_render_options.point_spacing), 0 when h is to be used
 * everywhere (fewer than 8 points, a zero median). Cancellable. */
BSURF_API bsurf_status bsurf_render_spacing(const double *xyz, size_t point_count, int threads,
                                            bsurf_progress_fn progress, void *progress_user,
                                            double *h, double *point_spacing, int *filled);

/* The up axis (bsurf_render_options.up_axis) of `--up auto` for a cloud
 * whose bsurf_cloud.shape is `shape`: 2 (z) for bootsurf's generated shapes,
 * like LiDAR and GIS data; else 1 (y), the convention of scans and meshes
 * from graphics (OpenGL's). */
BSURF_API int bsurf_render_auto_up(const char *shape);

/* The value range between two percentiles (in percent) of the finite values;
 * BSURF_ERR_INVALID_VALUE when there is none. */
BSURF_API bsurf_status bsurf_render_range(const double *values, size_t count, double percentile_lo,
                                          double percentile_hi, double *lo, double *hi);

/* Draws a vertical colour bar with labelled ticks into the box (x, y, w, h)
 * of an image (the bar, its ticks and the label all stay in the box). */
BSURF_API void bsurf_render_colorbar(uint8_t *rgb, int width, int height, int x, int y, int w,
                                     int h, bsurf_colormap cmap, double lo, double hi,
                                     const char *label, const uint8_t background[3]);
/* Draws text (5x7 font, enlarged `scale` times) with its top-left at (x, y). */
BSURF_API void bsurf_render_text(uint8_t *rgb, int width, int height, int x, int y,
                                 const char *text, int scale, const uint8_t color[3]);

typedef struct bsurf_histogram_options {
  int width, height;         /* 800 x 500 */
  int bins;                  /* 50 */
  double range_lo, range_hi; /* NaN: min and max of the finite values */
  double threshold;          /* a marker line at this value; NaN: none */
  int log_counts;            /* 1: bar heights are log10(1 + count) */
  const char *label;         /* x-axis caption or NULL */
  const char *title;         /* NULL */
} bsurf_histogram_options;

BSURF_API bsurf_histogram_options bsurf_histogram_options_default(void);

typedef struct bsurf_histogram_info {
  size_t counted;         /* finite values inside the range */
  size_t above_threshold; /* values > threshold */
  size_t max_count;       /* of the fullest bin */
} bsurf_histogram_info;

/* A histogram picture: bars, axes with ticks and labels, threshold marker.
 *   rgb  out: height x width x 3 */
BSURF_API bsurf_status bsurf_render_histogram(uint8_t *rgb, const double *values, size_t count,
                                              const bsurf_histogram_options *opt,
                                              bsurf_histogram_info *info);

/* Writes an 8-bit RGB PNG (libpng; no time stamp, so the same image gives the
 * same bytes). Atomic like bsurf_write: a temporary file renamed at the end. */
BSURF_API bsurf_status bsurf_write_png(const char *path, const uint8_t *rgb, int width, int height,
                                       bsurf_failure *err);

/* ------------------------------------------------------------------------ */
/* Meshes and evaluation against ground truth                                */
/* ------------------------------------------------------------------------ */

/* Ground truth from a triangle mesh (thesis 5.2.2: normals "from the
 * connectivity" of smooth meshes; 7.1.2 and 5.3.2: feature areas near the
 * sharp edges of the Fandisk and the Cube). A mesh is a bsurf_cloud with
 * faces (triangles; the readers fan-triangulate polygons) whose vertices are
 * shared between faces: a triangle soup has only boundary edges, hence no
 * sharp edge and face normals at its vertices. */

/* Area-weighted vertex normals: at each vertex the sum of the unnormalised
 * cross products (b - a) x (c - a) of its faces (twice their area times their
 * unit normal), normalised. Faces are taken in file order, so the result does
 * not depend on threads. normals out: point_count x 3. A vertex whose sum is
 * zero (no face, only zero-area faces, or faces that cancel) gets (0, 0, 0)
 * and is counted in *without_normal (may be NULL). BSURF_ERR_INVALID_ARG when
 * the mesh has no face or a face index is out of range. */
BSURF_API bsurf_status bsurf_mesh_vertex_normals(const bsurf_cloud *mesh, double *normals,
                                                 size_t *without_normal);

typedef struct bsurf_sample_options {
  size_t points;          /* 0 = the mesh's vertices (the thesis's protocol,
                             5.2.2); n > 0 = n points uniform by area (0) */
  uint64_t seed;          /* random seed of area sampling (1) */
  double sharp_angle_deg; /* an edge is sharp when the angle between its two
                             faces' normals exceeds this, in degrees (30) */
  double feature_width;   /* feature = 1 within feature_width x s of a sharp
                             edge, s = sqrt(area / output points), the nominal
                             spacing, as in bsurf_generate (2) */
  int threads;            /* 0 = all cores */
} bsurf_sample_options;

BSURF_API bsurf_sample_options bsurf_sample_options_default(void);

typedef struct bsurf_sample_report {
  size_t edges;              /* distinct undirected edges */
  size_t sharp_edges;        /* interior edges whose dihedral angle (between
                                the faces' normals) exceeds sharp_angle_deg */
  size_t boundary_edges;     /* edges of one face: mesh borders, never sharp */
  size_t nonmanifold_edges;  /* edges of 3+ faces: sharp when any two of their
                                faces differ by more than the angle */
  size_t inconsistent_edges; /* edges walked the same way by two faces (their
                               orientations disagree; the angle is measured
                               with one of them flipped) */
  size_t degenerate_faces;   /* zero area: never sampled, ignored for angles */
  size_t vertices_dropped;   /* vertex sampling: vertices without a normal
                                (see bsurf_mesh_vertex_normals), left out */
  size_t feature_points;     /* output points with feature = 1 */
  double area;               /* total surface area */
  double mean_edge_length;
  double spacing;         /* s = sqrt(area / output points) */
  double feature_width;   /* the absolute width: opts feature_width x s */
  double no_feature_dist; /* feature_dist when there is no sharp edge: the
                             mesh's bounding-box diagonal */
} bsurf_sample_report;

/* Points on a triangle mesh with ground truth (thesis 5.2.2, 7.x).
 *  - opts->points == 0: the mesh's vertices, each with its area-weighted
 *    vertex normal; vertices without one are dropped (counted in the
 *    report). The mesh's other vertex fields are kept, its normals replaced.
 *  - opts->points == n > 0: n points uniform by area. Point i picks a face by
 *    a binary search of the cumulative areas and uniform barycentric
 *    coordinates, all from the generator keyed by (seed, i), so the sample
 *    does not depend on threads; its normal is the face's unit normal.
 * Both write `feature_dist`, the exact distance from the point to the nearest
 * sharp edge segment (the mesh's bounding-box diagonal if it has none), and
 * `feature` (1 where feature_dist <= the absolute feature width). `out` gets
 * no faces: it is a point set. On failure `out` is left empty. `report` may
 * be NULL. */
BSURF_API bsurf_status bsurf_sample_mesh(bsurf_cloud *out, const bsurf_cloud *mesh,
                                         const bsurf_sample_options *opts,
                                         bsurf_sample_report *report);

/* The unoriented angle in radians, in [0, pi/2], between two directions of
 * any non-zero length: atan2(|a x b|, |a . b|) of the normalised vectors,
 * accurate near 0 and pi/2 (acos is not). NAN when either is zero. */
BSURF_API double bsurf_normal_angle(const double a[3], const double b[3]);

/* Statistics of a set of angle errors (radians). PGP5/PGP10 of PCPNet are
 * under5deg/under10deg (fractions, in [0, 1]). An empty set has count 0 and
 * NAN everywhere else. */
typedef struct bsurf_angle_stats {
  size_t count;
  double mean_rad;
  double median_rad; /* the middle value, or the mean of the two middle ones */
  double rms_rad;    /* sqrt(mean of squares) */
  double mean_deg;
  double under5deg;  /* fraction of angles < 5 degrees */
  double under10deg; /* fraction of angles < 10 degrees */
} bsurf_angle_stats;

/* Statistics of angles[i] over the points with mask[i] == keep (mask NULL:
 * all points). Sums run in point order (deterministic). angles in: count. */
BSURF_API bsurf_status bsurf_angle_stats_compute(const double *angles, const uint8_t *mask,
                                                 uint8_t keep, size_t count,
                                                 bsurf_angle_stats *stats);

/* Angle errors of estimated normals against ground-truth normals of the same
 * points in the same order (unoriented: a flipped normal has error 0).
 * result, truth in: count x 3; angles out: count (may be NULL); stats out
 * (may be NULL). BSURF_ERR_INVALID_VALUE if a normal has zero length or is
 * not finite; *bad_index (may be NULL) is then the first such point. */
BSURF_API bsurf_status bsurf_eval_normals(const double *result, const double *truth, size_t count,
                                          double *angles, bsurf_angle_stats *stats,
                                          size_t *bad_index);

/* Splits points at the q-quantile of a per-point value (thesis 5.2.3, Table
 * 5.2: "the highest 15%" is q = 0.85). With the values sorted ascending as
 * v[0..count-1] and m = ceil(q count) (q count rounded first when within 1e-9
 * of a whole number), threshold = v[m-1] (-INFINITY when m = 0); high points
 * are those with value > threshold, the others are low. On distinct values
 * exactly count - m points are high (3 of 20 at q = 0.85); values tied with
 * the threshold are all low. high out: count, 1 = high, 0 = low (may be
 * NULL); threshold and high_count out (may be NULL). q in [0, 1];
 * BSURF_ERR_INVALID_VALUE (and *bad_index) for a NaN value. */
BSURF_API bsurf_status bsurf_quantile_split(const double *values, size_t count, double q,
                                            uint8_t *high, double *threshold, size_t *high_count,
                                            size_t *bad_index);

/* Precision, recall and F1 of detected features against ground truth
 * (feature = 1 / 0 per point). A ratio whose denominator is 0 is NAN
 * (precision with no detection, recall with no true feature). */
typedef struct bsurf_feature_stats {
  size_t true_pos, false_pos, false_neg, true_neg;
  double precision, recall, f1;
} bsurf_feature_stats;

/* result, truth in: count (non-zero = feature). */
BSURF_API bsurf_status bsurf_eval_features(const uint8_t *result, const uint8_t *truth,
                                           size_t count, bsurf_feature_stats *stats);

/* Position error: the distance from points (e.g. a smoothed cloud) to the
 * true surface. */

/* Exact distance from p to the triangle (a, b, c): the closest point by
 * Voronoi regions (Ericson, Real-Time Collision Detection, 5.1.5). A
 * zero-area triangle is treated as its edges (never NaN for finite input).
 * closest out: 3, may be NULL. */
BSURF_API double bsurf_triangle_distance(const double p[3], const double a[3], const double b[3],
                                         const double c[3], double closest[3]);

/* A bounding-volume hierarchy over a mesh's triangles for exact distances. */
typedef struct bsurf_mesh_index bsurf_mesh_index;

/* Builds the index over a mesh's faces (a copy: the mesh need not outlive
 * it). Deterministic. BSURF_ERR_INVALID_ARG when the mesh has no face or a
 * face index is out of range, BSURF_ERR_INVALID_VALUE for a non-finite
 * vertex. */
BSURF_API bsurf_status bsurf_mesh_index_build(bsurf_mesh_index **index, const bsurf_cloud *mesh);
BSURF_API void bsurf_mesh_index_free(bsurf_mesh_index *index);

/* Exact distance from p to the nearest triangle: the minimum of
 * bsurf_triangle_distance over all faces, bit for bit (equal distances: the
 * lowest face index). face out (may be NULL): that face; closest out: 3, may
 * be NULL. NAN for a non-finite p. Thread-safe (the index is read only). */
BSURF_API double bsurf_mesh_distance(const bsurf_mesh_index *index, const double p[3], size_t *face,
                                     double closest[3]);

typedef enum bsurf_surface_kind {
  BSURF_SURFACE_MESH = 0,     /* a triangle mesh: bsurf_mesh_distance */
  BSURF_SURFACE_SHAPE,        /* a generated shape: bsurf_shape_distance */
  BSURF_SURFACE_TANGENT_PLANE /* |(p - t) . n| / |n| with t, n the corresponding
                                 truth point and its normal */
} bsurf_surface_kind;

/* The true surface of bsurf_position_errors; only the kind's members are read. */
typedef struct bsurf_true_surface {
  bsurf_surface_kind kind;
  const bsurf_mesh_index *mesh; /* MESH */
  bsurf_shape shape;            /* SHAPE */
  const double *truth_xyz;      /* TANGENT_PLANE: truth_count x 3 */
  const double *truth_normals;  /* TANGENT_PLANE: truth_count x 3, non-zero */
  size_t truth_count;
  const uint32_t *match; /* TANGENT_PLANE: point i corresponds to truth
                            point match[i] (count); NULL: to truth point i */
} bsurf_true_surface;

/* Per-point distance to the true surface, in parallel; the same for any
 * thread count. xyz in: count x 3; dist out: count. BSURF_ERR_INVALID_ARG
 * for a missing member or a match out of range; BSURF_ERR_INVALID_VALUE when
 * a distance is NaN (a zero truth normal, a non-finite point), the others
 * being filled. */
BSURF_API bsurf_status bsurf_position_errors(const double *xyz, size_t count,
                                             const bsurf_true_surface *surface, int threads,
                                             double *dist, bsurf_progress_fn progress,
                                             void *progress_user);

/* Correspondence of two clouds with different points: for each point of xyz
 * (count x 3) the nearest truth point (k-d tree; ties by the lower index).
 * match out: count. Parallel, deterministic. truth_count >= 1. */
BSURF_API bsurf_status bsurf_match_nearest(const double *truth_xyz, size_t truth_count,
                                           const double *xyz, size_t count, int threads,
                                           uint32_t *match);

/* Summary of distances. An empty set has count 0 and NAN elsewhere. */
typedef struct bsurf_distance_stats {
  size_t count;
  double mean, rms, max;
} bsurf_distance_stats;

/* Statistics of dist[i] over the points with mask[i] == keep (mask NULL:
 * all), summed in point order. dist in: count. */
BSURF_API bsurf_status bsurf_distance_stats_compute(const double *dist, const uint8_t *mask,
                                                    uint8_t keep, size_t count,
                                                    bsurf_distance_stats *stats);

/* The position section of `bootsurf eval` in one call: the distance of each
 * result point to the true surface and its summaries.
 *
 * The true surface, in order of preference (bsurf_eval_position_surface):
 * `surface` (a triangle mesh, e.g. the one the truth was sampled from), the
 * truth's own faces, the generated shape the truth samples (truth->shape),
 * the tangent plane of the corresponding truth point (truth->normals).
 * Result point i corresponds to truth point i when the counts agree, else to
 * its nearest truth point (bsurf_match_nearest; computed only when the
 * tangent planes or the truth's `feature` labels need it). h is the truth's
 * mean spacing (bsurf_mean_spacing; NAN under 2 truth points). */
typedef enum bsurf_position_group {
  BSURF_POSITION_ALL = 0, /* every result point */
  BSURF_POSITION_HIGH,    /* the split's high points (opts->high[i] = 1) */
  BSURF_POSITION_LOW,     /* the others */
  BSURF_POSITION_GROUPS
} bsurf_position_group;

typedef enum bsurf_position_part {
  BSURF_POSITION_PART_ALL = 0,     /* the group's points */
  BSURF_POSITION_PART_FEATURE,     /* those whose truth point has feature != 0 */
  BSURF_POSITION_PART_NON_FEATURE, /* the others */
  BSURF_POSITION_PARTS
} bsurf_position_part;

typedef struct bsurf_position_eval_options {
  const bsurf_cloud *surface; /* a triangle mesh (with faces), or NULL */
  const uint32_t *match;      /* result point i <-> truth point match[i], or
                                 NULL: by index when the counts agree, else
                                 the nearest (computed when needed) */
  const uint8_t *high;        /* a split of the result points (1 high, 0 low),
                                 or NULL: only the group ALL */
  int threads;
  bsurf_progress_fn progress; /* the distances, may cancel; or NULL */
  void *progress_user;
} bsurf_position_eval_options;

/* Where bsurf_eval_position failed. */
typedef enum bsurf_position_stage {
  BSURF_POSITION_STAGE_NONE = 0,
  BSURF_POSITION_STAGE_SPACING,  /* h of the truth */
  BSURF_POSITION_STAGE_MATCH,    /* the nearest truth points */
  BSURF_POSITION_STAGE_MESH,     /* the mesh index (a face index out of range) */
  BSURF_POSITION_STAGE_DISTANCE, /* a distance is NaN: bad_point, bad_truth_point */
} bsurf_position_stage;

typedef struct bsurf_position_eval {
  bsurf_surface_kind surface; /* the surface used */
  int surface_is_truth;       /* MESH: the truth's faces (not opts->surface) */
  int nearest;                /* correspondence by nearest point (else index,
                                 or not needed) */
  double h;                   /* the truth's mean spacing, NAN under 2 points */
  int has_feature;            /* the truth has `feature`: the parts exist */
  int groups;                 /* 1, or 3 with opts->high */
  bsurf_distance_stats stats[BSURF_POSITION_GROUPS][BSURF_POSITION_PARTS];
  bsurf_position_stage stage;        /* on failure: where */
  size_t bad_point, bad_truth_point; /* STAGE_DISTANCE: the first NaN distance */
} bsurf_position_eval;

/* The true surface bsurf_eval_position would use: 1 and *kind (and *shape
 * for SHAPE), or 0 when there is none (no surface, faces, known shape or
 * normals). surface may be NULL. */
BSURF_API int bsurf_eval_position_surface(const bsurf_cloud *truth, const bsurf_cloud *surface,
                                          bsurf_surface_kind *kind, bsurf_shape *shape);

/* Position errors of result points (xyz, count x 3) against the truth
 * cloud (its points, and as available faces, shape, normals and a `feature`
 * field). opts: NULL = defaults. dist out: count per-point distances (may be
 * NULL). BSURF_ERR_INVALID_ARG (bsurf_last_message) without a true surface
 * or for bad arguments; otherwise the status of the failed stage (out->stage):
 * BSURF_ERR_INVALID_VALUE at STAGE_DISTANCE for a zero-length truth normal
 * or a non-finite point. Sums run in point order: the same bits for any
 * thread count. */
BSURF_API bsurf_status bsurf_eval_position(const double *xyz, size_t count,
                                           const bsurf_cloud *truth,
                                           const bsurf_position_eval_options *opts,
                                           bsurf_position_eval *out, double *dist);

/* ------------------------------------------------------------------------ */
/* Distributed runs                                                          */
/* ------------------------------------------------------------------------ */

/* Tiled runs (bsurf_job_io: tile_points) cut a cloud too large for memory
 * into tiles with proven halos; the same bits as in memory (docs/scaling.md).
 * The tile engine itself is internal (src/tile/tile_engine.h). */

/* Messages between the processes of a distributed run (MPI in the CLI; the
 * library itself never links MPI). All calls are collective. */
typedef struct bsurf_tile_comm {
  int rank, ranks;
  void *user;
  void (*barrier)(void *user);
  /* element-wise sum over the ranks of count doubles, result on every rank */
  void (*sum)(void *user, double *values, size_t count);
  /* the largest of the ranks' values, on every rank */
  int (*max)(void *user, int value);
  /* bytes from rank 0 to every rank */
  void (*broadcast)(void *user, void *data, size_t bytes);
  /* every rank's `bytes` bytes of `mine`, in rank order, to `all` (ranks x
   * bytes) on every rank */
  void (*allgather)(void *user, const void *mine, void *all, size_t bytes);
  /* element-wise sum over the ranks of count uint64 values, on every rank */
  void (*sum_u64)(void *user, uint64_t *values, size_t count);
  /* element-wise exclusive prefix sum over the ranks, in place: rank r gets
   * the sum of ranks 0 .. r-1 (rank 0: zeros) */
  void (*exscan_u64)(void *user, uint64_t *values, size_t count);
} bsurf_tile_comm;

/* ------------------------------------------------------------------------ */
/* Jobs: one call per command, in memory or tiled (issue 18)                 */
/* ------------------------------------------------------------------------ */

/* Where a job's points come from and where its results go: either a cloud
 * in memory (`cloud`: the job adds its output fields to it; writing it is
 * the caller's choice) or a binary PLY file processed tile by tile
 * (`input`, `output`, `tile_points`, the same bytes as in memory; with
 * `comm`, every process of a distributed run makes the same call). */
typedef struct bsurf_job_io {
  bsurf_cloud *cloud;          /* in memory; NULL for a tiled run */
  const bsurf_cloud *test;     /* error: an independent sample of the same
                                  points (err_test), in memory only; or NULL */
  const char *input;           /* tiled: binary PLY read by offset */
  const char *output;          /* tiled: binary little-endian PLY, written
                                  atomically (nothing on failure) */
  size_t tile_points;          /* tiled: about this many points per tile
                                  (raised to 2 K) */
  size_t range_points;         /* tiled: the output is assembled at most this
                                  many points at a time, at least 64 (0: the
                                  larger of tile_points and 32 MiB of rows;
                                  with comm at most points / ranks) */
  const bsurf_tile_comm *comm; /* tiled: messages between processes, or NULL */
} bsurf_job_io;

#define BSURF_ERROR_JOB_FIELDS 10

/* What `bootsurf error` prints (text and --json): every number comes from
 * here. */
typedef struct bsurf_error_job_summary {
  size_t points;
  double h;                                        /* mean nearest-neighbour distance */
  size_t duplicates;                               /* points at the same place as another */
  bsurf_error_report report;                       /* replicate and degree counters */
  int field_count;                                 /* 8, or 10 with a test sample */
  const char *field_names[BSURF_ERROR_JOB_FIELDS]; /* err_train, err_boot,
                                err_loo, err_loo_center, err_632,
                                err_632plus, gamma, overfit_rate (Eqs. 4.3-4.11),
                                err_test, err_test_center */
  double means[BSURF_ERROR_JOB_FIELDS];            /* each field's mean over the points,
                                           summed in point order (tiled: per tile, then
                                           over the tiles in order) */
  size_t tile_points, tiles;                       /* tiled runs: the tile size used, the tiles */
  size_t bad_point;                                /* BSURF_ERR_INVALID_VALUE in a tiled run: the
                                                      first non-finite point */
} bsurf_error_job_summary;

/* Bootstrap test error of every point (Algorithm 1, bsurf_estimate_error)
 * with its neighbourhoods (bsurf_neighbors_build) and the summary, in
 * memory or tiled through the same call. opts: NULL = defaults; its
 * progress callback (which may cancel) sees the neighbour search, then the
 * estimation (tiled: the points done of this process's share). The fields
 * (field_names, BSURF_FLOAT32) are added to io->cloud, or written with the
 * input's to io->output. err (may be NULL): where a tiled run's input is
 * wrong. BSURF_ERR_INVALID_ARG (message: bsurf_last_message()) for bad
 * options or io; otherwise the statuses of the calls above. */
BSURF_API bsurf_status bsurf_error_job(const bsurf_job_io *io, const bsurf_error_options *opts,
                                       bsurf_error_job_summary *summary, bsurf_failure *err);

/* ---- normals (thesis chapter 5) ---- */

typedef enum bsurf_orient_mode {
  BSURF_ORIENT_NONE = 0, /* unoriented, as estimated */
  BSURF_ORIENT_MST       /* bsurf_orient_normals (Hoppe et al. 1992) */
} bsurf_orient_mode;

/* One candidate (K, degree) of a selection: its means over the points
 * (figs. 5.6-5.11), summed in point order. */
typedef struct bsurf_normals_curve_row {
  int k, degree;          /* degree 1 for PCA */
  double mean_normal_err; /* Eq. 5.10 */
  double mean_normal_var; /* Eq. 5.5 */
  double mean_angle_err;  /* against curve_truth (rad); NAN without it */
} bsurf_normals_curve_row;

/* What `bootsurf normals` does, its options with the command's defaults
 * (bsurf_normals_job_options_default). New fields are added at the end. */
typedef struct bsurf_normals_job_options {
  bsurf_normal_options normals; /* fit, PCA centre, K (30), degree (2), B (50),
                                   seed, threads, and the progress callback of
                                   the whole job (which may cancel); its
                                   point_index is the job's own */
  int test_error;               /* 1: also normal_err (Eq. 5.10) against the
                                   reference normals (0; 1 when selecting) */
  int k_ref;                    /* K of the reference PCA normals of Eq. 5.10,
                                   >= 3 (0 = normals.k) */
  /* Per-point selection (5.5, Algorithm 3): candidate K values, strictly
   * ascending, each >= 3 (NULL: none, normals.k alone), and with POLY
   * candidate degrees 1..4 (NULL: normals.degree alone). K >= the degree's
   * terms. At most 1024 candidates of K. */
  const int *select_k;
  int select_k_count;
  const int *select_degree;
  int select_degree_count;
  bsurf_kselect_rule select_rule; /* AUTO (the default: MSE where it
                                     applies, else TEST_ERROR), TEST_ERROR
                                     (the thesis's), or MSE (bsurf_select_k:
                                     candidates >= 7, PCA or POLY; in two
                                     stages in a tiled run) */
  int noise_k;                    /* MSE: the noise fits' neighbourhood (12; >= 12) */
  bsurf_noise_pool noise_pool;    /* MSE: GLOBAL (default) or LOCAL noise level */
  /* Bilateral normal smoothing after the estimate (bsurf_smooth_normals,
   * Eq. 5.6; in memory only): passes (0), strength alpha (0.1, in [0, 1]),
   * spatial sigma (<= 0: h), variance sigma (NAN: auto, the 85th percentile
   * of normal_var; INFINITY: the single Gaussian filter; else > 0). */
  int smooth_iterations;
  double alpha;
  double sigma_d;
  double sigma_nu;
  bsurf_orient_mode orient; /* NONE (MST: in memory only) */
  /* In memory only, with select_k and the TEST_ERROR rule: NULL, or room
   * for select_k_count x max(1, select_degree_count) rows, filled with each
   * candidate's means in the order K, then degree (summary->curve_rows). */
  bsurf_normals_curve_row *curve;
  const double *curve_truth; /* NULL or point_count x 3 true normals: the
                                curve's mean_angle_err */
} bsurf_normals_job_options;

BSURF_API bsurf_normals_job_options bsurf_normals_job_options_default(void);

#define BSURF_NORMALS_JOB_FIELDS 4

/* What `bootsurf normals` prints (text and --json). */
typedef struct bsurf_normals_job_summary {
  size_t points;
  double h;                                          /* mean nearest-neighbour distance */
  size_t duplicates;                                 /* points at the same place as another */
  bsurf_normal_report report;                        /* over every candidate run */
  int field_count;                                   /* the fields written besides the normals */
  const char *field_names[BSURF_NORMALS_JOB_FIELDS]; /* of normal_var (B >= 2),
                                 normal_err, k_selected, degree_selected */
  double means[BSURF_NORMALS_JOB_FIELDS];            /* each field's mean over the
                                                        points (as the error job's) */
  double sigma_d, sigma_nu;       /* smoothing: the sigmas applied (INFINITY: single Gaussian) */
  size_t curve_rows;              /* rows filled in opts->curve */
  size_t tile_points, tiles;      /* tiled runs: the tile size used, the tiles */
  size_t bad_point;               /* BSURF_ERR_INVALID_VALUE in a tiled run: the
                                     first non-finite point */
  bsurf_kselect_rule select_rule; /* the rule applied (AUTO resolved) */
} bsurf_normals_job_summary;

/* Normals with bootstrap confidence of every point (bsurf_estimate_normals,
 * or the per-point selection of K and degree; then smoothing and
 * orientation if asked), in memory or tiled through the same call. The
 * normals replace the cloud's (FLOAT32 when it had none) and the fields
 * (field_names: normal_var FLOAT32, normal_err FLOAT32, k_selected UINT16,
 * degree_selected UINT8) are added to io->cloud, or written with the
 * input's to io->output. Tiled runs with normal_err run two stages (the
 * reference normals of every point first). err (may be NULL): where a tiled
 * run's input is wrong. BSURF_ERR_INVALID_ARG (message:
 * bsurf_last_message()) for bad options or io, BSURF_ERR_TOO_FEW_POINTS for
 * fewer points than the largest K; otherwise the statuses of the calls
 * above. */
BSURF_API bsurf_status bsurf_normals_job(const bsurf_job_io *io,
                                         const bsurf_normals_job_options *opts,
                                         bsurf_normals_job_summary *summary, bsurf_failure *err);

/* What bsurf_normals_job runs with these options and the memory it needs,
 * for a front end's memory plan (whether to tile, how large the tiles;
 * docs/scaling.md): */
typedef struct bsurf_normals_job_plan {
  bsurf_kselect_rule select_rule; /* the rule applied (AUTO resolved as the job
                                     resolves it) */
  int k_max;                      /* the neighbourhood searched: the largest of
                                     normals.k, k_ref, the candidates and, with
                                     MSE, noise_k */
  int field_count;                /* the fields written besides the normals */
  double point_bytes;             /* bytes per point of the cloud in memory, or of a
                                     tile's points, of the job's own arrays (results,
                                     the selection's passes), besides the cloud, the
                                     neighbour rows and the k-d tree: an upper bound
                                     (MSE: every candidate counted as tied) */
  double cloud_bytes;             /* bytes per point of the whole cloud that a tiled
                                     run holds on every rank besides a tile: 16 for MSE
                                     with the GLOBAL pool (the pooled values and their
                                     median's copy), else 0 */
} bsurf_normals_job_plan;

/* The plan of bsurf_normals_job(io, opts, ...) for any io: opts NULL =
 * defaults. BSURF_ERR_INVALID_ARG (message: bsurf_last_message(), naming
 * bsurf_normals_job_memory) for the options the job refuses in memory, or
 * plan NULL. */
BSURF_API bsurf_status bsurf_normals_job_memory(const bsurf_normals_job_options *opts,
                                                bsurf_normals_job_plan *plan);

/* ---- smooth (thesis chapter 6) ---- */

/* What `bootsurf smooth` does (bsurf_smooth_job_options_default: the
 * command's defaults). Lengths of `smooth` may be given in units of h, the
 * mean spacing, which is known only once the neighbourhoods are: a flag
 * set to 1 multiplies that length by h (NAN, INFINITY and values <= 0 keep
 * their meaning). New fields are added at the end. */
typedef struct bsurf_smooth_job_options {
  bsurf_smooth_options smooth;                        /* method, error (K, degree, B, seed, gamma,
                                                         PCA centre, threads, progress of the whole
                                                         job), estimator, lengths, guard ... */
  int threshold_in_h, h1_in_h, h2_in_h, k_error_in_h; /* (0) */
} bsurf_smooth_job_options;

BSURF_API bsurf_smooth_job_options bsurf_smooth_job_options_default(void);

#define BSURF_SMOOTH_JOB_FIELDS 5

/* What `bootsurf smooth` prints (text and --json). */
typedef struct bsurf_smooth_job_summary {
  size_t points;
  double h;
  size_t duplicates;
  bsurf_smooth_report report;                       /* mean |W|, threshold, sigmas,
                                                       moved points, counters */
  const char *estimator;                            /* W: "err_632" or "err_632plus" */
  int field_count;                                  /* 3, or 5 for multipass */
  const char *field_names[BSURF_SMOOTH_JOB_FIELDS]; /* err_632, err_632plus,
                                                       moved, k_hat, d_local */
  double means[BSURF_SMOOTH_JOB_FIELDS];
  size_t tile_points, tiles, bad_point; /* as bsurf_normals_job_summary */
  bsurf_smooth_method method;           /* the method that ran (AUTO resolved) */
} bsurf_smooth_job_summary;

/* Denoising driven by the bootstrap error (bsurf_smooth), in memory or
 * tiled through the same call (naive and bilateral with the parallel order:
 * two tiled stages; multipass and the sequential order are in memory only).
 * The points move; the input's normals are dropped (they belong to the old
 * positions); the fields are added to io->cloud or written to io->output.
 * Statuses as bsurf_normals_job. */
BSURF_API bsurf_status bsurf_smooth_job(const bsurf_job_io *io,
                                        const bsurf_smooth_job_options *opts,
                                        bsurf_smooth_job_summary *summary, bsurf_failure *err);

/* The doubles per point a smooth job keeps besides the cloud and its
 * neighbourhoods (the values of its first tiled stage), for a caller's
 * choice between memory and tiles; 0: the method and order run in memory
 * only (multipass, the sequential order). */
BSURF_API size_t bsurf_smooth_job_point_values(const bsurf_smooth_job_options *opts);

/* What bsurf_smooth_job runs in memory with these options and the memory it
 * needs, for a front end's memory plan (whether to tile, how large the
 * tiles, how wide the scale rule may widen K; docs/smoothing.md, "Memory"): */
typedef struct bsurf_smooth_job_plan {
  bsurf_smooth_method method; /* in memory (AUTO resolved: MULTIPASS; a tiled run
                                 of AUTO runs BILATERAL) */
  int k;                      /* the neighbourhood searched first: smooth.error.k */
  int k_max;                  /* the largest neighbourhood the run may search: with
                                 MULTIPASS and the guard the scale rule's cap
                                 (smooth.k_max, 0: 8 k, at most 65535), else k */
  int field_count;            /* the fields added: 3, or 5 for MULTIPASS */
  double point_bytes;         /* bytes per point the job holds at once besides the
                                 cloud (coordinates and fields) and the k-neighbour
                                 rows (4 k) with their k-d tree: an upper bound
                                 counting k_max (the scale rule's neighbour table,
                                 reverse lists and active pairs at k_max) */
  double k_max_bytes;         /* the part of point_bytes per unit of k_max (12 with
                                 the scale rule, else 0): point_bytes at a smaller
                                 cap K is point_bytes - (k_max - K) k_max_bytes */
} bsurf_smooth_job_plan;

/* The plan of bsurf_smooth_job(io with a cloud, opts, ...): opts NULL =
 * defaults. The thread count (smooth.error.threads, resolved) counts when
 * multipass runs a fixed number of passes. BSURF_ERR_INVALID_ARG (message:
 * bsurf_last_message()) for the options the job refuses in memory, or plan
 * NULL. */
BSURF_API bsurf_status bsurf_smooth_job_memory(const bsurf_smooth_job_options *opts,
                                               bsurf_smooth_job_plan *plan);

/* ---- features (thesis chapter 7) ---- */

/* What `bootsurf features` prints (text and --json). */
typedef struct bsurf_features_job_summary {
  size_t points;
  double h;
  size_t duplicates;
  bsurf_feature_report report;
  const char *field_names[2]; /* "feature" (UINT8) and the score: "feature_dist"
                                 (distance) or "normal_var" (variance), FLOAT32 */
  /* An input field of that name: kept[i] = 1 when it was renamed NAME_in
   * (ground truth, most often); replaced[i] = 1 when NAME_in existed (NAME
   * was an earlier result and is overwritten). */
  int kept[2], replaced[2];
  size_t tile_points, tiles, bad_point; /* as bsurf_normals_job_summary */
} bsurf_features_job_summary;

/* Feature detection (bsurf_detect_features, both methods), in memory or
 * tiled through the same call (distance: a chain of tiled stages, one per
 * filter pass; variance: two). opts: NULL = bsurf_feature_options_default();
 * its progress callback is the whole job's. The fields are added to
 * io->cloud or written to io->output. Statuses as bsurf_normals_job. */
BSURF_API bsurf_status bsurf_features_job(const bsurf_job_io *io, const bsurf_feature_options *opts,
                                          bsurf_features_job_summary *summary, bsurf_failure *err);
/* The largest neighbourhood table bsurf_features_job may build in memory for
 * these options (distance: k_max; variance: normals.k, or the K choice's cap
 * with feature_angle > 0, and the quadric check's K_q and the noise passes'
 * 80 under the null rule), for a memory estimate. opts: NULL = the
 * defaults. */
BSURF_API int bsurf_features_job_neighbors(const bsurf_feature_options *opts);

/* ------------------------------------------------------------------------ */
/* Random numbers                                                            */
/* ------------------------------------------------------------------------ */

/* A counter-based generator: the stream is a pure function of (seed, a, b),
 * so draws never depend on thread scheduling. */
typedef struct bsurf_rng {
  uint64_t s[4];
} bsurf_rng;

BSURF_API void bsurf_rng_init(bsurf_rng *rng, uint64_t seed, uint64_t a, uint64_t b);
BSURF_API uint64_t bsurf_rng_next(bsurf_rng *rng);
/* Uniform in [0, 1) with 53 random bits. */
BSURF_API double bsurf_rng_uniform(bsurf_rng *rng);
/* Uniform integer in [0, n), unbiased (n > 0). */
BSURF_API uint32_t bsurf_rng_below(bsurf_rng *rng, uint32_t n);
/* Standard normal (Box-Muller, both values drawn from this stream). */
BSURF_API double bsurf_rng_normal(bsurf_rng *rng);

/* ------------------------------------------------------------------------ */
/* Threads                                                                   */
/* ------------------------------------------------------------------------ */

/* The number of threads a call with `threads` will use (0 = all cores); 1
 * when built without OpenMP. */
BSURF_API int bsurf_threads_resolve(int threads);

#ifdef __cplusplus
}
#endif

#endif /* BOOTSURF_H */
