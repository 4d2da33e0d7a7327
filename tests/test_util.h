/* Helpers shared by the cmocka tests (include after cmocka.h and
 * bootsurf.h): scratch paths under $BSURF_TMP and the check of a refused
 * call's status and message. */
#ifndef BSURF_TEST_UTIL_H
#define BSURF_TEST_UTIL_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The scratch directory: tmp_dir_init() at the start of main. */
static char tmp_dir[1024];

static inline void tmp_dir_init(void) {
  const char *t = getenv("BSURF_TMP");
  snprintf(tmp_dir, sizeof tmp_dir, "%s", t ? t : "/tmp");
}

/* tmp_dir/name; the last four results stay valid. */
static inline const char *tmp_path(const char *name) {
  static char buf[4][1200];
  static int slot = 0;
  slot = (slot + 1) % 4;
  snprintf(buf[slot], sizeof buf[slot], "%s/%s", tmp_dir, name);
  return buf[slot];
}

/* status BSURF_ERR_INVALID_ARG and a message that names the function
 * ("func:") and contains `needle` (the parameter and its value) */
#define assert_invalid(call, func, needle)                                                         \
  do {                                                                                             \
    bsurf_status st_ = (call);                                                                     \
    assert_int_equal(st_, BSURF_ERR_INVALID_ARG);                                                  \
    const char *m_ = bsurf_last_message();                                                         \
    if (!strstr(m_, func ":") || !strstr(m_, needle))                                              \
      fail_msg("message '%s' lacks '%s' / '%s'", m_, func, needle);                                \
  } while (0)

#endif /* BSURF_TEST_UTIL_H */
