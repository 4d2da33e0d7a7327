// knn_nanoflann — all-K-nearest-neighbour search with nanoflann (Debian's
// libnanoflann-dev, header-only), for comparison with bootsurf's bsurf_knn_all
// (bench/peers/knn_bootsurf.c).
//
// usage: knn_nanoflann INPUT.ply -o CHECK.f64 [-k 50] [-j 2] [--method tree|input]
//
// Index: KDTreeSingleIndexAdaptor<L2_Simple_Adaptor<double>, 3 dimensions,
// uint32_t indices>, leaf size 10 (nanoflann's default), built in its
// constructor (sequential in nanoflann 1.4; "seconds_build").
// Search: knnSearch(point, K) for every point, in an OpenMP loop over the points
// (-j threads, dynamic chunks of 1024 points), into N x K uint32 indices and N x K
// double squared distances allocated, untouched, before the clock starts, as
// knn_bootsurf does ("seconds_search"). Query order (--method): "tree" (default)
// walks the points in the tree's leaf order (its public index permutation vAcc),
// so consecutive queries touch the same nodes and points, as an all-kNN over a
// cloud should; "input" queries them in file order (random on the benchmark's
// sphere), as a naive loop does — slower from cache misses alone. The query point is in the cloud,
// so it is among its K (distance 0): the same K as bootsurf's. "seconds" = build + search. Not
// timed: reading the PLY, writing CHECK.f64.
//
// CHECK.f64: per point the sum and the largest of its K squared distances, as
// n x 2 little-endian doubles (bench/peers/bs_driver.h's format).
#include <omp.h>

#include <cstdint>
#include <memory>
#include <nanoflann.hpp>
#include <vector>

#include "peer_util.hpp"
#include "ply_io.hpp"

struct Cloud {
  const double *xyz;
  size_t n;
  size_t kdtree_get_point_count() const {
    return n;
  }
  double kdtree_get_pt(const size_t i, const size_t d) const {
    return xyz[3 * i + d];
  }
  template <class BBox> bool kdtree_get_bbox(BBox &) const {
    return false;
  }
};

typedef nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud, 3,
                                            uint32_t>
    Tree;

int main(int argc, char **argv) {
  // --method input|tree: the order of the queries (see the header)
  peer::Options o = peer::parse(argc, argv, " [--method tree|input]", "tree");
  if (o.method != "tree" && o.method != "input") peer::usage(argv[0], " [--method tree|input]");
  const bool tree_order = o.method == "tree";
  std::vector<double> xyz;
  try {
    plyio::read_xyz(o.in, xyz);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "knn_nanoflann: %s\n", e.what());
    return 1;
  }
  const size_t n = xyz.size() / 3, k = (size_t)o.k;
  if (k > n) {
    std::fprintf(stderr, "knn_nanoflann: K = %zu > %zu points\n", k, n);
    return 2;
  }
  std::unique_ptr<uint32_t[]> idx(new uint32_t[n * k]);
  std::unique_ptr<double[]> dist2(new double[n * k]);
  Cloud cloud{xyz.data(), n};
  omp_set_num_threads(o.threads);

  const double c0 = peer::cpu_seconds();
  const double t0 = peer::now();
  Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const double t1 = peer::now();
  long short_rows = 0;
#pragma omp parallel for schedule(dynamic, 1024) reduction(+ : short_rows)
  for (long t = 0; t < (long)n; t++) {
    const size_t i = tree_order ? (size_t)tree.vAcc[(size_t)t] : (size_t)t;
    const size_t got = tree.knnSearch(&xyz[3 * i], k, &idx[i * k], &dist2[i * k]);
    short_rows += got != k;
  }
  const double t2 = peer::now();
  const double cpu = peer::cpu_seconds() - c0;

  FILE *f = std::fopen(o.out.c_str(), "wb");
  bool bad = !f;
  for (size_t i = 0; i < n && !bad; i++) {
    double row[2] = {0.0, 0.0};
    for (size_t j = 0; j < k; j++) {
      row[0] += dist2[i * k + j];
      if (dist2[i * k + j] > row[1]) row[1] = dist2[i * k + j];
    }
    bad = std::fwrite(row, sizeof row, 1, f) != 1;
  }
  if (f && std::fclose(f) != 0) bad = true;
  if (bad) {
    std::fprintf(stderr, "knn_nanoflann: %s: cannot write\n", o.out.c_str());
    return 1;
  }
  std::printf("{\"peer\":\"nanoflann\",\"version\":\"%d.%d.%d\",\"method\":\"knnSearch\",\"k\":%zu,"
              "\"threads\":%d,\"points\":%zu,\"seconds\":%.6f,\"seconds_build\":%.6f,"
              "\"seconds_search\":%.6f,\"cpu_seconds\":%.6f,\"leaf_size\":10,\"order\":\"%s\","
              "\"short_rows\":%ld,"
              "\"peak_rss_kb\":%ld,\"timed\":\"KDTreeSingleIndexAdaptor build + knnSearch per "
              "point (OpenMP)\"}\n",
              NANOFLANN_VERSION >> 8, (NANOFLANN_VERSION >> 4) & 0xf, NANOFLANN_VERSION & 0xf, k,
              o.threads, n, t2 - t0, t1 - t0, t2 - t1, cpu, o.method.c_str(), short_rows,
              peer::peak_rss_kb());
  return 0;
}
