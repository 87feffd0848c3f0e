"""Injected points: MR1 noise outside the ROI, and points inside it away from obstacles.

* :class:`NoiseOutsideROI` - the paper's MR1 recipe (Zhou & Sun, CACM 2019): n points with
  (x, y) uniform over the sensor's range *outside* the ROI, z uniform in the frame's
  [min z, max z], intensity uniform in the frame's [min, max] intensity. "Outside" holds
  for the exact polygons and for Apollo's 0.25 m bitmap, with at least one free cell
  between every injected point and every set cell.
* :class:`NoiseInsideROI` - points inside the ROI (both methods) and away from obstacles.
* :class:`PreparedNoise` - what every follow-up of one frame shares (the allowed cells, the
  frame's z and intensity ranges), so that each follow-up costs only its own points.

Sampling is exact: a cell is chosen uniformly among the allowed cells that reach into the
sensor's range, a position uniformly within it, and positions beyond the range are redrawn
from the next hash values of the same seed (rejection).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.followups.perturb.edits import SHOWN_ITEMS
from pytest_metamorphic.lidar.followups.perturb.seeds import (
    _as_seeds,
    _draw_seeds,
    seeded_uniforms,
)
from pytest_metamorphic.lidar.model.cloud import PointCloud, column_bounds
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, footprint_distances
from pytest_metamorphic.lidar.roi import ROI, CellSet

__all__ = [
    "NOISE_INSTANCE",
    "PAPER_NOISE_SIZES",
    "NoiseInsideROI",
    "NoiseOutsideROI",
    "PreparedNoise",
    "append_points",
]

PAPER_NOISE_SIZES = (10, 100, 1000)
"""The numbers of noise points Zhou & Sun added per follow-up."""

NOISE_INSTANCE = -3
"""``instance`` field value given to injected points (see
:mod:`pytest_metamorphic.lidar.synthetic`)."""

_MAX_ATTEMPTS = 64
# Hash counters: position attempts use 0 .. 3 * _MAX_ATTEMPTS - 1, then z and intensity.
_Z_COUNTER = 3 * _MAX_ATTEMPTS
_INTENSITY_COUNTER = _Z_COUNTER + 1
# The first attempt's three values and z and intensity come from one hash of all seeds
# (each value depends only on its seed and counter, so nothing changes).
_FIRST_COUNTERS = np.array([0, 1, 2, _Z_COUNTER, _INTENSITY_COUNTER])
_TRIPLE = np.arange(3)

_P = TypeVar("_P", bound="_InjectedPoints")


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


@dataclass(frozen=True, eq=False)
class PreparedNoise(Generic[_P]):
    """One frame's noise recipe, ready to turn seeds into points.

    What every follow-up of a frame shares: the allowed cells, the sensor's range and the
    frame's z and intensity ranges (one pass over the sweep, as long as placing a thousand
    points). Build it with ``NoiseOutsideROI.prepare(frame, ...)`` (or
    ``NoiseInsideROI.prepare``) once per source frame, then call :meth:`from_seeds` or
    :meth:`sample` per follow-up; the points are those ``from_seeds(frame, seeds, ...)``
    gives. The strategies and relations of this library do so.

    Attributes
    ----------
    noise_type : type
      :class:`NoiseOutsideROI` or :class:`NoiseInsideROI`, what :meth:`from_seeds` returns.
    cells : CellSet
      Where points may go.
    cell_size, max_range : float
      The ROI bitmap's cell size and the sensor's range, in metres.
    z_range, intensity_range : (float, float)
      The frame's lowest and highest z and intensity.
    where : str
      The region in words, for errors ("outside the ROI").
    """

    noise_type: type[_P]
    cells: CellSet
    cell_size: float
    max_range: float
    z_range: tuple[float, float]
    intensity_range: tuple[float, float]
    where: str

    @classmethod
    def _of(
        cls,
        noise_type: type[_P],
        frame: Frame,
        cells: CellSet,
        region: ROI,
        limit: float,
        where: str,
    ) -> PreparedNoise[_P]:
        z_range, intensity_range = _frame_ranges(frame)
        return cls(noise_type, cells, region.cell_size, limit, z_range, intensity_range, where)

    def from_seeds(self, seeds: ArrayLike) -> _P:
        """The points for one integer seed each (deterministic).

        Parameters
        ----------
        seeds : (n,) array_like of int in [0, 2**32)
        """
        return self.noise_type(_place_points(_as_seeds(seeds), self))

    def sample(self, n: int, *, rng: np.random.Generator) -> _P:
        """``n`` points with seeds drawn from a numpy generator (campaign mode)."""
        return self.from_seeds(_draw_seeds(n, rng))


def _place_points(seeds: NDArray[np.int64], noise: PreparedNoise[Any]) -> NDArray[np.float32]:
    """Map seeds to (n, 4) points: uniform in the allowed cells within the range."""
    n = len(seeds)
    points = np.empty((n, 4), dtype=np.float32)
    if n == 0:
        return points
    if len(noise.cells) == 0:
        raise DataError(f"there is no room {noise.where} within {noise.max_range} m of the sensor")
    first = seeded_uniforms(seeds, _FIRST_COUNTERS)
    xy, beyond = _candidates(first, noise)
    # Most cells lie wholly within range: redraw only the few positions beyond it (the
    # first attempt keeps its candidates in place instead of scattering them).
    pending = np.flatnonzero(beyond)
    for attempt in range(1, _MAX_ATTEMPTS):
        if len(pending) == 0:
            break
        candidate, beyond = _candidates(
            seeded_uniforms(seeds[pending], 3 * attempt + _TRIPLE), noise
        )
        kept = ~beyond
        xy[pending[kept]] = candidate[kept]
        pending = pending[beyond]
    if len(pending):
        raise DataError(
            f"could not place {len(pending)} point(s) {noise.where} in {_MAX_ATTEMPTS} "
            "attempts (the allowed region is almost entirely beyond max_range)"
        )
    (z_low, z_high), (i_low, i_high) = noise.z_range, noise.intensity_range
    points[:, :2] = xy
    points[:, 2] = z_low + first[:, 3] * (z_high - z_low)
    points[:, 3] = i_low + first[:, 4] * (i_high - i_low)
    return points


def _candidates(
    u: NDArray[np.float64], noise: PreparedNoise[Any]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """(m, 2) positions for (m, >= 3) uniforms (cell, x and y within it), and which lie
    beyond the sensor's range."""
    count = len(noise.cells)
    cell = (u[:, 0] * count).astype(np.intp)
    np.minimum(cell, count - 1, out=cell)
    xy = noise.cells.origins(cell)
    xy += u[:, 1:3] * noise.cell_size
    x, y = xy[:, 0], xy[:, 1]
    return xy, x * x + y * y > noise.max_range**2


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

    # Each subclass's classmethod ``prepare(frame, **its own options)``; declared this way
    # because the options differ (a method here would make them incompatible).
    prepare: ClassVar[Callable[..., PreparedNoise[Any]]]

    @classmethod
    def from_seeds(cls: type[_P], frame: Frame, seeds: ArrayLike, **options: Any) -> _P:
        """The points for one integer seed each (deterministic).

        Parameters
        ----------
        frame : Frame
          Gives the z and intensity ranges, and the ROI unless ``roi`` is passed.
        seeds : (n,) array_like of int in [0, 2**32)
        **options
          As for :meth:`prepare` (``roi``, ``max_range``, ``margin_cells``, ...). Many
          follow-ups of one frame: ``prepare`` it once, then call its ``from_seeds``.
        """
        drawn: _P = cls.prepare(frame, **options).from_seeds(seeds)
        return drawn

    @classmethod
    def sample(
        cls: type[_P], frame: Frame, n: int, *, rng: np.random.Generator, **options: Any
    ) -> _P:
        """``n`` points with seeds drawn from a numpy generator (campaign mode); ``options``
        as for :meth:`prepare`."""
        return cls.from_seeds(frame, _draw_seeds(n, rng), **options)

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
            f"({x:.2f}, {y:.2f}, {z:.2f}, {i:.2f})" for x, y, z, i in self.points[:SHOWN_ITEMS]
        )
        more = f", ... {len(self) - SHOWN_ITEMS} more" if len(self) > SHOWN_ITEMS else ""
        return f"{type(self).__name__}(n={len(self)}: [{shown}{more}])"


@dataclass(frozen=True, eq=False, repr=False)
class NoiseOutsideROI(_InjectedPoints):
    """MR1 noise: points outside the ROI (exact and rasterised), appended to the frame."""

    kind = "noise_outside_roi"

    @classmethod
    def prepare(
        cls,
        frame: Frame,
        *,
        roi: ROI | None = None,
        max_range: float = 120.0,
        margin_cells: int = 1,
    ) -> PreparedNoise[NoiseOutsideROI]:
        """The frame's noise recipe, for :meth:`from_seeds` or many follow-ups.

        Parameters
        ----------
        frame : Frame
          Gives the z and intensity ranges, and the ROI unless ``roi`` is passed.
        roi : ROI, optional
          Defaults to ``frame.roi``.
        max_range : float
          The sensor's range in metres (HDL-64E: 120); (x, y) are uniform over the disk
          of this radius minus the ROI and its ``margin_cells`` border. At most the ROI's
          ``raster_range``.
        margin_cells : int
          Free cells kept between injected points and the ROI (>= 1).

        Raises
        ------
        InvalidArgument, DataError
          Now, what :meth:`from_seeds` would raise for any seeds: no ROI, a bad range or
          margin, an empty frame.
        """
        region = _frame_roi(frame, roi)
        limit = _check_range(region, max_range, margin_cells)
        cells = region.cells("free", margin_cells=int(margin_cells), max_range=limit)
        return PreparedNoise._of(cls, frame, cells, region, limit, "outside the ROI")


@dataclass(frozen=True, eq=False, repr=False)
class NoiseInsideROI(_InjectedPoints):
    """Points inside the ROI (both methods), away from the obstacles, appended to the frame."""

    kind = "noise_inside_roi"

    @classmethod
    def prepare(
        cls,
        frame: Frame,
        *,
        roi: ROI | None = None,
        obstacles: Sequence[Box] | None = None,
        clearance: float = 1.0,
        max_range: float = 120.0,
        margin_cells: int = 1,
    ) -> PreparedNoise[NoiseInsideROI]:
        """The frame's recipe: points uniform over the ROI's interior cells that are
        ``clearance`` m from every box.

        z and intensity follow the MR1 recipe (uniform over the frame's ranges).
        ``obstacles`` defaults to the frame's ground-truth boxes; other options as for
        :meth:`NoiseOutsideROI.prepare`.
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
        return PreparedNoise._of(cls, frame, cells, region, limit, where)


def _near_boxes(
    origins: NDArray[np.float64], cell: float, boxes: Sequence[Box], clearance: float
) -> NDArray[np.bool_]:
    """Cells any point of which may lie within ``clearance`` of a box footprint."""
    # A cell's points are within cell * sqrt(2) / 2 of its centre.
    reach = clearance + cell * math.sqrt(0.5)
    return footprint_distances(origins + cell / 2.0, boxes) <= reach
