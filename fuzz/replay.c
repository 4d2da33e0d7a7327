/* A main() for a libFuzzer target without libFuzzer: runs
 * LLVMFuzzerTestOneInput once on every file of the directories (or files)
 * given, in name order, as ctest's replay of a seed corpus
 * (fuzz_cli_read_replay). Prints how many inputs ran; exits 1 when a
 * directory cannot be read or holds no input. */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int run_file(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return 0;
  size_t cap = 1 << 16, n = 0;
  uint8_t *buf = malloc(cap);
  size_t got;
  while (buf && (got = fread(buf + n, 1, cap - n, f)) > 0) {
    n += got;
    if (n == cap) {
      uint8_t *nb = realloc(buf, cap *= 2);
      if (!nb) break;
      buf = nb;
    }
  }
  fclose(f);
  if (!buf) return 0;
  /* an allocation of exactly n bytes, so that ASan sees reads past the end */
  uint8_t *exact = malloc(n ? n : 1);
  if (exact) {
    memcpy(exact, buf, n);
    LLVMFuzzerTestOneInput(exact, n);
  }
  free(exact);
  free(buf);
  return 1;
}

static int by_name(const void *a, const void *b) {
  return strcmp(*(char *const *)a, *(char *const *)b);
}

int main(int argc, char **argv) {
  LLVMFuzzerInitialize(&argc, &argv);
  size_t total = 0;
  for (int a = 1; a < argc; a++) {
    struct stat sb;
    if (stat(argv[a], &sb) == 0 && S_ISREG(sb.st_mode)) {
      total += (size_t)run_file(argv[a]);
      continue;
    }
    DIR *d = opendir(argv[a]);
    if (!d) {
      fprintf(stderr, "replay: cannot read %s\n", argv[a]);
      return 1;
    }
    char **names = NULL;
    size_t count = 0;
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
      if (de->d_name[0] == '.') continue;
      char **nn = realloc(names, (count + 1) * sizeof *names);
      if (!nn) break;
      names = nn;
      size_t len = strlen(argv[a]) + strlen(de->d_name) + 2;
      names[count] = malloc(len);
      if (names[count]) snprintf(names[count++], len, "%s/%s", argv[a], de->d_name);
    }
    closedir(d);
    qsort(names, count, sizeof *names, by_name);
    for (size_t i = 0; i < count; i++) {
      total += (size_t)run_file(names[i]);
      free(names[i]);
    }
    free(names);
  }
  printf("replay: %zu inputs\n", total);
  return total ? 0 : 1;
}
