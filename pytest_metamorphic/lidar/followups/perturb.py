"""Deterministic frame perturbations for follow-up inputs, usable with or without Hypothesis.

Each perturbation is a small value object with ``apply(frame) -> Frame``, ``params()``
(what a :class:`~pytest_metamorphic.core.engine.Followup` records) and a ``repr`` short
enough for failure messages:

* :class:`NoiseOutsideROI` - the paper's MR1 recipe (Zhou & Sun, CACM 2019): n points with
  (x, y) uniform over the sensor's range *outside* the ROI, z uniform in the frame's
  [min z, max z], intensity uniform in the frame's [min, max] intensity. "Outside" holds
  for the exact polygons and for Apollo's 0.25 m bitmap, with at least one free cell
  between every injected point and every set cell.
* :class:`NoiseInsideROI` - points inside the ROI (both methods) and away from obstacles.
* :class:`DropPoints`, :class:`DuplicatePoints`, :class:`PermutePoints`.
* :class:`RotateAboutSensor` - the cloud, the ROI and the boxes turned together about z.

Noise points are built from one integer seed per point through a counter-based hash
(SplitMix64), so a list of small integers is a complete, replayable description: Hypothesis
shrinks noise by deleting seeds, campaign code draws seeds from a numpy generator, and the
same seeds always give the same points. Sampling is exact: a cell is chosen uniformly
among the allowed cells that reach into the sensor's range, a position uniformly within
it, and positions beyond the range are redrawn from the next hash values (rejection).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, TypeVar, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud, column_bounds
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, footprint_distances
from pytest_metamorphic.lidar.roi import ROI, CellSet

__all__ = [
    "NOISE_INSTANCE",
    "PAPER_NOISE_SIZES",
    "SEED_BITS",
    "DropPoints",
    "DuplicatePoints",
    "NoiseInsideROI",
    "NoiseOutsideROI",
    "PermutePoints",
    "Perturbation",
    "RotateAboutSensor",
    "append_points",
    "seeded_uniforms",
]

PAPER_NOISE_SIZES = (10, 100, 1000)
"""The numbers of noise points Zhou & Sun added per follow-up."""

SEED_BITS = 32
"""Noise seeds are integers in ``[0, 2**SEED_BITS)``."""
NOISE_INSTANCE = -3
"""``instance`` field value given to injected points (see
:mod:`pytest_metamorphic.lidar.synthetic`)."""

_MAX_ATTEMPTS = 64
# Hash counters: position attempts use 0 .. 3 * _MAX_ATTEMPTS - 1, then z and intensity.
_Z_COUNTER = 3 * _MAX_ATTEMPTS
_INTENSITY_COUNTER = _Z_COUNTER + 1
_TRIPLE = np.arange(3)
_SHOWN_POINTS = 8

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


@runtime_checkable
class Perturbation(Protocol):
    """A deterministic change to a frame (the "input transform" of a metamorphic relation)."""

    def apply(self, frame: Frame) -> Frame:
        """The perturbed frame; ``frame`` is not modified."""
        ...

    def params(self) -> dict[str, Any]:
        """Parameters to record with the follow-up (shown in failure reports)."""
        ...


# -- seeded uniforms ---------------------------------------------------------------------------


def _mix(z: NDArray[np.uint64]) -> NDArray[np.uint64]:
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


def seeded_uniforms(seeds: ArrayLike, counters: ArrayLike) -> NDArray[np.float64]:
    """Uniform floats in [0, 1) from (seed, counter) pairs, SplitMix64-hashed.

    Parameters
    ----------
    seeds : (n,) array_like of int
    counters : (k,) array_like of int
      Which values of each seed's stream to return.

    Returns
    -------
    (n, k) float64
      ``out[i, j]`` depends only on ``seeds[i]`` and ``counters[j]``.
    """
    seed = np.asarray(seeds, dtype=np.uint64).reshape(-1, 1)
    counter = np.asarray(counters, dtype=np.uint64).reshape(1, -1)
    # Hash the seed first so that neighbouring seeds give unrelated streams.
    state = _mix(seed + _GOLDEN) + (counter + np.uint64(1)) * _GOLDEN
    return (_mix(state) >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def _as_seeds(seeds: ArrayLike) -> NDArray[np.int64]:
    try:
        array = np.asarray(seeds)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"seeds cannot be converted to an array: {error}") from None
    if array.size == 0:
        return np.empty(0, dtype=np.int64)
    if array.ndim != 1 or not np.issubdtype(array.dtype, np.integer):
        raise InvalidArgument(
            f"seeds must be a 1-D list of ints, got shape {array.shape} {array.dtype}"
        )
    if array.min() < 0 or array.max() >= 2**SEED_BITS:
        raise InvalidArgument(f"seeds must lie in [0, 2**{SEED_BITS})")
    return array.astype(np.int64)


# -- injected points ---------------------------------------------------------------------------


def _frame_roi(frame: Frame, roi: ROI | None) -> ROI:
    if not isinstance(frame, Frame):
        raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
    chosen = frame.roi if roi is None else roi
    if chosen is None:
        raise InvalidArgument(
            f"{frame!r} has no ROI; pass roi=ROI.from_polygons(...) (or from_apollo_poly, "
            "from_roads) to say where the ROI is"
        )
    if not isinstance(chosen, ROI):
        raise InvalidArgument(f"roi must be an ROI, got {type(chosen).__name__}")
    return chosen


def _check_range(roi: ROI, max_range: Any, margin_cells: Any) -> float:
    if isinstance(max_range, bool) or not isinstance(max_range, (int, float)):
        raise InvalidArgument(f"max_range={max_range!r} must be a number of metres")
    if not (math.isfinite(max_range) and max_range > 0):
        raise InvalidArgument(f"max_range={max_range!r} must be positive")
    if max_range > roi.raster_range:
        raise InvalidArgument(
            f"max_range={max_range} exceeds the ROI's raster_range={roi.raster_range}: beyond "
            "the bitmap the two containment methods disagree; build the ROI with "
            f"raster_range >= {max_range}"
        )
    if isinstance(margin_cells, bool) or not isinstance(margin_cells, (int, np.integer)):
        raise InvalidArgument(f"margin_cells={margin_cells!r} must be an int >= 1")
    if margin_cells < 1:
        raise InvalidArgument(
            f"margin_cells={margin_cells} must be >= 1: injected points keep at least one "
            "free cell to the rasterised ROI"
        )
    return float(max_range)


def _frame_ranges(frame: Frame) -> tuple[tuple[float, float], tuple[float, float]]:
    if len(frame.cloud) == 0:
        raise DataError(
            f"{frame!r} is empty: noise z and intensity ranges come from the frame's points"
        )
    # column_bounds folds rows so numpy reduces long rows: half the time of four
    # strided column reductions, ~30x less than a plain (n, 4) reduction along axis 0.
    low, high = column_bounds(frame.cloud.points)
    return (float(low[2]), float(high[2])), (float(low[3]), float(high[3]))


def _seeded_points(
    frame: Frame,
    seeds: ArrayLike,
    cells: CellSet,
    region: ROI,
    limit: float,
    what: str,
) -> NDArray[np.float32]:
    """Points for ``seeds`` in ``cells``, z and intensity over the frame's ranges."""
    z_range, intensity_range = _frame_ranges(frame)
    return _place_points(
        _as_seeds(seeds), cells, region.cell_size, limit, z_range, intensity_range, what
    )


def _place_points(
    seeds: NDArray[np.int64],
    cells: CellSet,
    cell_size: float,
    max_range: float,
    z_range: tuple[float, float],
    intensity_range: tuple[float, float],
    what: str,
) -> NDArray[np.float32]:
    """Map seeds to (n, 4) points: uniform in the allowed cells within ``max_range``."""
    n = len(seeds)
    points = np.empty((n, 4), dtype=np.float32)
    if n == 0:
        return points
    if len(cells) == 0:
        raise DataError(f"there is no room {what} within {max_range} m of the sensor")
    xy = np.empty((n, 2))
    pending = np.arange(n)
    # The first attempt's three values and z and intensity come from one hash of all
    # seeds (each value depends only on its seed and counter, so nothing changes).
    first = seeded_uniforms(seeds, [0, 1, 2, _Z_COUNTER, _INTENSITY_COUNTER])
    for attempt in range(_MAX_ATTEMPTS):
        u = first if attempt == 0 else seeded_uniforms(seeds[pending], 3 * attempt + _TRIPLE)
        cell = np.minimum((u[:, 0] * len(cells)).astype(np.intp), len(cells) - 1)
        candidate = cells.origins(cell) + u[:, 1:3] * cell_size
        inside = (candidate**2).sum(axis=1) <= max_range**2
        xy[pending[inside]] = candidate[inside]
        pending = pending[~inside]
        if len(pending) == 0:
            break
    else:
        raise DataError(
            f"could not place {len(pending)} point(s) {what} in {_MAX_ATTEMPTS} attempts "
            "(the allowed region is almost entirely beyond max_range)"
        )
    (z_low, z_high), (i_low, i_high) = z_range, intensity_range
    points[:, :2] = xy
    points[:, 2] = z_low + first[:, 3] * (z_high - z_low)
    points[:, 3] = i_low + first[:, 4] * (i_high - i_low)
    return points


def append_points(
    cloud: PointCloud,
    points: NDArray[np.float32],
    *,
    instance: int = NOISE_INSTANCE,
    given: Mapping[str, NDArray[Any]] | None = None,
) -> PointCloud:
    """The cloud with extra points at the end.

    Their fields are 0, except ``instance`` (``instance``: -3 for noise) and the fields
    named in ``given`` (e.g. the ``ring`` of each added return), where the cloud has them.
    """
    n = len(points)
    given = given or {}
    fields = {}
    for name, values in cloud.fields.items():
        shape, dtype = (n, *values.shape[1:]), values.dtype
        if name in given:
            fields[name] = np.asarray(given[name]).astype(dtype).reshape(shape)
            continue
        fill = instance if name == "instance" and np.issubdtype(dtype, np.signedinteger) else 0
        fields[name] = np.full(shape, fill, dtype=dtype)
    extra = PointCloud(points, fields=fields, frame_id=cloud.frame_id, name="added points")
    return PointCloud.concatenate([cloud, extra])


_P = TypeVar("_P", bound="_InjectedPoints")


@dataclass(frozen=True, eq=False)
class _InjectedPoints:
    """Points added to a frame. ``points`` is (n, 4) float32: x, y, z, intensity."""

    points: NDArray[np.float32]

    kind = "points"

    def __post_init__(self) -> None:
        try:
            array = np.array(self.points, dtype=np.float32)
        except (TypeError, ValueError) as error:
            raise InvalidArgument(f"points cannot be converted to float32: {error}") from None
        if array.size == 0:
            array = array.reshape(0, 4)
        if array.ndim != 2 or array.shape[1] != 4:
            raise InvalidArgument(f"points must have shape (n, 4), got {array.shape}")
        if not np.isfinite(array).all():
            raise InvalidArgument("points must be finite")
        array.setflags(write=False)
        object.__setattr__(self, "points", array)

    def __len__(self) -> int:
        return len(self.points)

    # Each subclass's classmethod ``from_seeds(frame, seeds, **its own options)``; declared
    # this way because the options differ (a method here would make them incompatible).
    from_seeds: ClassVar[Callable[..., Any]]

    @classmethod
    def sample(
        cls: type[_P], frame: Frame, n: int, *, rng: np.random.Generator, **options: Any
    ) -> _P:
        """``n`` points with seeds drawn from a numpy generator (campaign mode); ``options``
        as for :meth:`from_seeds`."""
        drawn: _P = cls.from_seeds(frame, _draw_seeds(n, rng), **options)
        return drawn

    def apply(self, frame: Frame) -> Frame:
        """The frame with the points appended (ROI, boxes, pose and origin kept)."""
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        return frame.with_cloud(append_points(frame.cloud, self.points))

    def params(self) -> dict[str, Any]:
        return {"n": len(self), self.kind: self}

    def equals(self, other: object) -> bool:
        return type(other) is type(self) and np.array_equal(self.points, other.points)

    def describe(self, width: int = 115) -> str:
        """One line of at most ``width`` characters with as many points as fit.

        Failure messages use this (they cap values at 120 characters); ``repr`` shows
        more points.
        """
        head = f"{type(self).__name__} n={len(self)}: "
        parts: list[str] = []
        used = len(head)
        for x, y, z, i in self.points:
            text = f"({x:.1f}, {y:.1f}, {z:.1f}, {i:.2f})"
            if used + len(text) + 2 + 12 > width:  # leave room for ", +NNNN more"
                break
            parts.append(text)
            used += len(text) + 2
        rest = len(self) - len(parts)
        return head + ", ".join(parts) + (f", +{rest} more" if rest else "")

    def __repr__(self) -> str:
        shown = ", ".join(
            f"({x:.2f}, {y:.2f}, {z:.2f}, {i:.2f})" for x, y, z, i in self.points[:_SHOWN_POINTS]
        )
        more = f", ... {len(self) - _SHOWN_POINTS} more" if len(self) > _SHOWN_POINTS else ""
        return f"{type(self).__name__}(n={len(self)}: [{shown}{more}])"


@dataclass(frozen=True, eq=False, repr=False)
class NoiseOutsideROI(_InjectedPoints):
    """MR1 noise: points outside the ROI (exact and rasterised), appended to the frame."""

    kind = "noise_outside_roi"

    @classmethod
    def from_seeds(
        cls,
        frame: Frame,
        seeds: ArrayLike,
        *,
        roi: ROI | None = None,
        max_range: float = 120.0,
        margin_cells: int = 1,
    ) -> NoiseOutsideROI:
        """The noise for one integer seed per point (deterministic).

        Parameters
        ----------
        frame : Frame
          Gives the z and intensity ranges, and the ROI unless ``roi`` is passed.
        seeds : (n,) array_like of int in [0, 2**32)
        roi : ROI, optional
          Defaults to ``frame.roi``.
        max_range : float
          The sensor's range in metres (HDL-64E: 120); (x, y) are uniform over the disk
          of this radius minus the ROI and its ``margin_cells`` border. At most the ROI's
          ``raster_range``.
        margin_cells : int
          Free cells kept between injected points and the ROI (>= 1).
        """
        region = _frame_roi(frame, roi)
        limit = _check_range(region, max_range, margin_cells)
        cells = region.cells("free", margin_cells=int(margin_cells), max_range=limit)
        return cls(_seeded_points(frame, seeds, cells, region, limit, "outside the ROI"))


@dataclass(frozen=True, eq=False, repr=False)
class NoiseInsideROI(_InjectedPoints):
    """Points inside the ROI (both methods), away from the obstacles, appended to the frame."""

    kind = "noise_inside_roi"

    @classmethod
    def from_seeds(
        cls,
        frame: Frame,
        seeds: ArrayLike,
        *,
        roi: ROI | None = None,
        obstacles: Sequence[Box] | None = None,
        clearance: float = 1.0,
        max_range: float = 120.0,
        margin_cells: int = 1,
    ) -> NoiseInsideROI:
        """Points uniform over the ROI's interior cells that are ``clearance`` m from every box.

        z and intensity follow the MR1 recipe (uniform over the frame's ranges).
        ``obstacles`` defaults to the frame's ground-truth boxes.
        """
        region = _frame_roi(frame, roi)
        limit = _check_range(region, max_range, margin_cells)
        boxes = tuple(frame.boxes if obstacles is None else obstacles)
        if isinstance(clearance, bool) or not isinstance(clearance, (int, float)):
            raise InvalidArgument(f"clearance={clearance!r} must be a number of metres")
        if not (math.isfinite(clearance) and clearance >= 0):
            raise InvalidArgument(f"clearance={clearance!r} must be >= 0")
        cells = region.cells("interior", margin_cells=int(margin_cells), max_range=limit)
        cells = cells.subset(
            ~_near_boxes(cells.origins(), region.cell_size, boxes, float(clearance))
        )
        where = "inside the ROI away from obstacles"
        return cls(_seeded_points(frame, seeds, cells, region, limit, where))


def _draw_seeds(n: Any, rng: Any) -> NDArray[np.int64]:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise InvalidArgument(f"n={n!r} must be a non-negative int")
    if not isinstance(rng, np.random.Generator):
        raise InvalidArgument(f"rng must be a numpy Generator, got {type(rng).__name__}")
    return rng.integers(0, 2**SEED_BITS, size=int(n), dtype=np.int64)


def _near_boxes(
    origins: NDArray[np.float64], cell: float, boxes: Sequence[Box], clearance: float
) -> NDArray[np.bool_]:
    """Cells any point of which may lie within ``clearance`` of a box footprint."""
    # A cell's points are within cell * sqrt(2) / 2 of its centre.
    reach = clearance + cell * math.sqrt(0.5)
    return footprint_distances(origins + cell / 2.0, boxes) <= reach


# -- point edits -------------------------------------------------------------------------------


def _indices(values: Any, name: str) -> NDArray[np.intp]:
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"{name} cannot be converted to an array: {error}") from None
    if array.size == 0:
        return np.empty(0, dtype=np.intp)
    if array.ndim != 1 or not np.issubdtype(array.dtype, np.integer) or array.min() < 0:
        raise InvalidArgument(f"{name} must be a 1-D list of non-negative ints")
    return array.astype(np.intp)


def _check_in_cloud(indices: NDArray[np.intp], frame: Frame, name: str) -> None:
    if not isinstance(frame, Frame):
        raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
    if len(indices) and indices.max() >= len(frame.cloud):
        raise InvalidArgument(
            f"{name} holds index {int(indices.max())} but the frame has {len(frame.cloud)} points"
        )


@dataclass(frozen=True, eq=False)
class DropPoints:
    """Remove the points at ``indices`` (repeats are fine)."""

    indices: NDArray[np.intp]

    def __post_init__(self) -> None:
        object.__setattr__(self, "indices", _indices(self.indices, "indices"))

    def apply(self, frame: Frame) -> Frame:
        _check_in_cloud(self.indices, frame, "DropPoints.indices")
        keep = np.ones(len(frame.cloud), dtype=bool)
        keep[self.indices] = False
        return frame.with_cloud(frame.cloud[keep])

    def params(self) -> dict[str, Any]:
        # The object itself, so the engine can reduce a violating drop to the few that matter.
        return {"dropped": len(np.unique(self.indices)), "drop_points": self}

    def __repr__(self) -> str:
        return f"DropPoints({_short_list(self.indices)})"


@dataclass(frozen=True, eq=False)
class DuplicatePoints:
    """Append copies of the points at ``indices`` to the end of the cloud."""

    indices: NDArray[np.intp]

    def __post_init__(self) -> None:
        object.__setattr__(self, "indices", _indices(self.indices, "indices"))

    def apply(self, frame: Frame) -> Frame:
        _check_in_cloud(self.indices, frame, "DuplicatePoints.indices")
        copies = frame.cloud[self.indices]
        return frame.with_cloud(PointCloud.concatenate([frame.cloud, copies]))

    def params(self) -> dict[str, Any]:
        return {"duplicated": len(self.indices), "duplicate_points": self}

    def __repr__(self) -> str:
        return f"DuplicatePoints({_short_list(self.indices)})"


@dataclass(frozen=True)
class PermutePoints:
    """Reorder all points by a permutation drawn from ``numpy.random.default_rng(seed)``."""

    seed: int

    def __post_init__(self) -> None:
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, (int, np.integer))
            or self.seed < 0
        ):
            raise InvalidArgument(f"seed={self.seed!r} must be a non-negative int")

    def order(self, n: int) -> NDArray[np.intp]:
        """The permutation applied to a cloud of ``n`` points."""
        return np.random.default_rng(int(self.seed)).permutation(n)

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        return frame.with_cloud(frame.cloud[self.order(len(frame.cloud))])

    def params(self) -> dict[str, Any]:
        return {"permutation_seed": int(self.seed)}


@dataclass(frozen=True)
class RotateAboutSensor:
    """Turn the cloud, the ROI and the boxes by ``theta`` radians about the sensor's z axis."""

    theta: float

    def __post_init__(self) -> None:
        if isinstance(self.theta, bool) or not isinstance(self.theta, (int, float)):
            raise InvalidArgument(f"theta={self.theta!r} must be a number of radians")
        if not math.isfinite(self.theta):
            raise InvalidArgument(f"theta={self.theta!r} must be finite")
        object.__setattr__(self, "theta", float(self.theta))

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        c, s = math.cos(self.theta), math.sin(self.theta)
        xyz = frame.cloud.points[:, :3].astype(np.float64)
        points = frame.cloud.points.copy()
        points[:, 0] = c * xyz[:, 0] - s * xyz[:, 1]
        points[:, 1] = s * xyz[:, 0] + c * xyz[:, 1]
        roi = frame.roi
        if roi is not None:
            rotate = getattr(roi, "rotated", None)
            if not callable(rotate):
                raise InvalidArgument(f"the frame's roi ({type(roi).__name__}) has no rotated()")
            roi = rotate(self.theta)
        return dataclasses.replace(
            frame,
            cloud=frame.cloud.with_points(points),
            roi=roi,
            boxes=tuple(box.rotated(self.theta) for box in frame.boxes),
        )

    def params(self) -> dict[str, Any]:
        return {"theta_deg": round(math.degrees(self.theta), 6)}


def _short_list(values: NDArray[np.intp]) -> str:
    shown = ", ".join(str(v) for v in values[:_SHOWN_POINTS])
    more = f", ... {len(values) - _SHOWN_POINTS} more" if len(values) > _SHOWN_POINTS else ""
    return f"[{shown}{more}]"
