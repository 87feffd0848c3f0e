"""The :class:`Box` type of detected and ground-truth obstacles, the exact bird's-eye IoU of
rotated boxes (vectorised over all pairs) and their centre distances, and per-class size
priors for generating realistic ones."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = [
    "LABELS",
    "SIZE_PRIORS",
    "Box",
    "Label",
    "SizePrior",
    "as_boxes",
    "bev_intersection",
    "bev_iou",
    "center_distances",
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
        center, size, yaw = _checked(self.center, self.size, self.yaw, self.label)
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "yaw", yaw)

    @classmethod
    def _quick(
        cls,
        center: Sequence[float],
        size: Sequence[float],
        yaw: float,
        label: Label,
        points: int | None,
    ) -> Box:
        """``Box(center, size, yaw, label, points=points)`` with the same checks, without
        the frozen dataclass's field-by-field ``__init__``: 3x faster, for detectors that
        build tens of boxes per sweep."""
        center, size, yaw = _checked(center, size, yaw, label)
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


def _checked(
    center: Sequence[float], size: Sequence[float], yaw: float, label: Any
) -> tuple[tuple[float, float, float], tuple[float, float, float], float]:
    """A box's numbers as floats, checked: 3 + 3 finite values, sizes > 0, a known label."""
    center = tuple(map(float, center))
    size = tuple(map(float, size))
    if len(center) != 3 or len(size) != 3:
        raise InvalidArgument(f"Box center and size need 3 values, got {center}, {size}")
    yaw = float(yaw)
    if not all(map(math.isfinite, (*center, *size, yaw))):
        raise InvalidArgument(f"Box has non-finite values: center={center} size={size}")
    if min(size) <= 0:
        raise InvalidArgument(f"Box size must be positive, got {size}")
    if label not in LABELS:
        raise InvalidArgument(f"Box label {label!r} must be one of {LABELS}")
    return center, size, yaw


# -- bird's-eye overlap ------------------------------------------------------------------------


def _corners(boxes: Sequence[Box]) -> NDArray[np.float64]:
    """(n, 4, 2) bird's-eye corners, counter-clockwise."""
    if not boxes:
        return np.empty((0, 4, 2))
    return np.stack([box.corners_bev() for box in boxes])


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
    inter = bev_intersection(source, followup)
    a_area = np.array([box.footprint_area() for box in source]).reshape(-1, 1)
    b_area = np.array([box.footprint_area() for box in followup]).reshape(1, -1)
    union = a_area + b_area - inter
    return np.clip(np.divide(inter, union, out=np.zeros_like(inter), where=union > 0), 0.0, 1.0)


def bev_intersection(source: Sequence[Box], followup: Sequence[Box]) -> NDArray[np.float64]:
    """(n, m) float64: bird's-eye areas (m^2) shared by every pair of boxes' footprints."""
    source = as_boxes(source, "source")
    followup = as_boxes(followup, "followup")
    inter = np.zeros((len(source), len(followup)))
    if not source or not followup:
        return inter
    a_radius = np.array([math.hypot(*box.size[:2]) / 2 for box in source])
    b_radius = np.array([math.hypot(*box.size[:2]) / 2 for box in followup])
    distance = center_distances(source, followup)
    rows, cols = np.nonzero(distance < a_radius[:, None] + b_radius[None, :])
    if len(rows) == 0:
        return inter
    inter[rows, cols] = _convex_intersection_area(_corners(source)[rows], _corners(followup)[cols])
    return inter


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
