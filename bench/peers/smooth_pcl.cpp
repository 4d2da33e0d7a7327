// smooth_pcl — PCL's MovingLeastSquares (no upsampling: every point projected onto
// the degree-2 polynomial fitted to the points within the search radius), for
// comparison with `bootsurf smooth` (bench/smooth_compare.sh).
//
// usage: smooth_pcl INPUT.ply -o OUTPUT.ply [-k 50] [-j 2] [-d 2] [--radius R]
//
// Search radius: MLS takes a radius, not K. Unless --radius is given it is
// chosen so that about K points (the point included) fall inside: the mean,
// over up to 10,000 points spread evenly through the file, of the distance to
// the K-th nearest neighbour (the point itself the first). This adapts to the
// sampling (a regular grid and a uniform random sample with the same mean
// spacing h need radii about 2x apart for the same K). The JSON reports the
// radius, its cost (radius_seconds, NOT in "seconds": choosing the parameter is
// the harness's job, as K is for the others) and the mean number of points
// inside it over the same sample. Gaussian weight parameter: PCL's default,
// radius^2. Projection: PCL's default (SIMPLE). PCL fits the polynomial only
// where at least 5 x 6 = 30 neighbours are inside the radius, else the plane
// (mls.hpp); "plane_only" in the JSON counts those points.
//
// Timed (monotonic clock, "seconds"): MovingLeastSquares::process() alone, which
// builds its FLANN k-d tree (single-threaded) and then, in OpenMP threads
// (setNumberOfThreads(-j)), radius-searches and fits every point. Not timed:
// reading the PLY, conversion to pcl::PointXYZ (float: PCL works in single
// precision), the radius choice, writing. The per-point MLSResult cache stays on
// (PCL's default) although only upsampling needs it: with it off, PCL 1.13's
// OpenMP loop has every thread write the same dummy MLSResult (mls_results_[0],
// performProcessing in mls.hpp), a data race that aborts in Eigen (seen here).
//
// Dropped points: MLS skips points with fewer than 3 neighbours inside the
// radius, and with threads it returns the rest in per-thread order. The output
// is put back in input order through getCorrespondingIndices(); a dropped
// point is written at its INPUT position (unsmoothed) so that every output has
// the input's points in the input's order, and the field mls_kept (1 smoothed,
// 0 dropped) marks them; the JSON counts them ("dropped").
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/surface/mls.h>

#include <cmath>

#include "peer_util.hpp"
#include "ply_io.hpp"
#include "pcl_util.hpp"

static const char *EXTRA = " [-d DEGREE] [--radius R]\n  default K here: 50";

int main(int argc, char **argv) {
  double radius = 0;
  bool k_given = false;
  std::vector<char *> rest{argv[0]};
  for (int i = 1; i < argc; i++) {
    const std::string a = argv[i];
    if (a == "--radius" && i + 1 < argc)
      radius = std::atof(argv[++i]);
    else {
      if (a == "-k") k_given = true;
      rest.push_back(argv[i]);
    }
  }
  peer::Options o = peer::parse((int)rest.size(), rest.data(), EXTRA, "mls");
  if (!k_given) o.k = 50;
  if (o.degree < 0 || o.degree > 4) peer::usage(argv[0], EXTRA);

  std::vector<double> xyz;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = peer::read_pcl_cloud(o.in, "smooth_pcl", xyz);
  if (!cloud) return 1;
  const size_t n = cloud->size();

  // radius: mean distance to the K-th neighbour (point included) over a sample
  const size_t sample = n < 10000 ? n : 10000;
  double radius_secs = 0, inside_mean = 0;
  {
    const double t0 = peer::now();
    pcl::search::KdTree<pcl::PointXYZ> tree(false);
    tree.setInputCloud(cloud);
    pcl::Indices idx;
    std::vector<float> d2;
    if (radius <= 0) {
      double sum = 0;
      for (size_t s = 0; s < sample; s++) {
        const size_t i = s * n / sample;
        tree.nearestKSearch((*cloud)[i], o.k, idx, d2);
        sum += std::sqrt((double)d2.back());
      }
      radius = sum / (double)sample;
    }
    radius_secs = peer::now() - t0;
    double inside = 0; // not timed: how many points the radius holds
    for (size_t s = 0; s < sample; s++) {
      const size_t i = s * n / sample;
      inside += (double)tree.radiusSearch((*cloud)[i], radius, idx, d2);
    }
    inside_mean = inside / (double)sample;
  }

  pcl::PointCloud<pcl::PointXYZ> smoothed;
  pcl::MovingLeastSquares<pcl::PointXYZ, pcl::PointXYZ> mls;
  const double c0 = peer::cpu_seconds();
  const double t0 = peer::now();
  mls.setInputCloud(cloud);
  mls.setPolynomialOrder(o.degree);
  mls.setSearchRadius(radius); // also sets the Gaussian parameter to radius^2
  mls.setComputeNormals(false);
  mls.setNumberOfThreads((unsigned)o.threads);
  mls.setSearchMethod(
      pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>(false)));
  mls.process(smoothed); // builds the k-d tree, then the OpenMP loop
  const double secs = peer::now() - t0;
  const double cpu = peer::cpu_seconds() - c0;

  // back to input order; dropped points stay where they were
  const pcl::PointIndicesPtr corr = mls.getCorrespondingIndices();
  std::vector<double> out(xyz);
  plyio::Extra kept{"mls_kept", std::vector<float>(n, 0.0f)};
  size_t dup = 0;
  if (!corr || corr->indices.size() != smoothed.size()) {
    std::fprintf(stderr, "smooth_pcl: no corresponding indices from MLS\n");
    return 1;
  }
  for (size_t j = 0; j < smoothed.size(); j++) {
    const size_t i = (size_t)corr->indices[j];
    if (kept.values[i] != 0.0f) dup++;
    kept.values[i] = 1.0f;
    out[3 * i] = smoothed[j].x;
    out[3 * i + 1] = smoothed[j].y;
    out[3 * i + 2] = smoothed[j].z;
  }
  size_t dropped = 0;
  double moved_sum = 0, moved_max = 0;
  for (size_t i = 0; i < n; i++) {
    if (kept.values[i] == 0.0f) dropped++;
    const double dx = out[3 * i] - xyz[3 * i], dy = out[3 * i + 1] - xyz[3 * i + 1],
                 dz = out[3 * i + 2] - xyz[3 * i + 2];
    const double d = std::sqrt(dx * dx + dy * dy + dz * dz);
    moved_sum += d;
    if (d > moved_max) moved_max = d;
  }
  // points where PCL fitted only the plane (fewer than 5 * nr_coeff neighbours),
  // counted on the sample (not timed)
  size_t plane_only = 0;
  if (o.degree > 1) {
    pcl::search::KdTree<pcl::PointXYZ> tree(false);
    tree.setInputCloud(cloud);
    pcl::Indices idx;
    std::vector<float> d2;
    const int need = 5 * (o.degree + 1) * (o.degree + 2) / 2;
    for (size_t s = 0; s < sample; s++)
      if (tree.radiusSearch((*cloud)[s * n / sample], radius, idx, d2) < need) plane_only++;
  }
  try {
    plyio::write_points(o.out, out, {}, {kept}, "smooth_pcl MovingLeastSquares");
  } catch (const std::exception &e) {
    std::fprintf(stderr, "smooth_pcl: %s\n", e.what());
    return 1;
  }
  std::printf(
      "{\"peer\":\"pcl\",\"version\":\"%s\",\"method\":\"mls\",\"degree\":%d,\"k\":%d,"
      "\"threads\":%d,\"points\":%zu,\"output_points\":%zu,\"dropped\":%zu,\"duplicates\":%zu,"
      "\"radius\":%.9g,\"radius_seconds\":%.6f,\"mean_inside_radius\":%.2f,"
      "\"plane_only_share\":%.5f,\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"peak_rss_kb\":%ld,"
      "\"moved_mean\":%.9g,\"moved_max\":%.9g,"
      "\"timed\":\"MovingLeastSquares::process incl. FLANN kd-tree build\"}\n",
      PCL_VERSION_PRETTY, o.degree, o.k, o.threads, n, smoothed.size(), dropped, dup, radius,
      radius_secs, inside_mean, sample ? (double)plane_only / (double)sample : 0.0, secs, cpu,
      peer::peak_rss_kb(), n ? moved_sum / (double)n : 0.0, moved_max);
  return 0;
}
