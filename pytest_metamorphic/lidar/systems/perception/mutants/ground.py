"""Faulty variants of the reference pipeline: the ROI lookup and the ground estimate.

See :mod:`pytest_metamorphic.lidar.systems.perception.mutants` for the list.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.lidar.systems.perception.ground import ground_heights
from pytest_metamorphic.lidar.systems.perception.mutants.inputs import _voxel_keys
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    ReferencePerception,
)

__all__ = [
    "FullCloudGround",
    "FullCloudHeightCut",
    "GlobalGroundPlane",
    "LevelGround",
    "RoiOffByOne",
    "SlopeCappedGround",
]


class FullCloudGround(ReferencePerception):
    """Ground heights estimated from the whole sweep, then applied to the ROI points.

    Apollo's default ``use_full_cloud: true`` built the segmentation features from all
    points, not only those in the ROI, so points far outside the ROI changed obstacles
    inside it (Zhou & Sun's MR1 violations; Apollo issue #3341). Here the ground grid
    sees points outside the ROI: a low point just outside lowers the ground under
    objects near the ROI's edge.
    """

    name = "full_cloud_ground"

    def ground_heights(
        self, points: NDArray[np.float32], sweep: NDArray[np.float32], roi: object = None
    ) -> NDArray[np.float32]:
        both = np.concatenate([points, sweep])
        return ground_heights(both, self.params.ground)[: len(points)]


class FullCloudHeightCut(ReferencePerception):
    """Overhanging points cut at the sweep's 99th z percentile instead of above the ground.

    A "robust" global threshold computed over the whole cloud: any point anywhere,
    inside the ROI or not, moves it.
    """

    name = "full_cloud_height_cut"

    def obstacle_mask(
        self,
        points: NDArray[np.float32],
        ground_z: NDArray[np.float32],
        sweep: NDArray[np.float32],
    ) -> NDArray[np.bool_]:
        cut = np.percentile(sweep[:, 2], 99.0)
        above = points[:, 2] - ground_z
        return (above >= self.params.ground.tolerance) & (points[:, 2] <= cut)


class GlobalGroundPlane(ReferencePerception):
    """One ground plane z = ax + by + c, least squares over the lowest point per 2 m cell.

    Fitted on all points of the sweep rather than locally in the ROI.
    """

    name = "global_ground_plane"

    def ground_heights(
        self, points: NDArray[np.float32], sweep: NDArray[np.float32], roi: object = None
    ) -> NDArray[np.float32]:
        _, inverse = np.unique(_voxel_keys(sweep[:, :2], 2.0), return_inverse=True)
        lowest = np.full(inverse.max() + 1, np.inf)
        np.minimum.at(lowest, inverse, sweep[:, 2])
        pick = sweep[:, 2] == lowest[inverse]
        x, y, z = (sweep[pick, i].astype(np.float64) for i in range(3))
        design = np.column_stack([x, y, np.ones_like(x)])
        (a, b, c), *_ = np.linalg.lstsq(design, z, rcond=None)
        return (a * points[:, 0] + b * points[:, 1] + c).astype(np.float32)


class LevelGround(ReferencePerception):
    """The ground is where a level sensor at its calibrated height puts it: the plane
    ``z = -sensor_height`` of the sensor frame (1.73 m, KITTI's mount), not estimated.

    Ground filters that take the sensor's height as a parameter and the sensor as level
    (Autoware's ``ray_ground_filter``, whose ``sensor_height`` and slopes are "essential
    parameters to the algorithm", autowarefoundation/autoware issue #825; a crop box in
    the sensor frame) are right on a flat road seen by a level sensor, which is what the
    recordings and rendered streets hold. When the car's body pitches (braking, a speed
    bump: Autoware's ``scan_ground_filter`` left ghost points in front of a car passing
    a speed bump, autoware_universe issue #3673), the road ahead rises out of the plane
    and joins the objects on it, or drops below it and takes their lower parts along.
    """

    name = "level_ground"
    sensor_height = 1.73

    def ground_heights(
        self, points: NDArray[np.float32], sweep: NDArray[np.float32], roi: object = None
    ) -> NDArray[np.float32]:
        return np.full(len(points), -self.sensor_height, dtype=np.float32)


class SlopeCappedGround(ReferencePerception):
    """Ground may rise from the sensor's own road by at most ``max_slope`` (3 %) of the
    distance: higher returns are obstacles, whatever the local ground says.

    A global slope gate keeps walls and embankments out of the ground; tuned on level
    roads it also cuts an uphill road. Autoware's ``scan_ground_filter`` clamps the ground
    gradient it fits to ``global_slope_max_ratio`` (autoware_universe pull request
    #9297) and for a while judged local slopes against that global limit (pull request
    #10666, "global_slope_max_angle_deg has been implemented in threshold of local
    slope"). On a level road, and downhill, nothing changes; where the road ahead climbs
    8 %, it rises through the gate and joins the cars on it.
    """

    name = "slope_capped_ground"
    max_slope = 0.03
    sensor_height = 1.73

    def ground_heights(
        self, points: NDArray[np.float32], sweep: NDArray[np.float32], roi: object = None
    ) -> NDArray[np.float32]:
        local = super().ground_heights(points, sweep, roi)
        reach = np.hypot(points[:, 0], points[:, 1])
        gate = -self.sensor_height + self.max_slope * reach
        return np.minimum(local, gate.astype(np.float32))


class RoiOffByOne(ReferencePerception):
    """The ROI bitmap is looked up one cell off in x (``ix + 1``): an indexing slip."""

    name = "roi_off_by_one"

    def roi_mask(self, points: NDArray[np.float32], roi: Any) -> NDArray[np.bool_]:
        if roi is None:
            return np.ones(len(points), dtype=bool)
        shifted = points[:, :2].astype(np.float64)
        shifted[:, 0] += float(getattr(roi, "cell_size", 0.25))
        return np.asarray(roi.contains(shifted, method=self.params.roi_method), dtype=np.bool_)
