// pcl_util.hpp — what the PCL peers share: the input read into a PCL cloud.
// Header-only; include after peer_util.hpp and ply_io.hpp.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "ply_io.hpp"

namespace peer {

// The positions of a PLY file (xyz, doubles) and the same as a PCL cloud
// (PCL's points are float); nullptr, with "PROG: message" on stderr, when the
// file cannot be read.
inline pcl::PointCloud<pcl::PointXYZ>::Ptr read_pcl_cloud(const std::string &path, const char *prog,
                                                          std::vector<double> &xyz) {
  try {
    plyio::read_xyz(path, xyz);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "%s: %s\n", prog, e.what());
    return nullptr;
  }
  const size_t n = xyz.size() / 3;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(n);
  for (size_t i = 0; i < n; i++) {
    (*cloud)[i].x = (float)xyz[3 * i];
    (*cloud)[i].y = (float)xyz[3 * i + 1];
    (*cloud)[i].z = (float)xyz[3 * i + 2];
  }
  return cloud;
}

} // namespace peer
