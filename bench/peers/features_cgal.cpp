// features_cgal — the Voronoi covariance measure baseline of the feature
// comparison (scripts/validate_features.py): CGAL::compute_vcm (offset radius
// R, convolution radius r; Merigot, Ovsjanikov and Guibas 2011) and the score
// that CGAL::vcm_is_on_feature_edge thresholds, lambda1 / (lambda0 + lambda1 +
// lambda2) of the convolved VCM (CGAL/vcm_estimate_edges.h; a point is on an
// edge when it is >= threshold: external angle >= 2/sqrt(3) sqrt(threshold)).
//
// usage: features_cgal INPUT.ply -o SCORES.txt --R R --r r [--threshold 0.16]
//
// R and r are absolute (the script sets them from the mean spacing h, as CGAL's
// edges_example.cpp does implicitly: R = 0.2, r = 0.1 on data/fandisk.off whose
// h is 0.01687, i.e. R = 11.85 h, r = 5.93 h). SCORES.txt: one value per point,
// in input order (-1 where the covariance could not be diagonalised, nan where
// the VCM itself is not finite; vcm_is_on_feature_edge says "not an edge" to
// both). The JSON line on stdout
// counts vcm_is_on_feature_edge(cov, threshold) itself (the example's 0.16 by
// default) as a check that score >= threshold is CGAL's decision. Timed:
// compute_vcm (Delaunay triangulation, offset Voronoi cells, convolution);
// CGAL 5.5's compute_vcm is sequential.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/vcm_estimate_edges.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "peer_util.hpp"
#include "ply_io.hpp"

typedef CGAL::Exact_predicates_inexact_constructions_kernel Kernel;
typedef Kernel::Point_3 Point;
typedef std::array<double, 6> Covariance;

static void usage() {
  std::fprintf(stderr,
               "usage: features_cgal INPUT.ply -o SCORES.txt --R R --r r [--threshold T]\n");
  std::exit(2);
}

int main(int argc, char **argv) {
  std::string in, out;
  double R = 0, r = -1, threshold = 0.16;
  for (int i = 1; i < argc; i++) {
    const std::string a = argv[i];
    auto val = [&]() -> const char * {
      if (i + 1 >= argc) usage();
      return argv[++i];
    };
    if (a == "-o")
      out = val();
    else if (a == "--R")
      R = std::atof(val());
    else if (a == "--r")
      r = std::atof(val());
    else if (a == "--threshold")
      threshold = std::atof(val());
    else if (!a.empty() && a[0] == '-')
      usage();
    else if (in.empty())
      in = a;
    else
      usage();
  }
  if (in.empty() || out.empty() || !(R > 0) || !(r >= 0)) usage();
  std::vector<double> xyz;
  try {
    plyio::read_xyz(in, xyz);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "features_cgal: %s\n", e.what());
    return 1;
  }
  const size_t n = xyz.size() / 3;
  std::vector<Point> points;
  points.reserve(n);
  for (size_t i = 0; i < n; i++)
    points.emplace_back(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);

  std::vector<Covariance> cov;
  const double c0 = peer::cpu_seconds();
  const double t0 = peer::now();
  CGAL::compute_vcm(points, cov, R, r, CGAL::parameters::geom_traits(Kernel()));
  const double secs = peer::now() - t0;
  const double cpu = peer::cpu_seconds() - c0;

  FILE *f = std::fopen(out.c_str(), "w");
  if (!f) {
    std::fprintf(stderr, "features_cgal: cannot write %s\n", out.c_str());
    return 1;
  }
  size_t on_edge = 0, agree = 0, failed = 0, nan = 0;
  for (size_t i = 0; i < n; i++) {
    std::array<double, 3> ev;
    double score = -1;
    // the same traits and ratio as vcm_is_on_feature_edge(cov, threshold)
    if (CGAL::Default_diagonalize_traits<double, 3>::diagonalize_selfadjoint_covariance_matrix(
            cov[i], ev))
      score = ev[1] / (ev[0] + ev[1] + ev[2]);
    else
      failed++;
    if (std::isnan(score)) nan++; // e.g. degenerate Delaunay cells of a regular grid
    const bool e = CGAL::vcm_is_on_feature_edge(cov[i], threshold);
    on_edge += e;
    agree += e == (score >= threshold);
    std::fprintf(f, "%.9g\n", score);
  }
  if (std::fclose(f) != 0) {
    std::fprintf(stderr, "features_cgal: cannot write %s\n", out.c_str());
    return 1;
  }
  std::printf(
      "{\"peer\":\"cgal\",\"version\":\"%s\",\"score\":\"vcm l1/(l0+l1+l2)\",\"R\":%.9g,\"r\":%.9g,"
      "\"points\":%zu,\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"threshold\":%.9g,\"on_edge\":%zu,"
      "\"score_agrees\":%zu,\"failed\":%zu,\"nan\":%zu}\n",
      CGAL_VERSION_STR, R, r, n, secs, cpu, threshold, on_edge, agree, failed, nan);
  return 0;
}
