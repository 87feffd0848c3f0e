"""A reference AEB controller with the MATLAB example's staging, and the 3.6 m-lane mutant.

Staging (MATLAB/Simulink "Autonomous Emergency Braking with Sensor Fusion" example):

* time to collision ``TTC = headway / closing speed`` to the most important object (MIO);
* forward collision warning when ``TTC < v / 4.0 + 1.2 s`` (deceleration 4 m/s^2 assumed
  for the driver plus 1.2 s reaction time);
* partial braking 1 / partial braking 2 / full braking at 3.8 / 5.3 / 9.8 m/s^2 when
  ``TTC`` drops below the stopping time of that stage, ``v / a + 0.08 s``;
* once braking, the stage only escalates until the car stands still.

The controller knows its car (:attr:`Observation.max_deceleration`,
:attr:`Observation.system_delay`): a stage's deceleration is capped at what the brakes
can do and its stopping time includes the car's sensor latency and brake delay, as a
production AEB calibrated for its vehicle does. On the ideal car (9.8 m/s^2, no delays)
this is exactly MATLAB's staging.

Most important object: the closest actor ahead whose centre lies in the car's corridor
(and, when it stands still, only if it is in the car's swept path, so parked cars beside
the lane are ignored). The reference controller takes the corridor from the map, i.e. the
road's real geometry: a moving pedestrian counts anywhere on the carriageway
(``Observation.road_right/road_left``), other actors only in the car's own lane
(``lane_right/lane_left``, so oncoming cars are no braking targets). MATLAB's example,
without lane detections, assumes a 3.6 m lane centred on the car; on a 10 m road that
ignores a pedestrian until it is 1.8 m from the car's path, the fault Iqbal found.
:func:`mutant_fixed_lane` is exactly that controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from pytest_metamorphic.core.arguments import check_number
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.kinematics import BrakeCommand, Observation, Track, is_relevant

__all__ = [
    "STAGES",
    "AEBController",
    "TTCController",
    "mutant_fixed_lane",
    "reference_controller",
    "ttc_controller",
]

#: Stage names, in escalation order.
STAGES = ("off", "FCW", "PB1", "PB2", "FB")


@dataclass
class AEBController:
    """The MATLAB-style AEB state machine.

    Parameters
    ----------
    lane_width : float or None
        None (reference): the MIO corridor comes from the map (see ``pedestrian_region``).
        A number: a corridor of that width centred on the car's path for every actor,
        whatever the road is like (3.6 is the MATLAB example's default and the mutant).
    pedestrian_region : {"road", "lane"}
        With ``lane_width=None``: where a moving pedestrian becomes a candidate, anywhere
        on the carriageway (default) or only in the car's lane.
    fcw_deceleration, fcw_reaction_time : float
        FCW time = ``v / fcw_deceleration + fcw_reaction_time``.
    pb1_deceleration, pb2_deceleration, fb_deceleration : float
        m/s^2 of the three braking stages.
    time_margin : float
        Added to each stage's stopping time ``v / a``.
    """

    lane_width: float | None = None
    pedestrian_region: Literal["road", "lane"] = "road"
    fcw_deceleration: float = 4.0
    fcw_reaction_time: float = 1.2
    pb1_deceleration: float = 3.8
    pb2_deceleration: float = 5.3
    fb_deceleration: float = 9.8
    time_margin: float = 0.08
    stage: str = field(default="off", init=False)
    ttc: float = field(default=math.inf, init=False)
    mio: Track | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        if self.lane_width is not None and not (
            isinstance(self.lane_width, (int, float))
            and math.isfinite(self.lane_width)
            and self.lane_width > 0
        ):
            raise InvalidArgument(f"lane_width={self.lane_width!r} must be None or > 0")
        if self.pedestrian_region not in ("road", "lane"):
            raise InvalidArgument(
                f"pedestrian_region={self.pedestrian_region!r} must be 'road' or 'lane'"
            )
        for name in ("fcw_deceleration", "pb1_deceleration", "pb2_deceleration", "fb_deceleration"):
            check_number(getattr(self, name), name, positive=True)

    def reset(self) -> None:
        """Forget the latched stage (called by the simulator before each run)."""
        self.stage = "off"
        self.ttc = math.inf
        self.mio = None

    # -- object selection --------------------------------------------------------------
    def in_corridor(self, track: Track, observation: Observation) -> bool:
        """Whether an actor is a braking candidate (see the module docstring)."""
        if self.lane_width is None:
            region = self.pedestrian_region if track.kind == "pedestrian" else "lane"
            return is_relevant(track, observation, region)
        if track.moving and abs(track.d) <= self.lane_width / 2:
            return True
        return abs(track.d) < (observation.ego_width + track.width) / 2

    def most_important_object(self, observation: Observation) -> Track | None:
        """The closest candidate ahead of the bumper, or None."""
        ahead = [
            track
            for track in observation.tracks
            if track.headway > 0 and self.in_corridor(track, observation)
        ]
        return min(ahead, key=lambda track: track.headway, default=None)

    # -- staging ------------------------------------------------------------------------
    def _stage_for(self, ttc: float, speed: float, observation: Observation) -> str:
        brakes, margin = observation.max_deceleration, self.time_margin + observation.system_delay
        stopping = {
            "FB": speed / min(self.fb_deceleration, brakes) + margin,
            "PB2": speed / min(self.pb2_deceleration, brakes) + margin,
            "PB1": speed / min(self.pb1_deceleration, brakes) + margin,
        }
        for stage in ("FB", "PB2", "PB1"):
            if ttc < stopping[stage]:
                return stage
        if ttc < speed / self.fcw_deceleration + self.fcw_reaction_time:
            return "FCW"
        return "off"

    def __call__(self, observation: Observation) -> BrakeCommand:
        speed = observation.ego_speed
        self.mio = self.most_important_object(observation)
        self.ttc = math.inf
        if self.mio is not None:
            closing = speed - self.mio.vs
            if closing > 0:
                self.ttc = self.mio.headway / closing
        wanted = self._stage_for(self.ttc, speed, observation)
        # Braking stages latch (escalate only; the car is held once stopped); a warning
        # alone may come and go.
        if self.stage in ("off", "FCW") or STAGES.index(wanted) > STAGES.index(self.stage):
            self.stage = wanted
        deceleration = {
            "PB1": self.pb1_deceleration,
            "PB2": self.pb2_deceleration,
            "FB": self.fb_deceleration,
        }.get(self.stage, 0.0)
        return BrakeCommand(deceleration, self.stage)


def reference_controller() -> AEBController:
    """The reference AEB: MATLAB staging, MIO corridor from the road's real geometry."""
    return AEBController(lane_width=None)


def mutant_fixed_lane(lane_width: float = 3.6) -> AEBController:
    """The faulty AEB Iqbal found: the MIO corridor assumes a ``lane_width`` m lane."""
    return AEBController(lane_width=lane_width)


@dataclass
class TTCController:
    """A second, independently designed AEB: time to collision with a predicted path.

    No staging and no corridor: every actor's lateral position is extrapolated at its
    current velocity over the interval in which the car would overlap it along the road
    (from the bumper reaching its near face until the car's rear passes its far face). When
    that predicted band comes within ``lateral_margin`` of the car's body and the time to
    reach the actor is below the car's own stopping time (its brakes and delays from the
    observation) plus ``time_margin``, it brakes fully and holds the brakes until the car
    stands. Standing actors beside the path never trigger it; a pedestrian walking towards
    the path does before it arrives, wherever on the road it walks.

    Parameters
    ----------
    lateral_margin : float
        Metres of clearance wanted beside the car's body.
    time_margin : float
        Seconds added to the stopping time.
    """

    lateral_margin: float = 0.3
    time_margin: float = 0.3
    braking: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        for name in ("lateral_margin", "time_margin"):
            check_number(getattr(self, name), name)

    def reset(self) -> None:
        self.braking = False

    def threatens(self, track: Track, observation: Observation) -> float | None:
        """Seconds until the bumper reaches ``track`` if its predicted path meets the car's."""
        closing = observation.ego_speed - track.vs
        if closing <= 0 or track.s + track.length / 2 < 0:
            return None
        reach = max(track.headway, 0.0) / closing
        leave = (track.headway + track.length + observation.ego_length) / closing
        lows = track.d + track.vd * reach, track.d + track.vd * leave
        low, high = min(lows) - track.width / 2, max(lows) + track.width / 2
        half = observation.ego_width / 2 + self.lateral_margin
        return reach if high >= -half and low <= half else None

    def __call__(self, observation: Observation) -> BrakeCommand:
        speed = observation.ego_speed
        stopping = speed / observation.max_deceleration + observation.system_delay
        if not self.braking:
            for track in observation.tracks:
                reach = self.threatens(track, observation)
                if reach is not None and reach < stopping + self.time_margin:
                    self.braking = True
                    break
        return (
            BrakeCommand(observation.max_deceleration, "FB")
            if self.braking
            else BrakeCommand(0.0, "off")
        )


def ttc_controller() -> TTCController:
    """The independent TTC-based AEB (a correct design unlike the MATLAB staging)."""
    return TTCController()
