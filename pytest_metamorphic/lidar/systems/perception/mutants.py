"""Faulty variants of the reference pipeline, each modelled on a real failure mechanism.

Each mutant changes one stage of :class:`~.pipeline.ReferencePerception` and is
selectable by name: ``mutant("full_cloud_ground")``. They exist to measure how well
metamorphic relations find real faults (``bench/mutation_score.py``); a relation that
kills none of them is not worth running.

==========================  =================================================================
name                        fault
==========================  =================================================================
full_cloud_ground           ground estimated from every point, not only ROI points (Apollo's
                            ``use_full_cloud: true``, the root cause of Apollo issue #3341)
full_cloud_height_cut       height cut-off taken from a percentile of the whole sweep
random_point_budget         random subsample to a point budget before the ROI filter
truncating_buffer           fixed 120,000-point buffer: later points silently dropped
voxel_budget                voxel size adapted to the sweep's point count, before the ROI
global_ground_plane         one ground plane fitted to the lowest points of the whole sweep
roi_off_by_one              ROI bitmap looked up one cell off in x
count_scaled_radius         clustering cell scaled with the sweep's point count
order_dependent_voxels      voxel filter keeping the first point of each voxel
grid_anchored_at_sweep      clustering grid anchored at the sweep's bounding box
axis_aligned_boxes          axis-aligned bounding boxes instead of MinBox
raw_point_count             small objects kept by raw point count (repeats count twice)
turned_output_frame         boxes reported in a frame turned 2 degrees about the sensor (a
                            wrong yaw extrinsic applied to the detections)
dense_min_points            objects need 40 points (a minimum cluster size tuned on a dense
                            64-beam sweep)
nearest_object_list         only the 20 nearest obstacles reported (a fixed-length object
                            list, as ADAS sensors send over CAN)
intensity_floor             returns weaker than intensity 0.05 dropped as speckle (a filter
                            tuned in clear weather)
short_range_gate            returns beyond 40 m dropped (a range gate carried over from a
                            shorter-range sensor)
repeated_range_filter       returns whose range repeats a neighbouring firing's dropped as
                            dual-return echoes (harmless at 2 mm range steps)
road_user_context           clusters of fewer than 20 points kept only within 10 m of a car,
                            pedestrian or cyclist (a clutter filter that keeps road users'
                            fragments)
blinded_sensor_monitor      nothing reported when returns within 2.5 m of the sensor come from
                            two thirds of the azimuth sectors (a blockage monitor)
sweep_seam_filter           obstacles next to a gap of > 0.5 degrees in the ROI's azimuths
                            dropped as cut by the sweep's boundary
==========================  =================================================================
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import intensity_scale
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.clustering import (
    ClusterParams,
    Clusters,
    cluster_points,
)
from pytest_metamorphic.lidar.systems.perception.ground import ground_heights
from pytest_metamorphic.lidar.systems.perception.minbox import MinBox
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    PerceptionParams,
    ReferencePerception,
)

__all__ = ["MUTANTS", "mutant"]


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


class RandomPointBudget(ReferencePerception):
    """A random subsample to at most ``budget`` points, taken before the ROI filter.

    Learned detectors take a fixed number of points; sampling the whole sweep (instead
    of the ROI) with a fixed seed makes every kept point depend on every other one.
    """

    name = "random_point_budget"
    budget = 100_000

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        if len(points) <= self.budget:
            return points
        chosen = np.random.default_rng(0).choice(len(points), self.budget, replace=False)
        return points[np.sort(chosen)]


class TruncatingBuffer(ReferencePerception):
    """Only the first 120,000 points are processed (a fixed-size sweep buffer)."""

    name = "truncating_buffer"
    capacity = 120_000

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        return points[: self.capacity]


class VoxelBudget(ReferencePerception):
    """Voxel downsampling whose voxel size grows with the sweep's size, before the ROI.

    Keeping memory constant by scaling the voxel edge with the point count: any point
    anywhere moves every voxel border. Each voxel is replaced by its centroid.
    """

    name = "voxel_budget"
    base_size = 0.08  # metres at 100,000 points

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        size = self.base_size * math.sqrt(max(len(points), 1) / 100_000)
        keys = _voxel_keys(points[:, :3], size)
        _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
        sums = np.zeros((len(counts), 4))
        np.add.at(sums, inverse, points)
        return (sums / counts[:, None]).astype(np.float32)


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


class RoiOffByOne(ReferencePerception):
    """The ROI bitmap is looked up one cell off in x (``ix + 1``): an indexing slip."""

    name = "roi_off_by_one"

    def roi_mask(self, points: NDArray[np.float32], roi: Any) -> NDArray[np.bool_]:
        if roi is None:
            return np.ones(len(points), dtype=bool)
        shifted = points[:, :2].astype(np.float64)
        shifted[:, 0] += float(getattr(roi, "cell_size", 0.25))
        return np.asarray(roi.contains(shifted, method=self.params.roi_method), dtype=np.bool_)


class CountScaledRadius(ReferencePerception):
    """The clustering cell grows with the square root of the sweep's point count.

    Meant to keep sparse sweeps connected; a point outside the ROI changes it.
    """

    name = "count_scaled_radius"

    def segment(self, points: NDArray[np.float32], sweep: NDArray[np.float32]) -> Clusters:
        scale = math.sqrt(max(len(sweep), 1) / 120_000)
        params = ClusterParams(cell_size=self.params.cluster.cell_size * scale)
        return cluster_points(points, params)


class OrderDependentVoxels(ReferencePerception):
    """A 0.1 m voxel filter that keeps the first point it meets in each voxel."""

    name = "order_dependent_voxels"
    size = 0.1

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        _, first = np.unique(_voxel_keys(points[:, :3], self.size), return_index=True)
        return points[np.sort(first)]


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


class IntensityFloor(ReferencePerception):
    """Returns with intensity below ``floor`` are dropped before anything else.

    A speckle filter tuned on clear-weather sweeps, where dark returns at this level are
    mostly noise. Fog and rain scale every return's intensity down with range: a car
    20 m away whose returns all still arrive drops below the floor and is lost. Geometric
    relations never change intensities, so only weather shows it.
    """

    name = "intensity_floor"
    floor = 0.05

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        return points[points[:, 3] >= self.floor * intensity_scale(points[:, 3])]


class RepeatedRangeFilter(ReferencePerception):
    """Returns whose range equals (within 0.1 mm) that of the next firing of the same laser
    are dropped, both of them, as the two echoes of one pulse in dual-return mode.

    At the HDL-64E's 2 mm resolution neighbouring firings seldom report the same range:
    the filter drops 1.5 % of a KITTI sweep's returns and changes none of the reference's
    obstacles on the six sweeps. A sensor or driver with coarser range steps reports runs
    of equal ranges on every flat surface facing it, and the filter eats them. Repeated
    points are merged first, so duplication, reordering and rigid motions leave it alone.
    """

    name = "repeated_range_filter"
    tolerance = 1e-4

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        points = np.unique(points, axis=0)
        xyz = points[:, :3].astype(np.float64)
        ranges = np.linalg.norm(xyz, axis=1)
        beam = np.round(np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))) / 0.2)
        order = np.lexsort((np.arctan2(xyz[:, 1], xyz[:, 0]), beam))
        same = (np.abs(np.diff(ranges[order])) < self.tolerance) & (np.diff(beam[order]) == 0)
        repeated = np.zeros(len(points), dtype=bool)
        repeated[order[1:][same]] = True
        repeated[order[:-1][same]] = True
        return points[~repeated]


class ShortRangeGate(ReferencePerception):
    """Returns farther than ``max_range`` metres (bird's eye) are dropped first.

    A range gate carried over from a 16-beam sensor's configuration. Nothing beyond it is
    ever reported, in the source or in any follow-up, so relations that compare the two
    never see it; an object inserted at a range nobody saw one at before does.
    """

    name = "short_range_gate"
    max_range = 40.0

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        return points[np.hypot(points[:, 0], points[:, 1]) <= self.max_range]


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


class BlindedSensorMonitor(ReferencePerception):
    """Nothing is reported when the sensor looks blinded: returns closer than ``near``
    metres in at least ``min_sectors`` of the 36 azimuth sectors of 10 degrees (a sector
    counts with ``min_returns`` distinct returns).

    A blockage monitor (mud, snow or a bag on the window give returns at the cover all
    round) whose output is withheld while it fires. Clear KITTI sweeps light at most 12
    sectors (a wall or a kerb close by); droplet echoes in fog of 200 m visibility or rain
    of 100 m light nearly all 36, while cars 20 m away are still seen plainly. Nothing but
    weather puts returns next to the sensor all round.
    """

    name = "blinded_sensor_monitor"
    near = 2.5
    min_returns = 3
    min_sectors = 24

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        close = np.unique(points[np.linalg.norm(points[:, :3], axis=1) < self.near], axis=0)
        sector = np.floor(np.degrees(np.arctan2(close[:, 1], close[:, 0])) / 10.0) % 36
        lit = np.bincount(sector.astype(np.intp), minlength=36) >= self.min_returns
        return points[:0] if lit.sum() >= self.min_sectors else points


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


def _voxel_keys(coordinates: NDArray[np.float32], size: float) -> NDArray[np.int64]:
    """(n,) int64: one key per voxel of edge ``size`` (cells packed into one integer)."""
    cells = np.floor(coordinates / np.float32(size)).astype(np.int64)
    cells -= cells.min(axis=0)
    key = np.zeros(len(cells), dtype=np.int64)
    for column in range(cells.shape[1]):
        key = key * (int(cells[:, column].max()) + 1) + cells[:, column]
    return key


MUTANTS: dict[str, type[ReferencePerception]] = {
    cls.name: cls
    for cls in (
        FullCloudGround,
        FullCloudHeightCut,
        RandomPointBudget,
        TruncatingBuffer,
        VoxelBudget,
        GlobalGroundPlane,
        RoiOffByOne,
        CountScaledRadius,
        OrderDependentVoxels,
        GridAnchoredAtSweep,
        AxisAlignedBoxes,
        RawPointCount,
        TurnedOutputFrame,
        DenseMinPoints,
        NearestObjectList,
        IntensityFloor,
        RepeatedRangeFilter,
        ShortRangeGate,
        RoadUserContext,
        BlindedSensorMonitor,
        SweepSeamFilter,
    )
}


def mutant(name: str, params: PerceptionParams | None = None) -> ReferencePerception:
    """The faulty pipeline called ``name`` (see the module docstring for the list)."""
    try:
        cls = MUTANTS[name]
    except (KeyError, TypeError):
        raise InvalidArgument(f"unknown mutant {name!r}; known: {sorted(MUTANTS)}") from None
    return cls(params)
