"""An outside detector with DBSCAN's ties, for the relations' soundness tests (not a test
module).

A lowest-point ground per 0.5 m cell (anchored at the sensor, so quarter turns and the
mirror map it onto itself) and scikit-learn's DBSCAN over the points above it, in the
order the sweep gives them, with a PCA box and size rules per cluster: the shape of many
teams' first clustering stack. DBSCAN's clusters are fixed by its core points, but a
border point within reach of two touching clusters goes to whichever the KD-tree's
traversal reaches first, so turning, mirroring or reordering the sweep moves a few border
points between neighbours: boxes move by centimetres, which is jitter, not a fault.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from sklearn.cluster import DBSCAN

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


def _box(points: NDArray[np.float64]) -> Box:
    xy = points[:, :2]
    centre = xy.mean(axis=0)
    axis = np.linalg.eigh(np.cov((xy - centre).T))[1][:, -1] if len(xy) > 2 else (1.0, 0.0)
    yaw = float(np.arctan2(axis[1], axis[0]))
    turn = np.array([[np.cos(yaw), np.sin(yaw)], [-np.sin(yaw), np.cos(yaw)]])
    local = (xy - centre) @ turn.T
    low, high = local.min(axis=0), local.max(axis=0)
    middle = centre + ((low + high) / 2) @ turn
    length, width = (max(float(v), 0.1) for v in high - low)
    bottom, top = float(points[:, 2].min()), float(points[:, 2].max())
    height = max(top - bottom, 0.1)
    if 2.5 < length < 6 and 1.2 < width < 2.5:
        label = "car"
    elif length < 1.2 and width < 1.2 and 1.0 < height < 2.1:
        label = "pedestrian"
    else:
        label = "unknown"
    center = (float(middle[0]), float(middle[1]), (bottom + top) / 2)
    return Box(center, (length, width, height), yaw, label, points=len(points))
