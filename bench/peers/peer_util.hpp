// peer_util.hpp — what the C++ peer programs share besides PLY I/O: a monotonic
// clock, CPU time, the process's peak resident set size, options and the one-line JSON
// result every peer prints on stdout.
#pragma once

#include <sys/resource.h>
#include <time.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace peer {

static inline double now() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

// Peak resident set size of this process so far, kB (Linux: ru_maxrss is kB).
static inline long peak_rss_kb() {
  rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss;
}

// CPU time (user + system) of all threads of this process so far, seconds.
static inline double cpu_seconds() {
  rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
         (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
}

struct Options {
  std::string in, out, method;
  int k = 30; // neighbourhood size, the point itself included (bootsurf's K)
  int threads = 2;
  int degree = 2; // jet fitting degree (CGAL)
};

static inline void usage(const char *prog, const char *extra) {
  std::fprintf(stderr,
               "usage: %s INPUT.ply -o OUTPUT.ply [-k K] [-j THREADS]%s\n"
               "  K counts the point itself (bootsurf's convention); default 30, 2 threads\n",
               prog, extra);
  std::exit(2);
}

static inline Options parse(int argc, char **argv, const char *extra, const char *def_method) {
  Options o;
  o.method = def_method;
  for (int i = 1; i < argc; i++) {
    const std::string a = argv[i];
    auto val = [&]() -> const char * {
      if (i + 1 >= argc) usage(argv[0], extra);
      return argv[++i];
    };
    if (a == "-o")
      o.out = val();
    else if (a == "-k")
      o.k = std::atoi(val());
    else if (a == "-j")
      o.threads = std::atoi(val());
    else if (a == "-d")
      o.degree = std::atoi(val());
    else if (a == "--method")
      o.method = val();
    else if (a == "-h" || a == "--help")
      usage(argv[0], extra);
    else if (!a.empty() && a[0] == '-')
      usage(argv[0], extra);
    else if (o.in.empty())
      o.in = a;
    else
      usage(argv[0], extra);
  }
  if (o.in.empty() || o.out.empty() || o.k < 3 || o.threads < 1) usage(argv[0], extra);
  return o;
}

} // namespace peer
