"""An outside detector with DBSCAN's ties, for the relations' soundness tests (not a test
module).

A lowest-point ground per 0.5 m cell (anchored at the sensor, so quarter turns and the
mirror map it onto itself) and scikit-learn's DBSCAN over the points above it, in the
order the sweep gives them, with the scikit-learn example's PCA box and size rules per
cluster: the shape of many teams' first clustering stack. DBSCAN's clusters are fixed by
its core points, but a border point within reach of two touching clusters goes to
whichever the KD-tree's traversal reaches first, so turning, mirroring or reordering the
sweep moves a few border points between neighbours: boxes move by centimetres, which is
jitter, not a fault.
"""

from __future__ import annotations

import numpy as np
from sklearn.cluster import DBSCAN

from examples.test_sklearn_detector import _box  # the example's PCA box and size rules
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box


class TiesDetector:
    """Cell-minimum ground + DBSCAN (eps 0.5 m, 5 samples) + PCA boxes, whole sweep."""

    def __init__(self, *, cell: float = 0.5, eps: float = 0.5, min_samples: int = 5) -> None:
        self.cell, self.eps, self.min_samples = cell, eps, min_samples

    def __repr__(self) -> str:
        return "TiesDetector()"

    def __call__(self, frame: Frame) -> list[Box]:
        xyz = np.asarray(frame.cloud.points[:, :3], dtype=np.float64)
        xyz = xyz[np.hypot(xyz[:, 0], xyz[:, 1]) < 60.0]
        cells = np.floor(xyz[:, :2] / self.cell).astype(np.int64)
        _, inverse = np.unique(cells, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        lowest = np.full(inverse.max() + 1, np.inf)
        np.minimum.at(lowest, inverse, xyz[:, 2])
        above = xyz[(xyz[:, 2] - lowest[inverse] > 0.2) & (xyz[:, 2] < 1.5)]
        if len(above) < self.min_samples:
            return []
        labels = DBSCAN(eps=self.eps, min_samples=self.min_samples).fit_predict(above[:, :2])
        return [_box(above[labels == k]) for k in range(labels.max() + 1)]
