// normals_cgal — CGAL's pca_estimate_normals and jet_estimate_normals, for
// comparison with `bootsurf normals --fit pca -B 0` and `--fit poly -d 2 -B 0`.
//
// usage: normals_cgal INPUT.ply -o OUTPUT.ply [--method pca|jet] [-k 30] [-d 2] [-j 2]
//
// Timed (monotonic clock): the one call to CGAL::pca_estimate_normals or
// CGAL::jet_estimate_normals, which builds CGAL's k-d tree (sequentially,
// Neighbor_query's constructor) and then, per point, searches the neighbours
// and fits. Not timed: reading the PLY, building the point vector, writing.
//
// Neighbourhood: CGAL's `k` does NOT count the point itself — Neighbor_query
// searches k + 1 neighbours, the query point first (Point_set_processing_3/
// internal/Neighbor_query.h). To use the same K points as bootsurf's K (point
// included) this program passes k = K - 1 to CGAL; the JSON reports both.
//
// Threads: CGAL::Parallel_if_available_tag is Parallel_tag when CGAL is built
// with CGAL_LINKED_WITH_TBB (build.sh defines it and links libtbb from Debian's
// libtbb-dev); the thread count is capped with tbb::global_control. Without TBB
// the loop is sequential and the JSON says "tbb":false, "threads":1.
//
// Kernel: Simple_cartesian<double>. Jet fitting (Monge_via_jet_fitting) and the
// PCA's eigen solve use Eigen (CGAL_EIGEN3_ENABLED).
#include <CGAL/Simple_cartesian.h>
#include <CGAL/jet_estimate_normals.h>
#include <CGAL/pca_estimate_normals.h>
#include <CGAL/property_map.h>
#include <CGAL/version.h>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#include <memory>
#endif

#include <utility>
#include <vector>

#include "peer_util.hpp"
#include "ply_io.hpp"

typedef CGAL::Simple_cartesian<double> Kernel;
typedef Kernel::Point_3 Point;
typedef Kernel::Vector_3 Vector;
typedef std::pair<Point, Vector> PointVectorPair;

int main(int argc, char **argv) {
  peer::Options o = peer::parse(argc, argv, " [--method pca|jet] [-d DEGREE]", "pca");
  if (o.method != "pca" && o.method != "jet")
    peer::usage(argv[0], " [--method pca|jet] [-d DEGREE]");
  const unsigned need = (unsigned)((o.degree + 1) * (o.degree + 2) / 2);
  if (o.method == "jet" && (o.degree < 1 || (unsigned)o.k < need)) {
    std::fprintf(stderr, "normals_cgal: K = %d too small for degree %d\n", o.k, o.degree);
    return 2;
  }
  std::vector<double> xyz;
  try {
    plyio::read_xyz(o.in, xyz);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "normals_cgal: %s\n", e.what());
    return 1;
  }
  const size_t n = xyz.size() / 3;
  std::vector<PointVectorPair> pts(n);
  for (size_t i = 0; i < n; i++)
    pts[i] = PointVectorPair(Point(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]), Vector(0, 0, 0));

#ifdef CGAL_LINKED_WITH_TBB
  const bool tbb = true;
  const int threads = o.threads;
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, (size_t)o.threads);
#else
  const bool tbb = false;
  const int threads = 1;
#endif
  const unsigned cgal_k = (unsigned)(o.k - 1); // CGAL adds the point itself
  auto np = CGAL::parameters::point_map(CGAL::First_of_pair_property_map<PointVectorPair>())
                .normal_map(CGAL::Second_of_pair_property_map<PointVectorPair>());

  const double c0 = peer::cpu_seconds();
  const double t0 = peer::now();
  if (o.method == "pca")
    CGAL::pca_estimate_normals<CGAL::Parallel_if_available_tag>(pts, cgal_k, np);
  else
    CGAL::jet_estimate_normals<CGAL::Parallel_if_available_tag>(
        pts, cgal_k, np.degree_fitting((unsigned)o.degree));
  const double secs = peer::now() - t0;
  const double cpu = peer::cpu_seconds() - c0;

  std::vector<double> nrm(3 * n);
  for (size_t i = 0; i < n; i++) {
    const Vector &v = pts[i].second;
    nrm[3 * i] = v.x();
    nrm[3 * i + 1] = v.y();
    nrm[3 * i + 2] = v.z();
  }
  try {
    plyio::write_xyz_normals(o.out, xyz, nrm, "normals_cgal " + o.method);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "normals_cgal: %s\n", e.what());
    return 1;
  }
  std::printf("{\"peer\":\"cgal\",\"version\":\"%s\",\"method\":\"%s\",\"degree\":%d,\"k\":%d,"
              "\"cgal_k\":%u,\"threads\":%d,\"tbb\":%s,\"points\":%zu,\"seconds\":%.6f,\"cpu_"
              "seconds\":%.6f,"
              "\"peak_rss_kb\":%ld,\"timed\":\"%s_estimate_normals incl. kd-tree build\"}\n",
              CGAL_VERSION_STR, o.method.c_str(), o.method == "jet" ? o.degree : 1, o.k, cgal_k,
              threads, tbb ? "true" : "false", n, secs, cpu, peer::peak_rss_kb(), o.method.c_str());
  return 0;
}
