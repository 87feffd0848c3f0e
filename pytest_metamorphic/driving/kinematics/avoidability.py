"""Physical avoidability: could full braking from the moment the pedestrian became relevant
have avoided the impact?
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.kinematics.control import Observation, Region, is_relevant
from pytest_metamorphic.driving.kinematics.sensor import Sensor
from pytest_metamorphic.driving.kinematics.simulator import simulate
from pytest_metamorphic.driving.scenario import KMH, Scenario

__all__ = ["Avoidability", "physically_avoidable"]


@dataclass(frozen=True)
class Avoidability:
    """Could the car have stopped in time?

    Attributes
    ----------
    avoidable : bool
    relevant_time : float or None
        When the pedestrian first became relevant (see :func:`physically_avoidable`);
        None if it never did before the contact.
    gap : float
        With ideal braking from then on: free distance left between the car and the
        pedestrian when the car stopped (negative: the impact speed in m/s with a minus
        sign, when even ideal braking collides).
    """

    avoidable: bool
    relevant_time: float | None
    gap: float

    def describe(self) -> str:
        if self.relevant_time is None:
            return "unavoidable: the pedestrian never became relevant before the contact"
        when = f"relevant at t={self.relevant_time:.2f} s"
        if self.avoidable:
            return f"avoidable: {when}, full braking stops {self.gap:.2f} m short"
        return f"unavoidable: {when}, full braking still hits at {-self.gap / KMH:.1f} km/h"


class _IdealBraking:
    """Full braking from the first step the pedestrian is relevant (+ ``slack``)."""

    def __init__(self, deceleration: float, slack: float, region: Region) -> None:
        self.deceleration = deceleration
        self.slack = slack
        self.region = region
        self.relevant_time: float | None = None

    def reset(self) -> None:
        self.relevant_time = None

    def __call__(self, observation: Observation) -> float:
        if self.relevant_time is None and any(
            track.kind == "pedestrian"
            and track.headway > -0.5
            and is_relevant(track, observation, self.region)
            for track in observation.tracks
        ):
            self.relevant_time = observation.time
        if (
            self.relevant_time is not None
            and observation.time >= self.relevant_time + self.slack - 1e-9
        ):
            return self.deceleration
        return 0.0


def physically_avoidable(
    scenario: Scenario,
    *,
    slack: float = 0.1,
    relevance: Region = "road",
    dt: float = 0.01,
    sensor: Sensor | None = None,
) -> Avoidability:
    """Whether a collision in ``scenario`` could have been avoided by braking alone.

    Definition: the pedestrian becomes *relevant* at the first moment it is visible to the
    car's sensor (not hidden by the parked cars) and either moving with its centre on the
    carriageway (from the road geometry; ``relevance="lane"``: only inside the car's own
    lane, a laxer standard for the car) or standing in the car's swept path.
    The collision is *physically avoidable* when the car, braking at its
    ``max_deceleration`` (after its ``brake_delay``) from ``slack`` seconds after that
    moment, stops or is overtaken without touching the pedestrian. ``slack`` absorbs one
    control step and the rounding of a fixed-step controller.
    """
    if not (isinstance(slack, (int, float)) and math.isfinite(slack) and slack >= 0):
        raise InvalidArgument(f"slack={slack!r} must be >= 0")
    if relevance not in ("lane", "road"):
        raise InvalidArgument(f"relevance={relevance!r} must be 'lane' or 'road'")
    ideal = _IdealBraking(scenario.vehicle.max_deceleration, slack, relevance)
    result = simulate(scenario, ideal, dt=dt, sensor=sensor)
    if ideal.relevant_time is None:
        return Avoidability(False, None, -result.impact_speed)
    if result.collision is not None:
        return Avoidability(False, ideal.relevant_time, -result.collision.impact_speed)
    motion = scenario.pedestrian()
    ped_s, _ = motion.road_position(result.end_time)
    gap = float(ped_s) - motion.extent_along_road / 2 - result.ego_s
    return Avoidability(True, ideal.relevant_time, gap)
