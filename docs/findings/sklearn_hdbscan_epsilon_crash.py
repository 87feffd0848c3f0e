"""scikit-learn's HDBSCAN(cluster_selection_epsilon=0.3) crashes on 10 returns of a KITTI
sweep (scikit-learn issue #33219, tied distances).

Needs only scikit-learn and numpy, and the KITTI sweep ``training/velodyne/000001.bin``
(KITTI's object benchmark; OpenPCDet ships it as test data): pass its path. Exits with the
TypeError while the defect is present (seen with scikit-learn 1.9.1, numpy 2.4.6).

    python sklearn_hdbscan_epsilon_crash.py path/to/000001.bin
"""

import sys

import numpy as np
from sklearn.cluster import HDBSCAN

# A 1-minimal subset of the sweep's returns (rows of the .bin file), found by reducing
# the 120,268 returns while the crash persisted: removing any one of them avoids it.
ROWS = [2918, 2919, 2920, 2921, 2922, 2929, 2931, 2932, 2933, 2934]

sweep = np.fromfile(sys.argv[1], dtype=np.float32).reshape(-1, 4)
points = sweep[ROWS, :3].astype(np.float64)
print(np.round(points, 3))
HDBSCAN(cluster_selection_epsilon=0.3, copy=True).fit_predict(points)
print("no crash: the defect is fixed in this scikit-learn")
