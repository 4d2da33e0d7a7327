/* rss_exec — runs a command and records its wall time and peak RSS.
 *
 * usage: rss_exec STATS_FILE COMMAND [ARGS...]
 *
 * Writes "WALL_SECONDS PEAK_RSS_KB CPU_SECONDS" (user + system) to STATS_FILE and exits with the
 * command's status. Why not measure from the Python harness directly: Linux carries a process's RSS
 * high-water mark across fork and exec (ru_maxrss of a child is at least its parent's RSS at fork
 * time), so a child of the numpy-loaded harness would report at least the harness's ~40 MB. This
 * launcher is small, so the peak it passes on is about 1 MB. Wall time: monotonic clock from just
 * before fork to the reaping of the child (process start-up included). */
#define _GNU_SOURCE
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: rss_exec STATS_FILE COMMAND [ARGS...]\n");
    return 2;
  }
  const double t0 = now();
  pid_t pid = fork();
  if (pid < 0) {
    perror("rss_exec: fork");
    return 127;
  }
  if (pid == 0) {
    execvp(argv[2], argv + 2);
    perror("rss_exec: exec");
    _exit(127);
  }
  int status = 0;
  struct rusage ru;
  if (wait4(pid, &status, 0, &ru) < 0) {
    perror("rss_exec: wait4");
    return 127;
  }
  const double wall = now() - t0;
  FILE *f = fopen(argv[1], "w");
  if (!f ||
      fprintf(f, "%.6f %ld %.6f\n", wall, ru.ru_maxrss,
              (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
                  (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec) < 0 ||
      fclose(f) != 0) {
    perror("rss_exec: stats file");
    return 127;
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}
