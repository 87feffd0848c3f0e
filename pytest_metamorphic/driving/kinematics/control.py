"""What an AEB controller sees (an :class:`Observation` of :class:`Track` objects) and returns
(a deceleration or a :class:`BrakeCommand`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Protocol, runtime_checkable

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["BrakeCommand", "Controller", "Observation", "Track", "is_relevant", "stopping_distance"]


def stopping_distance(speed: float, deceleration: float, delay: float = 0.0) -> float:
    """Closed form: ``speed * delay + speed**2 / (2 * deceleration)`` (metres)."""
    if deceleration <= 0:
        raise InvalidArgument(f"deceleration={deceleration!r} must be > 0")
    return speed * delay + speed**2 / (2 * deceleration)


# ---------------------------------------------------------------------------------------
# What the controller sees and returns


@dataclass(frozen=True)
class Track:
    """One actor as the sensor reports it, relative to the car, in road coordinates.

    Attributes
    ----------
    id : int
    kind : {"pedestrian", "vehicle"}
    s : float
        Distance along the road from the car's front bumper to the actor's centre (m).
    d : float
        Lateral offset of the actor's centre from the car's path (m, left positive).
    vs, vd : float
        Actor velocity along / across the road (m/s, ground frame).
    length, width : float
        The actor's extent along / across the road (m).
    """

    id: int
    kind: str
    s: float
    d: float
    vs: float
    vd: float
    length: float
    width: float

    @property
    def moving(self) -> bool:
        return math.hypot(self.vs, self.vd) >= 0.1

    @property
    def headway(self) -> float:
        """Free distance from the bumper to the actor's near face, along the road."""
        return self.s - self.length / 2


@dataclass(frozen=True)
class Observation:
    """Everything a controller gets each step.

    Attributes
    ----------
    time : float
    dt : float
    ego_speed : float
        m/s.
    ego_length, ego_width : float
    lane_right, lane_left : float
        The car's lane boundaries from the map, relative to its path (m; right negative).
        A controller that uses them selects objects with the road's real geometry.
    road_right, road_left : float
        The carriageway's edges relative to the car's path (m).
    tracks : tuple of Track
    max_deceleration : float
        What the car's brakes can do (m/s^2): a controller that knows its car plans with it.
    system_delay : float
        The car's sensor latency plus brake delay (s): how late braking takes effect.
    """

    time: float
    dt: float
    ego_speed: float
    ego_length: float
    ego_width: float
    lane_right: float
    lane_left: float
    road_right: float
    road_left: float
    tracks: tuple[Track, ...]
    max_deceleration: float = 9.8
    system_delay: float = 0.0


@dataclass(frozen=True)
class BrakeCommand:
    """A deceleration request (m/s^2, >= 0) and the controller's stage name, for traces."""

    deceleration: float
    stage: str = ""


@runtime_checkable
class Controller(Protocol):
    """An AEB function: observation in, deceleration (or :class:`BrakeCommand`) out."""

    def __call__(self, observation: Observation) -> float | BrakeCommand: ...


Region = Literal["lane", "road"]


def is_relevant(track: Track, observation: Observation, region: Region = "lane") -> bool:
    """The physical relevance rule (also the reference controller's object selection).

    An actor matters when it is moving (at 0.1 m/s or more, :attr:`Track.moving`) with its
    centre inside the car's real lane (``region="lane"``; ``"road"``: anywhere on the
    carriageway), or when it stands in the car's swept path (laterally overlapping the
    car's body).
    """
    right, left = (
        (observation.lane_right, observation.lane_left)
        if region == "lane"
        else (observation.road_right, observation.road_left)
    )
    if track.moving and right <= track.d <= left:
        return True
    return abs(track.d) < (observation.ego_width + track.width) / 2
