// normals_pcl — PCA normals with PCL's NormalEstimationOMP, for comparison with
// `bootsurf normals --fit pca -B 0`.
//
// usage: normals_pcl INPUT.ply -o OUTPUT.ply [-k 30] [-j 2]
//
// Timed (monotonic clock): NormalEstimationOMP::compute() alone, which builds
// the FLANN k-d tree (pcl::search::KdTree, single-threaded) and then, in
// parallel, searches the K nearest neighbours of every point and fits its
// plane. bootsurf's timing likewise includes its k-d tree and all-kNN search.
// Not timed: reading the PLY, converting to pcl::PointXYZ (float), writing.
//
// Neighbourhood: nearestKSearch(K) over the cloud itself returns the query
// point (distance 0) among the K, so K = 30 here is bootsurf's K = 30.
// PCL works in single precision (PointXYZ, covariance and eigen solve in float).
// Normals are flipped towards the viewpoint (0, 0, 0) — irrelevant for the
// unoriented angle errors of the comparison.
#include <pcl/features/normal_3d_omp.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <cmath>

#include "peer_util.hpp"
#include "ply_io.hpp"
#include "pcl_util.hpp"

int main(int argc, char **argv) {
  const peer::Options o = peer::parse(argc, argv, "", "pca");
  std::vector<double> xyz;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = peer::read_pcl_cloud(o.in, "normals_pcl", xyz);
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
  ne.compute(normals); // builds the k-d tree (initCompute), then the OMP loop
  const double secs = peer::now() - t0;
  const double cpu = peer::cpu_seconds() - c0;

  std::vector<double> nrm(3 * n);
  size_t invalid = 0;
  for (size_t i = 0; i < n; i++) {
    const pcl::Normal &p = normals[i];
    if (!std::isfinite(p.normal_x)) invalid++;
    nrm[3 * i] = p.normal_x;
    nrm[3 * i + 1] = p.normal_y;
    nrm[3 * i + 2] = p.normal_z;
  }
  try {
    plyio::write_xyz_normals(o.out, xyz, nrm, "normals_pcl NormalEstimationOMP");
  } catch (const std::exception &e) {
    std::fprintf(stderr, "normals_pcl: %s\n", e.what());
    return 1;
  }
  std::printf("{\"peer\":\"pcl\",\"version\":\"%s\",\"method\":\"pca\",\"k\":%d,\"threads\":%d,"
              "\"points\":%zu,\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"peak_rss_kb\":%ld,\"invalid_"
              "normals\":%zu,"
              "\"timed\":\"NormalEstimationOMP::compute incl. FLANN kd-tree build\"}\n",
              PCL_VERSION_PRETTY, o.k, o.threads, n, secs, cpu, peer::peak_rss_kb(), invalid);
  return 0;
}
