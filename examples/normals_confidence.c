/* Normals with a confidence value (thesis chapter 5): the mean of B bootstrap
 * PCA normals (Eq. 5.4) and the variance of their angles (Eq. 5.5, radians^2;
 * small = confident), written as the cloud's normals and a field normal_var.
 * Usage: normals_confidence INPUT OUTPUT.ply */
#include <bootsurf.h>

#include "example.h"

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
  bsurf_cloud cloud;
  int rc = example_read_input(argc, argv, &cloud);
  if (rc) return rc;
  bsurf_normal_options opt = bsurf_normal_options_default(); /* PCA, K = 30, B = 50 */
  bsurf_neighbors nb;
  bsurf_status st = bsurf_neighbors_build(&nb, cloud.xyz, cloud.point_count, opt.k, 0, NULL, NULL);
  if (st != BSURF_OK) {
    fprintf(stderr, "%s: %s\n", argv[1], bsurf_strerror(st));
    bsurf_cloud_free(&cloud);
    return 1;
  }
  /* The cloud owns its arrays. A field's values stay where they are when
   * another field is added (bootsurf.h, "Ownership"), so both pointers below
   * remain valid. */
  if (!cloud.normals && !(cloud.normals = calloc(cloud.point_count * 3, sizeof(double))))
    st = BSURF_ERR_NOMEM;
  bsurf_field *var =
      st == BSURF_OK ? bsurf_cloud_add_field(&cloud, "normal_var", BSURF_FLOAT32) : NULL;
  if (!var) st = BSURF_ERR_NOMEM;
  bsurf_normal_report rep;
  if (st == BSURF_OK) {
    bsurf_normal_fields out = {cloud.normals, var->values, NULL};
    st = bsurf_estimate_normals(cloud.xyz, &nb, NULL, &opt, &out, &rep);
  }
  bsurf_neighbors_free(&nb);
  bsurf_failure where;
  if (st == BSURF_OK) st = bsurf_write(argv[2], &cloud, NULL, &where);
  if (st != BSURF_OK) {
    fprintf(stderr, "normals_confidence: %s\n", bsurf_strerror(st));
    bsurf_cloud_free(&cloud);
    return 1;
  }
  size_t unsure = 0;
  for (size_t i = 0; i < cloud.point_count; i++)
    unsure += var->values[i] > 0.01; /* ~6 degrees */
  printf("%zu points, %zu with an angular spread above 0.1 rad, %zu degenerate -> %s\n",
         cloud.point_count, unsure, rep.degenerate, argv[2]);
  bsurf_cloud_free(&cloud);
  return 0;
}
