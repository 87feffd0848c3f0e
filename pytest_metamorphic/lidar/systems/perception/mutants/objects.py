"""Faulty variants of the reference pipeline: clustering, object filters by size and
context, boxes and the output list.

See :mod:`pytest_metamorphic.lidar.systems.perception.mutants` for the list.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.clustering import (
    ClusterParams,
    Clusters,
    cluster_points,
)
from pytest_metamorphic.lidar.systems.perception.minbox import MinBox
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    ReferencePerception,
)

__all__ = [
    "AxisAlignedBoxes",
    "CountScaledRadius",
    "DenseMinPoints",
    "GridAnchoredAtSweep",
    "LongClusterFilter",
    "NearestObjectList",
    "RawPointCount",
    "RoadUserContext",
    "SweepSeamFilter",
    "TurnedOutputFrame",
]


class CountScaledRadius(ReferencePerception):
    """The clustering cell grows with the square root of the sweep's point count.

    Meant to keep sparse sweeps connected; a point outside the ROI changes it.
    """

    name = "count_scaled_radius"

    def segment(self, points: NDArray[np.float32], sweep: NDArray[np.float32]) -> Clusters:
        scale = math.sqrt(max(len(sweep), 1) / 120_000)
        params = ClusterParams(cell_size=self.params.cluster.cell_size * scale)
        return cluster_points(points, params)


class GridAnchoredAtSweep(ReferencePerception):
    """The clustering grid starts at the sweep's minimum corner, not at the sensor.

    ``floor((xy - xy.min()) / cell)`` over the whole cloud: any point that extends the
    bounding box shifts every cell border.
    """

    name = "grid_anchored_at_sweep"

    def segment(self, points: NDArray[np.float32], sweep: NDArray[np.float32]) -> Clusters:
        if len(points) == 0:
            return cluster_points(points, self.params.cluster)
        corner = sweep[:, :2].min(axis=0)
        cell = self.params.cluster.cell_size
        # Shift so that the sensor-anchored grid of cluster_points starts at the corner.
        offset = corner - np.floor(corner / cell) * cell
        return cluster_points(points[:, :2] - offset, self.params.cluster)


class AxisAlignedBoxes(ReferencePerception):
    """Axis-aligned bounding boxes instead of MinBox: headings are always 0 or 90 degrees."""

    name = "axis_aligned_boxes"

    def fit_boxes(self, points: NDArray[np.float32], labels: NDArray[np.intp]) -> list[MinBox]:
        count = int(labels.max()) + 1
        low = np.full((count, 3), np.inf, dtype=np.float32)
        high = np.full((count, 3), -np.inf, dtype=np.float32)
        np.minimum.at(low, labels, points[:, :3])
        np.maximum.at(high, labels, points[:, :3])
        sizes = np.bincount(labels, minlength=count)
        boxes = []
        for lo, hi, size in zip(low.tolist(), high.tolist(), sizes.tolist(), strict=True):
            dx, dy = hi[0] - lo[0], hi[1] - lo[1]
            direction = (1.0, 0.0, 0.0) if dx >= dy else (0.0, 1.0, 0.0)
            boxes.append(
                MinBox(
                    center=((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]),
                    length=max(dx, dy),
                    width=min(dx, dy),
                    height=hi[2] - lo[2],
                    direction=direction,
                    polygon=np.array([[lo[0], lo[1], lo[2]]]),
                    points=size,
                )
            )
        return boxes


class RawPointCount(ReferencePerception):
    """Objects of fewer than 4 cells kept only with at least 6 points, counting repeats.

    Point-count thresholds (PCL's ``setMinClusterSize``) count a point the driver sent
    twice as two.
    """

    name = "raw_point_count"
    min_points = 6

    def keep_objects(self, clusters: Clusters, top: NDArray[np.float32]) -> NDArray[np.bool_]:
        counts = np.bincount(clusters.labels, minlength=clusters.count)
        small = clusters.cells < 4
        enough = np.where(small, counts >= self.min_points, True)
        return enough & (clusters.cells >= self.params.min_cells) & (top >= self.params.min_height)


class DenseMinPoints(ReferencePerception):
    """Objects kept only with at least 40 points.

    A minimum cluster size (PCL's ``setMinClusterSize``) tuned on dense 64-beam sweeps:
    a pedestrian at 20 m that loses one of its five or six rings to a dead laser drops
    below it, although its remaining points show it plainly.
    """

    name = "dense_min_points"
    min_points = 40

    def keep_objects(self, clusters: Clusters, top: NDArray[np.float32]) -> NDArray[np.bool_]:
        counts = np.bincount(clusters.labels, minlength=clusters.count)
        return super().keep_objects(clusters, top) & (counts >= self.min_points)


class TurnedOutputFrame(ReferencePerception):
    """Boxes reported in a frame turned ``degrees`` about the sensor.

    A yaw extrinsic (sensor to vehicle) calibrated wrong and applied to the detections:
    positions and headings turn together, consistently in every frame, so the boxes look
    plausible and every relation that commutes with rotations about the sensor (noise,
    removal, reordering, rotation itself) is blind to it. A reflection is not.
    """

    name = "turned_output_frame"
    degrees = 2.0

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        theta = math.radians(self.degrees)
        return [box.rotated(theta) for box in super().build_boxes(points, ground_z, clusters)]


class NearestObjectList(ReferencePerception):
    """Only the ``slots`` nearest obstacles are reported.

    ADAS sensors and perception ECUs send a fixed-length object list (a CAN message per
    slot); the software behind them drops what does not fit, nearest first. In a busy
    street a car that enters the view pushes a farther, unchanged obstacle off the list:
    no noise, reordering, rotation or removal shows it (nothing new appears), an inserted
    object does.
    """

    name = "nearest_object_list"
    slots = 20

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        boxes = super().build_boxes(points, ground_z, clusters)
        return sorted(boxes, key=lambda box: math.hypot(*box.center[:2]))[: self.slots]


class RoadUserContext(ReferencePerception):
    """Clusters of fewer than ``min_points`` distinct points are kept only when a car,
    pedestrian or cyclist (of at least ``min_points``) has its centre within ``radius``
    metres of theirs.

    A clutter filter: a few points on their own are taken for spray, leaves or litter,
    while next to a road user they are kept as part of it (a mirror, a bag, a wheel seen
    apart). Each small object's fate then hangs on another object up to 10 m away: when a
    parked car leaves, the fragments beside it (a post, a far pedestrian's few returns) are
    dropped although nothing about them changed. Faults and weather judge only obstacles
    of >= 30 points, reordering, repeats and rigid motions keep every neighbour, noise
    outside the ROI adds none: taking an object out of the sweep shows it.
    """

    name = "road_user_context"
    min_points = 20
    radius = 10.0

    def obstacle_mask(
        self,
        points: NDArray[np.float32],
        ground_z: NDArray[np.float32],
        sweep: NDArray[np.float32],
    ) -> NDArray[np.bool_]:
        # The filter counts distinct returns (a return the driver sent twice is one): keep
        # the first of each repeated obstacle point, which changes no cell and no hull.
        rows = np.flatnonzero(super().obstacle_mask(points, ground_z, sweep))
        _, first = np.unique(points[rows], axis=0, return_index=True)
        distinct = np.zeros(len(points), dtype=bool)
        distinct[rows[first]] = True
        return distinct

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        boxes = super().build_boxes(points, ground_z, clusters)
        anchors = np.array(
            [
                b.center[:2]
                for b in boxes
                if b.label != "unknown" and (b.points or 0) >= self.min_points
            ]
        ).reshape(-1, 2)

        def supported(box: Box) -> bool:
            distance = np.hypot(*(anchors - np.asarray(box.center[:2])).T)
            return bool((distance <= self.radius).any())

        return [box for box in boxes if (box.points or 0) >= self.min_points or supported(box)]


class SweepSeamFilter(ReferencePerception):
    """Obstacles whose bearings come within ``margin`` degrees of a gap of more than
    ``min_gap`` degrees between the ROI's returns are dropped.

    A driver assembles a sweep from packets and takes a gap in azimuth for the sweep's
    boundary; an object next to it is taken for one cut in two (its other half arrives
    with the next sweep) and dropped. A complete sweep has no such gap inside the ROI (the
    KITTI sweeps' largest is 0.15 degrees; the edges of an ROI narrower than the sweep
    are one, the same in every follow-up), so nothing changes until a packet is lost:
    then the object it cut into is dropped although half or more of it is still there.
    Dead lasers leave the other rings at every azimuth, and points outside the ROI do not
    count: only a lost packet shows it.
    """

    name = "sweep_seam_filter"
    min_gap = 0.5
    margin = 0.2

    def review_boxes(self, boxes: list[Box], in_roi: NDArray[np.float32]) -> list[Box]:
        edges = _gap_edges(in_roi, self.min_gap)
        if len(edges) == 0:
            return boxes
        return [box for box in boxes if not _bearing_near(box, edges, self.margin)]


def _gap_edges(points: NDArray[np.float32], min_gap: float) -> NDArray[np.float64]:
    """Bearings (degrees) of the returns on either side of each gap wider than
    ``min_gap`` degrees between neighbouring bearings, the wrap-around included."""
    if len(points) < 2:
        return np.empty(0)
    bearing = np.sort(np.degrees(np.arctan2(points[:, 1], points[:, 0]).astype(np.float64)))
    step = np.diff(np.concatenate([bearing, [bearing[0] + 360.0]]))
    wide = np.flatnonzero(step > min_gap)
    return np.concatenate([bearing[wide], bearing[(wide + 1) % len(bearing)]])


def _bearing_near(box: Box, edges: NDArray[np.float64], margin: float) -> bool:
    """Whether a bearing in ``edges`` lies within ``margin`` degrees of the box's
    footprint, as seen from the sensor."""
    centre = math.degrees(math.atan2(box.center[1], box.center[0]))
    corners = box.corners_bev()
    offsets = np.degrees(np.arctan2(corners[:, 1], corners[:, 0])) - centre
    offsets = (offsets + 180.0) % 360.0 - 180.0
    relative = (edges - centre + 180.0) % 360.0 - 180.0
    return bool(((relative >= offsets.min() - margin) & (relative <= offsets.max() + margin)).any())


class LongClusterFilter(ReferencePerception):
    """Obstacles longer than ``max_length`` metres dropped as walls, fences or kerbs.

    Clusters of building facades and fences are long; a size cap meant for them also
    silently drops the longest road users, as Autoware's clustering dropped clusters over
    its size cap ("losing every point in large connected components, e.g. long trailers":
    autoware_universe pull request #12738, autoware_core issue #1379). Every recorded car
    is shorter; a bus (12 m) or an articulated lorry (16.5 m) is not, and only an inserted
    one shows it.
    """

    name = "long_cluster_filter"
    max_length = 10.0

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        boxes = super().build_boxes(points, ground_z, clusters)
        return [box for box in boxes if box.size[0] <= self.max_length]
