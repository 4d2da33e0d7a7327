/* Writing a file so that a failure never leaves a partial one (DESIGN.md:
 * "An output file is written to a temporary name and renamed at the end").
 * The temporary is created next to the target, so rename() is atomic; it
 * takes the target's permissions (or those a new file would get, since
 * mkstemp makes it 0600); it is flushed and fsynced before the rename, and
 * removed on any failure. Used by every writer (point clouds, PNG).
 *
 * The output-path policy (docs/robustness.md, "Where the output goes"):
 *   - a symbolic link is followed: its target is written (the temporary file
 *     beside the target, renamed over it), the link stays a link;
 *   - an existing FIFO, character or block device or socket (`-o /dev/null`)
 *     is opened and written directly: not atomic, nothing to rename;
 *   - an existing file without any write permission is refused unless the
 *     caller forces it (bsurf_output_check);
 *   - temporary files are named ".NAME.bsurf-tmp.PID.XXXXXX": bsurf_atomic_open
 *     removes those in the target's directory whose process PID is gone (a run
 *     killed by SIGKILL or a power cut), and a signal handler can remove the
 *     current ones at once (bsurf_atomic_remove_temporaries). */
#include "common/common.h"

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define TMP_TAG ".bsurf-tmp."

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

/* ---- the temporaries open now, for a signal handler ------------------------ */

#define OPEN_MAX_TMP 32
static char *volatile open_tmp[OPEN_MAX_TMP];
static volatile sig_atomic_t interrupted = 0;

static void register_tmp(char *tmp) {
  for (int i = 0; i < OPEN_MAX_TMP; i++)
    if (!open_tmp[i]) {
      open_tmp[i] = tmp;
      return;
    }
  /* more than 32 at once: that one is not removed by a signal (the next run
   * removes it, its process being gone) */
}

static void unregister_tmp(const char *tmp) {
  for (int i = 0; i < OPEN_MAX_TMP; i++)
    if (open_tmp[i] == tmp) open_tmp[i] = NULL;
}

void bsurf_atomic_remove_temporaries(void) {
  for (int i = 0; i < OPEN_MAX_TMP; i++) {
    char *t = open_tmp[i];
    if (t) unlink(t); /* async-signal-safe */
  }
}

void bsurf_atomic_interrupt(void) {
  interrupted = 1;
}

/* ---- paths ----------------------------------------------------------------- */

/* The file a path names once every symbolic link is followed (the path
 * itself when it is no link; a dangling link gives its target, which is
 * created). malloc'ed; NULL when out of memory or when the links loop. */
static char *resolve_links(const char *path) {
  char *cur = strdup(path);
  for (int hops = 0; cur && hops < 40; hops++) {
    struct stat sb;
    if (lstat(cur, &sb) != 0 || !S_ISLNK(sb.st_mode)) return cur;
    char target[PATH_MAX];
    ssize_t len = readlink(cur, target, sizeof target - 1);
    if (len < 0) return cur;
    target[len] = '\0';
    char *next;
    const char *slash = strrchr(cur, '/');
    if (target[0] == '/' || !slash) {
      next = strdup(target);
    } else { /* relative to the link's directory */
      size_t dir = (size_t)(slash - cur) + 1;
      next = malloc(dir + (size_t)len + 1);
      if (next) {
        memcpy(next, cur, dir);
        memcpy(next + dir, target, (size_t)len + 1);
      }
    }
    free(cur);
    cur = next;
  }
  free(cur);
  errno = ELOOP;
  return NULL;
}

/* An existing file that is neither regular nor a directory (FIFO, device,
 * socket): written directly. */
static int is_special(const struct stat *sb) {
  return !S_ISREG(sb->st_mode) && !S_ISDIR(sb->st_mode);
}

int bsurf_output_is_stream(const char *path) {
  struct stat sb; /* stat follows links */
  return path && stat(path, &sb) == 0 && is_special(&sb);
}

bsurf_status bsurf_output_check(const char *path, int force, bsurf_failure *err) {
  struct stat sb;
  if (stat(path, &sb) != 0) return BSURF_OK; /* a new file (or a dangling link's target) */
  if (S_ISDIR(sb.st_mode)) return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "is a directory");
  if (is_special(&sb)) return BSURF_OK;
  int no_write_bit = (sb.st_mode & (S_IWUSR | S_IWGRP | S_IWOTH)) == 0;
  if (!force && (no_write_bit || access(path, W_OK) != 0))
    return bsurf_fail(
        err, BSURF_ERR_INVALID_ARG, 0, -1,
        "the output file is read-only (mode %04o); refusing to replace it (use --force)",
        (unsigned)(sb.st_mode & 07777));
  return BSURF_OK;
}

/* Removes the temporaries of dead processes in directory `dir` (length
 * dir_len, with its '/'; 0: the current directory). */
static void remove_stale(const char *dir, size_t dir_len) {
  char d[PATH_MAX];
  if (dir_len >= sizeof d) return;
  memcpy(d, dir_len ? dir : ".", dir_len ? dir_len : 1);
  d[dir_len ? dir_len : 1] = '\0';
  DIR *dp = opendir(d);
  if (!dp) return;
  struct dirent *de;
  while ((de = readdir(dp)) != NULL) {
    const char *name = de->d_name, *tag;
    if (name[0] != '.' || !(tag = strstr(name, TMP_TAG))) continue;
    char *end;
    errno = 0;
    long pid = strtol(tag + sizeof TMP_TAG - 1, &end, 10);
    if (errno || pid <= 0 || end == tag + sizeof TMP_TAG - 1 || *end != '.' || strlen(end + 1) != 6)
      continue;
    if ((pid_t)pid == getpid() || kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive */
    char full[PATH_MAX];
    if ((size_t)snprintf(full, sizeof full, "%.*s%s", (int)dir_len, dir, name) >= sizeof full)
      continue;
    struct stat sb;
    if (lstat(full, &sb) == 0 && S_ISREG(sb.st_mode)) unlink(full);
  }
  closedir(dp);
}

/* ---- open and close ------------------------------------------------------- */

static void use_buffer(bsurf_atomic_file *af) {
  const size_t bufsize = (size_t)1 << 20;
  af->iobuf = malloc(bufsize);
  if (af->iobuf) setvbuf(af->f, af->iobuf, _IOFBF, bufsize);
}

/* A FIFO or device: opened for writing as it is. */
static bsurf_status open_direct(bsurf_atomic_file *af, char *target, bsurf_failure *err) {
  FILE *f = fopen(target, "wb");
  if (!f) {
    int e = errno;
    free(target);
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open: %s", strerror(e));
  }
  af->f = f;
  af->target = target;
  af->direct = 1;
  use_buffer(af);
  return BSURF_OK;
}

bsurf_status bsurf_atomic_open(bsurf_atomic_file *af, const char *path, bsurf_failure *err) {
  memset(af, 0, sizeof *af);
  if (strcmp(path, "-") == 0) { /* standard output: no temporary (tmp stays NULL) */
    af->f = stdout;
    af->path = path;
    return BSURF_OK;
  }
  af->path = path;
  char *target = resolve_links(path);
  if (!target)
    return errno == ELOOP
               ? bsurf_fail(err, BSURF_ERR_IO, 0, -1, "too many levels of symbolic links")
               : bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  struct stat sb;
  if (stat(target, &sb) == 0 && is_special(&sb)) return open_direct(af, target, err);
  const char *slash = strrchr(target, '/');
  const char *base = slash ? slash + 1 : target;
  if (!*base) {
    free(target);
    return bsurf_fail(err, BSURF_ERR_INVALID_ARG, 0, -1, "the output path names a directory");
  }
  size_t dir_len = slash ? (size_t)(slash - target) + 1 : 0; /* with the '/' */
  size_t base_len = strlen(base);
  if (base_len > 180) base_len = 180; /* stay under NAME_MAX */
  remove_stale(target, dir_len);
  char tag[64];
  int tag_len = snprintf(tag, sizeof tag, "%s%ld.XXXXXX", TMP_TAG, (long)getpid());
  char *tmp = malloc(dir_len + 1 + base_len + (size_t)tag_len + 1);
  if (!tmp) {
    free(target);
    return bsurf_fail(err, BSURF_ERR_NOMEM, 0, -1, "out of memory");
  }
  memcpy(tmp, target, dir_len);
  tmp[dir_len] = '.';
  memcpy(tmp + dir_len + 1, base, base_len);
  memcpy(tmp + dir_len + 1 + base_len, tag, (size_t)tag_len + 1);
  int fd = mkstemp(tmp);
  if (fd < 0) {
    int e = errno;
    int shown = slash ? (int)(slash == target ? 1 : dir_len - 1) : 1;
    bsurf_status st =
        bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot create a file in directory '%.*s': %s", shown,
                   slash ? target : ".", strerror(e));
    free(tmp);
    free(target);
    return st;
  }
  register_tmp(tmp);
  mode_t mode = (stat(target, &sb) == 0 && S_ISREG(sb.st_mode)) ? (sb.st_mode & 07777)
                                                                : (0666 & ~current_umask());
  (void)fchmod(fd, mode);
  FILE *f = fdopen(fd, "wb");
  if (!f) {
    int e = errno;
    close(fd);
    unregister_tmp(tmp);
    unlink(tmp);
    free(tmp);
    free(target);
    return bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot open the temporary file: %s", strerror(e));
  }
  af->f = f;
  af->tmp = tmp;
  af->target = target;
  use_buffer(af);
  return BSURF_OK;
}

bsurf_status bsurf_atomic_close(bsurf_atomic_file *af, bsurf_status status, int write_errno,
                                bsurf_failure *err) {
  int failed = status != BSURF_OK || write_errno != 0, e = write_errno;
  if (af->f == stdout && !af->direct) { /* standard output: flushed, never closed; a failure may
                     leave part of the data in the pipe (docs/formats.md) */
    errno = 0;
    if (fflush(af->f) != 0 && !failed) {
      failed = 1;
      e = errno ? errno : EIO;
    }
    memset(af, 0, sizeof *af);
    if (status != BSURF_OK) return status;
    return failed ? bsurf_fail(err, BSURF_ERR_IO, 0, -1, "write to standard output failed: %s",
                               strerror(e))
                  : BSURF_OK;
  }
  if (!failed) {
    errno = 0;
    if (fflush(af->f) != 0) {
      failed = 1;
      e = errno ? errno : EIO;
    } else if (!af->direct && fsync(fileno(af->f)) != 0 && errno != EINVAL && errno != ENOTSUP) {
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
  if (af->direct) {
    if (failed)
      st = status != BSURF_OK
               ? status
               : bsurf_fail(err, BSURF_ERR_IO, 0, -1, "write failed: %s", strerror(e));
  } else if (failed || interrupted) {
    unlink(af->tmp);
    st = status != BSURF_OK ? status
         : failed           ? bsurf_fail(err, BSURF_ERR_IO, 0, -1, "write failed: %s", strerror(e))
                  : bsurf_fail(err, BSURF_ERR_CANCELLED, 0, -1, "interrupted; nothing written");
  } else if (rename(af->tmp, af->target) != 0) {
    e = errno;
    unlink(af->tmp);
    st = bsurf_fail(err, BSURF_ERR_IO, 0, -1, "cannot move the finished file into place: %s",
                    strerror(e));
  }
  if (af->tmp) unregister_tmp(af->tmp);
  free(af->tmp);
  free(af->target);
  memset(af, 0, sizeof *af);
  return st;
}
