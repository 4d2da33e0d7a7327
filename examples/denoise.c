/* Denoise a file (thesis chapter 6): bilateral smoothing driven by the
 * bootstrap error (Algorithm 4, Eq. 6.2) with the library's defaults, the
 * moved points written with every input field plus `moved`.
 * Usage: denoise INPUT OUTPUT.ply */
#include <bootsurf.h>

#include "example.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv) {
  bsurf_cloud cloud;
  int rc = example_read_input(argc, argv, &cloud);
  if (rc) return rc;
  bsurf_smooth_options opt = bsurf_smooth_options_default(); /* bilateral, K = 50 */
  bsurf_neighbors nb;
  double *out_xyz = malloc(cloud.point_count * 3 * sizeof *out_xyz);
  bsurf_field *moved = bsurf_cloud_add_field(&cloud, "moved", BSURF_FLOAT32);
  bsurf_status st = out_xyz && moved ? bsurf_neighbors_build(&nb, cloud.xyz, cloud.point_count,
                                                             opt.error.k, 0, NULL, NULL)
                                     : BSURF_ERR_NOMEM;
  bsurf_smooth_report rep;
  if (st == BSURF_OK) {
    bsurf_smooth_fields fields = {0};
    fields.moved = moved->values;
    st = bsurf_smooth(cloud.xyz, &nb, &opt, out_xyz, &fields, &rep);
    bsurf_neighbors_free(&nb);
  }
  if (st == BSURF_OK) {
    memcpy(cloud.xyz, out_xyz, cloud.point_count * 3 * sizeof *out_xyz);
    bsurf_failure where;
    st = bsurf_write(argv[2], &cloud, NULL, &where);
  }
  free(out_xyz);
  if (st != BSURF_OK) {
    fprintf(stderr, "denoise: %s\n", bsurf_strerror(st));
    bsurf_cloud_free(&cloud);
    return 1;
  }
  printf("%zu points, h = %g: %zu moved, by %g h on average -> %s\n", cloud.point_count, rep.h,
         rep.moved_points, rep.moved_mean / rep.h, argv[2]);
  bsurf_cloud_free(&cloud);
  return 0;
}
