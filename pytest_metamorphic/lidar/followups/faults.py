"""Sensor faults of a spinning LiDAR as follow-up transforms: beams missing, a packet lost,
a coarser range resolution.

A real sensor loses whole lasers (a dead channel, a dirty window segment) and whole
packets (an Ethernet drop takes one azimuth block of every laser). Both need the sensor
(:mod:`pytest_metamorphic.lidar.model.sensors`): which laser (ring) fired each point, and
how wide a packet is. Recorded PCD/bag clouds usually carry a laser field (``ring``,
``channel``, ...); KITTI's ``.bin`` sweeps do not, but store points laser by laser in
firing order, from which the ring is recovered exactly; rendered scenes carry it; other
clouds are matched to a catalogue sensor by their elevations, or the lasers are unknown
and a relation that needs them says so.

:class:`DropRings` is :class:`~pytest_metamorphic.core.perturbation.Reducible` over the
missing rings: a violation reduces to the fewest beams whose loss still fails.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.model.obstacles import (
    LABELS,
    Box,
    Label,
    as_boxes,
    points_in_boxes,
    share_inside,
)
from pytest_metamorphic.lidar.model.sensors import (
    RING_FIELDS,
    estimate_sensor,
    frame_sensor,
    ring_field,
)
from pytest_metamorphic.lidar.model.sensors.identify import (
    rings_from_elevation,
    rings_from_scan_order,
)

__all__ = [
    "PACKET_DEGREES",
    "QUANTIZATION_RANGE",
    "CoveredObstaclesKept",
    "DropAzimuthBlock",
    "DropRings",
    "QuantizeRange",
    "RingMethod",
    "derive_rings",
]

RingMethod = Literal["auto", "field", "scan_order", "elevation"]
PACKET_DEGREES = 1.04
"""Azimuth covered by one HDL-64E data packet at 10 Hz (6 firings of 0.1728 degrees);
other sensors' packets: ``BeamLayout.packet_degrees``."""
_METHODS = ("auto", "field", "scan_order", "elevation")


def _azimuth(xyz: NDArray[np.float32]) -> NDArray[np.float64]:
    """Azimuth in [0, 2π), counter-clockwise from +x."""
    return np.mod(np.arctan2(xyz[:, 1].astype(np.float64), xyz[:, 0]), 2 * math.pi)


def derive_rings(
    cloud: PointCloud, *, layout: BeamLayout | None = None, method: RingMethod = "auto"
) -> NDArray[np.int64]:
    """The laser (ring) of every point of ``cloud``.

    Parameters
    ----------
    cloud : PointCloud
    layout : BeamLayout, optional
        The sensor, when known; otherwise it is identified
        (:func:`~pytest_metamorphic.lidar.model.sensors.estimate_sensor`).
    method : {"auto", "field", "scan_order", "elevation"}
        ``"field"``: the cloud's laser field under any of the names drivers use
        (``ring``, ``channel``, ``laser_id``, ...: the driver's own numbering).
        ``"scan_order"``: recovered from the storage order of a sweep stored laser by
        laser (KITTI's ``.bin``; exact when it applies). ``"elevation"``: the nearest beam
        of the sensor by elevation angle (exact for scenes rendered with it; a real unit's
        own calibration differs: on a shuffled KITTI sweep it is off by 2 rings at the
        median, 10 at most). ``"auto"``: the first that applies, in that order, and
        ``"elevation"`` only for a sensor given or identified with confidence.

    Returns
    -------
    rings : (n,) int64

    Raises
    ------
    InvalidArgument
        The method does not apply to this cloud, or the lasers cannot be known (no laser
        field, not stored laser by laser, and no sensor fits the elevations): the message
        says which.
    """
    if not isinstance(cloud, PointCloud):
        raise InvalidArgument(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    if method not in _METHODS:
        raise InvalidArgument(f"method={method!r} must be one of {list(_METHODS)}")
    if layout is not None and not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout or None")
    if method == "auto":
        estimate = estimate_sensor(cloud, sensor=layout)
        if estimate.rings is None:
            raise InvalidArgument(
                f"the lasers of this cloud cannot be known: {estimate.describe()}"
            )
        return estimate.rings
    if method == "field":
        name = ring_field(cloud)
        if name is None:
            raise InvalidArgument(f"the cloud has no laser field (any of {list(RING_FIELDS)})")
        return np.asarray(cloud.fields[name]).astype(np.int64)
    sensor = layout if layout is not None else estimate_sensor(cloud).sensor
    if method == "scan_order":
        lasers = sensor.lasers if isinstance(sensor, BeamLayout) else HDL64E.lasers
        rings = rings_from_scan_order(cloud.xyz, lasers)
        if rings is None:
            raise InvalidArgument(
                "the cloud is not stored laser by laser in firing order "
                f"(expected {lasers} revolutions of rising azimuth); use "
                "method='elevation' or a cloud with a ring field"
            )
        return rings
    if not isinstance(sensor, BeamLayout):
        raise InvalidArgument(
            "method='elevation' needs the sensor: pass layout=, or a frame whose sensor is known"
        )
    return rings_from_elevation(cloud.xyz, sensor)


def _ring_list(rings: Any, lasers: int | None) -> tuple[int, ...]:
    try:
        values = [int(r) for r in rings]
    except (TypeError, ValueError):
        raise InvalidArgument(f"rings={rings!r} must be a sequence of ring numbers") from None
    upper = 65535 if lasers is None else lasers - 1
    if any(isinstance(r, bool) for r in rings) or not all(0 <= r <= upper for r in values):
        raise InvalidArgument(f"rings={rings!r} must be ring numbers in [0, {upper}]")
    return tuple(sorted(set(values)))


@dataclass(frozen=True)
class DropRings:
    """Remove every return of the lasers ``rings`` (dead channels).

    Parameters
    ----------
    rings : sequence of int
        Laser numbers, repeats ignored; kept as a sorted tuple. With a laser field they
        are the field's values (the driver's numbering: Velodyne's and nebula's count from
        the lowest beam, Ouster's from the highest); otherwise 0 is the lowest beam.
    layout : BeamLayout, optional
        The sensor; default: the frame's (given, or identified from its cloud).
    method : str
        How rings are found (see :func:`derive_rings`).
    """

    rings: Sequence[int]  # a list is fine; __post_init__ stores a sorted tuple
    layout: BeamLayout | None = None
    method: RingMethod = "auto"

    def __post_init__(self) -> None:
        if self.layout is not None and not isinstance(self.layout, BeamLayout):
            raise InvalidArgument(f"layout={self.layout!r} must be a BeamLayout or None")
        lasers = None if self.layout is None else self.layout.lasers
        object.__setattr__(self, "rings", _ring_list(self.rings, lasers))

    def __len__(self) -> int:
        return len(self.rings)

    def restrict(self, indices: Sequence[int]) -> DropRings:
        return DropRings(tuple(self.rings[i] for i in indices), self.layout, self.method)

    def kept(self, frame: Frame) -> NDArray[np.bool_]:
        """Which points of ``frame`` survive."""
        if self.layout is None and self.method == "auto":
            estimate = frame_sensor(frame)
            if estimate.rings is None:
                raise InvalidArgument(
                    f"the lasers of {frame!r} cannot be known: {estimate.describe()}"
                )
            rings = estimate.rings
        else:
            rings = derive_rings(frame.cloud, layout=self.layout, method=self.method)
        return ~np.isin(rings, self.rings)

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        return frame.with_cloud(frame.cloud[self.kept(frame)])

    def params(self) -> dict[str, Any]:
        return {"missing_rings": list(self.rings), "drop_rings": self}

    def describe_elements(self, limit: int) -> list[str]:
        return [f"ring {ring}" for ring in self.rings[:limit]]

    def __repr__(self) -> str:
        return f"DropRings({list(self.rings)})"


@dataclass(frozen=True)
class DropAzimuthBlock:
    """Remove every return whose azimuth lies in ``[start, start + width)`` (a lost packet:
    one block of firings of every laser).

    Parameters
    ----------
    start : float
        Radians, counter-clockwise from +x (the car's forward axis).
    width : float
        Radians, in (0, 2π). An HDL-64E packet holds 6 firings of all lasers at 10 Hz,
        about 1.04 degrees.
    """

    start: float
    width: float

    def __post_init__(self) -> None:
        for name in ("start", "width"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                raise InvalidArgument(f"{name}={value!r} must be a number (radians)")
            if not math.isfinite(value):
                raise InvalidArgument(f"{name}={value!r} must be finite")
        if not 0 < self.width < 2 * math.pi:
            raise InvalidArgument(f"width={self.width!r} must be in (0, 2π) radians")
        object.__setattr__(self, "start", float(self.start) % (2 * math.pi))
        object.__setattr__(self, "width", float(self.width))

    def kept(self, frame: Frame) -> NDArray[np.bool_]:
        offset = np.mod(_azimuth(frame.cloud.xyz) - self.start, 2 * math.pi)
        return offset >= self.width

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        return frame.with_cloud(frame.cloud[self.kept(frame)])

    def params(self) -> dict[str, Any]:
        return {
            "lost_block_start_deg": round(math.degrees(self.start), 3),
            "lost_block_width_deg": round(math.degrees(self.width), 3),
        }


#: Range steps (metres) that :func:`~pytest_metamorphic.strategies.quantized_ranges` draws
#: from by default: 5-20 cm, in whole millimetres (a 16-bit range field at 2-4 mm is
#: KITTI's; 5-20 cm is a cheap sensor's or a compressed recording's).
QUANTIZATION_RANGE: tuple[float, float] = (0.05, 0.2)


@dataclass(frozen=True)
class QuantizeRange:
    """Round every return's range to a multiple of ``step`` metres, along its beam (a
    coarser range resolution: a cheaper sensor, or a driver packing ranges into fewer
    bits; the HDL-64E reports 2 mm steps with 2 cm noise).

    Parameters
    ----------
    step : float
        Metres, in (0, 1].
    """

    step: float

    def __post_init__(self) -> None:
        value = self.step
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
            raise InvalidArgument(f"step={value!r} must be a number of metres in (0, 1]")
        if not (math.isfinite(value) and 0 < value <= 1):
            raise InvalidArgument(f"step={value!r} must be a number of metres in (0, 1]")
        object.__setattr__(self, "step", float(value))

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        points = frame.cloud.points.copy()
        xyz = points[:, :3].astype(np.float64)
        ranges = np.linalg.norm(xyz, axis=1)
        rounded = np.maximum(np.round(ranges / self.step), 1.0) * self.step
        scale = np.divide(rounded, ranges, out=np.ones_like(ranges), where=ranges > 0)
        points[:, :3] = (xyz * scale[:, None]).astype(np.float32)
        return frame.with_cloud(frame.cloud.with_points(points))

    def params(self) -> dict[str, Any]:
        return {"range_step_m": self.step, "quantize_range": self}


# -- what a fault must leave intact ---------------------------------------------------------


def _frames(context: CheckContext) -> tuple[Frame, Frame]:
    frames = (context.source_input, context.followup_input)
    if not all(isinstance(frame, Frame) for frame in frames):
        raise InvalidArgument("the coverage check needs Frame inputs on both sides")
    return frames


def _count(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InvalidArgument(f"{name}={value!r} must be a positive int")
    return value


def _fraction(value: Any, name: str, *, upper: float = 1.0) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name}={value!r} must be a number in [0, {upper:g}]")
    if not (math.isfinite(value) and 0.0 <= value <= upper):
        raise InvalidArgument(f"{name}={value!r} must be a number in [0, {upper:g}]")
    return float(value)


def _labels(labels: Collection[Label]) -> frozenset[Label]:
    if isinstance(labels, str) or not isinstance(labels, Collection):
        raise InvalidArgument(f"labels={labels!r} must be a collection of labels from {LABELS}")
    chosen = frozenset(labels)
    if not chosen or not chosen <= set(LABELS):
        raise InvalidArgument(f"labels={labels!r} must be a non-empty subset of {LABELS}")
    return chosen


class CoveredObstaclesKept(Relation):
    """Every judged source obstacle that the fault leaves *well covered* is still detected.

    Well covered: at least ``min_points`` of the follow-up cloud's points, and at least
    ``min_share`` of the points it had, lie in the source obstacle's box, and they still
    span at least ``min_height_share`` of its points' vertical extent (a fault that takes
    an obstacle's lowest rows takes the ground next to it too, and a detector may then
    fairly read what is left as ground: seen on KITTI, a car at 38 m losing two rings).
    Still detected: at least ``min_detected`` of those remaining points lie in follow-up
    obstacles (boxes grown by 10 cm; any label and any number of them: fewer points may
    turn a car into an unknown object, and a lost packet may cut one in two). Obstacles
    labelled ``unknown`` and those the ``scope`` does not judge are skipped, and with
    ``range_param`` those whose centre lies farther from the sensor than the follow-up's
    ``params[range_param]`` metres (e.g. the visibility in fog).
    """

    def __init__(
        self,
        *,
        min_points: int = 30,
        min_share: float = 0.5,
        min_height_share: float = 0.8,
        min_detected: float = 0.5,
        scope: ScopeLike = "roi",
        range_param: str | None = None,
        labels: Collection[Label] = LABELS,
    ) -> None:
        self.labels = _labels(labels)
        if range_param is not None and not isinstance(range_param, str):
            raise InvalidArgument(f"range_param={range_param!r} must be a params key or None")
        self.range_param = range_param
        self.min_points = _count(min_points, "min_points")
        self.min_share = _fraction(min_share, "min_share")
        self.min_height_share = _fraction(min_height_share, "min_height_share")
        self.min_detected = _fraction(min_detected, "min_detected")
        self.scope: ObstacleScope = as_scope(scope)
        self.name = (
            f"well-covered obstacles kept (>= {min_points} points and >= {min_share:.0%} "
            f"left over >= {min_height_share:.0%} of the height, >= {min_detected:.0%} of "
            f"them still in obstacles; {self.scope.describe()})"
        )

    def covered(
        self,
        boxes: Sequence[Box],
        source: Frame,
        followup: Frame,
        reach: float = math.inf,
        *,
        judged: NDArray[np.bool_] | None = None,
    ) -> list[tuple[int, int, int]]:
        """``(index, points before, points after)`` of the judged boxes left well covered
        (within ``reach`` metres of the sensor); ``judged``: the scope's verdict on
        ``boxes`` when the caller has it already."""
        return [
            (index, before, len(rows))
            for index, before, rows in self._covered_rows(boxes, source, followup, reach, judged)
        ]

    def _covered_rows(
        self,
        boxes: Sequence[Box],
        source: Frame,
        followup: Frame,
        reach: float,
        judged: NDArray[np.bool_] | None,
    ) -> list[tuple[int, int, NDArray[np.intp]]]:
        """Like :meth:`covered`, with the follow-up's rows in each box for the points."""
        if judged is None:
            judged = self.scope.judged(list(boxes), source)
        candidates = [
            index
            for index, box in enumerate(boxes)
            if judged[index]
            and box.label in self.labels
            and math.hypot(box.center[0], box.center[1]) <= reach
        ]
        chosen_boxes = [boxes[index] for index in candidates]
        inside_before = points_in_boxes(source.cloud.xyz, chosen_boxes)
        inside_after = points_in_boxes(followup.cloud.xyz, chosen_boxes)
        chosen = []
        for index, rows_before, rows_after in zip(
            candidates, inside_before, inside_after, strict=True
        ):
            before, after = len(rows_before), len(rows_after)
            if after < self.min_points or after < self.min_share * before:
                continue
            z_before = source.cloud.xyz[rows_before, 2]
            z_after = followup.cloud.xyz[rows_after, 2]
            span = float(z_before.max() - z_before.min())
            if float(z_after.max() - z_after.min()) >= self.min_height_share * span:
                chosen.append((index, before, rows_after))
        return chosen

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source, followup = _frames(context)
        boxes = as_boxes(source_output, "source")
        found = as_boxes(followup_output, "follow-up")
        reach = math.inf
        if self.range_param is not None:
            reach = float(context.params.get(self.range_param, math.inf))
        judged = self.scope.judged(boxes, source)  # once: for coverage and for the picture
        covered = self._covered_rows(boxes, source, followup, reach, judged)
        missing = []
        for index, before, rows in covered:
            share = share_inside(followup.cloud.xyz[rows], found)
            if share < self.min_detected:
                missing.append((index, before, len(rows), share))
        details = {
            "covered": len(covered),
            "judged": len(covered),
            "missing": [boxes[i].describe() for i, *_ in missing],
            "scope": self.scope.describe(),
            # Source indices: what a picture marks as lost, and what it shows as not judged.
            "blamed": [i for i, *_ in missing],
            "unjudged_source": [int(i) for i in np.flatnonzero(~judged)],
        }
        if not missing:
            return Verdict(True, self.name, details=details)
        lines = [
            f"{boxes[i].describe()} lost although its box still holds {after} points after the "
            f"fault ({before} before; {share:.0%} of them in follow-up obstacles)"
            for i, before, after, share in missing
        ]
        return Verdict(False, self.name, "; ".join(lines[:10]), details)
