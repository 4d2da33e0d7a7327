#!/usr/bin/env python3
"""Open3D interop: an open3d.geometry.PointCloud's points -> bootsurf.normals
(bootstrap normals with their confidence normal_var, thesis Eqs. 5.4-5.5)
-> the cloud's normals and colours (viridis by normal_var) back in Open3D.

Usage: /usr/bin/python3 examples/python/open3d_normals.py [INPUT.ply] [OUT.ply]
Without INPUT, a noisy cube from bootsurf.generate. Skipped (exit 0 with a
message) when Open3D is not installed (apt-get install python3-open3d)."""
import sys

import numpy as np

import bootsurf

try:
    import open3d as o3d
except ImportError:
    print("SKIP: open3d is not installed (apt-get install python3-open3d)")
    sys.exit(0)

if len(sys.argv) > 1:
    pcd = o3d.io.read_point_cloud(sys.argv[1])
    if not pcd.has_points():  # Open3D warns and returns an empty cloud
        sys.exit("%s: Open3D read no points from it" % sys.argv[1])
else:
    cube = bootsurf.generate("cube", points=20000)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
        bootsurf.noise(cube["points"], cube["normals"], level=0.5)))

points = np.asarray(pcd.points)              # (N, 3) float64, passed without a copy
fields, summary = bootsurf.normals(points, neighbors=30, bootstrap=20)
pcd.normals = o3d.utility.Vector3dVector(fields["normals"])
var = fields["normal_var"]
lo, hi = np.percentile(var, [1, 99])
t = np.clip((var - lo) / (hi - lo if hi > lo else 1), 0, 1)
try:
    from matplotlib import cm
    colors = cm.viridis(t)[:, :3]
except ImportError:                           # dark = confident, yellow = not
    colors = np.stack([t, t, 0.3 * (1 - t)], axis=1)
pcd.colors = o3d.utility.Vector3dVector(colors)
print("%d points, h = %.4g, mean normal_var %.4g rad^2" %
      (summary["points"], summary["h"], summary["means"]["normal_var"]))
if len(sys.argv) > 2:
    o3d.io.write_point_cloud(sys.argv[2], pcd)
    print("->", sys.argv[2])
