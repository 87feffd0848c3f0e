"""``CNNSegmentation``: Apollo's learned LiDAR obstacle segmentation as a system under test.

The stages follow Apollo's ``CNNSegmentation::Segment`` (``../shared/REFERENCE.md``
section 9, ``modules/perception/lidar/lib/segmentation/cnnseg``):

1. **Valid points**: the sweep's points inside the HD-map ROI (Apollo's ROI indices), minus
   the ground (the reference's ground model on those points, as Apollo's later versions
   segment the ground before the network's clusters are built).
2. **Features** (:mod:`.features`) from *every* point of the sweep when ``full_cloud`` is
   True (Apollo 2.x/3.0's ``use_full_cloud: true``: the network sees what lies off the
   road), or from the ROI's points alone when False.
3. **Network** (:mod:`.network`): per-cell objectness, centre offset, class, top height
   and, where the model has it, heading.
4. **Cluster2D** (:mod:`.cluster2d`): object cells grouped by their predicted centres.
5. **Objects**: each group's valid points no higher than its predicted top plus
   ``height_thresh``; groups with fewer than ``min_points``, reaching within
   ``edge_margin`` of the grid's border (cut by it), or with no point within
   ``max_lift`` of the ground under it (floating: a wall's top, foliage; not Apollo's),
   are dropped. The box is the
   visible outline of those points, oriented by the network's heading (cars and
   cyclists, Apollo's ``heading_pt``: the mean over the group's cells) or else by the
   project's MinBox, completed to the
   far side the sensor cannot see so that it is symmetric about the network's predicted
   centre (a car seen from behind is a 1.8 x 0.3 m outline; its predicted centre, two
   metres behind, says where the rest is), capped at the class's largest size. Class:
   the largest mean class probability over the group's cells; score: its mean
   objectness.

Only the features depend on ``full_cloud``: with ``full_cloud=False`` nothing outside the
ROI reaches the detector, so points added there cannot change its output (the fix of
Apollo issue #3341); with ``full_cloud=True`` they change the network's maps around the
ROI's edge, the defect Zhou & Sun's MR1 found.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import SIZE_PRIORS, Box, Label
from pytest_metamorphic.lidar.systems.perception.cnnseg.cluster2d import (
    cluster_cells,
    predicted_centers,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import (
    GridSpec,
    bev_features,
    point_cells,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.network import (
    CLASSES,
    NetworkOutput,
    OnnxNetwork,
)
from pytest_metamorphic.lidar.systems.perception.ground import GroundParams, ground_heights
from pytest_metamorphic.lidar.systems.perception.minbox import min_boxes
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    MIN_EXTENT,
    box_order,
    sweep_and_roi,
)

__all__ = ["CNNSegParams", "CNNSegmentation", "Segmentation"]


@dataclass(frozen=True)
class CNNSegParams:
    """Post-processing parameters (Apollo's velodyne64 values where Apollo has one).

    Attributes
    ----------
    objectness_thresh : float
        Cells at or above this objectness are object cells (Apollo: 0.5).
    height_thresh : float
        Points more than this above the predicted top are left out (Apollo: 0.5 m).
    min_points : int
        Objects with fewer points are dropped. Apollo's ``min_pts_num`` is 3; 10 here,
        chosen on 40 validation streets (``held_out_frame(1000 + i)``, no real sweep):
        car F1 within 70 m 0.867 at 3, 0.890 at 10, 0.889 at 15 for the shipped model
        (before ``max_lift``; the evaluation's own bar: an object with fewer than 10
        returns is not scored).
    edge_margin : float
        Objects with a point within this many metres of the grid's border are dropped:
        the grid cuts them, so the network sees a fragment (Apollo drops objects beyond
        its ``confidence_range`` for the same reason). Without it a car straddling the
        40 m border came back from a quarter turn as a "cyclist" 0.7 m away.
    ground : GroundParams
        The ground model that removes ground returns from the valid points.
    max_lift : float or None
        Objects none of whose returns comes within this many metres of the ground under
        them are dropped: what floats is the top of a wall or a tree crown seen over what
        stands before it, not a road user (a car hidden behind another up to its roof is
        lost too). None keeps them, as Apollo does. On the two unlabelled KITTI crops the
        shipped model reports one such "car" per sweep, on held-out rendered streets one
        in 12 sweeps (``bench/learned_gap.py``); 1 m was fixed from that before it was
        measured anywhere else, and it passed the rule the model is chosen by
        (``docs/learned-model.md``).
    """

    objectness_thresh: float = 0.5
    height_thresh: float = 0.5
    min_points: int = 10
    edge_margin: float = 1.0
    ground: GroundParams = field(default_factory=GroundParams)
    max_lift: float | None = 1.0

    def __post_init__(self) -> None:
        if not 0.0 < self.objectness_thresh < 1.0:
            raise InvalidArgument(f"objectness_thresh={self.objectness_thresh!r} must be in (0, 1)")
        if not (math.isfinite(self.height_thresh) and self.height_thresh >= 0):
            raise InvalidArgument(f"height_thresh={self.height_thresh!r} must be >= 0")
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int):
            raise InvalidArgument(f"min_points={self.min_points!r} must be an int")
        if self.min_points < 1:
            raise InvalidArgument(f"min_points={self.min_points!r} must be >= 1")
        if not (math.isfinite(self.edge_margin) and self.edge_margin >= 0):
            raise InvalidArgument(f"edge_margin={self.edge_margin!r} must be >= 0")
        if self.max_lift is not None and not (
            isinstance(self.max_lift, numbers.Real)
            and not isinstance(self.max_lift, bool)
            and math.isfinite(self.max_lift)
            and self.max_lift > 0
        ):
            raise InvalidArgument(f"max_lift={self.max_lift!r} must be None or a number > 0")


@dataclass(frozen=True)
class Segmentation:
    """One frame through the detector, stage by stage (:meth:`CNNSegmentation.run`).

    Attributes
    ----------
    features : (6, size, size) float32
        What the network saw.
    output : NetworkOutput
        Its maps.
    cell_labels : (size * size,) intp
        Object of every cell, -1 for none.
    boxes : list of Box
        The detections.
    """

    features: NDArray[np.float32]
    output: NetworkOutput
    cell_labels: NDArray[np.intp]
    boxes: list[Box]


@dataclass(frozen=True)
class _Prepared:
    """A frame's inputs to the network and to the clustering."""

    features: NDArray[np.float32]
    valid: NDArray[np.float32]  # (k, 4) ROI points above the ground
    clearance: NDArray[np.float32]  # (k,) how far each is above the ground under it


class CNNSegmentation:
    """Apollo-style CNN segmentation: ``detector(frame) -> list[Box]``.

    Parameters
    ----------
    full_cloud : bool
        True: features from the whole sweep (Apollo's ``use_full_cloud: true``, the
        paper's defect). False: features from the ROI's points only.
    network : OnnxNetwork, path, or an object with ``grid`` and ``predict``, optional
        The trained network; the model shipped with the package by default.
    params : CNNSegParams, optional
    threads : int or None
        onnxruntime threads when ``network`` is a path or None (default 1).
    device : {"cpu", "cuda", "auto"}
        Where the shipped or given ONNX network runs (:class:`~.network.OnnxNetwork`);
        features, clustering and boxes stay on the CPU.
    batch_size : int
        Most frames per network call when a campaign or ``@metamorphic(batch=True)``
        test hands it batches (:mod:`pytest_metamorphic.core.batching`).

    Notes
    -----
    Call it like the reference pipeline (``detector(frame)`` or ``detector(cloud, roi)``),
    or give it many frames at once with :meth:`detect_batch`: the network then runs on
    them as one batch, which is what a learned model is fast at.
    """

    name = "cnnseg"

    def __init__(
        self,
        full_cloud: bool = True,
        *,
        network: Any = None,
        params: CNNSegParams | None = None,
        threads: int | None = 1,
        batch_size: int = 8,
        device: str = "auto",
    ) -> None:
        if not isinstance(full_cloud, bool):
            raise InvalidArgument(f"full_cloud={full_cloud!r} must be True or False")
        if params is not None and not isinstance(params, CNNSegParams):
            raise InvalidArgument(f"params={params!r} must be a CNNSegParams")
        if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
            raise InvalidArgument(f"batch_size={batch_size!r} must be an int >= 1")
        self.full_cloud = full_cloud
        self.batch_size = batch_size
        self.params = params or CNNSegParams()
        # Anything with a ``grid`` and ``predict(features) -> [NetworkOutput]`` will do
        # (an ONNX file by default; a PyTorch module wrapped alike, a fake in tests).
        is_network = hasattr(network, "predict") and hasattr(network, "grid")
        self.network = (
            network if is_network else OnnxNetwork(network, threads=threads, device=device)
        )

    def __repr__(self) -> str:
        return f"CNNSegmentation(full_cloud={self.full_cloud})"

    @property
    def grid(self) -> GridSpec:
        return self.network.grid

    def __call__(self, cloud: Any, roi: Any = None) -> list[Box]:
        """Detect obstacles in one sweep.

        Parameters
        ----------
        cloud : Frame, PointCloud, or (n, 3) / (n, 4) array_like
            The sweep in the sensor frame; a frame's own ``.roi`` is used when ``roi`` is
            not given.
        roi : ROI or None
            Anything with ``contains(xy, method=...)``; None: every point is valid.

        Returns
        -------
        list of Box
            Sorted by centre x, then y, z, size and yaw.
        """
        return self.run(cloud, roi).boxes

    def detect_batch(self, frames: Sequence[Any]) -> list[list[Box]]:
        """Detect obstacles in several frames with one network call.

        Parameters
        ----------
        frames : sequence of Frame (or anything :meth:`__call__` takes alone)

        Returns
        -------
        list of list of Box
            The same boxes as calling the detector on each frame (the network's batch
            dimension is independent per frame).
        """
        prepared = [self._prepare(frame, None) for frame in frames]
        if not prepared:
            return []
        outputs = self.network.predict(np.stack([p.features for p in prepared]))
        return [self._objects(p, o)[1] for p, o in zip(prepared, outputs, strict=True)]

    def run_batch(self, frames: Sequence[Any]) -> list[list[Box]]:
        """The batch protocol's name for :meth:`detect_batch`."""
        return self.detect_batch(frames)

    def run(self, cloud: Any, roi: Any = None) -> Segmentation:
        """Like calling the detector, but also return the features and network maps."""
        prepared = self._prepare(cloud, roi)
        (output,) = self.network.predict(prepared.features[None])
        labels, boxes = self._objects(prepared, output)
        return Segmentation(prepared.features, output, labels, boxes)

    # -- stages ---------------------------------------------------------------------------

    def _prepare(self, cloud: Any, roi: Any) -> _Prepared:
        points, roi = sweep_and_roi(cloud, roi)
        in_roi = (
            np.ones(len(points), dtype=bool)
            if roi is None
            else np.asarray(roi.contains(points[:, :2], method="raster"), dtype=bool)
        )
        roi_points = points[in_roi]
        features = bev_features(points if self.full_cloud else roi_points, self.grid)
        clearance = roi_points[:, 2] - ground_heights(roi_points, self.params.ground)
        above = clearance >= self.params.ground.tolerance
        return _Prepared(features, roi_points[above], clearance[above])

    def _objects(
        self, prepared: _Prepared, output: NetworkOutput
    ) -> tuple[NDArray[np.intp], list[Box]]:
        grid = self.grid
        params = self.params
        n = grid.size
        flat, inside = point_cells(prepared.valid, grid)
        has_points = np.zeros(n * n, dtype=bool)
        has_points[flat[inside]] = True
        labels, count = cluster_cells(
            output.objectness,
            output.offset,
            has_points.reshape(n, n),
            grid,
            objectness_thresh=params.objectness_thresh,
        )
        if count == 0:
            return labels, []
        point_object = np.where(inside, labels[flat], -1)
        top = output.height.ravel()[flat] + params.height_thresh
        keep = (point_object >= 0) & (prepared.valid[:, 2] <= top)
        members, ids = prepared.valid[keep], point_object[keep]
        sizes = np.bincount(ids, minlength=count)
        reach = np.zeros(count)
        np.maximum.at(reach, ids, np.abs(members[:, :2]).max(axis=1))
        wanted = (sizes >= params.min_points) & (reach < grid.range - params.edge_margin)
        if params.max_lift is not None:
            lowest = np.full(count, np.inf)
            np.minimum.at(lowest, ids, prepared.clearance[keep])
            wanted &= lowest <= params.max_lift
        kept = np.flatnonzero(wanted)
        if len(kept) == 0:
            return labels, []
        renumber = np.full(count, -1, dtype=np.intp)
        renumber[kept] = np.arange(len(kept))
        chosen = renumber[ids] >= 0
        members, ids = members[chosen], renumber[ids[chosen]]
        shapes = min_boxes(members, ids, start="nearest")
        cells = np.flatnonzero(labels >= 0)
        cell_object = renumber[labels[cells]]
        cells, cell_object = cells[cell_object >= 0], cell_object[cell_object >= 0]
        weight = np.bincount(cell_object, minlength=len(kept)).astype(np.float64)

        def mean(cell_map: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
            """Each kept object's mean of ``cell_map`` over its cells."""
            summed = np.bincount(cell_object, weights=cell_map.ravel()[cells], minlength=len(kept))
            return summed / weight

        class_mean = np.stack([mean(prob) for prob in output.class_prob])
        score = mean(output.objectness)
        cx, cy = predicted_centers(output.offset, grid)
        centre = np.stack([mean(cx), mean(cy)], axis=1)
        heading = None if output.heading is None else [mean(h) for h in output.heading]
        low = np.full(len(kept), np.inf)
        high = np.full(len(kept), -np.inf)
        np.minimum.at(low, ids, members[:, 2])
        np.maximum.at(high, ids, members[:, 2])
        boxes = []
        for k, shape in enumerate(shapes):
            label: Label = CLASSES[int(np.argmax(class_mean[:, k]))]  # type: ignore[assignment]
            points_k = members[ids == k, :2].astype(np.float64)
            yaw, predicted = shape.yaw, False
            if heading is not None and label in _ORIENTED:
                # Apollo's heading_pt: the mean of (cos 2θ, sin 2θ) over the object's
                # cells. A far car's outline is a few returns of one side, whose
                # smallest enclosing box can point anywhere; the network sees the street.
                yaw, predicted = 0.5 * math.atan2(heading[1][k], heading[0][k]), True
            boxes.append(
                _completed_box(
                    points_k,
                    yaw,
                    centre[k],
                    label,
                    float(low[k]),
                    float(high[k]),
                    float(score[k]),
                    shape.points,
                    along_yaw=predicted,
                )
            )
        return labels, sorted(boxes, key=box_order)


_SIDE_SLACK = 0.2  # metres an outline may exceed a class's largest side (noise, mirrors)
_ORIENTED = ("car", "cyclist")  # the classes the network's heading is trained on


def _completed_box(
    xy: NDArray[np.float64],
    yaw: float,
    centre: NDArray[np.float64],
    label: Label,
    bottom: float,
    top: float,
    score: float,
    points: int | None,
    *,
    along_yaw: bool = False,
) -> Box:
    """The outline of ``xy`` along ``yaw``, completed about the predicted ``centre``.

    A sensor sees one or two sides of an object, so the outline is short of it where it
    cannot see: a car seen from behind is a 1.8 x 0.3 m outline. Cars are completed to
    at least the class's mean size (:func:`_car_bounds`); pedestrians and cyclists, whose
    sizes vary as much as their outlines, symmetrically about the predicted centre
    (:func:`_mirrored_bounds`). The visible outline is always kept. ``along_yaw``: the
    yaw is the network's heading, so a car's length lies along it (an outline's own
    axes say nothing of which is the length).
    """
    axes = np.array([[math.cos(yaw), math.sin(yaw)], [-math.sin(yaw), math.cos(yaw)]])
    projected = xy @ axes.T  # (k, 2): along the outline's heading, across it
    middle = axes @ centre
    lo, hi = projected.min(axis=0), projected.max(axis=0)
    if label == "car":
        (a0, a1), (b0, b1) = _car_bounds(
            lo, hi, middle, label, turns=(False,) if along_yaw else (False, True)
        )
    else:
        (a0, a1), (b0, b1) = _mirrored_bounds(lo, hi, middle, label)
    along, across = (a0 + a1) / 2, (b0 + b1) / 2
    length, width = max(a1 - a0, MIN_EXTENT), max(b1 - b0, MIN_EXTENT)
    x, y = axes.T @ np.array([along, across])
    if width > length:
        length, width, yaw = width, length, yaw + math.pi / 2
    return Box(
        center=(float(x), float(y), (bottom + top) / 2.0),
        size=(length, width, max(top - bottom, MIN_EXTENT)),
        yaw=math.remainder(yaw, math.pi),
        label=label,
        score=score,
        points=points,
    )


Bounds = list[tuple[float, float]]


def _mirrored_bounds(lo: NDArray[np.float64], hi: NDArray[np.float64],
                     middle: NDArray[np.float64], label: Label) -> Bounds:  # fmt: skip
    """The outline mirrored about the predicted centre, capped at the class's largest
    length (a centre implausibly far is completed to the cap on its side only)."""
    cap = max(SIZE_PRIORS[label].high[:2])
    bounds = []
    for axis in range(2):
        low, high, c = float(lo[axis]), float(hi[axis]), float(middle[axis])
        full_lo, full_hi = min(low, 2 * c - high), max(high, 2 * c - low)
        if full_hi - full_lo > max(cap, high - low):
            length = max(cap, high - low)
            full_lo, full_hi = (
                (low, low + length) if c >= (low + high) / 2 else (high - length, high)
            )
        bounds.append((full_lo, full_hi))
    return bounds


def _car_bounds(lo: NDArray[np.float64], hi: NDArray[np.float64],
                middle: NDArray[np.float64], label: Label,
                turns: Sequence[bool] = (False, True)) -> Bounds:  # fmt: skip
    """Each side at least the class's mean size (at most its largest, unless the outline
    is longer), centred on the prediction as far as the outline allows. Of the two ways
    to lay the length along the outline's axes, the one that needs the smaller shift away
    from the predicted centre wins; a way whose side would be shorter than the outline
    by more than the class's widest allows is not taken."""
    prior = SIZE_PRIORS[label]
    seen_sides = hi - lo
    best: tuple[float, Bounds] | None = None
    for turn in turns:
        wanted = (prior.mean[1], prior.mean[0]) if turn else (prior.mean[0], prior.mean[1])
        largest = (prior.high[1], prior.high[0]) if turn else (prior.high[0], prior.high[1])
        if best is not None and np.any(seen_sides > np.array(largest) + _SIDE_SLACK):
            continue
        shift, bounds = 0.0, []
        for axis in range(2):
            length = max(float(seen_sides[axis]), min(wanted[axis], largest[axis]))
            start = float(middle[axis]) - length / 2
            start = min(max(start, float(hi[axis]) - length), float(lo[axis]))
            shift += abs(start + length / 2 - float(middle[axis]))
            bounds.append((start, start + length))
        if best is None or shift < best[0] - 1e-9:
            best = (shift, bounds)
    assert best is not None
    return best[1]
