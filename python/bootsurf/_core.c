/* bootsurf._core: the CPython + NumPy binding of include/bootsurf.h.
 *
 * A thin front end: every function converts its arguments, releases the GIL,
 * makes the library call(s) the command line makes, and converts the results
 * back. Nothing is computed here that the library could compute (the
 * Python-level wrappers, docstrings and option names are in __init__.py).
 *
 * Arrays: points and other inputs are taken as C-contiguous float64 arrays
 * (numpy converts float32, integer or strided input with one copy, and passes
 * a C-contiguous float64 array through untouched). Outputs the library
 * allocates (a read cloud's arrays, a job's fields) are handed to numpy
 * without a copy: the array owns them through a capsule that free()s them.
 *
 * Interrupts: the library calls its progress callback between chunks of
 * points, on the calling thread. The callback takes the GIL back, runs
 * PyErr_CheckSignals() (Python's SIGINT handler raises KeyboardInterrupt
 * there, on the main thread) and the user's progress callable, and asks the
 * library to stop when either raised; the exception then propagates. Should
 * the callback ever run on another thread (an OpenMP worker), it only reads
 * the `stop` flag set by the calling thread and never touches Python. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bootsurf.h"

/* ---- calls with the GIL released, the progress callback ---- */

typedef struct call_ctx {
  PyObject *progress; /* a callable (done, total), or NULL */
  PyThreadState *ts;  /* the calling thread's state while the GIL is released */
  pthread_t thread;   /* the calling thread */
  volatile int stop;  /* a Python exception is pending: stop the library */
} call_ctx;

static void ctx_init(call_ctx *c, PyObject *progress) {
  c->progress = progress == Py_None ? NULL : progress;
  c->ts = NULL;
  c->thread = pthread_self();
  c->stop = 0;
}

static int progress_cb(void *user, size_t done, size_t total) {
  call_ctx *c = user;
  if (!pthread_equal(pthread_self(), c->thread) || c->stop) return c->stop;
  PyEval_RestoreThread(c->ts);
  if (PyErr_CheckSignals() < 0) {
    c->stop = 1;
  } else if (c->progress) {
    PyObject *r = PyObject_CallFunction(c->progress, "nn", (Py_ssize_t)done, (Py_ssize_t)total);
    if (!r)
      c->stop = 1;
    else
      Py_DECREF(r);
  }
  c->ts = PyEval_SaveThread();
  return c->stop;
}

/* ctx_init (progress != NULL) and the library's progress members of an
 * options struct set to the binding's callback. */
static void ctx_hook(call_ctx *c, PyObject *progress, bsurf_progress_fn *fn, void **user) {
  if (progress) ctx_init(c, progress);
  *fn = progress_cb;
  *user = c;
}

#define RELEASE(c) ((c)->ts = PyEval_SaveThread())
#define ACQUIRE(c) PyEval_RestoreThread((c)->ts)

/* ---- errors ---- */

/* The exception of a failed status: the pending Python exception after a
 * cancel, ValueError (bad arguments and data: the library's message),
 * MemoryError, OSError "PATH:LINE: message" for files. */
static PyObject *fail(bsurf_status st, const call_ctx *c, const char *path,
                      const bsurf_failure *err) {
  if (st == BSURF_ERR_CANCELLED && c && c->stop && PyErr_Occurred()) return NULL;
  if (st == BSURF_ERR_CANCELLED) {
    PyErr_SetNone(PyExc_KeyboardInterrupt);
    return NULL;
  }
  const char *msg = bsurf_last_message();
  if (!msg || !msg[0]) msg = bsurf_strerror(st);
  switch (st) {
  case BSURF_ERR_NOMEM: PyErr_NoMemory(); return NULL;
  case BSURF_ERR_IO:
  case BSURF_ERR_PARSE:
  case BSURF_ERR_UNSUPPORTED:
    if (path) {
      const char *m = err && err->message[0] ? err->message : msg;
      if (err && err->line > 0)
        PyErr_Format(PyExc_OSError, "%s:%ld: %s", path, err->line, m);
      else if (err && err->byte >= 0)
        PyErr_Format(PyExc_OSError, "%s: byte %lld: %s", path, err->byte, m);
      else
        PyErr_Format(PyExc_OSError, "%s: %s", path, m);
      return NULL;
    }
    PyErr_SetString(PyExc_OSError, msg);
    return NULL;
  default:
    if (err && err->message[0]) msg = err->message;
    if (path)
      PyErr_Format(PyExc_ValueError, "%s: %s", path, msg);
    else
      PyErr_SetString(PyExc_ValueError, msg);
    return NULL;
  }
}

/* In memory, the subject of the data's faults (too few points, a NaN
 * coordinate), where the command line names the input file: "points". */
static const char *about_points(bsurf_status st) {
  return st == BSURF_ERR_TOO_FEW_POINTS || st == BSURF_ERR_INVALID_VALUE ? "points" : NULL;
}

/* ---- arrays ---- */

/* `obj` as a C-contiguous float64 array of shape (N, cols) (cols 0: (N,)),
 * copied only when needed. NULL with TypeError / ValueError naming `what`. */
static PyArrayObject *as_f64(PyObject *obj, const char *what, int cols) {
  PyArrayObject *in = (PyArrayObject *)PyArray_FROMANY(obj, NPY_NOTYPE, 0, 0, 0);
  if (!in) return NULL;
  int kind = PyArray_DESCR(in)->kind;
  if (kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b') {
    PyErr_Format(PyExc_TypeError, "%s: expected a float32 or float64 array, not dtype %S", what,
                 (PyObject *)PyArray_DESCR(in));
    Py_DECREF(in);
    return NULL;
  }
  int nd = PyArray_NDIM(in);
  if ((cols > 0 && (nd != 2 || PyArray_DIM(in, 1) != cols)) || (cols == 0 && nd != 1)) {
    PyObject *shape = PyObject_GetAttrString((PyObject *)in, "shape");
    if (cols > 0)
      PyErr_Format(PyExc_ValueError, "%s: expected an array of shape (N, %d), not %S", what, cols,
                   shape);
    else
      PyErr_Format(PyExc_ValueError, "%s: expected an array of shape (N,), not %S", what, shape);
    Py_XDECREF(shape);
    Py_DECREF(in);
    return NULL;
  }
  PyArrayObject *out = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)in, NPY_DOUBLE,
                                                         NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
  Py_DECREF(in);
  return out;
}

/* Optional (N, cols) input: NULL with no error for None. */
static int opt_f64(PyObject *obj, const char *what, int cols, size_t n, PyArrayObject **out) {
  *out = NULL;
  if (!obj || obj == Py_None) return 0;
  *out = as_f64(obj, what, cols);
  if (!*out) return -1;
  if ((size_t)PyArray_DIM(*out, 0) != n) {
    PyErr_Format(PyExc_ValueError, "%s: has %zd rows, the points %zu", what, PyArray_DIM(*out, 0),
                 n);
    Py_CLEAR(*out);
    return -1;
  }
  return 0;
}

/* A (n,) array of 0/1 labels as C-contiguous uint8; NULL with ValueError
 * naming `what` when its length is not n. */
static PyArrayObject *mask_u8(PyObject *obj, const char *what, size_t n) {
  PyArrayObject *m = (PyArrayObject *)PyArray_FROMANY(obj, NPY_UINT8, 1, 1,
                                                      NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
  if (m && (size_t)PyArray_DIM(m, 0) != n) {
    PyErr_Format(PyExc_ValueError, "%s: has %zd values, the points %zu", what, PyArray_DIM(m, 0),
                 n);
    Py_CLEAR(m);
  }
  return m;
}

static double *f64(PyArrayObject *a) {
  return a ? (double *)PyArray_DATA(a) : NULL;
}

static void capsule_free(PyObject *cap) {
  free(PyCapsule_GetPointer(cap, "bootsurf.buffer"));
}

/* A numpy array over `data` (malloc'ed by the library), which it then owns. */
static PyObject *adopt(void *data, int nd, npy_intp *dims, int type) {
  if (!data) return PyArray_ZEROS(nd, dims, type, 0);
  PyObject *a = PyArray_SimpleNewFromData(nd, dims, type, data);
  if (!a) return NULL;
  PyObject *cap = PyCapsule_New(data, "bootsurf.buffer", capsule_free);
  if (!cap || PyArray_SetBaseObject((PyArrayObject *)a, cap) < 0) {
    Py_XDECREF(cap);
    Py_DECREF(a);
    return NULL;
  }
  return a;
}

static int npy_type_of(bsurf_type t) {
  switch (t) {
  case BSURF_INT8: return NPY_INT8;
  case BSURF_UINT8: return NPY_UINT8;
  case BSURF_INT16: return NPY_INT16;
  case BSURF_UINT16: return NPY_UINT16;
  case BSURF_INT32: return NPY_INT32;
  case BSURF_UINT32: return NPY_UINT32;
  case BSURF_FLOAT32: return NPY_FLOAT32;
  default: return NPY_FLOAT64;
  }
}

static bsurf_type bsurf_type_of(PyArrayObject *a) {
  switch (PyArray_TYPE(a)) {
  case NPY_INT8: return BSURF_INT8;
  case NPY_UINT8:
  case NPY_BOOL: return BSURF_UINT8;
  case NPY_INT16: return BSURF_INT16;
  case NPY_UINT16: return BSURF_UINT16;
  case NPY_INT32: return BSURF_INT32;
  case NPY_UINT32: return BSURF_UINT32;
  case NPY_FLOAT32: return BSURF_FLOAT32;
  default: return BSURF_FLOAT64;
  }
}

/* A library array of doubles as numpy `type`: adopted when float64, else
 * cast (values of the file's type are exact) and freed. */
static PyObject *doubles_as(double *data, int nd, npy_intp *dims, int type) {
  PyObject *a = adopt(data, nd, dims, NPY_DOUBLE);
  if (!a || type == NPY_DOUBLE) return a;
  PyObject *b = PyArray_Cast((PyArrayObject *)a, type);
  Py_DECREF(a);
  return b;
}

static int set_item(PyObject *dict, const char *key, PyObject *value) {
  if (!value) return -1;
  int r = PyDict_SetItemString(dict, key, value);
  Py_DECREF(value);
  return r;
}

/* Moves a cloud's arrays into a dict of numpy arrays ("points", "normals",
 * "faces", one per field in the type it is stored with); empties the cloud. */
static PyObject *dict_from_cloud(bsurf_cloud *c) {
  PyObject *d = PyDict_New();
  if (!d) return NULL;
  npy_intp n3[2] = {(npy_intp)c->point_count, 3}, n1[1] = {(npy_intp)c->point_count};
  npy_intp f3[2] = {(npy_intp)c->face_count, 3};
  int xyz32 = c->xyz_type == BSURF_FLOAT32, nrm32 = c->normal_type == BSURF_FLOAT32;
  if (set_item(d, "points", doubles_as(c->xyz, 2, n3, xyz32 ? NPY_FLOAT32 : NPY_DOUBLE))) goto bad;
  c->xyz = NULL;
  if (c->normals) {
    if (set_item(d, "normals", doubles_as(c->normals, 2, n3, nrm32 ? NPY_FLOAT32 : NPY_DOUBLE)))
      goto bad;
    c->normals = NULL;
  }
  for (size_t f = 0; f < c->field_count; f++) {
    bsurf_field *fl = &c->fields[f];
    if (set_item(d, fl->name, doubles_as(fl->values, 1, n1, npy_type_of(fl->type)))) goto bad;
    fl->values = NULL;
  }
  if (c->face_count) {
    if (set_item(d, "faces", adopt(c->faces, 2, f3, NPY_UINT32))) goto bad;
    c->faces = NULL;
  }
  bsurf_cloud_free(c);
  return d;
bad:
  Py_DECREF(d);
  bsurf_cloud_free(c);
  return NULL;
}

/* (dict, shape name) of a cloud the library made (read, generate), whose
 * arrays the dict takes. */
static PyObject *cloud_result(bsurf_cloud *c) {
  char shape[BSURF_FIELD_NAME_MAX];
  memcpy(shape, c->shape, sizeof shape);
  PyObject *d = dict_from_cloud(c);
  return d ? Py_BuildValue("(Ns)", d, shape) : NULL;
}

/* A cloud that borrows the buffers of a dict's arrays (never freed by the
 * library: only read). `keep` holds the converted arrays; `fields` is
 * PyMem-allocated (free it after use). */
typedef struct borrowed {
  bsurf_cloud cloud;
  PyObject *keep; /* list */
} borrowed;

static void borrowed_free(borrowed *b) {
  PyMem_Free(b->cloud.fields);
  b->cloud.fields = NULL;
  Py_CLEAR(b->keep);
}

static int keep_array(borrowed *b, PyArrayObject *a) {
  int r = PyList_Append(b->keep, (PyObject *)a);
  Py_DECREF(a);
  return r;
}

static int borrow_cloud(PyObject *dict, borrowed *b) {
  memset(b, 0, sizeof *b);
  if (!PyDict_Check(dict)) {
    PyErr_SetString(PyExc_TypeError, "a cloud is a dict of arrays with at least 'points'");
    return -1;
  }
  b->keep = PyList_New(0);
  if (!b->keep) return -1;
  bsurf_cloud *c = &b->cloud;
  PyObject *pts = PyDict_GetItemString(dict, "points");
  if (!pts) {
    PyErr_SetString(PyExc_ValueError, "the cloud has no 'points'");
    goto bad;
  }
  PyArrayObject *a = as_f64(pts, "points", 3);
  if (!a) goto bad;
  PyArrayObject *orig = (PyArrayObject *)PyArray_FROMANY(pts, NPY_NOTYPE, 0, 0, 0);
  c->xyz_type = orig && PyArray_TYPE(orig) == NPY_FLOAT32 ? BSURF_FLOAT32 : BSURF_FLOAT64;
  Py_XDECREF(orig);
  c->point_count = (size_t)PyArray_DIM(a, 0);
  c->xyz = f64(a);
  if (keep_array(b, a)) goto bad;
  c->normal_type = BSURF_FLOAT32;
  PyObject *key, *value;
  Py_ssize_t pos = 0, nf = 0;
  c->fields = PyMem_Calloc((size_t)PyDict_Size(dict) + 1, sizeof *c->fields);
  if (!c->fields) {
    PyErr_NoMemory();
    goto bad;
  }
  while (PyDict_Next(dict, &pos, &key, &value)) {
    const char *name = PyUnicode_Check(key) ? PyUnicode_AsUTF8(key) : NULL;
    if (!name) {
      PyErr_SetString(PyExc_TypeError, "the cloud's keys must be strings");
      goto bad;
    }
    if (!strcmp(name, "points")) continue;
    if (!strcmp(name, "faces")) {
      PyArrayObject *f = (PyArrayObject *)PyArray_FROMANY(value, NPY_UINT32, 2, 2,
                                                          NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
      if (!f) goto bad;
      if (PyArray_DIM(f, 1) != 3) {
        Py_DECREF(f);
        PyErr_SetString(PyExc_ValueError, "faces: expected an array of shape (F, 3)");
        goto bad;
      }
      c->face_count = (size_t)PyArray_DIM(f, 0);
      c->faces = PyArray_DATA(f);
      if (keep_array(b, f)) goto bad;
      continue;
    }
    PyArrayObject *orig2 = (PyArrayObject *)PyArray_FROMANY(value, NPY_NOTYPE, 0, 0, 0);
    if (!orig2) goto bad;
    bsurf_type t = bsurf_type_of(orig2);
    Py_DECREF(orig2);
    int normals = !strcmp(name, "normals");
    PyArrayObject *v = NULL;
    if (opt_f64(value, name, normals ? 3 : 0, c->point_count, &v)) goto bad;
    if (normals) {
      c->normals = f64(v);
      c->normal_type = t == BSURF_FLOAT64 ? BSURF_FLOAT64 : BSURF_FLOAT32;
    } else {
      if (strlen(name) >= BSURF_FIELD_NAME_MAX) {
        Py_DECREF(v);
        PyErr_Format(PyExc_ValueError, "field name '%s' is longer than %d characters", name,
                     BSURF_FIELD_NAME_MAX - 1);
        goto bad;
      }
      bsurf_field *fl = &c->fields[nf++];
      strcpy(fl->name, name);
      fl->type = t;
      fl->values = f64(v);
    }
    if (keep_array(b, v)) goto bad;
  }
  c->field_count = (size_t)nf;
  return 0;
bad:
  borrowed_free(b);
  return -1;
}

/* ---- files ---- */

static PyObject *py_read(PyObject *self, PyObject *args) {
  (void)self;
  const char *path;
  if (!PyArg_ParseTuple(args, "s", &path)) return NULL;
  bsurf_cloud c;
  bsurf_failure err = {0, -1, ""};
  bsurf_status st;
  Py_BEGIN_ALLOW_THREADS st = bsurf_read(path, &c, &err);
  Py_END_ALLOW_THREADS if (st != BSURF_OK) return fail(st, NULL, path, &err);
  return cloud_result(&c);
}

static PyObject *py_write(PyObject *self, PyObject *args) {
  (void)self;
  const char *path, *shape, *format;
  PyObject *dict;
  int ascii, float32, ply_names, las_legacy;
  if (!PyArg_ParseTuple(args, "sOszpipp", &path, &dict, &shape, &format, &ascii, &ply_names,
                        &float32, &las_legacy))
    return NULL;
  bsurf_write_options wo;
  memset(&wo, 0, sizeof wo);
  wo.ascii = ascii;
  wo.float32 = float32;
  wo.ply_names = (bsurf_ply_names)ply_names;
  wo.las_legacy = las_legacy;
  if (format) {
    wo.format = bsurf_format_from_name(format);
    if (wo.format == BSURF_FORMAT_UNKNOWN)
      return PyErr_Format(PyExc_ValueError,
                          "format '%s': unknown (ply, pcd, las, csv, asc, xyz, off, obj)", format);
  }
  borrowed b;
  if (borrow_cloud(dict, &b)) return NULL;
  snprintf(b.cloud.shape, sizeof b.cloud.shape, "%s", shape);
  bsurf_failure err = {0, -1, ""};
  bsurf_status st;
  Py_BEGIN_ALLOW_THREADS st = bsurf_write(path, &b.cloud, &wo, &err);
  Py_END_ALLOW_THREADS borrowed_free(&b);
  if (st != BSURF_OK) return fail(st, NULL, path, &err);
  Py_RETURN_NONE;
}

/* ---- neighbourhoods ---- */

static PyObject *py_knn(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *progress;
  int k, threads;
  if (!PyArg_ParseTuple(args, "OiiO", &pts, &k, &threads, &progress)) return NULL;
  PyArrayObject *a = as_f64(pts, "points", 3);
  if (!a) return NULL;
  size_t n = (size_t)PyArray_DIM(a, 0);
  if (k < 1 || (size_t)k > n) {
    Py_DECREF(a);
    return PyErr_Format(PyExc_ValueError, "k = %d: must be in [1, %zu] (the number of points)", k,
                        n);
  }
  /* bsurf_knn_build takes any doubles (a NaN point lands somewhere in the
   * tree): refuse them as bsurf_neighbors_build does for the jobs */
  const double *xyz = f64(a);
  for (size_t i = 0; i < 3 * n; i++)
    if (!isfinite(xyz[i])) {
      Py_DECREF(a);
      return PyErr_Format(PyExc_ValueError, "points: point %zu has a NaN or infinite coordinate",
                          i / 3);
    }
  npy_intp dims[2] = {(npy_intp)n, k};
  PyObject *idx = PyArray_SimpleNew(2, dims, NPY_UINT32),
           *d2 = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
  if (!idx || !d2) goto bad;
  call_ctx c;
  ctx_init(&c, progress);
  bsurf_knn_index *index = NULL;
  RELEASE(&c);
  bsurf_status st = bsurf_knn_build(&index, f64(a), n);
  if (st == BSURF_OK)
    st = bsurf_knn_all(index, k, threads, PyArray_DATA((PyArrayObject *)idx),
                       PyArray_DATA((PyArrayObject *)d2), progress_cb, &c);
  bsurf_knn_free(index);
  ACQUIRE(&c);
  Py_DECREF(a);
  if (st != BSURF_OK) {
    Py_DECREF(idx);
    Py_DECREF(d2);
    return fail(st, &c, about_points(st), NULL);
  }
  return Py_BuildValue("(NN)", idx, d2);
bad:
  Py_XDECREF(idx);
  Py_XDECREF(d2);
  Py_DECREF(a);
  return NULL;
}

static PyObject *py_spacing(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *progress;
  int threads;
  if (!PyArg_ParseTuple(args, "OiO", &pts, &threads, &progress)) return NULL;
  PyArrayObject *a = as_f64(pts, "points", 3);
  if (!a) return NULL;
  if (PyArray_DIM(a, 0) < 2) {
    Py_DECREF(a);
    return PyErr_Format(PyExc_ValueError,
                        "points: has %zd point(s); the spacing h needs at least 2",
                        PyArray_DIM(a, 0));
  }
  call_ctx c;
  ctx_init(&c, progress);
  double h = 0;
  RELEASE(&c);
  bsurf_status st =
      bsurf_mean_spacing_progress(f64(a), (size_t)PyArray_DIM(a, 0), threads, &h, progress_cb, &c);
  ACQUIRE(&c);
  Py_DECREF(a);
  if (st != BSURF_OK) return fail(st, &c, about_points(st), NULL);
  return PyFloat_FromDouble(h);
}

/* ---- jobs: in memory on the caller's points, or tiled file to file ---- */

/* Moves the named fields of a job's cloud into a dict (and frees the cloud;
 * its xyz is borrowed and left alone). */
static PyObject *take_fields(bsurf_cloud *c) {
  PyObject *d = PyDict_New();
  npy_intp n1[1] = {(npy_intp)c->point_count}, n3[2] = {(npy_intp)c->point_count, 3};
  for (size_t f = 0; d && f < c->field_count; f++) {
    /* float32 fields stay doubles (the job's values, before they are
     * rounded for a file); integer fields (labels, selected K) take their
     * type, which holds them exactly */
    int t = npy_type_of(c->fields[f].type);
    if (t == NPY_FLOAT32) t = NPY_DOUBLE;
    if (set_item(d, c->fields[f].name, doubles_as(c->fields[f].values, 1, n1, t)))
      Py_CLEAR(d);
    else
      c->fields[f].values = NULL;
  }
  if (d && c->normals) {
    if (set_item(d, "normals", adopt(c->normals, 2, n3, NPY_DOUBLE)))
      Py_CLEAR(d);
    else
      c->normals = NULL;
  }
  c->xyz = NULL;
  bsurf_cloud_free(c);
  return d;
}

/* One job call: its bsurf_job_io, the cloud over the caller's points (in
 * memory) or the files and tile size (tiled), the progress context and
 * where a tiled input is wrong. */
typedef struct job_call {
  PyArrayObject *a; /* in memory: the caller's points as float64 */
  int own_xyz;      /* cloud.xyz is a copy (jobs that move the points) */
  bsurf_cloud cloud;
  bsurf_job_io io;
  call_ctx c;
  bsurf_failure err;
} job_call;

/* tiled: None (in memory: the points, copied when `copy`) or (input,
 * output, tile_points), a binary PLY file processed tile by tile into
 * another (bsurf_job_io). -1 with an exception. */
static int job_begin(job_call *j, PyObject *pts, PyObject *tiled, int copy, PyObject *progress) {
  memset(j, 0, sizeof *j);
  bsurf_cloud_init(&j->cloud);
  j->err.byte = -1;
  ctx_init(&j->c, progress);
  if (tiled != Py_None) {
    Py_ssize_t tile_points;
    if (!PyArg_ParseTuple(tiled, "ssn", &j->io.input, &j->io.output, &tile_points)) return -1;
    if (tile_points < 1) {
      PyErr_Format(PyExc_ValueError, "tile_points = %zd: must be at least 1", tile_points);
      return -1;
    }
    j->io.tile_points = (size_t)tile_points;
    return 0;
  }
  if (!(j->a = as_f64(pts, "points", 3))) return -1;
  size_t n = (size_t)PyArray_DIM(j->a, 0);
  j->cloud.point_count = n;
  j->cloud.xyz = f64(j->a);
  if (copy) {
    j->cloud.xyz = malloc(n * 3 * sizeof(double) + 1);
    if (!j->cloud.xyz) {
      Py_CLEAR(j->a);
      PyErr_NoMemory();
      return -1;
    }
    memcpy(j->cloud.xyz, f64(j->a), n * 3 * sizeof(double));
    j->own_xyz = 1;
  }
  j->io.cloud = &j->cloud;
  return 0;
}

/* Frees what job_begin took (after an exception raised before the job). */
static void job_free(job_call *j) {
  if (j->own_xyz) free(j->cloud.xyz);
  j->cloud.xyz = NULL;
  bsurf_cloud_free(&j->cloud);
  Py_CLEAR(j->a);
}

/* After the job: its fields as a dict (None for a tiled run, whose results
 * are in the output file), or NULL with the exception: OSError naming the
 * input (and the line or byte) or, when the input is readable and nothing
 * places the failure in it, the output; ValueError "points: ..." for the
 * points' faults in memory. `points` (may be NULL): the moved
 * points of a job that moves them (None when tiled). Frees what job_begin
 * took. */
static PyObject *job_end(job_call *j, bsurf_status st, PyObject **points) {
  PyObject *fields = NULL;
  if (points) *points = NULL;
  if (st != BSURF_OK) {
    const char *path = about_points(st);
    if (j->io.input) {
      int located = j->err.line > 0 || j->err.byte >= 0;
      path = st == BSURF_ERR_IO && !located && access(j->io.input, R_OK) == 0 ? j->io.output
                                                                              : j->io.input;
    }
    fail(st, &j->c, path, j->io.input ? &j->err : NULL);
  } else if (!j->io.cloud) {
    Py_INCREF(Py_None);
    fields = Py_None;
    if (points) {
      Py_INCREF(Py_None);
      *points = Py_None;
    }
  } else if (points) {
    npy_intp n3[2] = {(npy_intp)j->cloud.point_count, 3};
    if ((*points = adopt(j->cloud.xyz, 2, n3, NPY_DOUBLE))) j->own_xyz = 0; /* numpy owns it */
    if (*points && !(fields = take_fields(&j->cloud))) Py_CLEAR(*points);
  } else {
    fields = take_fields(&j->cloud);
  }
  job_free(j);
  return fields;
}

/* (fields, summary) or (points, fields, summary), stealing the references;
 * NULL when any is NULL. */
static PyObject *job_result(PyObject *points, PyObject *fields, PyObject *sum) {
  if (!fields || !sum) {
    Py_XDECREF(points);
    Py_XDECREF(fields);
    Py_XDECREF(sum);
    return NULL;
  }
  return points ? Py_BuildValue("(NNN)", points, fields, sum) : Py_BuildValue("(NN)", fields, sum);
}

static PyObject *report_error(const bsurf_error_report *r) {
  return Py_BuildValue("{s:n,s:n,s:n,s:n}", "replicates_total", (Py_ssize_t)r->replicates_total,
                       "replicates_skipped", (Py_ssize_t)r->replicates_skipped, "degree_reduced",
                       (Py_ssize_t)r->degree_reduced, "center_unestimated",
                       (Py_ssize_t)r->center_unestimated);
}

/* The means of a job's fields as a dict. */
static PyObject *means_dict(const char *const *names, const double *means, int count) {
  PyObject *m = PyDict_New();
  for (int f = 0; m && f < count; f++)
    if (set_item(m, names[f], PyFloat_FromDouble(means[f]))) Py_CLEAR(m);
  return m;
}

/* `rest` (a dict, stolen) with the summary members every job has: points,
 * h, duplicates, and tile_points and tiles for a tiled run. */
static PyObject *job_summary(size_t points, double h, size_t duplicates, size_t tile_points,
                             size_t tiles, PyObject *rest) {
  if (!rest) return NULL;
  if (set_item(rest, "points", PyLong_FromSize_t(points)) ||
      set_item(rest, "h", PyFloat_FromDouble(h)) ||
      set_item(rest, "duplicates", PyLong_FromSize_t(duplicates)) ||
      (tiles && (set_item(rest, "tile_points", PyLong_FromSize_t(tile_points)) ||
                 set_item(rest, "tiles", PyLong_FromSize_t(tiles))))) {
    Py_DECREF(rest);
    return NULL;
  }
  return rest;
}

static PyObject *py_error(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *tiled, *test_obj, *progress;
  bsurf_error_options eo = bsurf_error_options_default();
  int gamma, center;
  unsigned long long seed;
  if (!PyArg_ParseTuple(args, "OOOiiiKiiiO", &pts, &tiled, &test_obj, &eo.k, &eo.degree,
                        &eo.bootstrap, &seed, &gamma, &center, &eo.threads, &progress))
    return NULL;
  eo.seed = seed;
  eo.gamma = (bsurf_gamma_mode)gamma;
  eo.pca_center = (bsurf_pca_center)center;
  job_call j;
  if (job_begin(&j, pts, tiled, 0, progress)) return NULL;
  PyArrayObject *t = NULL;
  bsurf_cloud test;
  bsurf_cloud_init(&test);
  if (opt_f64(test_obj, "test", 3, j.cloud.point_count, &t)) {
    job_free(&j);
    return NULL;
  }
  test.point_count = j.cloud.point_count;
  test.xyz = f64(t);
  j.io.test = t ? &test : NULL;
  ctx_hook(&j.c, NULL, &eo.progress, &eo.progress_user);
  bsurf_error_job_summary s;
  RELEASE(&j.c);
  bsurf_status st = bsurf_error_job(&j.io, &eo, &s, &j.err);
  ACQUIRE(&j.c);
  Py_XDECREF(t);
  PyObject *fields = job_end(&j, st, NULL);
  if (!fields) return NULL;
  return job_result(
      NULL, fields,
      job_summary(s.points, s.h, s.duplicates, s.tile_points, s.tiles,
                  Py_BuildValue("{s:N,s:N}", "report", report_error(&s.report), "means",
                                means_dict(s.field_names, s.means, s.field_count))));
}

/* An optional sequence of ints into buf (at most max); -1 with an error. */
static int int_list(PyObject *obj, const char *what, int *buf, int max) {
  if (obj == Py_None) return 0;
  PyObject *seq = PySequence_Fast(obj, "a sequence of integers");
  if (!seq) return -1;
  Py_ssize_t n = PySequence_Fast_GET_SIZE(seq);
  if (n > max) {
    Py_DECREF(seq);
    PyErr_Format(PyExc_ValueError, "%s: at most %d values, not %zd", what, max, n);
    return -1;
  }
  for (Py_ssize_t i = 0; i < n; i++) {
    long v = PyLong_AsLong(PySequence_Fast_GET_ITEM(seq, i));
    if (v == -1 && PyErr_Occurred()) {
      Py_DECREF(seq);
      return -1;
    }
    buf[i] = (int)v;
  }
  Py_DECREF(seq);
  return (int)n;
}

static PyObject *normal_report(const bsurf_normal_report *r) {
  return Py_BuildValue("{s:n,s:n,s:n,s:n}", "replicates_total", (Py_ssize_t)r->replicates_total,
                       "replicates_skipped", (Py_ssize_t)r->replicates_skipped, "degree_reduced",
                       (Py_ssize_t)r->degree_reduced, "degenerate", (Py_ssize_t)r->degenerate);
}

static PyObject *curve_rows(const bsurf_normals_curve_row *curve, size_t count) {
  PyObject *rows = PyList_New(0);
  for (size_t r = 0; rows && r < count; r++) {
    PyObject *row =
        Py_BuildValue("{s:i,s:i,s:d,s:d,s:d}", "k", curve[r].k, "degree", curve[r].degree,
                      "mean_normal_err", curve[r].mean_normal_err, "mean_normal_var",
                      curve[r].mean_normal_var, "mean_angle_err", curve[r].mean_angle_err);
    if (!row || PyList_Append(rows, row)) Py_CLEAR(rows);
    Py_XDECREF(row);
  }
  return rows;
}

#define MAX_KS 1024

static PyObject *py_normals(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *tiled, *ks_obj, *ds_obj, *truth_obj, *progress;
  bsurf_normals_job_options o = bsurf_normals_job_options_default();
  int fit, center, rule, noise_pool, orient, want_curve;
  unsigned long long seed;
  if (!PyArg_ParseTuple(args, "OOiiiiiKipiOiiiOidddipOO", &pts, &tiled, &o.normals.k, &fit,
                        &o.normals.degree, &center, &o.normals.bootstrap, &seed, &o.normals.threads,
                        &o.test_error, &o.k_ref, &ks_obj, &rule, &o.noise_k, &noise_pool, &ds_obj,
                        &o.smooth_iterations, &o.alpha, &o.sigma_d, &o.sigma_nu, &orient,
                        &want_curve, &truth_obj, &progress))
    return NULL;
  o.normals.fit = (bsurf_normal_fit)fit;
  o.normals.pca_center = (bsurf_pca_center)center;
  o.normals.seed = seed;
  o.select_rule = (bsurf_kselect_rule)rule;
  o.noise_pool = (bsurf_noise_pool)noise_pool;
  o.orient = (bsurf_orient_mode)orient;
  int kbuf[MAX_KS], dbuf[4];
  int nk = int_list(ks_obj, "select_k", kbuf, MAX_KS);
  int nd = nk < 0 ? -1 : int_list(ds_obj, "select_degree", dbuf, 4);
  if (nk < 0 || nd < 0) return NULL;
  o.select_k = nk ? kbuf : NULL;
  o.select_k_count = nk;
  o.select_degree = nd ? dbuf : NULL;
  o.select_degree_count = nd;
  job_call j;
  if (job_begin(&j, pts, tiled, 0, progress)) return NULL;
  PyArrayObject *tr = NULL;
  bsurf_normals_curve_row *curve = NULL;
  if (opt_f64(truth_obj, "truth", 3, j.cloud.point_count, &tr)) {
    job_free(&j);
    return NULL;
  }
  if (want_curve && nk &&
      !(curve = PyMem_Calloc((size_t)nk * (size_t)(nd ? nd : 1), sizeof *curve))) {
    Py_XDECREF(tr);
    job_free(&j);
    return PyErr_NoMemory();
  }
  o.curve = curve;
  o.curve_truth = f64(tr);
  ctx_hook(&j.c, NULL, &o.normals.progress, &o.normals.progress_user);
  bsurf_normals_job_summary s;
  RELEASE(&j.c);
  bsurf_status st = bsurf_normals_job(&j.io, &o, &s, &j.err);
  ACQUIRE(&j.c);
  Py_XDECREF(tr);
  PyObject *fields = job_end(&j, st, NULL), *ret = NULL;
  if (fields)
    ret = job_result(
        NULL, fields,
        job_summary(s.points, s.h, s.duplicates, s.tile_points, s.tiles,
                    Py_BuildValue("{s:N,s:N,s:d,s:d,s:N}", "report", normal_report(&s.report),
                                  "means", means_dict(s.field_names, s.means, s.field_count),
                                  "sigma_d", s.sigma_d, "sigma_nu", s.sigma_nu, "curve",
                                  curve_rows(curve, s.curve_rows))));
  PyMem_Free(curve);
  return ret;
}

/* ---- smoothing (chapter 6) and features (chapter 7): the library's jobs ---- */

static PyObject *py_smooth(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *tiled, *progress;
  bsurf_smooth_job_options o = bsurf_smooth_job_options_default();
  bsurf_smooth_options *so = &o.smooth;
  int method, gamma, center, estimator, order;
  unsigned long long seed;
  if (!PyArg_ParseTuple(args, "OOiiiiKiiidpdpdpdidiidpdpiiiO", &pts, &tiled, &method, &so->error.k,
                        &so->error.degree, &so->error.bootstrap, &seed, &gamma, &center, &estimator,
                        &so->threshold, &o.threshold_in_h, &so->h1, &o.h1_in_h, &so->h2, &o.h2_in_h,
                        &so->h2_fraction, &order, &so->a, &so->iterations, &so->k_min, &so->k_error,
                        &o.k_error_in_h, &so->k_error_fraction, &so->guard, &so->degree_test,
                        &so->k_max, &so->error.threads, &progress))
    return NULL;
  /* NAN: the library's default (the command's "auto") */
  const bsurf_smooth_options def = bsurf_smooth_options_default();
  if (isnan(so->h2)) so->h2 = def.h2;
  if (isnan(so->h2_fraction)) so->h2_fraction = def.h2_fraction;
  if (isnan(so->k_error)) so->k_error = def.k_error;
  if (isnan(so->k_error_fraction)) so->k_error_fraction = def.k_error_fraction;
  so->method = (bsurf_smooth_method)method;
  so->error.seed = seed;
  so->error.gamma = (bsurf_gamma_mode)gamma;
  so->error.pca_center = (bsurf_pca_center)center;
  so->estimator = (bsurf_smooth_estimator)estimator;
  so->order = (bsurf_smooth_order)order;
  /* the job moves the cloud's points: a copy the result array then owns */
  job_call j;
  if (job_begin(&j, pts, tiled, 1, progress)) return NULL;
  ctx_hook(&j.c, NULL, &so->error.progress, &so->error.progress_user);
  bsurf_smooth_job_summary s;
  RELEASE(&j.c);
  bsurf_status st = bsurf_smooth_job(&j.io, &o, &s, &j.err);
  ACQUIRE(&j.c);
  PyObject *points, *fields = job_end(&j, st, &points);
  if (!fields) return NULL;
  const bsurf_smooth_report *r = &s.report;
  return job_result(
      points, fields,
      job_summary(
          s.points, s.h, s.duplicates, s.tile_points, s.tiles,
          Py_BuildValue(
              "{s:s,s:s,s:N,s:N}", "method",
              s.method == BSURF_SMOOTH_NAIVE       ? "naive"
              : s.method == BSURF_SMOOTH_BILATERAL ? "bilateral"
                                                   : "multipass",
              "estimator", s.estimator ? s.estimator : "", "means",
              means_dict(s.field_names, s.means, s.field_count), "report",
              Py_BuildValue("{s:N,s:d,s:d,s:d,s:d,s:d,s:n,s:n,s:d,s:d,s:i,s:d,s:d,s:d,s:d,s:n,s:i}",
                            "error", report_error(&r->error), "mean_error", r->mean_error,
                            "threshold", r->threshold, "h1", r->h1, "h2", r->h2, "k_error",
                            r->k_error, "projected", (Py_ssize_t)r->projected, "moved_points",
                            (Py_ssize_t)r->moved_points, "moved_mean", r->moved_mean, "moved_max",
                            r->moved_max, "iterations", r->iterations, "noise", r->noise,
                            "noise_fits", r->noise_fits, "noise_select", r->noise_select,
                            "section_share", r->section_share, "misfit_fits",
                            (Py_ssize_t)r->misfit_fits, "k", r->k))));
}

static PyObject *py_features(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *tiled, *progress;
  bsurf_feature_options o = bsurf_feature_options_default();
  int method, rule;
  unsigned long long seed;
  if (!PyArg_ParseTuple(args, "OOiiiiiiddddiiddididdiKiO", &pts, &tiled, &method, &o.normals.k,
                        &o.normals.bootstrap, &o.k_min, &o.k_max, &o.k_step, &o.ratio_threshold,
                        &o.noise_factor, &o.derivative, &o.alpha, &o.iterations, &o.filter_k,
                        &o.sigma_range, &o.threshold, &rule, &o.false_positive_rate,
                        &o.variance_filter_k, &o.feature_angle, &o.quadric_angle, &o.variance_k_max,
                        &seed, &o.threads, &progress))
    return NULL;
  o.method = (bsurf_feature_method)method;
  o.tail_rule = (bsurf_tail_rule)rule;
  o.normals.seed = seed;
  job_call j;
  if (job_begin(&j, pts, tiled, 0, progress)) return NULL;
  ctx_hook(&j.c, NULL, &o.progress, &o.progress_user);
  bsurf_features_job_summary s;
  RELEASE(&j.c);
  bsurf_status st = bsurf_features_job(&j.io, &o, &s, &j.err);
  ACQUIRE(&j.c);
  PyObject *fields = job_end(&j, st, NULL);
  if (!fields) return NULL;
  const bsurf_feature_report *r = &s.report;
  return job_result(
      NULL, fields,
      job_summary(s.points, s.h, s.duplicates, s.tile_points, s.tiles,
                  Py_BuildValue(
                      "{s:{s:d,s:n,s:d,s:n,s:d,s:d,s:i,s:d,s:d,s:i,s:d,s:d,s:d,s:n,s:n}}", "report",
                      "threshold", r->threshold, "feature_points", (Py_ssize_t)r->feature_points,
                      "max_radius", r->max_radius, "immediate", (Py_ssize_t)r->immediate,
                      "ratio_threshold_kmin", r->ratio_threshold_kmin, "noise_level",
                      r->noise_level, "k", r->k, "edge_power", r->edge_power, "border_threshold",
                      r->border_threshold, "quadric_k", r->quadric_k, "quadric_threshold",
                      r->quadric_threshold, "quadric_power", r->quadric_power, "quadric_noise",
                      r->quadric_noise, "quadric_cleared", (Py_ssize_t)r->quadric_cleared,
                      "border_points", (Py_ssize_t)r->border_points)));
}

/* ---- synthetic data ---- */

static PyObject *py_generate(PyObject *self, PyObject *args) {
  (void)self;
  const char *shape_name;
  Py_ssize_t n;
  int sampling;
  unsigned long long seed;
  double width;
  if (!PyArg_ParseTuple(args, "sniKd", &shape_name, &n, &sampling, &seed, &width)) return NULL;
  bsurf_shape shape;
  if (bsurf_shape_from_name(shape_name, &shape) != 0)
    return PyErr_Format(PyExc_ValueError, "unknown shape '%s' (sphere, cube, torus, plane)",
                        shape_name);
  if (n < 1) return PyErr_Format(PyExc_ValueError, "points = %zd: must be at least 1", n);
  bsurf_cloud c;
  bsurf_status st;
  Py_BEGIN_ALLOW_THREADS st =
      bsurf_generate(&c, shape, (size_t)n, (bsurf_sampling)sampling, seed, width);
  Py_END_ALLOW_THREADS if (st != BSURF_OK) return fail(st, NULL, NULL, NULL);
  return cloud_result(&c);
}

static PyObject *py_noise(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *nrm, *progress;
  bsurf_noise_options no = bsurf_noise_options_default();
  int model;
  unsigned long long seed;
  if (!PyArg_ParseTuple(args, "OOiddKiO", &pts, &nrm, &model, &no.level, &no.sigma_diag, &seed,
                        &no.threads, &progress))
    return NULL;
  no.model = (bsurf_noise_model)model;
  no.seed = seed;
  /* the output: a new float64 array (the input is never modified) */
  PyArrayObject *a = as_f64(pts, "points", 3), *nr = NULL;
  if (!a) return NULL;
  PyArrayObject *out = (PyArrayObject *)PyArray_NewCopy(a, NPY_CORDER);
  Py_DECREF(a);
  if (!out) return NULL;
  size_t n = (size_t)PyArray_DIM(out, 0);
  if (opt_f64(nrm, "normals", 3, n, &nr)) {
    Py_DECREF(out);
    return NULL;
  }
  call_ctx c;
  ctx_hook(&c, progress, &no.progress, &no.progress_user);
  bsurf_noise_report r;
  RELEASE(&c);
  bsurf_status st = bsurf_noise_points(f64(out), f64(nr), n, &no, &r);
  ACQUIRE(&c);
  Py_XDECREF(nr);
  if (st != BSURF_OK) {
    Py_DECREF(out);
    return fail(st, &c, NULL, NULL);
  }
  return Py_BuildValue("(N{s:d,s:d,s:d,s:d})", out, "h", r.h, "diagonal", r.diagonal, "level",
                       r.level, "scale", r.scale);
}

static PyObject *py_sample(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *mesh;
  bsurf_sample_options so = bsurf_sample_options_default();
  Py_ssize_t points;
  unsigned long long seed;
  if (!PyArg_ParseTuple(args, "OnKddi", &mesh, &points, &seed, &so.sharp_angle_deg,
                        &so.feature_width, &so.threads))
    return NULL;
  if (points < 0) return PyErr_Format(PyExc_ValueError, "points = %zd: must be >= 0", points);
  so.points = (size_t)points;
  so.seed = seed;
  borrowed b;
  if (borrow_cloud(mesh, &b)) return NULL;
  if (!b.cloud.face_count) {
    borrowed_free(&b);
    return PyErr_Format(PyExc_ValueError, "the mesh has no 'faces': sample needs triangles");
  }
  bsurf_cloud out;
  bsurf_sample_report r;
  bsurf_status st;
  Py_BEGIN_ALLOW_THREADS st = bsurf_sample_mesh(&out, &b.cloud, &so, &r);
  Py_END_ALLOW_THREADS borrowed_free(&b);
  if (st != BSURF_OK) return fail(st, NULL, NULL, NULL);
  PyObject *d = dict_from_cloud(&out);
  if (!d) return NULL;
  return Py_BuildValue(
      "(N{s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:d,s:d,s:d,s:d})", d, "edges", (Py_ssize_t)r.edges,
      "sharp_edges", (Py_ssize_t)r.sharp_edges, "boundary_edges", (Py_ssize_t)r.boundary_edges,
      "nonmanifold_edges", (Py_ssize_t)r.nonmanifold_edges, "inconsistent_edges",
      (Py_ssize_t)r.inconsistent_edges, "degenerate_faces", (Py_ssize_t)r.degenerate_faces,
      "vertices_dropped", (Py_ssize_t)r.vertices_dropped, "feature_points",
      (Py_ssize_t)r.feature_points, "area", r.area, "mean_edge_length", r.mean_edge_length,
      "spacing", r.spacing, "feature_width", r.feature_width, "no_feature_dist", r.no_feature_dist);
}

/* ---- pictures ---- */

static PyObject *py_render(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *nrm, *vals, *progress;
  const char *path, *cmap, *view, *up, *shape, *title, *label;
  double az, el;
  bsurf_render_options ro = bsurf_render_options_default();
  int flat, square;
  if (!PyArg_ParseTuple(args, "OOOzszddssiiidddzzppiO", &pts, &nrm, &vals, &path, &cmap, &view, &az,
                        &el, &up, &shape, &ro.views, &ro.width, &ro.height, &ro.point_size,
                        &ro.range_lo, &ro.range_hi, &title, &label, &flat, &square, &ro.threads,
                        &progress))
    return NULL;
  if (bsurf_colormap_from_name(cmap, &ro.colormap) != 0)
    return PyErr_Format(PyExc_ValueError,
                        "colormap must be viridis, magma, gray or coolwarm, not '%s'", cmap);
  if (view && bsurf_view_from_name(view, &ro.azimuth, &ro.elevation) != 0)
    return PyErr_Format(PyExc_ValueError,
                        "view must be front, back, left, right, top, bottom or iso, not '%s'",
                        view);
  if (!isnan(az)) ro.azimuth = az;
  if (!isnan(el)) ro.elevation = el;
  if (!strcmp(up, "auto"))
    ro.up_axis = bsurf_render_auto_up(shape);
  else if (up[0] >= 'x' && up[0] <= 'z' && !up[1])
    ro.up_axis = up[0] - 'x';
  else
    return PyErr_Format(PyExc_ValueError, "up must be x, y, z or auto, not '%s'", up);
  ro.shade = !flat;
  ro.round_splats = !square;
  ro.title = title;
  ro.label = label;
  /* the view's ranges, in the command line's words (the library's check) */
  if (bsurf_render_options_check(&ro) != BSURF_OK)
    return PyErr_Format(PyExc_ValueError, "%s", bsurf_last_message());
  PyArrayObject *a = as_f64(pts, "points", 3), *nr = NULL, *v = NULL;
  if (!a) return NULL;
  size_t n = (size_t)PyArray_DIM(a, 0);
  PyObject *img = NULL, *ret = NULL;
  double *local = NULL;
  if (opt_f64(nrm, "normals", 3, n, &nr) || opt_f64(vals, "values", 0, n, &v)) goto done;
  npy_intp dims[3] = {ro.height, ro.width, 3};
  if (ro.width < 1 || ro.height < 1) {
    PyErr_Format(PyExc_ValueError, "size %dx%d: both must be positive", ro.width, ro.height);
    goto done;
  }
  img = PyArray_SimpleNew(3, dims, NPY_UINT8);
  local = n ? PyMem_Malloc(n * sizeof *local) : NULL;
  if (!img || (n && !local)) {
    if (img) PyErr_NoMemory();
    goto done;
  }
  call_ctx c;
  ctx_init(&c, progress);
  bsurf_render_info info;
  bsurf_failure err = {0, -1, ""};
  int filled = 0;
  double h = 0;
  RELEASE(&c);
  bsurf_status st =
      bsurf_render_spacing(f64(a), n, ro.threads, progress_cb, &c, &h, local, &filled);
  ro.spacing = h;
  ro.point_spacing = filled ? local : NULL;
  if (st == BSURF_OK)
    st = bsurf_render(PyArray_DATA((PyArrayObject *)img), f64(a), f64(nr), n, f64(v), &ro, &info);
  if (st == BSURF_OK && path)
    st = bsurf_write_png(path, PyArray_DATA((PyArrayObject *)img), ro.width, ro.height, &err);
  ACQUIRE(&c);
  if (st != BSURF_OK) {
    fail(st, &c, path, &err);
    goto done;
  }
  ret = Py_BuildValue("(O{s:d,s:d,s:d,s:n})", path ? Py_None : img, "range_lo", info.range_lo,
                      "range_hi", info.range_hi, "h", info.spacing, "covered_pixels",
                      (Py_ssize_t)info.covered_pixels);
done:
  PyMem_Free(local);
  Py_XDECREF(img);
  Py_XDECREF(a);
  Py_XDECREF(nr);
  Py_XDECREF(v);
  return ret;
}

/* ---- evaluation ---- */

static PyObject *angle_stats(const bsurf_angle_stats *s) {
  return Py_BuildValue("{s:n,s:d,s:d,s:d,s:d,s:d,s:d}", "count", (Py_ssize_t)s->count, "mean_rad",
                       s->mean_rad, "median_rad", s->median_rad, "rms_rad", s->rms_rad, "mean_deg",
                       s->mean_deg, "under5deg", s->under5deg, "under10deg", s->under10deg);
}

static PyObject *py_eval_normals(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *res, *tru, *mask_obj;
  if (!PyArg_ParseTuple(args, "OOO", &res, &tru, &mask_obj)) return NULL;
  PyArrayObject *a = as_f64(res, "normals", 3), *b = NULL, *m = NULL;
  if (!a) return NULL;
  size_t n = (size_t)PyArray_DIM(a, 0);
  PyObject *angles = NULL, *ret = NULL;
  if (opt_f64(tru, "true_normals", 3, n, &b)) goto done;
  if (!b) {
    PyErr_SetString(PyExc_ValueError, "true_normals: required");
    goto done;
  }
  if (mask_obj != Py_None && !(m = mask_u8(mask_obj, "split", n))) goto done;
  npy_intp dims[1] = {(npy_intp)n};
  angles = PyArray_SimpleNew(1, dims, NPY_DOUBLE);
  if (!angles) goto done;
  bsurf_angle_stats all, high, low;
  size_t bad = 0;
  bsurf_status st;
  double *ang = PyArray_DATA((PyArrayObject *)angles);
  Py_BEGIN_ALLOW_THREADS st = bsurf_eval_normals(f64(a), f64(b), n, ang, &all, &bad);
  if (st == BSURF_OK && m) st = bsurf_angle_stats_compute(ang, PyArray_DATA(m), 1, n, &high);
  if (st == BSURF_OK && m) st = bsurf_angle_stats_compute(ang, PyArray_DATA(m), 0, n, &low);
  Py_END_ALLOW_THREADS if (st == BSURF_ERR_INVALID_VALUE) {
    PyErr_Format(PyExc_ValueError, "normals[%zu] or true_normals[%zu]: zero length or not finite",
                 bad, bad);
    goto done;
  }
  if (st != BSURF_OK) {
    fail(st, NULL, NULL, NULL);
    goto done;
  }
  if (m)
    ret = Py_BuildValue("(O{s:N,s:N,s:N})", angles, "all", angle_stats(&all), "high",
                        angle_stats(&high), "low", angle_stats(&low));
  else
    ret = Py_BuildValue("(O{s:N})", angles, "all", angle_stats(&all));
done:
  Py_XDECREF(angles);
  Py_XDECREF(a);
  Py_XDECREF(b);
  Py_XDECREF(m);
  return ret;
}

/* The labels as eval reads them (cli/cmd_eval.c): a point is a feature where
 * its value is not 0. Read as doubles: a cast to uint8 truncated 0.5 to 0
 * (and 256 to 0), so a fractional or large label counted as "no feature". */
static uint8_t *feature_labels(PyArrayObject *a) {
  const npy_intp n = PyArray_DIM(a, 0);
  const double *v = PyArray_DATA(a);
  uint8_t *r = malloc(n ? (size_t)n : 1);
  if (!r) {
    PyErr_NoMemory();
    return NULL;
  }
  for (npy_intp i = 0; i < n; i++)
    r[i] = v[i] != 0;
  return r;
}

static PyObject *py_eval_features(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *res, *tru;
  if (!PyArg_ParseTuple(args, "OO", &res, &tru)) return NULL;
  PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(res, NPY_DOUBLE, 1, 1,
                                                      NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
  PyArrayObject *b = (PyArrayObject *)PyArray_FROMANY(tru, NPY_DOUBLE, 1, 1,
                                                      NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
  PyObject *ret = NULL;
  uint8_t *ra = NULL, *rb = NULL;
  if (!a || !b) goto done;
  if (PyArray_DIM(a, 0) != PyArray_DIM(b, 0)) {
    PyErr_SetString(PyExc_ValueError, "feature and true_feature: different lengths");
    goto done;
  }
  if (!(ra = feature_labels(a)) || !(rb = feature_labels(b))) goto done;
  bsurf_feature_stats s;
  bsurf_status st = bsurf_eval_features(ra, rb, (size_t)PyArray_DIM(a, 0), &s);
  if (st != BSURF_OK) {
    fail(st, NULL, NULL, NULL);
    goto done;
  }
  ret = Py_BuildValue("{s:n,s:n,s:n,s:n,s:d,s:d,s:d}", "true_pos", (Py_ssize_t)s.true_pos,
                      "false_pos", (Py_ssize_t)s.false_pos, "false_neg", (Py_ssize_t)s.false_neg,
                      "true_neg", (Py_ssize_t)s.true_neg, "precision", s.precision, "recall",
                      s.recall, "f1", s.f1);
done:
  free(ra);
  free(rb);
  Py_XDECREF(a);
  Py_XDECREF(b);
  return ret;
}

static PyObject *distance_stats(const bsurf_distance_stats *s, double h) {
  return Py_BuildValue("{s:n,s:d,s:d,s:d,s:d,s:d,s:d}", "points", (Py_ssize_t)s->count, "mean",
                       s->mean, "rms", s->rms, "max", s->max, "mean_h", s->mean / h, "rms_h",
                       s->rms / h, "max_h", s->max / h);
}

/* A group's statistics: {"points", "mean", ..., "feature": {...}, "non_feature": {...}} */
static PyObject *position_group(const bsurf_position_eval *r, int g) {
  static const char *const parts[BSURF_POSITION_PARTS] = {NULL, "feature", "non_feature"};
  PyObject *d = distance_stats(&r->stats[g][BSURF_POSITION_PART_ALL], r->h);
  for (int p = 1; d && r->has_feature && p < BSURF_POSITION_PARTS; p++)
    if (set_item(d, parts[p], distance_stats(&r->stats[g][p], r->h))) Py_CLEAR(d);
  return d;
}

static PyObject *py_eval_position(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *pts, *truth_obj, *surface_obj, *mask_obj, *progress;
  const char *shape;
  int threads;
  if (!PyArg_ParseTuple(args, "OOsOOiO", &pts, &truth_obj, &shape, &surface_obj, &mask_obj,
                        &threads, &progress))
    return NULL;
  PyArrayObject *a = as_f64(pts, "points", 3), *m = NULL;
  if (!a) return NULL;
  size_t n = (size_t)PyArray_DIM(a, 0);
  PyObject *dist = NULL, *ret = NULL;
  borrowed truth, surface;
  memset(&truth, 0, sizeof truth);
  memset(&surface, 0, sizeof surface);
  if (borrow_cloud(truth_obj, &truth) ||
      (surface_obj != Py_None && borrow_cloud(surface_obj, &surface)))
    goto done;
  snprintf(truth.cloud.shape, sizeof truth.cloud.shape, "%s", shape);
  if (surface_obj != Py_None && !surface.cloud.face_count) {
    PyErr_SetString(PyExc_ValueError, "surface: has no 'faces': a triangle mesh is needed");
    goto done;
  }
  if (mask_obj != Py_None && !(m = mask_u8(mask_obj, "split", n))) goto done;
  npy_intp dims[1] = {(npy_intp)n};
  if (!(dist = PyArray_SimpleNew(1, dims, NPY_DOUBLE))) goto done;
  bsurf_position_eval_options o;
  memset(&o, 0, sizeof o);
  o.surface = surface_obj != Py_None ? &surface.cloud : NULL;
  o.high = m ? PyArray_DATA(m) : NULL;
  o.threads = threads;
  call_ctx c;
  ctx_hook(&c, progress, &o.progress, &o.progress_user);
  bsurf_position_eval r;
  RELEASE(&c);
  bsurf_status st =
      bsurf_eval_position(f64(a), n, &truth.cloud, &o, &r, PyArray_DATA((PyArrayObject *)dist));
  ACQUIRE(&c);
  if (st == BSURF_ERR_INVALID_VALUE && r.stage == BSURF_POSITION_STAGE_DISTANCE) {
    PyErr_Format(PyExc_ValueError,
                 "truth: point %zu (for points[%zu]) has a zero-length normal, or points[%zu] is "
                 "not finite",
                 r.bad_truth_point, r.bad_point, r.bad_point);
    goto done;
  }
  if (st != BSURF_OK) {
    fail(st, &c, NULL, NULL);
    goto done;
  }
  static const char *const kinds[] = {"mesh", "shape", "tangent_plane"};
  static const char *const groups[BSURF_POSITION_GROUPS] = {"all", "high", "low"};
  PyObject *d = Py_BuildValue("{s:s,s:s,s:d}", "surface", kinds[r.surface], "correspondence",
                              n == truth.cloud.point_count ? "index"
                              : r.nearest                  ? "nearest"
                                                           : "none",
                              "h", r.h);
  for (int g = 0; d && g < r.groups; g++)
    if (set_item(d, groups[g], position_group(&r, g))) Py_CLEAR(d);
  if (d) ret = Py_BuildValue("(ON)", dist, d);
done:
  borrowed_free(&truth);
  borrowed_free(&surface);
  Py_XDECREF(dist);
  Py_XDECREF(m);
  Py_DECREF(a);
  return ret;
}

static PyObject *py_quantile_split(PyObject *self, PyObject *args) {
  (void)self;
  PyObject *vals;
  double q;
  if (!PyArg_ParseTuple(args, "Od", &vals, &q)) return NULL;
  PyArrayObject *a = as_f64(vals, "split", 0);
  if (!a) return NULL;
  size_t n = (size_t)PyArray_DIM(a, 0), count = 0, bad = 0;
  npy_intp dims[1] = {(npy_intp)n};
  PyObject *high = PyArray_SimpleNew(1, dims, NPY_UINT8);
  if (!high) {
    Py_DECREF(a);
    return NULL;
  }
  double thr = 0;
  bsurf_status st =
      bsurf_quantile_split(f64(a), n, q, PyArray_DATA((PyArrayObject *)high), &thr, &count, &bad);
  Py_DECREF(a);
  if (st != BSURF_OK) {
    Py_DECREF(high);
    if (st == BSURF_ERR_INVALID_VALUE)
      return PyErr_Format(PyExc_ValueError, "split[%zu] is NaN", bad);
    return fail(st, NULL, NULL, NULL);
  }
  return Py_BuildValue("(Ndn)", high, thr, (Py_ssize_t)count);
}

static PyObject *py_version(PyObject *self, PyObject *args) {
  (void)self;
  (void)args;
  return PyUnicode_FromString(bsurf_version_string());
}

static PyMethodDef methods[] = {
    {"read", py_read, METH_VARARGS, "read(path) -> (dict, shape)"},
    {"write", py_write, METH_VARARGS, "write(path, cloud, shape, format, ascii, ply_names, ...)"},
    {"knn", py_knn, METH_VARARGS, "knn(points, k, threads, progress) -> (idx, dist2)"},
    {"spacing", py_spacing, METH_VARARGS, "spacing(points, threads, progress) -> h"},
    {"error", py_error, METH_VARARGS, "error(points, test, k, ...) -> (fields, summary)"},
    {"normals", py_normals, METH_VARARGS, "normals(points, ...) -> (fields, summary)"},
    {"smooth", py_smooth, METH_VARARGS, "smooth(points, ...) -> (points, fields, summary)"},
    {"features", py_features, METH_VARARGS, "features(points, ...) -> (fields, summary)"},
    {"generate", py_generate, METH_VARARGS, "generate(shape, n, sampling, seed, width)"},
    {"noise", py_noise, METH_VARARGS, "noise(points, normals, model, level, ...)"},
    {"sample", py_sample, METH_VARARGS, "sample(mesh, points, seed, angle, width, threads)"},
    {"render", py_render, METH_VARARGS, "render(...)"},
    {"eval_normals", py_eval_normals, METH_VARARGS, "eval_normals(normals, truth, mask)"},
    {"eval_features", py_eval_features, METH_VARARGS, "eval_features(feature, truth)"},
    {"quantile_split", py_quantile_split, METH_VARARGS, "quantile_split(values, q)"},
    {"eval_position", py_eval_position, METH_VARARGS,
     "eval_position(points, truth, shape, surface, mask, threads, progress)"},
    {"version", py_version, METH_NOARGS, "the library's version string"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT,
                                    "bootsurf._core",
                                    "The C binding of libbootsurf (use the bootsurf package).",
                                    -1,
                                    methods,
                                    NULL,
                                    NULL,
                                    NULL,
                                    NULL};

PyMODINIT_FUNC PyInit__core(void) {
  import_array();
  return PyModule_Create(&module);
}
