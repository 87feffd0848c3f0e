"""Road geometry: a centreline with arc-length parametrisation, a width and lanes.

A :class:`RoadGeometry` is the frame every driving scenario lives in. Positions are
given in road coordinates ``(s, d)``: ``s`` the arc length along the centreline (metres
from its first vertex) and ``d`` the signed lateral offset (metres, positive to the left
of the direction of travel). Straight test-track roads and real OSM streets share the
same class, so the simulator and the AEB controller never care which one they are on.

Lanes are numbered from the right edge (lane 0 is the rightmost lane in the direction of
the centreline; right-hand traffic), all equally wide. Strips of the carriageway that are
not traffic lanes (cycle lanes, parking lanes: ``margins``) lie between the kerbs and the
outermost lanes; a parking lane (``parking``, part of the margin) lies at the kerb. Beyond
each kerb a footway (``sidewalks``) or, where none is mapped, a verge.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument

if TYPE_CHECKING:  # pragma: no cover
    from pytest_metamorphic.driving.osm import Road

__all__ = ["RoadGeometry"]


def _margins(value: Any, width: float) -> tuple[float, float]:
    right, left = _strips(value, "margins", None)
    if right + left >= width:
        raise InvalidArgument(
            f"margins={value!r} leave no room for lanes on a {width:g} m carriageway"
        )
    return right, left


def _strips(value: Any, name: str, limit: tuple[float, float] | None) -> tuple[float, float]:
    """A ``(right, left)`` pair of widths >= 0, each at most ``limit``'s when given."""
    try:
        right, left = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InvalidArgument(
            f"{name}={value!r} must be a (right, left) pair of widths in metres"
        ) from None
    if not (math.isfinite(right) and math.isfinite(left) and right >= 0 and left >= 0):
        raise InvalidArgument(f"{name}={value!r} must be finite widths >= 0")
    if limit is not None and (right > limit[0] + 1e-9 or left > limit[1] + 1e-9):
        raise InvalidArgument(
            f"{name}={value!r}: a parking lane is part of the margin on its side, margins={limit!r}"
        )
    return right, left


def _positive(value: Any, name: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidArgument(f"{name}={value!r} must be a positive number") from None
    if not math.isfinite(number) or number <= 0:
        raise InvalidArgument(f"{name}={value!r} must be a positive finite number")
    return number


@dataclass(frozen=True, eq=False)
class RoadGeometry:
    """A road: centreline polyline, constant width and lane count.

    Parameters
    ----------
    centerline : (k, 2) float
        Vertices in metres, k >= 2, consecutive vertices distinct. The direction of travel
        of lane 0 is from the first vertex to the last.
    width : float
        Carriageway width in metres (> 0).
    lanes : int
        Traffic lanes across the carriageway (>= 1), equally wide.
    name : str
        Shown in reports ("Euro NCAP straight road", "Goethestraße", ...).
    margins : (float, float)
        Widths in metres of the strips between the right / left kerb and the outermost
        traffic lane (cycle lanes, parking lanes; default none). They are part of the
        carriageway (a pedestrian there is on the road) but no lane.
    parking : (float, float)
        Widths of the parking lanes among the margins, at the right / left kerb (default
        none): where parked cars stand.
    sidewalks : (float, float)
        Widths of the footways beyond the right / left kerb (default none: a verge).

    Notes
    -----
    Outside ``[0, length]`` positions extrapolate along the first/last segment, so an
    actor may start a little before the road's first vertex.
    """

    centerline: NDArray[np.float64]
    width: float
    lanes: int = 1
    name: str = ""
    margins: tuple[float, float] = (0.0, 0.0)
    parking: tuple[float, float] = (0.0, 0.0)
    sidewalks: tuple[float, float] = (0.0, 0.0)
    # Derived in __post_init__: segments as arrays (vectorised queries) and as lists (the
    # scalar fast path of point_at).
    _seg_start: NDArray[np.float64] = field(init=False, repr=False)
    _seg_dir: NDArray[np.float64] = field(init=False, repr=False)
    _seg_len: NDArray[np.float64] = field(init=False, repr=False)
    _cum: NDArray[np.float64] = field(init=False, repr=False)
    _cum_list: list[float] = field(init=False, repr=False)
    _start_list: list[tuple[float, float]] = field(init=False, repr=False)
    _dir_list: list[tuple[float, float]] = field(init=False, repr=False)
    _cum_start: list[float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        points = np.array(self.centerline, dtype=np.float64, copy=True)
        if points.ndim != 2 or points.shape[1] != 2 or len(points) < 2:
            raise InvalidArgument(
                f"centerline must have shape (k, 2) with k >= 2, got {points.shape}"
            )
        if not np.isfinite(points).all():
            raise InvalidArgument("centerline contains NaN or infinite coordinates")
        segments = np.diff(points, axis=0)
        seg_len = np.linalg.norm(segments, axis=1)
        if (seg_len <= 1e-9).any():
            index = int(np.flatnonzero(seg_len <= 1e-9)[0])
            raise InvalidArgument(
                f"centerline vertices {index} and {index + 1} coincide; remove duplicates"
            )
        width = _positive(self.width, "width")
        if isinstance(self.lanes, bool) or not isinstance(self.lanes, (int, np.integer)):
            raise InvalidArgument(f"lanes={self.lanes!r} must be an int >= 1")
        if self.lanes < 1:
            raise InvalidArgument(f"lanes={self.lanes} must be >= 1")
        margins = _margins(self.margins, width)
        object.__setattr__(self, "parking", _strips(self.parking, "parking", margins))
        object.__setattr__(self, "sidewalks", _strips(self.sidewalks, "sidewalks", None))
        points.setflags(write=False)
        object.__setattr__(self, "margins", margins)
        object.__setattr__(self, "centerline", points)
        object.__setattr__(self, "width", width)
        object.__setattr__(self, "lanes", int(self.lanes))
        cumulative = np.concatenate([[0.0], np.cumsum(seg_len)])
        object.__setattr__(self, "_seg_start", points[:-1])
        object.__setattr__(self, "_seg_dir", segments / seg_len[:, None])
        object.__setattr__(self, "_seg_len", seg_len)
        object.__setattr__(self, "_cum", cumulative)
        # Plain-float copies for the simulator's per-step scalar queries (numpy's per-call
        # overhead dominates on one point at a time).
        object.__setattr__(self, "_cum_list", cumulative[1:-1].tolist())
        object.__setattr__(self, "_start_list", [tuple(p) for p in points[:-1].tolist()])
        object.__setattr__(
            self, "_dir_list", [tuple(u) for u in (segments / seg_len[:, None]).tolist()]
        )
        object.__setattr__(self, "_cum_start", cumulative[:-1].tolist())

    # -- construction --------------------------------------------------------------------
    @classmethod
    def straight(
        cls,
        *,
        length: float = 300.0,
        width: float = 10.0,
        lanes: int = 1,
        heading: float = 0.0,
        origin: Sequence[float] = (0.0, 0.0),
        name: str = "",
        margins: tuple[float, float] = (0.0, 0.0),
        parking: tuple[float, float] = (0.0, 0.0),
        sidewalks: tuple[float, float] = (0.0, 0.0),
    ) -> RoadGeometry:
        """A straight road of any width, from ``origin`` along ``heading`` (radians)."""
        length = _positive(length, "length")
        start = np.asarray(origin, dtype=np.float64)
        if start.shape != (2,) or not np.isfinite(start).all():
            raise InvalidArgument(f"origin={origin!r} must be a finite (x, y) pair")
        if not math.isfinite(heading):
            raise InvalidArgument(f"heading={heading!r} must be finite")
        direction = np.array([math.cos(heading), math.sin(heading)])
        label = name or f"straight {float(width):g} m road"
        return cls(
            np.stack([start, start + length * direction]), width, lanes, label, margins,
            parking, sidewalks,
        )  # fmt: skip

    @classmethod
    def from_osm(
        cls,
        road: Road,
        *,
        width: float | None = None,
        lanes: int | None = None,
        margins: tuple[float, float] | None = None,
    ) -> RoadGeometry:
        """The geometry of an OSM :class:`~pytest_metamorphic.driving.osm.Road`.

        ``width``/``lanes``/``margins`` override the values read from its tags.
        """
        return cls(
            road.centerline,
            road.width if width is None else width,
            road.lanes if lanes is None else lanes,
            road.name or f"way {road.way_id}",
            road.margins if margins is None else margins,
            road.parking if margins is None else (0.0, 0.0),
            road.sidewalks,
        )

    # -- measures ------------------------------------------------------------------------
    @property
    def length(self) -> float:
        """Arc length of the centreline in metres."""
        return float(self._cum[-1])

    @property
    def lane_width(self) -> float:
        return (self.width - sum(self.margins)) / self.lanes

    def lane_bounds(self, lane: int = 0) -> tuple[float, float]:
        """``(d_right, d_left)`` of a lane (0 = rightmost)."""
        self._check_lane(lane)
        right = -self.width / 2 + self.margins[0] + lane * self.lane_width
        return right, right + self.lane_width

    def lane_center(self, lane: int = 0) -> float:
        """Lateral offset ``d`` of a lane's centre line (0 = rightmost lane)."""
        right, left = self.lane_bounds(lane)
        return (right + left) / 2

    def kerb(self, side: str) -> float:
        """Lateral offset ``d`` of the ``"right"`` or ``"left"`` kerb (carriageway edge)."""
        if side not in ("right", "left"):
            raise InvalidArgument(f"side={side!r} must be 'right' or 'left'")
        return -self.width / 2 if side == "right" else self.width / 2

    def parking_lane(self, side: str) -> tuple[float, float] | None:
        """``(d_low, d_high)`` of the parking lane at the ``side`` kerb, or None."""
        kerb, width = self.kerb(side), self.parking[0 if side == "right" else 1]
        if width <= 0:
            return None
        return (kerb, kerb + width) if side == "right" else (kerb - width, kerb)

    def lane_at(self, d: float) -> int | None:
        """Index of the lane containing lateral offset ``d``, or None outside the lanes
        (off the road, or on a margin)."""
        right = -self.width / 2 + self.margins[0]
        if not right <= d <= self.width / 2 - self.margins[1]:
            return None
        return min(int((d - right) // self.lane_width), self.lanes - 1)

    def _check_lane(self, lane: int) -> None:
        if isinstance(lane, bool) or not isinstance(lane, (int, np.integer)):
            raise InvalidArgument(f"lane={lane!r} must be an int")
        if not 0 <= lane < self.lanes:
            raise InvalidArgument(f"lane={lane} must be in [0, {self.lanes - 1}]")

    # -- arc length -> world -------------------------------------------------------------
    def _segment(self, s: NDArray[np.float64]) -> NDArray[np.intp]:
        index = np.searchsorted(self._cum, s, side="right") - 1
        return np.clip(index, 0, len(self._seg_len) - 1)

    def position(self, s: Any) -> NDArray[np.float64]:
        """Centreline point(s) at arc length ``s``: ``(..., 2)``."""
        s_arr = np.asarray(s, dtype=np.float64)
        index = self._segment(s_arr)
        offset = s_arr - self._cum[index]
        return self._seg_start[index] + offset[..., None] * self._seg_dir[index]

    def tangent(self, s: Any) -> NDArray[np.float64]:
        """Unit direction of travel at ``s``: ``(..., 2)`` (the segment's direction)."""
        return self._seg_dir[self._segment(np.asarray(s, dtype=np.float64))]

    def normal(self, s: Any) -> NDArray[np.float64]:
        """Unit left normal at ``s``: ``(..., 2)``."""
        t = self.tangent(s)
        return np.stack([-t[..., 1], t[..., 0]], axis=-1)

    def heading(self, s: Any) -> NDArray[np.float64] | float:
        """Heading in radians (counter-clockwise from +x) at ``s``."""
        t = self.tangent(s)
        result = np.arctan2(t[..., 1], t[..., 0])
        return float(result) if np.ndim(result) == 0 else result

    def chord_heading(self, s: float, span: float) -> float:
        """Heading of the chord from ``s - span/2`` to ``s + span/2``.

        A vehicle of wheelbase ``span`` following the centreline points along this chord,
        which turns smoothly through polyline corners instead of snapping at the vertex.
        """
        if len(self._start_list) == 1:
            return self.point(s)[2]
        ax, ay, _ = self.point(s - span / 2)
        bx, by, heading = self.point(s + span / 2)
        if math.hypot(bx - ax, by - ay) < 1e-9:
            return heading
        return math.atan2(by - ay, bx - ax)

    def point(self, s: float, d: float = 0.0) -> tuple[float, float, float]:
        """Scalar ``(x, y, heading)`` at road coordinates ``(s, d)`` (fast path, plain floats)."""
        index = bisect.bisect_right(self._cum_list, s)
        (x0, y0), (ux, uy) = self._start_list[index], self._dir_list[index]
        along = s - self._cum_start[index]
        return x0 + along * ux - d * uy, y0 + along * uy + d * ux, math.atan2(uy, ux)

    def to_world(self, s: Any, d: Any) -> NDArray[np.float64]:
        """World point(s) at road coordinates ``(s, d)``: ``(..., 2)``."""
        s_arr, d_arr = np.broadcast_arrays(
            np.asarray(s, dtype=np.float64), np.asarray(d, dtype=np.float64)
        )
        return self.position(s_arr) + d_arr[..., None] * self.normal(s_arr)

    # -- world -> arc length -------------------------------------------------------------
    def to_frenet(self, points: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Road coordinates ``(s, d)`` of world points ``(n, 2)`` (or one ``(2,)`` point).

        The closest point on the centreline gives ``s``; ``d`` is the signed distance to it
        (left positive). Points beyond the ends project onto the extended end segments.
        """
        pts = np.asarray(points, dtype=np.float64)
        single = pts.ndim == 1
        pts = np.atleast_2d(pts)
        if pts.shape[-1] != 2:
            raise InvalidArgument(f"points must have shape (n, 2), got {pts.shape}")
        rel = pts[:, None, :] - self._seg_start[None, :, :]
        along = (rel * self._seg_dir[None]).sum(axis=-1)
        last = len(self._seg_len) - 1
        lo = np.full(len(self._seg_len), 0.0)
        hi = self._seg_len.copy()
        lo[0] = -np.inf  # extrapolate before the first vertex
        hi[last] = np.inf  # and after the last
        clamped = np.clip(along, lo, hi)
        foot = self._seg_start[None] + clamped[..., None] * self._seg_dir[None]
        dist2 = ((pts[:, None, :] - foot) ** 2).sum(axis=-1)
        best = np.argmin(dist2, axis=1)
        rows = np.arange(len(pts))
        s = self._cum[best] + clamped[rows, best]
        direction = self._seg_dir[best]
        offset = pts - foot[rows, best]
        d = direction[:, 0] * offset[:, 1] - direction[:, 1] * offset[:, 0]
        if single:
            return s[0], d[0]
        return s, d

    def contains(self, points: Any) -> NDArray[np.bool_]:
        """Whether world points ``(n, 2)`` lie on the carriageway (within ``width/2``)."""
        s, d = self.to_frenet(points)
        return (np.abs(d) <= self.width / 2) & (s >= 0) & (s <= self.length)

    def describe(self) -> str:
        kind = "straight" if len(self.centerline) == 2 else f"{len(self.centerline)}-vertex"
        label = self.name or "road"
        strips = ""
        if any(self.margins):
            strips = ", margins {:g} / {:g} m".format(*self.margins)
        if any(self.parking):
            strips += " (parking {:g} / {:g} m)".format(*self.parking)
        if any(self.sidewalks):
            strips += ", sidewalks {:g} / {:g} m".format(*self.sidewalks)
        return (
            f"{label} ({kind}, {self.length:.0f} m, {self.width:.2f} m wide, "
            f"{self.lanes} lane(s){strips})"
        )

    def __repr__(self) -> str:
        return f"RoadGeometry({self.describe()})"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        # Hypothesis prints falsifying examples with this instead of every dataclass field.
        printer.text(repr(self))

    def equals(self, other: object) -> bool:
        """Exact equality (used by the engine's determinism check)."""
        return (
            isinstance(other, RoadGeometry)
            and self.width == other.width
            and self.lanes == other.lanes
            and self.margins == other.margins
            and self.parking == other.parking
            and self.sidewalks == other.sidewalks
            and self.name == other.name
            and self.centerline.shape == other.centerline.shape
            and bool((self.centerline == other.centerline).all())
        )
