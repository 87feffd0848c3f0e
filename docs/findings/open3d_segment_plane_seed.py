"""Open3D's segment_plane gives different planes for one sweep after the same global seed.

Needs only open3d and numpy, and a real sweep: the Velodyne VLP-16 recording of TIER IV's
nebula driver tests (``nebula_tests/data/velodyne/vlp16/.../1673400472138016708.pcd``,
Apache-2.0); pass its path. Exits with an AssertionError while the defect is present
(seen with open3d 0.20.0, numpy 2.4.6, 2 CPU cores); silent once every run agrees. Open3D
#5647 reported it for 0.16; #6308 and #6580 fixed it (merged); #7270 (2025) saw it again.

    python open3d_segment_plane_seed.py path/to/1673400472138016708.pcd
"""

import sys

import numpy as np
import open3d as o3d

cloud = o3d.io.read_point_cloud(sys.argv[1])
planes = {}
for run in range(20):
    o3d.utility.random.seed(0)
    model, inliers = cloud.segment_plane(distance_threshold=0.2, ransac_n=3, num_iterations=200)
    planes.setdefault((len(inliers), *np.round(model, 4).tolist()), []).append(run)
for plane, runs in sorted(planes.items()):
    print(f"{plane[0]} inliers, plane {plane[1:]}: runs {runs}")
assert len(planes) == 1, "the same seed, the same sweep: the plane should be the same"
