/* bootsurf: statistics for point clouds. The command table and dispatch.
 * Exit codes: 0 ok, 1 bad input or failed computation, 2 bad usage; after
 * SIGINT or SIGTERM the process dies of that signal (130 or 143). */
#include "cli.h"

#include <errno.h>
#include <string.h>

static const cli_command commands[] = {
    {"info", "Print point count, fields, bounding box and mean point spacing h.", "INPUT [options]",
     "h is the mean distance from a point to its nearest neighbour: the unit in which\n"
     "bootsurf reports errors (thesis 4.2).",
     cmd_info},
    {"generate", "Generate points on a shape with exact normals and feature labels.",
     "SHAPE -o OUTPUT [options]",
     "SHAPE is sphere (radius 1), cube (edge 2), torus (radii 1 and 0.35) or plane\n"
     "([-1,1]^2). The cube also gets feature_dist (distance to the nearest sharp edge)\n"
     "and feature (1 within --feature-width nominal spacings of an edge).",
     cmd_generate},
    {"noise", "Displace points along their normals by t*h (thesis 4.2).",
     "INPUT -o OUTPUT [options]",
     "t ~ N(0, level^2) (gaussian, default) or U[-level, level] (uniform, the thesis\n"
     "text's model); h is the input's mean nearest-neighbour distance. Or, with\n"
     "--sigma-diag s, gaussian noise of sigma = s x bounding-box diagonal (PCPNet's\n"
     "protocol: 0.00125, 0.006, 0.012). The input must have normals (nx ny nz, or the\n"
     "true_* fields of an earlier noise output). The output carries the exact normals\n"
     "and labels on as ground truth, named so that eval never scores them as results:\n"
     "true_nx true_ny true_nz, true_feature, true_feature_dist.",
     cmd_noise},
    {"error", "Bootstrap test-error estimates of local polynomial fits (thesis ch. 4).",
     "INPUT [-o OUTPUT] [options]",
     "For every point: PCA frame of its K nearest neighbours, least-squares fit of a\n"
     "height polynomial of degree d, B bootstrap refits, and the estimators\n"
     "err_train (4.6), err_boot (4.3), err_loo (4.4), err_loo_center (4.11),\n"
     "err_632 (4.5), err_632plus (4.7-4.10), gamma and overfit_rate (R, 4.9).\n"
     "All are written per point (model units); the summary gives their means in\n"
     "model units and in units of h.\n"
     "Out of core: --tile-points N (or an input above --memory-limit) processes a\n"
     "binary PLY file in tiles with proven halos; mpirun -n P shares the tiles between\n"
     "P processes. Same output bytes as in memory (not with --test-sample); see\n"
     "docs/scaling.md.",
     cmd_error},
    {"normals", "Normals with bootstrap confidence and test error (thesis ch. 5).",
     "INPUT -o OUTPUT [options]",
     "PCA or polynomial normals from the K nearest neighbours; with -B > 0 the\n"
     "normalised mean of B bootstrap normals (Eq. 5.4) and normal_var, the variance\n"
     "of their angles (Eq. 5.5), a confidence value: lower is more reliable. Optional:\n"
     "normal_err, the bootstrap test error of the normal (Eq. 5.10, Algorithm 3);\n"
     "per-point choice of K (--select-k) by --select-rule (auto, the default: the mse\n"
     "rule, an estimate of the normal's mean squared error; or test-error, smallest\n"
     "normal_err; docs/normals.md); bilateral smoothing of the normals (Eqs.\n"
     "5.6-5.8); consistent orientation (minimum spanning tree).\n"
     "Out of core: --tile-points N (or an input above --memory-limit), and mpirun,\n"
     "as for error: same bytes as in memory, --test-error and --select-k in tiled\n"
     "stages; not with --curve, --smooth-iterations or --orient (they reach beyond\n"
     "the K-neighbourhood). docs/scaling.md.",
     cmd_normals},
    {"sample", "Points from a triangle mesh with ground-truth normals and feature labels.",
     "MESH -o OUTPUT [options]",
     "By default the mesh's vertices with area-weighted vertex normals (thesis 5.2.2:\n"
     "normals from the mesh connectivity); with -n N, N points uniform by area with\n"
     "their face's normal. An edge is sharp when its two faces' normals differ by more\n"
     "than --sharp-angle degrees (mesh borders are not sharp). Every point gets\n"
     "feature_dist, the exact distance to the nearest sharp edge (the bounding-box\n"
     "diagonal when there is none), and feature, 1 within --feature-width nominal\n"
     "spacings sqrt(area / points) of one. MESH needs faces (.off, .obj, .ply).",
     cmd_sample},
    {"eval", "Compare a result with ground truth (normal angles, feature scores, position).",
     "RESULT --truth TRUTH [--surface MESH] [options]",
     "normals and features compare the same points in the same order (e.g. the output\n"
     "of normals and the sample or generate file it came from). normals: unoriented\n"
     "angle errors, mean, median and rms in radians, mean in degrees, and the\n"
     "fractions under 5 and 10 degrees (PCPNet's PGP5/PGP10). features: precision,\n"
     "recall and F1 of RESULT's feature field (0/1) against TRUTH's. position: the\n"
     "distance of each RESULT point to the true surface -- --surface MESH, else\n"
     "TRUTH's faces, else the shape TRUTH was generated as, else the tangent plane of\n"
     "the corresponding TRUTH point (its normal) -- mean, rms and max, absolute and in\n"
     "units of TRUTH's spacing h, also for TRUTH's feature and non-feature points.\n"
     "Point i corresponds to TRUTH point i when both have as many points, else to the\n"
     "nearest TRUTH point. --split FIELD:Q also reports the points whose FIELD (from\n"
     "RESULT, else TRUTH) is above its Q-quantile and the rest, e.g. normal_var:0.85\n"
     "for the highest 15% of the bootstrap variance (thesis Table 5.2).\n"
     "TRUTH's true_nx/true_ny/true_nz, true_feature and true_feature_dist (written by\n"
     "noise) are its normals and labels when present. A RESULT field bit-identical to\n"
     "TRUTH's (ground truth passed along, not computed) is not scored.",
     cmd_eval},
    {"render", "Render a cloud to PNG, shaded by normals or coloured by a field.",
     "INPUT -o IMAGE.png [options]",
     "Orthographic view of the points as z-buffered splats of diameter --point-size\n"
     "times h (the mean nearest-neighbour distance), so surfaces look closed.\n"
     "Without --field the surface is shaded by its normals (two-sided Lambert), or by\n"
     "depth when there are none; with --field the values go through a colormap\n"
     "(values outside --range, by default the 1st-99th percentile, are capped) and a\n"
     "colour bar is drawn. --views 4 shows front, right, top and iso in a 2x2 grid.\n"
     "The same input gives the same PNG bytes for any thread count.",
     cmd_render},
    {"histogram", "PNG histogram of a field, with an optional threshold marker (7.2).",
     "INPUT --field NAME -o IMAGE.png [options]",
     "Bars of the counts of the field's finite values in --bins equal bins between\n"
     "its minimum and maximum (or --range), axes with ticks; --threshold T draws a\n"
     "marker and counts the values above it; --log plots log10(1 + count).",
     cmd_histogram},
    {"compare", "Several clouds side by side in one PNG (same view and colour range).",
     "A B ... -o IMAGE.png [options]",
     "Each input becomes a panel of --size pixels with its title (--titles \"a,b\"\n"
     "or the file name); with --field every panel uses the same colour range (by\n"
     "default the 1st-99th percentile of all inputs together) and one colour bar.",
     cmd_compare},
    {"smooth", "Denoise: move points towards the bootstrap fits (thesis ch. 6).",
     "INPUT -o OUTPUT [options]",
     "naive (6.2, Eq. 6.1): each point to the mean of its B bootstrap fits, only where\n"
     "its error is below --threshold. bilateral (6.3, Algorithm 4, Eq. 6.2): every\n"
     "neighbourhood's fit pulls the point and its neighbours with weight\n"
     "G(distance, h1) G(W_i, h2), G(a, b) = exp(-a^2/b^2). multipass (6.4, Algorithm 5):\n"
     "per point a neighbourhood K_i (Eqs. 6.3-6.4 with --k-error), fits made once, then\n"
     "passes of Eq. 6.2 with h1 = a d_L (Eq. 6.5) until a pass moves points by less\n"
     "than the fits' own error (or --iterations passes). Thesis settings: --guard off\n"
     "--a 0.1 --h2 0.3W --k-error 1W --iterations 300. Every input\n"
     "field is kept; err_632, err_632plus and moved (and k_hat, d_local) are added.\n"
     "The input's normals (nx ny nz) are dropped: they belong to the points before\n"
     "they moved (run normals on the output for new ones).",
     cmd_smooth},
    {"features", "Feature detection: PCA distance map or bootstrap variance (thesis ch. 7).",
     "INPUT -o OUTPUT [options]",
     "distance (7.1): per point, PCA of growing neighbourhoods (--k-min..--k-max);\n"
     "the radius where lambda0/lambda2 first exceeds --ratio-threshold (raised to\n"
     "--noise-factor x its median over the points where noise lifts that above it) is\n"
     "the distance to the nearest feature (points exceeding it at once get -max radius),\n"
     "smoothed by a bilateral filter (Eq. 7.1); features: feature_dist <= --threshold x\n"
     "its maximum (auto: <= 0, or below Otsu's split of the positive values).\n"
     "variance (7.2, the default): features are normal_var > --threshold; auto (the\n"
     "default): a test against a simulated flat patch at the measured noise, on\n"
     "z = normal_var x design / noise^2 median-filtered, noise^2 with the curvature's\n"
     "share where the density varies (--false-positive-rate; parallel\n"
     "sheets count as flat), with -k grown until a --feature-angle edge at that noise\n"
     "passes the test; a flagged point stays a feature only where a quadric does not\n"
     "explain its neighbourhood at the noise the K selection reads (--quadric-angle:\n"
     "smooth bends are cleared; docs/features.md).\n"
     "The thesis: --method distance, or --feature-angle 0 --quadric-angle 0\n"
     "--threshold T. Writes feature\n"
     "(0/1) and the score (feature_dist, variance_z or normal_var); input fields of those names "
     "(e.g. ground truth from generate or\n"
     "sample) are kept as feature_in and feature_dist_in / normal_var_in, or, when\n"
     "those exist already, replaced (they were an earlier result).\n"
     "Out of core: --tile-points N (or an input above --memory-limit), and mpirun:\n"
     "both methods in tiled stages with the in-memory bytes (distance: the sample's\n"
     "medians, the raw map, one run per filter pass; --threshold auto keeps 8 bytes\n"
     "per point in memory). docs/scaling.md.",
     cmd_features},
    {"convert", "Convert between formats, keeping every field the output can hold.",
     "INPUT OUTPUT [options]",
     "Formats: .ply, .pcd (PCL; ascii, binary, binary_compressed read), .las (1.0-1.4,\n"
     "point formats 0-10; written as LAS 1.4 with the fields as extra bytes), .csv/.asc\n"
     "(a header line names the columns), .xyz/.txt/.pts, .off, .obj. The input's format\n"
     "comes from its content (ply, PCD, LASF, OFF signatures), else its extension; the\n"
     "output's from --format, else its extension. - is standard input or output (with\n"
     "--format). PLY, PCD, LAS and CSV keep every field with its values (LAS coordinates\n"
     "within their scale); OFF, OBJ and XYZ keep points, normals and faces. docs/formats.md.",
     cmd_convert},
};
static const int command_count = (int)(sizeof commands / sizeof commands[0]);

static void usage(FILE *f) {
  fprintf(f,
          "bootsurf %s: statistics for 3D point clouds (bootstrap error estimates,\n"
          "normals with confidence, denoising, feature detection).\n\n"
          "Usage: bootsurf COMMAND [options] INPUT [-o OUTPUT]\n"
          "       bootsurf help COMMAND | bootsurf COMMAND --help\n\nCommands:\n",
          BSURF_VERSION_STRING);
  for (int i = 0; i < command_count; i++)
    fprintf(f, "  %-10s %s\n", commands[i].name, commands[i].summary);
  fprintf(f, "\nFiles: .ply (ascii or binary), .pcd, .las, .csv/.asc, .off, .obj, .xyz/.txt; - is\n"
             "standard input or output (--format FMT). Output PLY is binary little-endian unless\n"
             "--ascii. Exit codes: 0 ok, 1 bad input or failure, 2 bad usage, 130 / 143\n"
             "interrupted by SIGINT / SIGTERM (temporary files removed).\n");
}

static const cli_command *find(const char *name) {
  for (int i = 0; i < command_count; i++)
    if (strcmp(commands[i].name, name) == 0) return &commands[i];
  return NULL;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage(stderr);
    return 2;
  }
  const char *name = argv[1];
  if (strcmp(name, "-h") == 0 || strcmp(name, "--help") == 0) {
    usage(stdout);
    return 0;
  }
  if (strcmp(name, "--version") == 0) {
    printf("bootsurf %s\n", BSURF_VERSION_STRING);
    return 0;
  }
  if (strcmp(name, "help") == 0) {
    if (argc < 3) {
      usage(stdout);
      return 0;
    }
    const cli_command *c = find(argv[2]);
    if (!c) {
      fprintf(stderr, "bootsurf: unknown command '%s'\n", argv[2]);
      return 2;
    }
    char *hargv[] = {argv[2], "--help", NULL};
    int rc = c->run(c, 2, hargv);
    return rc == CLI_HELP_SHOWN ? 0 : rc;
  }
  const cli_command *c = find(name);
  if (!c) {
    fprintf(stderr, "bootsurf: unknown command '%s'\n\n", name);
    usage(stderr);
    return 2;
  }
  cli_install_signals();
  if (cli_output_is_stdout(argc - 1, argv + 1)) cli_stdout_data_begin(); /* -o -: text to stderr */
  cli_mpi_init(&argc, &argv);
  int rc = c->run(c, argc - 1, argv + 1);
  if (rc == CLI_HELP_SHOWN) rc = 0;
  cli_mpi_finalize();
  /* a summary that could not be written (a full disk, /dev/full) is a
   * failure, not a silent success */
  errno = 0;
  if (fflush(stdout) != 0 || ferror(stdout)) {
    fprintf(stderr, "bootsurf: error: standard output: %s\n",
            errno ? strerror(errno) : "write failed");
    if (rc == 0) rc = 1;
  }
  return cli_exit_status(rc);
}
