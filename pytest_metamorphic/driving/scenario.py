"""Euro NCAP AEB pedestrian scenarios (CPNA-25/75, CPNCO-50, CPFA-50, CPLA-25/50) on any road.

The protocol's public parameters (AEB/LSS VRU test protocol v4.5.1, as encoded in
vectorgrp/OSC-NCAP-scenarios): dummy sizes and speeds, the initial lateral distance ``E``
of a crossing dummy from the vehicle path, its acceleration distance ``G``, the impact
position (percent of the car's width, from the side the dummy comes from), the obstruction
vehicles of CPNCO (1 m lateral gap to the car's path, 1 m gaps along it) and the speeds.

A :class:`Scenario` holds *parameters* only (kind, road, ego speed, where the paths
cross, how far away the car starts); the motion of every actor is derived from them, so a
follow-up that changes the ego speed re-synchronises the pedestrian automatically:

* the car drives along the centre of ``ego_lane`` at constant speed until its AEB acts;
* a crossing dummy stands ``E`` metres beside the car's path, accelerates uniformly over
  ``G`` metres to its final speed and then walks on; a longitudinal (CPLA) dummy does the
  same along the lane, ``G`` + 10 m before the collision point;
* the dummy is *synchronised* as in the protocol: without braking, the front bumper reaches
  the dummy exactly when the dummy is at the impact position. Its start time is derived
  from that; when it would be before t = 0, the dummy is already walking at t = 0.
  A follow-up may instead keep the dummy's own timing (``dummy_arrival_time``): a faster
  car then reaches the collision point early, and the dummy can walk into its side.

Road coordinates ``(s, d)`` are those of :class:`~pytest_metamorphic.driving.roads.RoadGeometry`
(left positive). Right-hand traffic: the near side is the right (``d`` below the car's
path), the far side the left.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.placement import crossing_start, parked_lateral
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.vehicle import EURO_NCAP_CAR, TYPICAL_CAR, VehicleSpec

__all__ = [
    "ADULT",
    "CHILD",
    "EURO_NCAP_CAR",
    "KEEP_MODES",
    "KINDS",
    "OBSTRUCTION_LARGE",
    "OBSTRUCTION_SMALL",
    "PLACEMENTS",
    "PROTOCOLS",
    "TYPICAL_CAR",
    "Footprint",
    "Keep",
    "PedestrianMotion",
    "Protocol",
    "Scenario",
    "StaticActor",
    "VehicleSpec",
    "euro_ncap",
    "euro_ncap_road",
]

KMH = 1 / 3.6
Keep = Literal["ego_start", "time", "pedestrian"]
Placement = Literal["protocol", "road"]
#: Where a scenario's actors stand (:attr:`Scenario.placement`).
PLACEMENTS: tuple[str, ...] = ("protocol", "road")
#: What a speed follow-up keeps (:meth:`Scenario.with_ego_speed`).
KEEP_MODES: tuple[str, ...] = ("ego_start", "time", "pedestrian")


@dataclass(frozen=True)
class Footprint:
    """An actor's box: ``length`` along its heading, ``width`` across, ``height``; metres."""

    name: str
    length: float
    width: float
    height: float


#: Euro NCAP pedestrian target dummies (adult EPTa, child EPTc).
ADULT = Footprint("adult", 0.6, 0.5, 1.8)
CHILD = Footprint("child", 0.711, 0.298, 1.154)
#: CPNCO obstruction vehicles (lengths 4.3-4.7 m / 4.1-4.4 m, widths 1.75-1.9 m allowed).
OBSTRUCTION_LARGE = Footprint("obstruction (large)", 4.418, 1.82, 1.5)
OBSTRUCTION_SMALL = Footprint("obstruction (small)", 4.316, 1.78, 1.45)


@dataclass(frozen=True)
class Protocol:
    """Public parameters of one Euro NCAP AEB pedestrian test.

    Attributes
    ----------
    kind : str
        ``"CPNA-25"``, ``"CPNA-75"``, ``"CPNCO-50"``, ``"CPFA-50"``, ``"CPLA-25"``, ``"CPLA-50"``.
    dummy : Footprint
    dummy_speed_kmh : float
    motion : {"near", "far", "longitudinal"}
        Crossing from the near (right) side, from the far (left) side, or walking ahead
        in the car's direction.
    lateral_start : float
        ``E``: initial lateral distance of a crossing dummy from the car's path (m).
    acceleration_distance : float
        ``G``: distance over which the dummy accelerates uniformly to its speed (m).
    steady_distance : float
        CPLA: distance walked at constant speed before the impact (m).
    overlap : float
        Impact position in percent of the car's width, counted from the side the dummy
        comes from (CPLA: from the near side).
    obstructed : bool
        CPNCO: two parked cars hide the dummy.
    speeds_kmh : tuple of int
        The car speeds the protocol tests.
    """

    kind: str
    dummy: Footprint
    dummy_speed_kmh: float
    motion: Literal["near", "far", "longitudinal"]
    lateral_start: float
    acceleration_distance: float
    overlap: float
    obstructed: bool = False
    steady_distance: float = 0.0
    speeds_kmh: tuple[int, ...] = tuple(range(10, 61, 5))


PROTOCOLS: Mapping[str, Protocol] = MappingProxyType(
    {
        "CPNA-25": Protocol("CPNA-25", ADULT, 5.0, "near", 4.0, 1.0, 25.0),
        "CPNA-75": Protocol("CPNA-75", ADULT, 5.0, "near", 4.0, 1.0, 75.0),
        "CPNCO-50": Protocol("CPNCO-50", CHILD, 5.0, "near", 4.0, 1.0, 50.0, obstructed=True),
        "CPFA-50": Protocol("CPFA-50", ADULT, 8.0, "far", 6.0, 1.5, 50.0),
        "CPLA-25": Protocol(
            "CPLA-25", ADULT, 5.0, "longitudinal", 0.0, 1.0, 25.0,
            steady_distance=10.0, speeds_kmh=tuple(range(20, 61, 5)),
        ),
        "CPLA-50": Protocol(
            "CPLA-50", ADULT, 5.0, "longitudinal", 0.0, 1.0, 50.0,
            steady_distance=10.0, speeds_kmh=tuple(range(20, 61, 5)),
        ),
    }
)  # fmt: skip
KINDS: tuple[str, ...] = tuple(PROTOCOLS)
"""The Euro NCAP scenario kinds, in protocol order."""

#: The protocol's initial time to collision: the car starts this far (in time) away.
INITIAL_TTC = 6.0


@dataclass(frozen=True)
class StaticActor:
    """A parked car or other fixed box, in road coordinates (heading along the road)."""

    footprint: Footprint
    s: float
    d: float


@dataclass(frozen=True)
class PedestrianMotion:
    """The derived straight-line motion of a dummy, in road coordinates.

    Position at time ``t``: ``(s0, d0) + walked(t) * (ds, dd)`` where ``(ds, dd)`` is a unit
    direction in road coordinates and ``walked`` is 0 before ``start_time``, then uniform
    acceleration over ``acceleration_distance``, then ``speed``.
    """

    footprint: Footprint
    s0: float
    d0: float
    ds: float
    dd: float
    speed: float
    acceleration_distance: float
    start_time: float

    @property
    def acceleration(self) -> float:
        return self.speed**2 / (2 * self.acceleration_distance)

    @property
    def acceleration_time(self) -> float:
        return 2 * self.acceleration_distance / self.speed

    def walked(self, t: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Distance walked by time ``t`` (vectorised)."""
        tau = np.maximum(np.asarray(t, dtype=np.float64) - self.start_time, 0.0)
        accelerating = tau <= self.acceleration_time
        return np.where(
            accelerating,
            0.5 * self.acceleration * tau**2,
            self.acceleration_distance + self.speed * (tau - self.acceleration_time),
        )

    def velocity(self, t: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Walking speed at ``t`` (vectorised)."""
        tau = np.maximum(np.asarray(t, dtype=np.float64) - self.start_time, 0.0)
        return np.minimum(self.acceleration * tau, self.speed)

    def time_to_walk(self, distance: float) -> float:
        """Time from the start of walking until ``distance`` metres are covered."""
        if distance <= self.acceleration_distance:
            return math.sqrt(2 * distance / self.acceleration)
        return self.acceleration_time + (distance - self.acceleration_distance) / self.speed

    def road_position(
        self, t: NDArray[np.float64] | float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(s, d)`` at time(s) ``t``."""
        u = self.walked(t)
        return self.s0 + u * self.ds, self.d0 + u * self.dd

    @property
    def extent_along_road(self) -> float:
        """The dummy's size along the road (its width when crossing, length when walking along)."""
        return self.footprint.length if abs(self.ds) > 0.5 else self.footprint.width

    @property
    def facing(self) -> float:
        """Heading relative to the road (radians): +-pi/2 crossing, 0 walking along it."""
        return math.copysign(math.pi / 2, self.dd) if abs(self.dd) > 0.5 else 0.0

    @property
    def extent_across_road(self) -> float:
        return self.footprint.width if abs(self.ds) > 0.5 else self.footprint.length


def _finite(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidArgument(f"{name}={value!r} must be a number")
    number = float(value)
    if not math.isfinite(number):
        raise InvalidArgument(f"{name}={value!r} must be finite")
    return number


@dataclass(frozen=True)
class Scenario:
    """One Euro NCAP AEB pedestrian test on a road, as parameters.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    road : RoadGeometry
    ego_speed_kmh : float
        The car's initial (and, without braking, constant) speed.
    conflict_s : float
        Arc length on the road of the collision point: where a crossing dummy's path
        crosses the car's path, or where a CPLA dummy's centre is at the impact.
    ego_distance : float
        Distance (m, along the road) from the car's front bumper at t = 0 to the point
        where, without braking, it touches the dummy. The protocol uses 6 s at the test
        speed (:func:`euro_ncap`).
    ego_lane : int
        The lane the car drives in the centre of (0 = rightmost).
    dummy_speed_kmh : float, optional
        Overrides the protocol's dummy speed.
    vehicle : VehicleSpec
    dummy_arrival_time : float, optional
        When (s after the start) the dummy reaches the impact position. None (the
        protocol): when the unbraked car's bumper does, ``time_to_collision_point``.
    placement : {"protocol", "road"}
        ``"protocol"``: the dummy and the parked cars where the protocol puts them
        relative to the car's path (a test track). ``"road"``: where the road's
        cross-section puts them (:mod:`~pytest_metamorphic.driving.placement`: a crossing
        dummy starts beyond the kerb, parked cars stand in the parking lane).
    """

    kind: str
    road: RoadGeometry
    ego_speed_kmh: float
    conflict_s: float
    ego_distance: float
    ego_lane: int = 0
    dummy_speed_kmh: float | None = None
    vehicle: VehicleSpec = field(default=EURO_NCAP_CAR)
    dummy_arrival_time: float | None = None
    placement: Placement = "protocol"

    def __post_init__(self) -> None:
        if self.kind not in PROTOCOLS:
            raise InvalidArgument(f"kind={self.kind!r} must be one of {list(KINDS)}")
        if not isinstance(self.road, RoadGeometry):
            raise InvalidArgument(f"road={self.road!r} must be a RoadGeometry")
        speed = _finite(self.ego_speed_kmh, "ego_speed_kmh")
        if speed <= 0:
            raise InvalidArgument(f"ego_speed_kmh={self.ego_speed_kmh!r} must be > 0")
        distance = _finite(self.ego_distance, "ego_distance")
        if distance <= 0:
            raise InvalidArgument(f"ego_distance={self.ego_distance!r} must be > 0")
        _finite(self.conflict_s, "conflict_s")
        self.road._check_lane(self.ego_lane)
        if self.dummy_speed_kmh is not None:
            dummy = _finite(self.dummy_speed_kmh, "dummy_speed_kmh")
            if dummy <= 0:
                raise InvalidArgument(f"dummy_speed_kmh={self.dummy_speed_kmh!r} must be > 0")
        if not isinstance(self.vehicle, VehicleSpec):
            raise InvalidArgument(f"vehicle={self.vehicle!r} must be a VehicleSpec")
        if self.dummy_arrival_time is not None:
            arrival = _finite(self.dummy_arrival_time, "dummy_arrival_time")
            if arrival <= 0:
                raise InvalidArgument(
                    f"dummy_arrival_time={self.dummy_arrival_time!r} must be > 0 seconds"
                )
            object.__setattr__(self, "dummy_arrival_time", arrival)
        if self.placement not in PLACEMENTS:
            raise InvalidArgument(f"placement={self.placement!r} must be one of {list(PLACEMENTS)}")
        if self.placement == "road" and self.protocol.obstructed:
            parked_lateral(self.road, OBSTRUCTION_LARGE.width)  # a clear error now, not later
        object.__setattr__(self, "ego_speed_kmh", speed)
        object.__setattr__(self, "ego_distance", distance)
        object.__setattr__(self, "conflict_s", float(self.conflict_s))

    # -- protocol-derived quantities ------------------------------------------------------
    @property
    def protocol(self) -> Protocol:
        return PROTOCOLS[self.kind]

    @property
    def ego_speed(self) -> float:
        """Initial speed in m/s."""
        return self.ego_speed_kmh * KMH

    @property
    def ego_offset(self) -> float:
        """Lateral offset ``d`` of the car's path (the centre of its lane)."""
        return self.road.lane_center(self.ego_lane)

    @property
    def time_to_collision_point(self) -> float:
        """Seconds until the bumper would touch the dummy at constant speed."""
        return self.ego_distance / self.ego_speed

    @property
    def dummy_arrival(self) -> float:
        """When the dummy reaches the impact position (s after the start)."""
        if self.dummy_arrival_time is None:
            return self.time_to_collision_point
        return self.dummy_arrival_time

    @property
    def impact_offset(self) -> float:
        """``H``: impact position relative to the car's centre line, towards the far side."""
        width = self.vehicle.width
        return width * self.protocol.overlap / 100 - width / 2

    @property
    def lateral_start(self) -> float:
        """How far beside the car's path a crossing dummy starts (m): the protocol's ``E``,
        or with ``placement="road"`` the distance to its start beyond the kerb."""
        protocol = self.protocol
        if self.placement == "protocol" or protocol.motion == "longitudinal":
            return protocol.lateral_start
        side = "right" if protocol.motion == "near" else "left"
        return abs(crossing_start(self.road, side) - self.ego_offset)

    @property
    def contact_s(self) -> float:
        """Arc length where the bumper first touches the dummy (no braking)."""
        return self.conflict_s - self.pedestrian().extent_along_road / 2

    @property
    def ego_start_s(self) -> float:
        """Arc length of the front bumper at t = 0."""
        return self.contact_s - self.ego_distance

    def pedestrian(self) -> PedestrianMotion:
        """The dummy's synchronised motion."""
        protocol = self.protocol
        speed = (self.dummy_speed_kmh or protocol.dummy_speed_kmh) * KMH
        lateral_centre = self.ego_offset
        if protocol.motion == "longitudinal":
            walk = protocol.acceleration_distance + protocol.steady_distance
            # CPLA overlap is counted from the near side: 25 % is right of the centre line.
            d0 = lateral_centre + self.vehicle.width * (protocol.overlap - 50) / 100
            s0, ds, dd = self.conflict_s - walk, 1.0, 0.0
        else:
            sign = 1.0 if protocol.motion == "near" else -1.0
            walk = self.lateral_start + self.impact_offset
            s0, ds, dd = self.conflict_s, 0.0, sign
            d0 = lateral_centre - sign * self.lateral_start
        motion = PedestrianMotion(
            protocol.dummy, s0, d0, ds, dd, speed, protocol.acceleration_distance, 0.0
        )
        start = self.dummy_arrival - motion.time_to_walk(walk)
        return dataclasses.replace(motion, start_time=start)

    @property
    def pedestrian_start_time(self) -> float:
        """When the dummy starts walking (negative: it is already walking at t = 0)."""
        return self.pedestrian().start_time

    def obstructions(self) -> tuple[StaticActor, ...]:
        """CPNCO's two parked cars on the near side; empty for the other tests.

        The small car's front is 1 m before the dummy's path, the large car 1 m behind the
        small one, both 1 m (lateral gap) beside the car under test; with
        ``placement="road"`` centred in the near-side parking lane instead.
        """
        if not self.protocol.obstructed:
            return ()
        small, large = OBSTRUCTION_SMALL, OBSTRUCTION_LARGE
        dummy = self.pedestrian()
        if self.placement == "road":
            lateral = parked_lateral(self.road, large.width)
        else:
            lateral = self.ego_offset - (1.0 + self.vehicle.width / 2 + large.width / 2)
        small_front = self.conflict_s - dummy.extent_along_road / 2 - 1.0
        small_s = small_front - small.length / 2
        large_s = small_s - small.length / 2 - 1.0 - large.length / 2
        return (StaticActor(small, small_s, lateral), StaticActor(large, large_s, lateral))

    # -- transforms -----------------------------------------------------------------------
    def with_ego_speed(self, speed_kmh: float, *, keep: Keep = "ego_start") -> Scenario:
        """The same test at another car speed (the speed follow-up).

        Parameters
        ----------
        speed_kmh : float
        keep : {"ego_start", "time", "pedestrian"}
            What stays as in this scenario:

            ``"ego_start"`` (default): the car's start; its time to the collision point
            becomes ``ego_distance / v'`` and the dummy's start moves so that it still
            reaches the impact position at that moment (re-synchronised).
            ``"time"``: the car's time to the collision point (the protocol's 6 s rule);
            its start moves, the dummy is unchanged.
            ``"pedestrian"`` (Iqbal's follow-up: "the pedestrian's start adjusted so [its]
            time to the collision point stays the same"): the car's start *and* the
            dummy's motion; a faster car reaches the collision point before the dummy, a
            slower one after it, so the dummy may walk into the car's side.
        """
        speed = _finite(speed_kmh, "speed_kmh")
        if speed <= 0:
            raise InvalidArgument(f"speed_kmh={speed_kmh!r} must be > 0")
        if keep == "ego_start":
            return dataclasses.replace(self, ego_speed_kmh=speed)
        if keep == "time":
            distance = self.ego_distance * speed / self.ego_speed_kmh
            return dataclasses.replace(self, ego_speed_kmh=speed, ego_distance=distance)
        if keep == "pedestrian":
            return dataclasses.replace(
                self, ego_speed_kmh=speed, dummy_arrival_time=self.dummy_arrival
            )
        raise InvalidArgument(f"keep={keep!r} must be one of {list(KEEP_MODES)}")

    def describe(self) -> str:
        timing = ""
        if self.dummy_arrival_time is not None:
            timing = f", dummy at the impact position at {self.dummy_arrival_time:.2f} s"
        placed = " (actors placed by the road)" if self.placement == "road" else ""
        return (
            f"{self.kind} at {self.ego_speed_kmh:g} km/h on {self.road.name or 'a road'} "
            f"({self.road.width:g} m, lane {self.ego_lane} of {self.road.lanes}), car "
            f"{self.ego_distance:.1f} m / {self.time_to_collision_point:.2f} s from impact"
            f"{timing}{placed}"
        )

    def __repr__(self) -> str:
        extra = "" if self.dummy_speed_kmh is None else f", dummy_speed_kmh={self.dummy_speed_kmh}"
        if self.dummy_arrival_time is not None:
            extra += f", dummy_arrival_time={self.dummy_arrival_time:g}"
        if self.placement != "protocol":
            extra += f", placement={self.placement!r}"
        return (
            f"Scenario({self.kind!r}, road={self.road!r}, ego_speed_kmh={self.ego_speed_kmh:g}, "
            f"conflict_s={self.conflict_s:g}, ego_distance={self.ego_distance:g}, "
            f"ego_lane={self.ego_lane}{extra})"
        )

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        # Hypothesis prints falsifying examples with this instead of every dataclass field.
        printer.text(repr(self))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scenario):
            return NotImplemented
        return (
            self.kind == other.kind
            and self.road.equals(other.road)
            and (self.ego_speed_kmh, self.conflict_s, self.ego_distance, self.ego_lane)
            == (other.ego_speed_kmh, other.conflict_s, other.ego_distance, other.ego_lane)
            and self.dummy_speed_kmh == other.dummy_speed_kmh
            and self.dummy_arrival_time == other.dummy_arrival_time
            and self.vehicle == other.vehicle
            and self.placement == other.placement
        )

    def __hash__(self) -> int:
        return hash((self.kind, self.road.name, self.ego_speed_kmh, self.conflict_s))


def euro_ncap_road(*, width: float = 10.0, length: float = 300.0) -> RoadGeometry:
    """The straight test road: one lane ``width`` metres wide (10 m in Iqbal's scenario)."""
    return RoadGeometry.straight(
        length=length, width=width, lanes=1, name=f"Euro NCAP straight {width:g} m road"
    )


def euro_ncap(
    kind: str,
    *,
    ego_speed_kmh: float = 20.0,
    road: RoadGeometry | None = None,
    ego_lane: int = 0,
    conflict_s: float | None = None,
    initial_ttc: float = INITIAL_TTC,
    dummy_speed_kmh: float | None = None,
    vehicle: VehicleSpec = EURO_NCAP_CAR,
    placement: Placement = "protocol",
) -> Scenario:
    """A protocol scenario: the car starts ``initial_ttc`` (6 s) before the impact.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    ego_speed_kmh : float
    road : RoadGeometry, optional
        Default :func:`euro_ncap_road` (straight, 10 m, one lane).
    ego_lane : int
    conflict_s : float, optional
        Where on the road the collision point lies; default: far enough along the road for
        the car's start (and, for CPLA, the dummy's) to be on it, when the road allows.
    initial_ttc : float
        Seconds between the start and the impact at constant speed.
    dummy_speed_kmh : float, optional
    vehicle : VehicleSpec
    placement : {"protocol", "road"}
        See :class:`Scenario`.
    """
    road = euro_ncap_road() if road is None else road
    ttc = _finite(initial_ttc, "initial_ttc")
    if ttc <= 0:
        raise InvalidArgument(f"initial_ttc={initial_ttc!r} must be > 0")
    speed = _finite(ego_speed_kmh, "ego_speed_kmh")
    if speed <= 0:
        raise InvalidArgument(f"ego_speed_kmh={ego_speed_kmh!r} must be > 0")
    distance = ttc * speed * KMH
    if conflict_s is None:
        protocol = PROTOCOLS.get(kind)
        room = vehicle.length + 2.0
        if protocol is not None and protocol.motion == "longitudinal":
            room += protocol.acceleration_distance + protocol.steady_distance
        conflict_s = min(distance + room, road.length)
    return Scenario(
        kind,
        road,
        speed,
        conflict_s,
        distance,
        ego_lane=ego_lane,
        dummy_speed_kmh=dummy_speed_kmh,
        vehicle=vehicle,
        placement=placement,
    )
