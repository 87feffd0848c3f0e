"""The reference LiDAR obstacle pipeline: ROI filter, ground removal, grid segmentation,
Apollo's MinBox, rule-based classes.

A system under test for learning the tool on, and for proving that relations find real
faults (the mutants in :mod:`.mutants` change one stage each). It follows the shape of
Apollo's LiDAR obstacle perception, which Zhou & Sun tested, without learned weights:

1. **HD-map ROI filter**: keep points whose 0.25 m bitmap cell is in the ROI
   (:meth:`ROI.contains <pytest_metamorphic.lidar.roi.ROI.contains>`, ``method="raster"``
   by default, like Apollo). Every later stage sees only ROI points.
2. **Ground removal** (:mod:`.ground`): drop points within ``ground.tolerance`` of the
   local ground, and points more than ``max_height`` above it (overhanging branches,
   signs), which would otherwise join objects underneath in the bird's-eye grid.
3. **Segmentation** (:mod:`.clustering`): 8-connected occupied cells of a 0.25 m grid.
   Objects with fewer than ``min_cells`` cells, or whose top is lower than
   ``min_height`` above the ground, are dropped.
4. **MinBox** (:mod:`.minbox`): Apollo's box builder on each object's points, judged
   from the sensor at the origin; the hull walk starts at the vertex nearest the sensor
   (``hull_start``) so that boxes turn with the scene. Box height spans the object's
   points.
5. **Classification** (:mod:`.classify`): car / cyclist / pedestrian / unknown from the
   box footprint, the points' vertical extent, and the height of the object's top and
   bottom above the ground.

The output is a list of :class:`~pytest_metamorphic.lidar.model.obstacles.Box`, sorted by
centre, so that equal inputs give equal lists. The pipeline is deterministic and depends
only on the *set* of points in the ROI: point order, repeated points and points outside
the ROI do not change it (the relations of :mod:`pytest_metamorphic.relations.lidar`
check exactly that). Grids are anchored at the sensor origin, so adding or removing
far-away points cannot shift a cell border, and a quarter turn of the scene about the
sensor maps every cell onto a cell: the boxes turn with it exactly (except next to the
ROI's edges, whose bitmap is rasterised afresh). Turns by other angles move cell borders
across objects, so boxes change by up to tens of centimetres and borderline objects can
split or change class.

Speed: about 10 ms per 120k-point KITTI sweep on one core with the camera-wedge ROI
(``bench/perception.py``); every stage is vectorised except MinBox's per-object hull walk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.classify import (
    CROWN_BAND,
    ClassifierParams,
    ObjectShape,
    classify,
)
from pytest_metamorphic.lidar.systems.perception.clustering import (
    ClusterParams,
    Clusters,
    cluster_points,
)
from pytest_metamorphic.lidar.systems.perception.ground import GroundParams, ground_heights
from pytest_metamorphic.lidar.systems.perception.minbox import HullStart, MinBox, min_boxes

__all__ = [
    "MIN_EXTENT",
    "PerceptionParams",
    "ReferencePerception",
    "Stages",
    "box_order",
    "sweep_and_roi",
]

# Apollo's SetDefaultValue widens degenerate extents to 1 mm; Box needs sizes > 0.
MIN_EXTENT = 1e-3


@dataclass(frozen=True)
class PerceptionParams:
    """Every parameter of :class:`ReferencePerception`, with documented defaults.

    Attributes
    ----------
    roi_method : {"raster", "exact"}
        How ROI membership is decided: Apollo's 0.25 m bitmap, or exact polygons.
    ground : GroundParams
        Ground estimation (1 m cells, 7 x 7 neighbourhood, 0.25 m tolerance).
    max_height : float
        Points more than this many metres above the local ground are dropped.
    cluster : ClusterParams
        Segmentation grid (0.25 m cells, 8-connected).
    min_cells : int
        Objects covering fewer occupied cells are noise.
    min_height : float
        Objects whose highest point is lower than this above the ground are dropped
        (kerbs, debris).
    sensor : (3,) tuple of float
        Sensor position in the cloud's frame; MinBox judges edges facing it.
    hull_start : {"nearest", "apollo"}
        Where MinBox's hull walk starts (see :func:`.minbox.min_boxes`): ``"nearest"``
        (default) makes boxes turn with the scene; ``"apollo"`` is PCL's order, whose
        tie-breaking depends on the scene's orientation.
    classifier : ClassifierParams
        Class rules.
    """

    roi_method: Literal["raster", "exact"] = "raster"
    ground: GroundParams = field(default_factory=GroundParams)
    max_height: float = 3.0
    cluster: ClusterParams = field(default_factory=ClusterParams)
    min_cells: int = 2
    min_height: float = 0.4
    sensor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    hull_start: HullStart = "nearest"
    classifier: ClassifierParams = field(default_factory=ClassifierParams)

    def __post_init__(self) -> None:
        if self.roi_method not in ("raster", "exact"):
            raise InvalidArgument(f"roi_method={self.roi_method!r} must be 'raster' or 'exact'")
        if not self.max_height > 0:
            raise InvalidArgument(f"max_height={self.max_height!r} must be > 0")
        if not isinstance(self.min_cells, int) or self.min_cells < 1:
            raise InvalidArgument(f"min_cells={self.min_cells!r} must be an int >= 1")
        if not math.isfinite(self.min_height):
            raise InvalidArgument(f"min_height={self.min_height!r} must be finite")
        sensor = tuple(float(v) for v in self.sensor)
        if len(sensor) != 3 or not all(math.isfinite(v) for v in sensor):
            raise InvalidArgument(f"sensor={self.sensor!r} must be 3 finite numbers")
        object.__setattr__(self, "sensor", sensor)
        if self.hull_start not in ("nearest", "apollo"):
            raise InvalidArgument(f"hull_start={self.hull_start!r} must be 'nearest' or 'apollo'")


@dataclass(frozen=True)
class Stages:
    """What each stage kept, for debugging and reports (see :meth:`ReferencePerception.run`).

    Attributes
    ----------
    in_roi : int
        Points the ROI filter kept.
    obstacle_points : int
        ROI points left after ground removal and the height cut.
    clusters : int
        Connected components before the size and height filters.
    boxes : list of Box
        The output.
    """

    in_roi: int
    obstacle_points: int
    clusters: int
    boxes: list[Box]


class ReferencePerception:
    """The reference obstacle detector: ``perception(cloud, roi) -> list[Box]``.

    Parameters
    ----------
    params : PerceptionParams, optional

    Notes
    -----
    Each stage is a method, so that a variant (see :mod:`.mutants`) can replace one.
    """

    name = "reference"

    def __init__(self, params: PerceptionParams | None = None) -> None:
        if params is not None and not isinstance(params, PerceptionParams):
            raise InvalidArgument(f"params={params!r} must be a PerceptionParams")
        self.params = params or PerceptionParams()

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __call__(self, cloud: Any, roi: Any = None) -> list[Box]:
        """Detect obstacles.

        Parameters
        ----------
        cloud : PointCloud, (n, 3) or (n, 4) array_like, or a frame with ``.cloud``
            The LiDAR sweep in the sensor frame. A frame's own ``.roi`` is used when
            ``roi`` is not given.
        roi : ROI or None
            Anything with ``contains(xy, method=...) -> (n,) bool``; None keeps every point.

        Returns
        -------
        list of Box
            Sorted by centre x, then y, z, size and yaw.
        """
        return self.run(cloud, roi).boxes

    def run(self, cloud: Any, roi: Any = None) -> Stages:
        """Like calling the pipeline, but also report what each stage kept."""
        points, roi = sweep_and_roi(cloud, roi)
        sweep = self.prepare(points)
        # np.compress: boolean row selection of an (n, 4) array is ~5x slower.
        in_roi = np.compress(self.roi_mask(sweep, roi), sweep, axis=0)
        ground_z = self.ground_heights(in_roi, sweep, roi)
        keep = self.obstacle_mask(in_roi, ground_z, sweep)
        obstacles, ground_z = np.compress(keep, in_roi, axis=0), ground_z[keep]
        clusters = self.segment(obstacles, sweep)
        boxes = self.review_boxes(self.build_boxes(obstacles, ground_z, clusters), in_roi)
        return Stages(len(in_roi), len(obstacles), clusters.count, boxes)

    # -- stages ---------------------------------------------------------------------------
    # ``sweep`` is the whole cloud. The reference never looks at it past the ROI filter;
    # it is passed so that faulty variants (.mutants) can, as real pipelines do.

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        """(m, 4) float32: the sweep the pipeline works on (the reference: unchanged)."""
        return points

    def roi_mask(self, points: NDArray[np.float32], roi: Any) -> NDArray[np.bool_]:
        """(n,) bool: points in the ROI."""
        if roi is None:
            return np.ones(len(points), dtype=bool)
        return np.asarray(roi.contains(points[:, :2], method=self.params.roi_method), dtype=bool)

    def ground_heights(
        self, points: NDArray[np.float32], sweep: NDArray[np.float32], roi: Any = None
    ) -> NDArray[np.float32]:
        """(n,) float32: local ground height under each ROI point (``roi``: the frame's)."""
        return ground_heights(points, self.params.ground)

    def obstacle_mask(
        self,
        points: NDArray[np.float32],
        ground_z: NDArray[np.float32],
        sweep: NDArray[np.float32],
    ) -> NDArray[np.bool_]:
        """(n,) bool: points that are neither ground nor above ``max_height``."""
        above = points[:, 2] - ground_z
        return (above >= self.params.ground.tolerance) & (above <= self.params.max_height)

    def segment(self, points: NDArray[np.float32], sweep: NDArray[np.float32]) -> Clusters:
        """Connected components of the obstacle points."""
        return cluster_points(points, self.params.cluster)

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        """Filter objects, build their MinBoxes and classes, sort."""
        if clusters.count == 0:
            return []
        labels = clusters.labels
        z = points[:, 2]
        top = np.full(clusters.count, -np.inf, dtype=np.float32)
        bottom = np.full(clusters.count, np.inf, dtype=np.float32)
        ground = np.full(clusters.count, np.inf, dtype=np.float32)
        np.maximum.at(top, labels, z)
        np.minimum.at(bottom, labels, z)
        np.minimum.at(ground, labels, ground_z)
        keep = self.keep_objects(clusters, top - ground)
        kept = np.flatnonzero(keep)
        if len(kept) == 0:
            return []
        cluster_points_, cluster_labels = _member_points(points, labels, keep, clusters.cells)
        shapes = self.fit_boxes(cluster_points_, cluster_labels)
        features = ObjectShape(
            length=np.array([shape.length for shape in shapes]),
            width=np.array([shape.width for shape in shapes]),
            height=np.array([shape.height for shape in shapes]),
            top=(top - ground)[kept].astype(np.float64),
            bottom=(bottom - ground)[kept].astype(np.float64),
            crown=_crowns(cluster_points_, cluster_labels, shapes, top[kept]),
        )
        classes = self.classify(features)
        boxes = [
            _to_box(shape, label, low, high)
            for shape, label, low, high in zip(
                shapes, classes, bottom[kept].tolist(), top[kept].tolist(), strict=True
            )
        ]
        return sorted(boxes, key=box_order)

    def review_boxes(self, boxes: list[Box], in_roi: NDArray[np.float32]) -> list[Box]:
        """The output, given the ROI's returns, ground included (the reference: as built)."""
        return boxes

    def keep_objects(self, clusters: Clusters, top: NDArray[np.float32]) -> NDArray[np.bool_]:
        """(count,) bool: objects big and tall enough (``top``: highest point above ground)."""
        return (clusters.cells >= self.params.min_cells) & (top >= self.params.min_height)

    def fit_boxes(self, points: NDArray[np.float32], labels: NDArray[np.intp]) -> list[MinBox]:
        """Apollo's MinBox for every kept object (labels 0..k-1)."""
        return min_boxes(
            points, labels, ref_center=self.params.sensor, start=self.params.hull_start
        )

    def classify(self, features: ObjectShape) -> list[str]:
        """Class of every kept object."""
        return list(classify(features, self.params.classifier))


def sweep_and_roi(cloud: Any, roi: Any) -> tuple[NDArray[np.float32], Any]:
    """A detector's input normalised: an (n, 4) float32 array and an ROI (or None).

    ``cloud`` may be a frame (its ``.roi`` is used when ``roi`` is None), a PointCloud or
    an (n, 3) or (n, 4) array_like.
    """
    frame_cloud = getattr(cloud, "cloud", None)
    if frame_cloud is not None:
        if roi is None:
            roi = getattr(cloud, "roi", None)
        cloud = frame_cloud
    if isinstance(cloud, PointCloud):
        points = cloud.points
    else:
        points = PointCloud(cloud, name="cloud").points
    if roi is not None and not callable(getattr(roi, "contains", None)):
        raise InvalidArgument(f"roi={roi!r} must have contains(xy, method=...) or be None")
    return points, roi


def _crowns(
    points: NDArray[np.float32],
    labels: NDArray[np.intp],
    shapes: list[MinBox],
    top: NDArray[np.float32],
) -> NDArray[np.float64]:
    """(k,) float64: how far each object's returns within ``CROWN_BAND`` of its ``top``
    reach along its box's length (``points`` (n, 3) with object ``labels`` 0..k-1)."""
    count = len(shapes)
    direction = np.array([shape.direction[:2] for shape in shapes], dtype=np.float64)
    near_top = points[:, 2] >= top[labels] - CROWN_BAND
    ids = labels[near_top]
    along = np.einsum("ij,ij->i", points[near_top, :2].astype(np.float64), direction[ids])
    low = np.full(count, np.inf)
    high = np.full(count, -np.inf)
    np.minimum.at(low, ids, along)
    np.maximum.at(high, ids, along)
    return np.maximum(high - low, 0.0)


def _member_points(
    points: NDArray[np.float32],
    labels: NDArray[np.intp],
    keep: NDArray[np.bool_],
    cells: NDArray[np.intp],
) -> tuple[NDArray[np.float32], NDArray[np.intp]]:
    """Points of the kept objects, relabelled 0..k-1 in object order.

    Objects of fewer than 4 cells lose repeated points: Apollo's "fewer than 4 points"
    rule would otherwise count a repeat as a new point. Larger objects keep repeats
    (they have at least 4 distinct points, so repeats change nothing).
    """
    new_id = np.cumsum(keep) - 1
    member = keep[labels]
    xyz, ids = np.compress(member, points, axis=0)[:, :3], new_id[labels[member]]
    small = cells[labels[member]] < 4
    if small.any():
        # np.compress / np.take: boolean and fancy row selection of (n, 3) views are
        # several times slower (this step went from 0.18 to 0.05 ms a KITTI sweep).
        few, few_ids = np.compress(small, xyz, axis=0), ids[small]
        order = np.lexsort((few[:, 2], few[:, 1], few[:, 0], few_ids))
        few, few_ids = np.take(few, order, axis=0), few_ids[order]
        fresh = np.ones(len(few), dtype=bool)
        fresh[1:] = (np.diff(few_ids) != 0) | (np.diff(few, axis=0) != 0).any(axis=1)
        many = ~small
        xyz = np.concatenate([np.compress(many, xyz, axis=0), np.compress(fresh, few, axis=0)])
        ids = np.concatenate([ids[many], few_ids[fresh]])
    return xyz, ids


def _to_box(shape: MinBox, label: str, bottom: float, top: float) -> Box:
    """The output box: MinBox's footprint, spanning the object's points in z."""
    length = max(shape.length, MIN_EXTENT)
    width = max(shape.width, MIN_EXTENT)
    height = max(top - bottom, MIN_EXTENT)
    x, y, _ = shape.center
    return Box._quick(
        (x, y, (bottom + top) / 2.0),
        (length, width, height),
        shape.yaw,
        label,  # type: ignore[arg-type]
        shape.points,
    )


def box_order(box: Box) -> tuple[float, ...]:
    """Sort key of a detector's output: centre x, y, z, then size and yaw (equal inputs
    give equal lists)."""
    return (*box.center, *box.size, box.yaw)
