/* Writing a file so that a failure never leaves a partial one (DESIGN.md:
 * "An output file is written to a temporary name and renamed at the end").
 * The temporary is created next to the target, so rename() is atomic; it
 * takes the target's permissions (or those a new file would get, since
 * mkstemp makes it 0600); it is flushed and fsynced before the rename, and
 * removed on any failure. Used by every writer (point clouds, PNG). */
#include "common/common.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* The process's umask, without changing it if the system can tell. */
static mode_t current_umask(void) {
  FILE *f = fopen("/proc/self/status", "r");
  if (f) {
    char line[256];
    while (fgets(line, sizeof line, f)) {
      unsigned v;
      if (strncmp(line, "Umask:", 6) == 0 && sscanf(line + 6, "%o", &v) == 1) {
        fclose(f);
        return (mode_t)v;
      }
    }
    fclose(f);
  }
  mode_t m = umask(022);
  umask(m);
  return m;
}


bsurf_status bsurf_atomic_open(bsurf_atomic_file *af, const char *path, bsurf_error *err) {
  memset(af, 0, sizeof *af);
  if (strcmp(path, "-") == 0) { /* standard output: no temporary (tmp stays NULL) */
    af->f = stdout;
    af->path = path;
    return BSURF_OK;
  }
  const char *slash = strrchr(path, '/');
  const char *base = slash ? slash + 1 : path;
  if (!*base)
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "the output path names a directory");
  size_t dir_len = slash ? (size_t)(slash - path) + 1 : 0; /* with the '/' */
  size_t base_len = strlen(base);
  if (base_len > 200) base_len = 200; /* stay under NAME_MAX */
  static const char suffix[] = ".tmp.XXXXXX";
  char *tmp = malloc(dir_len + 1 + base_len + sizeof suffix);
  if (!tmp) return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  memcpy(tmp, path, dir_len);
  tmp[dir_len] = '.';
  memcpy(tmp + dir_len + 1, base, base_len);
  memcpy(tmp + dir_len + 1 + base_len, suffix, sizeof suffix);
  int fd = mkstemp(tmp);
  if (fd < 0) {
    int e = errno;
    int shown = slash ? (int)(slash == path ? 1 : dir_len - 1) : 1;
    bsurf_status st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot create a file in directory '%.*s': %s",
                                 shown, slash ? path : ".", strerror(e));
    free(tmp);
    return st;
  }
  struct stat sb;
  mode_t mode = (stat(path, &sb) == 0 && S_ISREG(sb.st_mode)) ? (sb.st_mode & 07777)
                                                               : (0666 & ~current_umask());
  (void)fchmod(fd, mode);
  FILE *f = fdopen(fd, "wb");
  if (!f) {
    int e = errno;
    close(fd);
    unlink(tmp);
    free(tmp);
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open the temporary file: %s", strerror(e));
  }
  const size_t bufsize = (size_t)1 << 20;
  af->iobuf = malloc(bufsize);
  if (af->iobuf) setvbuf(f, af->iobuf, _IOFBF, bufsize);
  af->f = f;
  af->tmp = tmp;
  af->path = path;
  return BSURF_OK;
}

bsurf_status bsurf_atomic_close(bsurf_atomic_file *af, bsurf_status status, int write_errno,
                                bsurf_error *err) {
  int failed = status != BSURF_OK || write_errno != 0, e = write_errno;
  if (!af->tmp) { /* standard output: flushed, never closed; a failure may
                     leave part of the data in the pipe (docs/formats.md) */
    errno = 0;
    if (fflush(af->f) != 0 && !failed) {
      failed = 1;
      e = errno ? errno : EIO;
    }
    memset(af, 0, sizeof *af);
    if (status != BSURF_OK) return status;
    return failed ? bsurf_fail(err, BSURF_ERR_IO, 0, -1, "write to standard output failed: %s", strerror(e))
                  : BSURF_OK;
  }
  if (!failed) {
    errno = 0;
    if (fflush(af->f) != 0) {
      failed = 1;
      e = errno ? errno : EIO;
    } else if (fsync(fileno(af->f)) != 0 && errno != EINVAL && errno != ENOTSUP) {
      /* EINVAL / ENOTSUP: the file system cannot sync; nothing to report */
      failed = 1;
      e = errno;
    }
  }
  errno = 0;
  if (fclose(af->f) != 0 && !failed) {
    failed = 1;
    e = errno ? errno : EIO;
  }
  free(af->iobuf);
  bsurf_status st = BSURF_OK;
  if (failed) {
    unlink(af->tmp);
    st = status != BSURF_OK ? status
                            : bsurf_fail(err, BSURF_ERR_IO, 0, -1, "write failed: %s", strerror(e));
  } else if (rename(af->tmp, af->path) != 0) {
    e = errno;
    unlink(af->tmp);
    st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot move the finished file into place: %s",
                    strerror(e));
  }
  free(af->tmp);
  memset(af, 0, sizeof *af);
  return st;
}
