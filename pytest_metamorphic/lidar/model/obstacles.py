"""Detected or ground-truth obstacles as 3-D boxes in the sensor frame.

Besides the :class:`Box` type: exact bird's-eye IoU of rotated boxes (vectorised over all
pairs), centre distances, the two matchers the subset relation uses to pair source and
follow-up detections one-to-one (:class:`IoUMatcher`, :class:`CenterDistanceMatcher`, both
implementing :class:`~pytest_metamorphic.core.matching.Matcher`), and per-class size priors
for generating realistic obstacles.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = [
    "LABELS",
    "ROUNDING",
    "SIZE_PRIORS",
    "Box",
    "CenterDistanceMatcher",
    "IoUMatcher",
    "Label",
    "SizePrior",
    "as_boxes",
    "bev_iou",
    "center_distances",
    "footprint_distances",
    "points_in_boxes",
    "share_inside",
    "unmatched_twins",
]

Label = Literal["car", "pedestrian", "cyclist", "unknown"]
LABELS: tuple[Label, ...] = ("car", "pedestrian", "cyclist", "unknown")


@dataclass(frozen=True)
class Box:
    """An oriented 3-D box.

    Parameters
    ----------
    center : (3,) float
      x, y, z of the box centre in metres.
    size : (3,) float
      length (along the heading), width, height in metres; all > 0.
    yaw : float
      Heading about +z in radians, counter-clockwise from +x.
    label : {"car", "pedestrian", "cyclist", "unknown"}
    score : float or None
      Detection confidence, when the detector gives one.
    points : int or None
      How many LiDAR points support the box (detectors fill this in).
    """

    center: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0
    label: Label = "unknown"
    score: float | None = None
    points: int | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        center = tuple(float(v) for v in self.center)
        size = tuple(float(v) for v in self.size)
        if len(center) != 3 or len(size) != 3:
            raise InvalidArgument(f"Box center and size need 3 values, got {center}, {size}")
        if not all(math.isfinite(v) for v in (*center, *size, float(self.yaw))):
            raise InvalidArgument(f"Box has non-finite values: center={center} size={size}")
        if min(size) <= 0:
            raise InvalidArgument(f"Box size must be positive, got {size}")
        if self.label not in LABELS:
            raise InvalidArgument(f"Box label {self.label!r} must be one of {LABELS}")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "yaw", float(self.yaw))

    @classmethod
    def _checked_by_caller(
        cls,
        center: tuple[float, float, float],
        size: tuple[float, float, float],
        yaw: float,
        label: Label,
        points: int | None,
    ) -> Box:
        """A box from Python floats the caller has already made valid (finite, sizes > 0,
        a known label): the reference detector's boxes, built tens of times per sweep,
        where ``__post_init__``'s checks were a tenth of its box-building time."""
        box = object.__new__(cls)
        box.__dict__.update(
            center=center, size=size, yaw=yaw, label=label, score=None, points=points
        )
        return box

    def corners_bev(self) -> NDArray[np.float64]:
        """(4, 2) float64: bird's-eye corners, counter-clockwise."""
        length, width, _ = self.size
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = (
            np.array([[length, width], [-length, width], [-length, -width], [length, -width]]) / 2.0
        )
        rotation = np.array([[c, -s], [s, c]])
        return local @ rotation.T + np.array(self.center[:2])

    @property
    def bottom_z(self) -> float:
        """z of the box's underside (where it stands on the ground)."""
        return self.center[2] - self.size[2] / 2.0

    def footprint_area(self) -> float:
        """Bird's-eye area (length x width) in m²."""
        return self.size[0] * self.size[1]

    def rotated(self, theta: float) -> Box:
        """The box turned by ``theta`` radians counter-clockwise about the sensor's z axis.

        The centre moves on a circle about the origin and the heading turns with it, as
        when the whole scene (cloud and ROI) is rotated about the sensor.
        """
        theta = float(theta)
        if not math.isfinite(theta):
            raise InvalidArgument(f"theta={theta} must be finite")
        c, s = math.cos(theta), math.sin(theta)
        x, y, z = self.center
        yaw = math.remainder(self.yaw + theta, 2.0 * math.pi)
        return Box(
            (c * x - s * y, s * x + c * y, z), self.size, yaw, self.label, self.score, self.points
        )

    def mirrored(self) -> Box:
        """The box reflected in the sensor's x axis (y -> -y): the heading changes sign."""
        x, y, z = self.center
        yaw = math.remainder(-self.yaw, 2.0 * math.pi)
        return Box((x, -y, z), self.size, yaw, self.label, self.score, self.points)

    def translated(self, dx: float, dy: float, dz: float = 0.0) -> Box:
        """The box moved by ``(dx, dy, dz)`` metres."""
        x, y, z = self.center
        return Box(
            (x + dx, y + dy, z + dz), self.size, self.yaw, self.label, self.score, self.points
        )

    def grown(self, by: float) -> Box:
        """The box with ``by`` metres added on every side (length, width and height grow
        by ``2 * by``)."""
        length, width, height = self.size
        return Box(
            self.center,
            (length + 2 * by, width + 2 * by, height + 2 * by),
            self.yaw,
            self.label,
            self.score,
            self.points,
        )

    def to_json(self) -> dict[str, Any]:
        """``{"center", "size", "yaw", "label", "score", "points"}``, JSON-safe."""
        return {
            "center": list(self.center),
            "size": list(self.size),
            "yaw": self.yaw,
            "label": self.label,
            "score": self.score,
            "points": self.points,
        }

    @classmethod
    def from_json(cls, data: Any) -> Box:
        """The box :meth:`to_json` describes."""
        try:
            return cls(
                tuple(data["center"]),
                tuple(data["size"]),
                float(data.get("yaw", 0.0)),
                data.get("label", "unknown"),
                data.get("score"),
                data.get("points"),
            )
        except (KeyError, TypeError, ValueError) as error:
            raise InvalidArgument(f"not a box: {data!r} ({error})") from None

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Which points lie in the box (faces included).

        Parameters
        ----------
        points : (n, 3) or (n, >=3) array_like, or a PointCloud
          x, y, z in the box's frame of reference; extra columns are ignored.

        Returns
        -------
        (n,) bool
        """
        xyz = _as_xyz(getattr(points, "points", points))
        length, width, height = self.size
        offset = xyz - np.asarray(self.center)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        along = offset[:, 0] * c + offset[:, 1] * s
        across = -offset[:, 0] * s + offset[:, 1] * c
        return (
            (np.abs(along) <= length / 2.0)
            & (np.abs(across) <= width / 2.0)
            & (np.abs(offset[:, 2]) <= height / 2.0)
        )

    def iou_bev(self, other: Box) -> float:
        """Exact bird's-eye IoU with another box (rotated rectangles)."""
        return float(bev_iou([self], [other])[0, 0])

    def center_distance(self, other: Box) -> float:
        """Bird's-eye distance between the two centres in metres."""
        return math.hypot(self.center[0] - other.center[0], self.center[1] - other.center[1])

    def describe(self) -> str:
        """Short human description, e.g. ``car at (12.1, -3.4)``."""
        x, y, _ = self.center
        return f"{self.label} at ({x:.1f}, {y:.1f})"

    def __str__(self) -> str:
        return self.describe()


#: How far two boxes may differ and still be *identical*: floating-point rounding (metres,
#: radians, score). A detector that averages its points in the order it receives them
#: gives centres that differ in the 16th digit when the points are reordered
#: (1.7068876216562718 vs ...716): the same box, which exact float equality called a
#: change; no real difference is this small.
ROUNDING = 1e-6


def unmatched_twins(a: Sequence[Box], b: Sequence[Box]) -> tuple[list[int], list[int]]:
    """Indices of ``a`` and of ``b`` without an identical partner on the other side.

    A multiset difference (repeated equal boxes pair up one by one, in order): boxes hash
    by value, so exact twins pair in linear time; the rest pair when they differ by no
    more than :data:`ROUNDING` in every number, with the same label. Equality ignores
    ``points``, as ``Box ==`` does.
    """
    available = Counter(b)
    gone = []
    for index, box in enumerate(a):
        if available[box]:
            available[box] -= 1
        else:
            gone.append(index)
    paired = Counter(b)
    paired.subtract(available)  # per box value: how many of b's copies were paired
    new = []
    for index, box in enumerate(b):
        if paired[box]:
            paired[box] -= 1
        else:
            new.append(index)
    return _pair_rounded(a, b, gone, new)


def _pair_rounded(
    a: Sequence[Box], b: Sequence[Box], gone: list[int], new: list[int]
) -> tuple[list[int], list[int]]:
    """``gone`` and ``new`` less the pairs that differ by rounding only (few: a quadratic
    pass over what the exact pass left)."""
    left = list(new)
    still_gone = []
    for i in gone:
        twin = next((j for j in left if _rounded_twins(a[i], b[j])), None)
        if twin is None:
            still_gone.append(i)
        else:
            left.remove(twin)
    return still_gone, left


def _rounded_twins(first: Box, second: Box) -> bool:
    if first.label != second.label or (first.score is None) != (second.score is None):
        return False
    numbers = [*first.center, *first.size, first.yaw, first.score or 0.0]
    others = [*second.center, *second.size, second.yaw, second.score or 0.0]
    return all(abs(x - y) <= ROUNDING for x, y in zip(numbers, others, strict=True))


# -- size priors -----------------------------------------------------------------------------


@dataclass(frozen=True)
class SizePrior:
    """Typical and plausible (length, width, height) of one obstacle class, in metres.

    ``mean`` is a typical object; ``low`` and ``high`` bound the sizes generators draw.
    """

    mean: tuple[float, float, float]
    low: tuple[float, float, float]
    high: tuple[float, float, float]

    def __post_init__(self) -> None:
        for low, mean, high in zip(self.low, self.mean, self.high, strict=True):
            if not 0 < low <= mean <= high:
                raise InvalidArgument(f"SizePrior needs 0 < low <= mean <= high, got {self}")

    def contains(self, size: Sequence[float]) -> bool:
        """Whether a (length, width, height) lies within the prior's bounds."""
        return all(lo <= v <= hi for lo, v, hi in zip(self.low, size, self.high, strict=True))


# Means: the KITTI class averages used as anchor sizes by SECOND and PointPillars
# (car 3.9 x 1.6 x 1.56, pedestrian 0.8 x 0.6 x 1.73, cyclist 1.76 x 0.6 x 1.73). Bounds
# cover Euro NCAP's child dummy (0.711 x 0.298 x 1.154) and test car (4.358 x 1.815), see
# REFERENCE.md section 7. "unknown" stands for bins, cones, barriers and debris.
SIZE_PRIORS: Mapping[Label, SizePrior] = {
    "car": SizePrior(mean=(3.9, 1.6, 1.56), low=(3.4, 1.5, 1.35), high=(5.2, 2.0, 1.9)),
    "pedestrian": SizePrior(mean=(0.8, 0.6, 1.73), low=(0.3, 0.29, 1.1), high=(1.0, 0.8, 1.95)),
    "cyclist": SizePrior(mean=(1.76, 0.6, 1.73), low=(1.5, 0.45, 1.5), high=(2.0, 0.9, 1.95)),
    "unknown": SizePrior(mean=(1.0, 1.0, 1.0), low=(0.3, 0.3, 0.3), high=(2.5, 2.5, 2.0)),
}


# -- bird's-eye overlap ------------------------------------------------------------------------


def _as_xyz(points: Any) -> NDArray[np.float64]:
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"points cannot be converted to a float array: {error}") from None
    if array.ndim != 2 or array.shape[1] < 3:
        raise InvalidArgument(f"points must have shape (n, 3) or (n, >=3), got {array.shape}")
    return array[:, :3]


def as_boxes(value: Any, which: str) -> list[Box]:
    """``value`` as a list of :class:`Box`; an :class:`InvalidArgument` naming ``which``
    (e.g. "source", "follow-up") and the first item that is not one."""
    if isinstance(value, (str, bytes)):
        raise InvalidArgument(f"the {which} must be a list of Box, got {value!r}")
    try:
        boxes = list(value)
    except TypeError:
        raise InvalidArgument(f"the {which} must be a list of Box, got {value!r}") from None
    for index, box in enumerate(boxes):
        if not isinstance(box, Box):
            raise InvalidArgument(
                f"the {which}[{index}] is {box!r}; obstacle relations need "
                "pytest_metamorphic.lidar.model.obstacles.Box items (see "
                "pytest_metamorphic.lidar.systems.detectors for converters)"
            )
    return boxes


def _corners(boxes: Sequence[Box]) -> NDArray[np.float64]:
    """(n, 4, 2) bird's-eye corners, counter-clockwise."""
    if not boxes:
        return np.empty((0, 4, 2))
    return np.stack([box.corners_bev() for box in boxes])


def points_in_boxes(
    points: ArrayLike, boxes: Sequence[Box], *, grow: float = 0.0
) -> list[NDArray[np.intp]]:
    """The indices of ``points`` inside each box grown by ``grow`` metres (faces included).

    The same as ``np.flatnonzero(box.grown(grow).contains(points))`` for each box, but the
    exact test runs only on the points a k-d tree over x, y finds within the box's
    bounding circle: a sweep of 120k points and a hundred boxes in milliseconds.

    Parameters
    ----------
    points : (n, >=3) array_like or PointCloud
    boxes : sequence of Box
    grow : float

    Returns
    -------
    list of (k,) intp
        One sorted index array per box.
    """
    xyz = _as_xyz(getattr(points, "points", points))
    if not boxes:
        return []
    if len(xyz) == 0:
        return [np.zeros(0, dtype=np.intp) for _ in boxes]
    from scipy.spatial import cKDTree  # only here: most users of this module never need it

    grown = [box.grown(grow) if grow else box for box in boxes]
    centres = np.array([box.center[:2] for box in grown])
    # The bounding circle, plus a millimetre so float32 corners are never cut.
    reach = np.array([math.hypot(*box.size[:2]) / 2 + 1e-3 for box in grown])
    near = cKDTree(xyz[:, :2]).query_ball_point(centres, reach)
    found = []
    for box, candidates in zip(grown, near, strict=True):
        rows = np.sort(np.asarray(candidates, dtype=np.intp))
        found.append(rows[box.contains(xyz[rows])] if len(rows) else rows)
    return found


def share_inside(points: ArrayLike, boxes: Sequence[Box], *, grow: float = 0.1) -> float:
    """The share of ``points`` (n, 3) inside any of ``boxes`` grown by ``grow`` metres on
    every side (0 when there are no points): how much of an object a detector's boxes hold,
    whatever their labels and however many pieces."""
    xyz = _as_xyz(points)
    if len(xyz) == 0:
        return 0.0
    inside = np.zeros(len(xyz), dtype=bool)
    for box in boxes:
        inside |= box.grown(grow).contains(xyz)
    return float(inside.mean())


def center_distances(source: Sequence[Box], followup: Sequence[Box]) -> NDArray[np.float64]:
    """(n, m) float64: bird's-eye distances between box centres."""
    a = np.array([box.center[:2] for box in as_boxes(source, "source")]).reshape(-1, 2)
    b = np.array([box.center[:2] for box in as_boxes(followup, "followup")]).reshape(-1, 2)
    return np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2))


def bev_iou(source: Sequence[Box], followup: Sequence[Box]) -> NDArray[np.float64]:
    """(n, m) float64: exact bird's-eye IoU of every pair of boxes.

    The intersection of two rotated rectangles is the convex polygon spanned by the
    corners of each that lie in the other and the crossings of their edges; its area is
    taken with the shoelace formula after sorting those points by angle. All pairs whose
    bounding circles overlap are computed in one vectorised pass.
    """
    source = as_boxes(source, "source")
    followup = as_boxes(followup, "followup")
    iou = np.zeros((len(source), len(followup)))
    if not source or not followup:
        return iou
    a_corners, b_corners = _corners(source), _corners(followup)
    a_area = np.array([box.footprint_area() for box in source])
    b_area = np.array([box.footprint_area() for box in followup])
    a_radius = np.array([math.hypot(*box.size[:2]) / 2 for box in source])
    b_radius = np.array([math.hypot(*box.size[:2]) / 2 for box in followup])
    distance = center_distances(source, followup)
    rows, cols = np.nonzero(distance < a_radius[:, None] + b_radius[None, :])
    if len(rows) == 0:
        return iou
    inter = _convex_intersection_area(a_corners[rows], b_corners[cols])
    union = a_area[rows] + b_area[cols] - inter
    iou[rows, cols] = np.clip(inter / union, 0.0, 1.0)
    return iou


def _inside_convex(points: NDArray[np.float64], polygon: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(p, k) points against (p, 4, 2) counter-clockwise polygons -> (p, k) bool."""
    start = polygon[:, None, :, :]
    edge = np.roll(polygon, -1, axis=1)[:, None, :, :] - start
    rel = points[:, :, None, :] - start
    cross = edge[..., 0] * rel[..., 1] - edge[..., 1] * rel[..., 0]
    scale = np.abs(polygon).max(axis=(1, 2))[:, None, None] + 1.0
    return (cross >= -1e-9 * scale**2).all(axis=2)


def _convex_intersection_area(
    a: NDArray[np.float64], b: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Areas of the intersections of pairs of convex quadrilaterals (p, 4, 2) x (p, 4, 2)."""
    pairs = len(a)
    a_in_b = _inside_convex(a, b)
    b_in_a = _inside_convex(b, a)
    # Edge i of a against edge j of b: p + t r = q + u s.
    p = a[:, :, None, :]
    r = (np.roll(a, -1, axis=1) - a)[:, :, None, :]
    q = b[:, None, :, :]
    s = (np.roll(b, -1, axis=1) - b)[:, None, :, :]
    denominator = r[..., 0] * s[..., 1] - r[..., 1] * s[..., 0]
    qp = q - p
    parallel = np.abs(denominator) < 1e-12
    safe = np.where(parallel, 1.0, denominator)
    t = (qp[..., 0] * s[..., 1] - qp[..., 1] * s[..., 0]) / safe
    u = (qp[..., 0] * r[..., 1] - qp[..., 1] * r[..., 0]) / safe
    crossing = ~parallel & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
    crossings = (p + t[..., None] * r).reshape(pairs, 16, 2)
    candidates = np.concatenate([a, b, crossings], axis=1)
    valid = np.concatenate([a_in_b, b_in_a, crossing.reshape(pairs, 16)], axis=1)
    count = valid.sum(axis=1)
    centre = (candidates * valid[..., None]).sum(axis=1) / np.maximum(count, 1)[:, None]
    offset = candidates - centre[:, None, :]
    angle = np.where(valid, np.arctan2(offset[..., 1], offset[..., 0]), np.inf)
    order = np.argsort(angle, axis=1)
    ordered = np.take_along_axis(candidates, order[..., None], axis=1)
    ordered_valid = np.take_along_axis(valid, order, axis=1)
    # Invalid points (sorted last) collapse onto the first point: their edges add nothing.
    ordered = np.where(ordered_valid[..., None], ordered, ordered[:, :1, :])
    x, y = ordered[..., 0], ordered[..., 1]
    area = 0.5 * np.abs((x * np.roll(y, -1, axis=1) - y * np.roll(x, -1, axis=1)).sum(axis=1))
    return np.where(count >= 3, area, 0.0)


# -- matchers ----------------------------------------------------------------------------------


def _same_labels(source: Sequence[Box], followup: Sequence[Box]) -> NDArray[np.bool_]:
    a = np.array([box.label for box in source], dtype=object).reshape(-1, 1)
    b = np.array([box.label for box in followup], dtype=object).reshape(1, -1)
    return np.asarray(a == b, dtype=bool).reshape(len(source), len(followup))


def _check_flag(value: Any, name: str) -> None:
    if not isinstance(value, bool):
        raise InvalidArgument(f"{name}={value!r} must be True or False")


@dataclass(frozen=True)
class IoUMatcher:
    """Pairs boxes whose bird's-eye IoU is at least ``min_iou`` (cost: ``1 - IoU``).

    Parameters
    ----------
    min_iou : float
      In (0, 1]. 0.5 by default; KITTI evaluates cars at 0.7 and people at 0.5.
    same_label : bool
      Also require equal labels (default), so a car that turns into "unknown" in the
      follow-up counts as missing.
    """

    min_iou: float = 0.5
    same_label: bool = True

    def __post_init__(self) -> None:
        value = self.min_iou
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"min_iou={value!r} must be a number in (0, 1]")
        if not 0 < value <= 1:
            raise InvalidArgument(f"min_iou={value!r} must be in (0, 1]")
        _check_flag(self.same_label, "same_label")

    @property
    def name(self) -> str:
        label = ", same label" if self.same_label else ""
        return f"BEV IoU >= {self.min_iou:g}{label}"

    def pairwise(
        self, source: Sequence[Any], followup: Sequence[Any]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        iou = bev_iou(source, followup)
        compatible = iou >= self.min_iou
        if self.same_label:
            compatible &= _same_labels(source, followup)
        return compatible, 1.0 - iou


@dataclass(frozen=True)
class CenterDistanceMatcher:
    """Pairs boxes whose centres are at most ``max_distance`` metres apart in bird's-eye view.

    Cost is the distance. ``same_label`` as for :class:`IoUMatcher`. ``exclusive=False``
    lets several boxes share one match (:func:`~pytest_metamorphic.core.matching.matched_pairs`):
    pieces of one object reported in one output and one box in the other.
    """

    max_distance: float = 2.0
    same_label: bool = True
    exclusive: bool = True

    def __post_init__(self) -> None:
        value = self.max_distance
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"max_distance={value!r} must be a positive number of metres")
        if not (math.isfinite(value) and value > 0):
            raise InvalidArgument(f"max_distance={value!r} must be a positive number of metres")
        _check_flag(self.same_label, "same_label")
        _check_flag(self.exclusive, "exclusive")

    @property
    def name(self) -> str:
        label = ", same label" if self.same_label else ""
        shared = "" if self.exclusive else ", pieces share a match"
        return f"centre distance <= {self.max_distance:g} m{label}{shared}"

    def pairwise(
        self, source: Sequence[Any], followup: Sequence[Any]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        distance = center_distances(source, followup)
        compatible = distance <= self.max_distance
        if self.same_label:
            compatible &= _same_labels(source, followup)
        return compatible, distance


def footprint_distances(xy: NDArray[np.floating], boxes: Sequence[Box]) -> NDArray[np.float64]:
    """(n,) float64: bird's-eye distance from each point to the nearest box footprint.

    Parameters
    ----------
    xy : (n, >=2) array
        Point coordinates; columns after the second are ignored.
    boxes : sequence of Box
        0 inside a footprint; ``inf`` for every point when there are no boxes.
    """
    points = np.asarray(xy, dtype=np.float64)[:, :2]
    nearest = np.full(len(points), np.inf)
    for box in boxes:
        length, width, _ = box.size
        offset = points - np.asarray(box.center[:2])
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        along = np.abs(offset[:, 0] * c + offset[:, 1] * s) - length / 2.0
        across = np.abs(-offset[:, 0] * s + offset[:, 1] * c) - width / 2.0
        distance = np.hypot(np.maximum(along, 0.0), np.maximum(across, 0.0))
        np.minimum(nearest, distance, out=nearest)
    return nearest
