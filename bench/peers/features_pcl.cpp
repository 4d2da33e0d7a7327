// features_pcl — the surface-variation baseline of the feature comparison
// (scripts/validate_features.py): PCL's NormalEstimationOMP, whose `curvature`
// output is the surface variation lambda0 / (lambda0 + lambda1 + lambda2) of the
// K-neighbourhood's covariance (Pauly et al. 2002; CloudCompare's "surface
// variation" is the same quantity). Thresholding it is the PCL/CloudCompare way
// of marking sharp features; the thresholds themselves are chosen by the
// validation script (best fixed value of a sweep, and an automatic rule).
//
// usage: features_pcl INPUT.ply -o SCORES.txt [-k 30] [-j 2]
//
// SCORES.txt: one value per input point, in input order ("nan" where PCL could
// not fit a plane). Timed: NormalEstimationOMP::compute() (FLANN k-d tree build
// + parallel kNN and fits); not the file I/O. K counts the point itself
// (bootsurf's convention; PCL's nearestKSearch returns the query point).
#include <pcl/features/normal_3d_omp.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <cmath>
#include <cstdio>

#include "peer_util.hpp"
#include "ply_io.hpp"
#include "pcl_util.hpp"

int main(int argc, char **argv) {
  const peer::Options o = peer::parse(argc, argv, "", "surface_variation");
  std::vector<double> xyz;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = peer::read_pcl_cloud(o.in, "features_pcl", xyz);
  if (!cloud) return 1;
  const size_t n = cloud->size();
  pcl::PointCloud<pcl::Normal> normals;
  const double c0 = peer::cpu_seconds();
  const double t0 = peer::now();
  pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne;
  ne.setNumberOfThreads((unsigned)o.threads);
  ne.setInputCloud(cloud);
  ne.setSearchMethod(
      pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  ne.setKSearch(o.k);
  ne.compute(normals);
  const double secs = peer::now() - t0;
  const double cpu = peer::cpu_seconds() - c0;

  FILE *f = std::fopen(o.out.c_str(), "w");
  if (!f) {
    std::fprintf(stderr, "features_pcl: cannot write %s\n", o.out.c_str());
    return 1;
  }
  size_t invalid = 0;
  for (size_t i = 0; i < n; i++) {
    const float c = normals[i].curvature;
    if (!std::isfinite(c)) invalid++;
    std::fprintf(f, "%.9g\n", (double)c);
  }
  if (std::fclose(f) != 0) {
    std::fprintf(stderr, "features_pcl: cannot write %s\n", o.out.c_str());
    return 1;
  }
  std::printf(
      "{\"peer\":\"pcl\",\"version\":\"%s\",\"score\":\"surface variation l0/(l0+l1+l2)\",\"k\":%d,"
      "\"threads\":%d,\"points\":%zu,\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"invalid\":%zu}\n",
      PCL_VERSION_PRETTY, o.k, o.threads, n, secs, cpu, invalid);
  return 0;
}
