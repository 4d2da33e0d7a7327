// smooth_cgal — CGAL's point-set smoothing, for comparison with `bootsurf smooth`
// (bench/smooth_compare.sh):
//   --method jet        CGAL::jet_smooth_point_set: every point projected onto the
//                       jet (degree -d, 2 as CGAL's default; Monge degree min(2, d))
//                       fitted to its K neighbours; one pass.
//   --method bilateral  CGAL::bilateral_smooth_point_set (Huang et al. 2013, EAR
//                       section 4): --iterations passes (3, as CGAL's example), each
//                       projecting every point with spatial and normal weights
//                       (--sharpness degrees, default 25 as CGAL's example; CGAL's own
//                       default is 30). Moves the normals too; they are written out.
//
// usage: smooth_cgal INPUT.ply -o OUTPUT.ply [--method jet|bilateral] [-k 50] [-d 2] [-j 2]
//            [--sharpness 25] [--iterations 3] [--normals jet|input] [--orient mst|none]
//
// Normals for bilateral (it needs oriented normals: its normal weight is
// exp(-(1 - n_i.n_j)^2 / (1 - cos sharpness)^2), so a neighbour whose normal
// points the other way gets weight ~0):
//   --normals jet (default)  CGAL::jet_estimate_normals (degree 2, same K), then
//                            --orient mst (default) CGAL::mst_orient_normals (same
//                            K; sequential in CGAL), or none (jet signs as they come).
//   --normals input          the input's nx ny nz. NOT the default: the exact normals
//                            of the truth would be an oracle (`bootsurf noise` keeps
//                            them only as true_nx/ny/nz, so its outputs have no nx ny nz).
//
// Timed (monotonic clock, "seconds"): every CGAL call — for jet the one
// jet_smooth_point_set call (k-d tree build + per-point search and fit); for
// bilateral the normal estimation, the orientation and all the iterations
// (each builds its k-d tree and guesses its radius, 0.95 x the largest
// K-neighbour distance, sequentially). Their parts are reported separately
// (normals_seconds, orient_seconds, smooth_seconds). Not timed: reading the PLY,
// building the point vector, restoring the input order, writing.
//
// Neighbourhood: CGAL's `k` does NOT count the point itself (Neighbor_query
// searches k + 1, the query point first), so K here (bootsurf's K, point
// included) is passed to CGAL as K - 1, as in normals_cgal.cpp.
//
// Order: jet and bilateral keep the points in place; mst_orient_normals
// partitions the range (oriented points first), so every point carries its input
// index and the output is written in input order. No point is dropped.
//
// Threads: Parallel_if_available_tag = Parallel_tag with TBB (build.sh defines
// CGAL_LINKED_WITH_TBB), capped with tbb::global_control at -j.
#include <CGAL/Simple_cartesian.h>
#include <CGAL/bilateral_smooth_point_set.h>
#include <CGAL/jet_estimate_normals.h>
#include <CGAL/jet_smooth_point_set.h>
#include <CGAL/mst_orient_normals.h>
#include <CGAL/property_map.h>
#include <CGAL/version.h>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#endif

#include <cmath>
#include <tuple>
#include <vector>

#include "peer_util.hpp"
#include "ply_io.hpp"

typedef CGAL::Simple_cartesian<double> Kernel;
typedef Kernel::Point_3 Point;
typedef Kernel::Vector_3 Vector;
typedef std::tuple<Point, Vector, std::size_t> PNI; // point, normal, input index
typedef CGAL::Nth_of_tuple_property_map<0, PNI> PointMap;
typedef CGAL::Nth_of_tuple_property_map<1, PNI> NormalMap;

static const char *EXTRA =
    " [--method jet|bilateral] [-d DEGREE] [--sharpness DEG] [--iterations N]"
    " [--normals jet|input] [--orient mst|none]\n  default K here: 50";

int main(int argc, char **argv) {
  // our own options first; the rest goes to the shared parser
  double sharpness = 25;
  int iterations = 3;
  std::string normals_src = "jet", orient = "mst";
  bool k_given = false;
  std::vector<char *> rest{argv[0]};
  for (int i = 1; i < argc; i++) {
    const std::string a = argv[i];
    const bool has = i + 1 < argc;
    if (a == "--sharpness" && has)
      sharpness = std::atof(argv[++i]);
    else if (a == "--iterations" && has)
      iterations = std::atoi(argv[++i]);
    else if (a == "--normals" && has)
      normals_src = argv[++i];
    else if (a == "--orient" && has)
      orient = argv[++i];
    else {
      if (a == "-k") k_given = true;
      rest.push_back(argv[i]);
    }
  }
  peer::Options o = peer::parse((int)rest.size(), rest.data(), EXTRA, "jet");
  if (!k_given) o.k = 50;
  if ((o.method != "jet" && o.method != "bilateral") || !(sharpness > 0 && sharpness < 90) ||
      iterations < 1 || (normals_src != "jet" && normals_src != "input") ||
      (orient != "mst" && orient != "none"))
    peer::usage(argv[0], EXTRA);
  const unsigned need = (unsigned)((o.degree + 1) * (o.degree + 2) / 2);
  if (o.degree < 1 || (unsigned)o.k < need) {
    std::fprintf(stderr, "smooth_cgal: K = %d too small for degree %d\n", o.k, o.degree);
    return 2;
  }

  std::vector<double> xyz, in_nrm;
  try {
    plyio::read_xyz(o.in, xyz);
    if (o.method == "bilateral" && normals_src == "input" &&
        !plyio::read_columns(o.in, {"nx", "ny", "nz"}, in_nrm)) {
      std::fprintf(stderr, "smooth_cgal: %s has no nx ny nz (--normals input)\n", o.in.c_str());
      return 1;
    }
  } catch (const std::exception &e) {
    std::fprintf(stderr, "smooth_cgal: %s\n", e.what());
    return 1;
  }
  const size_t n = xyz.size() / 3;
  std::vector<PNI> pts(n);
  for (size_t i = 0; i < n; i++) {
    const Vector nv = in_nrm.empty() ? Vector(0, 0, 0)
                                     : Vector(in_nrm[3 * i], in_nrm[3 * i + 1], in_nrm[3 * i + 2]);
    pts[i] = PNI(Point(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]), nv, i);
  }

#ifdef CGAL_LINKED_WITH_TBB
  const bool tbb = true;
  const int threads = o.threads;
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, (size_t)o.threads);
#else
  const bool tbb = false;
  const int threads = 1;
#endif
  const unsigned cgal_k = (unsigned)(o.k - 1); // CGAL adds the point itself
  const unsigned monge = o.degree < 2 ? (unsigned)o.degree : 2u;
  auto np = CGAL::parameters::point_map(PointMap()).normal_map(NormalMap());

  double t_normals = 0, t_orient = 0, t_smooth = 0, move_error = 0;
  size_t unoriented = 0;
  const double c0 = peer::cpu_seconds();
  const double t0 = peer::now();
  if (o.method == "jet") {
    CGAL::jet_smooth_point_set<CGAL::Parallel_if_available_tag>(
        pts, cgal_k,
        CGAL::parameters::point_map(PointMap())
            .degree_fitting((unsigned)o.degree)
            .degree_monge(monge));
    t_smooth = peer::now() - t0;
  } else {
    if (normals_src == "jet") {
      CGAL::jet_estimate_normals<CGAL::Parallel_if_available_tag>(pts, cgal_k,
                                                                  np.degree_fitting(2));
      t_normals = peer::now() - t0;
      if (orient == "mst") {
        const double t1 = peer::now();
        auto first_unoriented = CGAL::mst_orient_normals(pts, cgal_k, np);
        unoriented = (size_t)std::distance(first_unoriented, pts.end());
        t_orient = peer::now() - t1;
      }
    }
    const double t2 = peer::now();
    for (int it = 0; it < iterations; it++)
      move_error = CGAL::bilateral_smooth_point_set<CGAL::Parallel_if_available_tag>(
          pts, cgal_k, np.sharpness_angle(sharpness));
    t_smooth = peer::now() - t2;
  }
  const double secs = peer::now() - t0;
  const double cpu = peer::cpu_seconds() - c0;

  // back to input order; move statistics in model units
  std::vector<double> out(3 * n), nrm;
  if (o.method == "bilateral") nrm.resize(3 * n);
  double moved_sum = 0, moved_max = 0;
  for (const PNI &p : pts) {
    const size_t i = std::get<2>(p);
    const Point &q = std::get<0>(p);
    out[3 * i] = q.x();
    out[3 * i + 1] = q.y();
    out[3 * i + 2] = q.z();
    const double d = std::sqrt((q.x() - xyz[3 * i]) * (q.x() - xyz[3 * i]) +
                               (q.y() - xyz[3 * i + 1]) * (q.y() - xyz[3 * i + 1]) +
                               (q.z() - xyz[3 * i + 2]) * (q.z() - xyz[3 * i + 2]));
    moved_sum += d;
    if (d > moved_max) moved_max = d;
    if (!nrm.empty()) {
      const Vector &v = std::get<1>(p);
      nrm[3 * i] = v.x();
      nrm[3 * i + 1] = v.y();
      nrm[3 * i + 2] = v.z();
    }
  }
  try {
    plyio::write_points(o.out, out, nrm, {}, "smooth_cgal " + o.method);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "smooth_cgal: %s\n", e.what());
    return 1;
  }
  std::printf(
      "{\"peer\":\"cgal\",\"version\":\"%s\",\"method\":\"%s\",\"degree\":%d,\"k\":%d,"
      "\"cgal_k\":%u,\"threads\":%d,\"tbb\":%s,\"points\":%zu,\"output_points\":%zu,\"dropped\":0,"
      "\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"peak_rss_kb\":%ld,"
      "\"normals_seconds\":%.6f,\"orient_seconds\":%.6f,\"smooth_seconds\":%.6f,"
      "\"moved_mean\":%.9g,\"moved_max\":%.9g",
      CGAL_VERSION_STR, o.method.c_str(), o.method == "jet" ? o.degree : 2, o.k, cgal_k, threads,
      tbb ? "true" : "false", n, n, secs, cpu, peer::peak_rss_kb(), t_normals, t_orient, t_smooth,
      n ? moved_sum / (double)n : 0.0, moved_max);
  if (o.method == "bilateral")
    std::printf(",\"sharpness\":%g,\"iterations\":%d,\"normals\":\"%s\",\"orient\":\"%s\","
                "\"unoriented\":%zu,\"last_move_error\":%.9g,"
                "\"timed\":\"%sbilateral_smooth_point_set x %d (each: kd-tree, radius guess)\"}\n",
                sharpness, iterations, normals_src.c_str(),
                normals_src == "jet" ? orient.c_str() : "input", unoriented, move_error,
                normals_src == "jet"
                    ? (orient == "mst" ? "jet_estimate_normals + mst_orient_normals + "
                                       : "jet_estimate_normals + ")
                    : "",
                iterations);
  else
    std::printf(",\"timed\":\"jet_smooth_point_set incl. kd-tree build\"}\n");
  return 0;
}
