/* The README's library example: per-point bootstrap test error of a scan.
 * Usage: estimate_error INPUT.ply OUTPUT.ply */
#include <bootsurf.h>

#include "example.h"

#include <stdio.h>

int main(int argc, char **argv) {
  bsurf_cloud cloud;
  int rc = example_read_input(argc, argv, &cloud);
  if (rc) return rc;

  bsurf_error_options opt = bsurf_error_options_default(); /* K=50, cubic, B=50, seed 1 */
  bsurf_neighbors nb;                                      /* built once, shared */
  bsurf_status st = bsurf_neighbors_build(&nb, cloud.xyz, cloud.point_count, opt.k, 0, NULL, NULL);
  if (st != BSURF_OK) {
    fprintf(stderr, "neighbourhoods: %s\n", bsurf_strerror(st));
    bsurf_cloud_free(&cloud);
    return 1;
  }

  bsurf_field *f = bsurf_cloud_add_field(&cloud, "err_632plus", BSURF_FLOAT32);
  bsurf_error_fields out = {0};
  out.err_632plus = f->values; /* outputs you don't need stay NULL */
  bsurf_error_report rep;
  st = bsurf_estimate_error(cloud.xyz, &nb, NULL, &opt, &out, &rep);
  bsurf_failure where;
  if (st == BSURF_OK) st = bsurf_write(argv[2], &cloud, NULL, &where); /* binary PLY, atomic */
  if (st != BSURF_OK)
    fprintf(stderr, "%s\n", bsurf_strerror(st));
  else
    printf("%zu points, h = %g, %zu replicate fits skipped\n", cloud.point_count, nb.h,
           rep.replicates_skipped);
  bsurf_neighbors_free(&nb);
  bsurf_cloud_free(&cloud);
  return st == BSURF_OK ? 0 : 1;
}
