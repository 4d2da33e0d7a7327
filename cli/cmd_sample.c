/* bootsurf sample: points on a triangle mesh with ground-truth normals and
 * feature labels (thesis 5.2.2: vertex normals from the mesh connectivity;
 * 7.1.2: feature areas around the sharp edges). */
#include "cli.h"

int cmd_sample(const cli_command *cmd, int argc, char **argv) {
  bsurf_sample_options so = bsurf_sample_options_default();
  const char *output = NULL;
  int vertices = 0, ascii = 0, json = 0, quiet = 0, force = 0;
  cli_option opts[] = {
      {0, "vertices", ARG_FLAG, &vertices, "",
       "the mesh's vertices with area-weighted normals (default)", 1, 0},
      {'n', "points", ARG_SIZE, &so.points, "N",
       "N points uniform by area with face normals (0 = vertices)", 0, 4e9},
      {0, "sharp-angle", ARG_DOUBLE, &so.sharp_angle_deg, "DEG",
       "an edge is sharp when its faces' normals differ by more than DEG degrees", 0, 180},
      {0, "feature-width", ARG_DOUBLE, &so.feature_width, "W",
       "feature = within W nominal spacings sqrt(area / points) of a sharp edge", 0, 1e300},
      {0, "seed", ARG_U64, &so.seed, "S", "random seed (area sampling)", 1, 0},
      CLI_OPT_THREADS(so.threads),
      CLI_OPTS_OUTPUT(output, ascii, force),
      CLI_OPT_DROP_INVALID,
      CLI_OPTS_REPORT(json, quiet),
  };
  char *pos[1];
  int rc =
      cli_parse_one(cmd, opts, (int)(sizeof opts / sizeof opts[0]), argc, argv, pos, "MESH file");
  if (rc != CLI_PARSED) return rc;
  if (vertices && so.points > 0) return cli_usage_error(cmd, "--vertices and -n are exclusive");
  if (!output) return cli_usage_error(cmd, "missing -o OUTPUT");
  if (cli_check_output(output, pos[0], force)) return 1;

  double t0 = cli_now();
  bsurf_cloud mesh, c;
  bsurf_cloud_init(&mesh);
  bsurf_cloud_init(&c);
  if (cli_read_cloud(pos[0], &mesh)) return 1;
  if (mesh.face_count == 0) {
    bsurf_cloud_free(&mesh);
    return cli_error(
        "%s: has no faces; sample needs a triangle mesh (.off, .obj or .ply with faces)", pos[0]);
  }
  bsurf_sample_report rep;
  bsurf_status st = bsurf_sample_mesh(&c, &mesh, &so, &rep);
  size_t mesh_points = mesh.point_count, mesh_faces = mesh.face_count;
  bsurf_cloud_free(&mesh);
  if (st == BSURF_ERR_INVALID_VALUE)
    return cli_error("%s: the faces have no area (all degenerate)", pos[0]);
  if (st == BSURF_ERR_TOO_FEW_POINTS)
    return cli_error("%s: no vertex belongs to a face of non-zero area", pos[0]);
  if (st != BSURF_OK) return cli_error("%s: %s", pos[0], bsurf_strerror(st));
  if (rep.vertices_dropped)
    cli_warn("%s: %zu vertices belong to no face of non-zero area (no normal); left out", pos[0],
             rep.vertices_dropped);
  if (rep.inconsistent_edges)
    cli_warn(
        "%s: %zu edges join faces of opposite orientation; vertex normals there are unreliable",
        pos[0], rep.inconsistent_edges);
  rc = cli_write_cloud(output, &c, ascii);
  if (rc == 0 && !quiet) {
    double secs = cli_now() - t0;
    const char *mode = so.points ? "area" : "vertices";
    if (json) {
      cli_json j = json_start("sample", pos[0], output);
      json_str(&j, "mode", mode);
      json_int(&j, "points", (long long)c.point_count);
      json_int(&j, "mesh_points", (long long)mesh_points);
      json_int(&j, "faces", (long long)mesh_faces);
      json_int(&j, "edges", (long long)rep.edges);
      json_int(&j, "sharp_edges", (long long)rep.sharp_edges);
      json_int(&j, "boundary_edges", (long long)rep.boundary_edges);
      json_int(&j, "nonmanifold_edges", (long long)rep.nonmanifold_edges);
      json_int(&j, "inconsistent_edges", (long long)rep.inconsistent_edges);
      json_int(&j, "degenerate_faces", (long long)rep.degenerate_faces);
      json_int(&j, "vertices_dropped", (long long)rep.vertices_dropped);
      json_int(&j, "feature_points", (long long)rep.feature_points);
      json_num(&j, "area", rep.area);
      json_num(&j, "mean_edge_length", rep.mean_edge_length);
      json_num(&j, "spacing", rep.spacing);
      json_num(&j, "sharp_angle", so.sharp_angle_deg);
      json_num(&j, "feature_width", so.feature_width);
      json_num(&j, "feature_width_abs", rep.feature_width);
      if (so.points) json_int(&j, "seed", (long long)so.seed);
      json_int(&j, "threads", bsurf_threads_resolve(so.threads));
      json_num(&j, "seconds", secs);
      json_end(&j);
    } else {
      printf("sample %s: %zu points (%s) from %zu vertices and %zu faces -> %s\n", pos[0],
             c.point_count, mode, mesh_points, mesh_faces, output);
      printf("  %zu edges: %zu sharp (> %g deg), %zu boundary, %zu non-manifold\n", rep.edges,
             rep.sharp_edges, so.sharp_angle_deg, rep.boundary_edges, rep.nonmanifold_edges);
      printf("  %zu feature points (within %g x spacing %.6g = %.6g of a sharp edge), %.2f s\n",
             rep.feature_points, so.feature_width, rep.spacing, rep.feature_width, secs);
      cli_print_input_report(stdout);
    }
  }
  bsurf_cloud_free(&c);
  return rc;
}
