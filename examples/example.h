/* The examples' common start: the arguments INPUT OUTPUT.ply and the input
 * read with bsurf_read (on failure a message naming the file and the line). */
#ifndef BSURF_EXAMPLE_H
#define BSURF_EXAMPLE_H

#include <bootsurf.h>

#include <stdio.h>

/* 0 with *cloud read; otherwise the exit status: 2 (usage), 1 (not read). */
static int example_read_input(int argc, char **argv, bsurf_cloud *cloud) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s INPUT OUTPUT.ply\n", argv[0]);
    return 2;
  }
  bsurf_failure where;
  if (bsurf_read(argv[1], cloud, &where) != BSURF_OK) {
    fprintf(stderr, "%s:%ld: %s\n", argv[1], where.line, where.message);
    return 1;
  }
  return 0;
}

#endif
