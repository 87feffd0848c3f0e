"""A second opinion from CommonRoad: its collision checker and vehicle model on our runs.

Our simulator finds contacts with its own polygon test and the avoidability judge with its
own rectangles; both are ours. This module asks components made for the field that we
did not write (TUM's CommonRoad, from PyPI):

* :func:`first_contact`: the car's trajectory of a run (from any simulator) and the
  pedestrian's and parked cars' boxes, tested step by step with the
  ``commonroad-drivability-checker``'s oriented-box collision test (``pycrcc.RectOBB``);
* :func:`braking_avoids`: the car under full braking from a given moment, its speed
  integrated with ``commonroad-vehicle-models``' kinematic single-track model (its
  acceleration constraints included), checked with the same collision test;
* :func:`crosscheck_campaign`: both over a whole campaign, with every disagreement listed.

Extra ``commonroad`` (``commonroad-io``, ``commonroad-drivability-checker``,
``commonroad-vehicle-models``). It needs an environment of its own: ``commonroad-io``
pins ``protobuf`` 3.20, which ``onnxruntime`` (the ``learned`` extra) refuses.

Along curved roads the car is placed on its lane's centre line by the distance the model
travelled (its steering is not simulated); on straight roads the model's own straight-line
motion is the same thing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.campaign import CONTROLLERS, CampaignSource, ControllerFactory
from pytest_metamorphic.driving.judge import judge_avoidable
from pytest_metamorphic.driving.kinematics import SimulationResult
from pytest_metamorphic.driving.scenario import Keep, Scenario
from pytest_metamorphic.driving.simulators import Simulator, check_simulator, run_simulator

__all__ = [
    "CrosscheckReport",
    "braking_avoids",
    "crosscheck_campaign",
    "first_contact",
    "format_crosscheck",
]

#: Seconds after our contact within which CommonRoad must find one too (one 10 ms step:
#: our contact time is refined inside the step, CommonRoad samples whole steps).
CONTACT_TOLERANCE = 0.01


def _pycrcc() -> Any:
    try:
        import commonroad_dc.pycrcc as pycrcc
    except ImportError:
        raise InvalidArgument(
            "the CommonRoad cross-check needs the commonroad extra: pip install "
            "'pytest-metamorphic[commonroad]' (in an environment without onnxruntime: "
            "commonroad-io pins protobuf 3.20)"
        ) from None
    return pycrcc


class _Boxes:
    """The scenario's actors as CommonRoad oriented boxes at any time."""

    def __init__(self, scenario: Scenario, pycrcc: Any) -> None:
        self.scenario, self.pycrcc = scenario, pycrcc
        self.motion = scenario.pedestrian()
        self.turn = math.copysign(math.pi / 2, self.motion.dd) if abs(self.motion.dd) > 0.5 else 0.0
        road = scenario.road
        self.parked = [
            self._box(*road.point(p.s, p.d), p.footprint.length, p.footprint.width)
            for p in scenario.obstructions()
        ]

    def _box(self, x: float, y: float, heading: float, length: float, width: float) -> Any:
        return self.pycrcc.RectOBB(length / 2, width / 2, heading, x, y)

    def car(self, front_s: float) -> Any:
        scenario = self.scenario
        vehicle, road = scenario.vehicle, scenario.road
        centre = front_s - vehicle.length / 2
        x, y, _ = road.point(centre, scenario.ego_offset)
        heading = road.chord_heading(centre, vehicle.wheelbase)
        return self._box(x, y, heading, vehicle.length, vehicle.width)

    def pedestrian(self, t: float) -> Any:
        s, d = self.motion.road_position(t)
        x, y, heading = self.scenario.road.point(float(s), float(d))
        footprint = self.motion.footprint
        return self._box(x, y, heading + self.turn, footprint.length, footprint.width)

    def touches(self, t: float, front_s: float) -> bool:
        car = self.car(front_s)
        return bool(car.collide(self.pedestrian(t))) or any(car.collide(p) for p in self.parked)


def first_contact(result: SimulationResult) -> float | None:
    """The first time CommonRoad's collision checker finds the run's car touching an actor.

    Samples the run's own steps (``result.times`` with the bumper's ``positions``), its
    end state and, for a run that ended in a collision, one step of
    :data:`CONTACT_TOLERANCE` beyond it at the final speed; None when nothing touches.
    """
    if not isinstance(result, SimulationResult):
        raise InvalidArgument(f"result={result!r} must be a SimulationResult")
    boxes = _Boxes(result.scenario, _pycrcc())
    samples = list(zip(result.times.tolist(), result.positions.tolist(), strict=True))
    samples.append((result.end_time, result.ego_s))
    if result.collision is not None:
        samples.append((
            result.end_time + CONTACT_TOLERANCE,
            result.ego_s + result.final_speed * CONTACT_TOLERANCE,
        ))  # fmt: skip
    for t, front in samples:
        if boxes.touches(t, front):
            return float(t)
    return None


def braking_avoids(
    scenario: Scenario, brake_time: float, *, dt: float = 0.001, until: float | None = None
) -> bool:
    """Whether full braking from ``brake_time`` avoids every contact, by CommonRoad.

    The car's speed follows ``commonroad-vehicle-models``' kinematic single-track model
    (``vehicle_dynamics_ks`` with its acceleration constraints; steering held straight),
    accelerating with 0 until ``brake_time`` and with ``-max_deceleration`` after; every
    step is tested with the drivability checker's box collision, until the car stands
    still (Euro NCAP: a pedestrian walking into a standing car is no impact) or ``until``.
    ``dt`` is 1 ms by default: at 10 ms a car at 60 km/h moves 17 cm per step, and a
    grazing contact with a child's corner falls between two steps (found on 8th Street,
    59 km/h, a 2 s start: the checker missed a contact at 10 ms that it finds at 1 ms).
    """
    pycrcc = _pycrcc()
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
    from vehiclemodels.vehicle_dynamics_ks import vehicle_dynamics_ks

    params = parameters_vehicle2()
    boxes = _Boxes(scenario, pycrcc)
    end = (
        until
        if until is not None
        else max(scenario.time_to_collision_point, scenario.dummy_arrival) + 5.0
    )
    # State [x, y, steering angle, speed, yaw] along the road's direction; only the speed
    # and the travelled distance are used (see the module docstring).
    state = np.array([0.0, 0.0, 0.0, scenario.ego_speed, 0.0])
    front, t = scenario.ego_start_s, 0.0
    while t <= end:
        if boxes.touches(t, front):
            return False
        if state[3] <= 1e-6 and t >= brake_time:
            return True
        command = -scenario.vehicle.max_deceleration if t >= brake_time - 1e-9 else 0.0
        rates = np.asarray(vehicle_dynamics_ks(state.tolist(), [0.0, command], params))
        speed_before = state[3]
        state = state + dt * rates
        state[3] = max(state[3], 0.0)
        front += dt * (speed_before + state[3]) / 2
        t = round(t + dt, 9)
    return True


@dataclass
class CrosscheckReport:
    """What CommonRoad said about a campaign's runs and collisions."""

    runs: int = 0
    contacts: int = 0
    contact_disagreements: list[str] = field(default_factory=list)
    judged: int = 0
    judge_disagreements: list[str] = field(default_factory=list)


def crosscheck_campaign(
    sources: Iterable[CampaignSource],
    controllers: Mapping[str, ControllerFactory] | None = None,
    *,
    speeds_kmh: Iterable[float] = range(15, 101),
    keep: Keep = "pedestrian",
    simulator: Simulator | None = None,
) -> CrosscheckReport:
    """Every run of a campaign (source and follow-ups) checked by CommonRoad: its contact
    against the simulator's, and for every collision the judge's verdict against
    :func:`braking_avoids` from the judge's brake time."""
    simulator = check_simulator(simulator)
    report = CrosscheckReport()
    speeds = sorted({float(v) for v in speeds_kmh})
    for source in sources:
        for name, factory in (controllers or CONTROLLERS).items():
            controller = factory()
            for speed in speeds:
                scenario = source.scenario.with_ego_speed(speed, keep=keep)
                result = run_simulator(simulator, scenario, controller)
                _check_run(report, f"{source.name} / {name} / {speed:g} km/h", result)
    return report


def _check_run(report: CrosscheckReport, label: str, result: SimulationResult) -> None:
    report.runs += 1
    theirs = first_contact(result)
    report.contacts += theirs is not None
    if (theirs is None) != (result.collision is None):
        ours = (
            "no contact"
            if result.collision is None
            else f"contact at {result.collision.time:.3f} s"
        )
        found = "none" if theirs is None else f"contact at {theirs:.3f} s"
        report.contact_disagreements.append(f"{label}: ours {ours}, CommonRoad {found}")
    if result.collision is None:
        return
    verdict = judge_avoidable(result.scenario)
    if verdict.brake_time is None:
        return
    report.judged += 1
    avoids = braking_avoids(result.scenario, verdict.brake_time)
    passes_first = verdict.standard.endswith("passes first")
    if avoids != (verdict.avoidable or passes_first):
        report.judge_disagreements.append(
            f"{label}: judge {verdict.describe()}; CommonRoad braking from "
            f"{verdict.brake_time:.2f} s {'avoids' if avoids else 'still touches'}"
        )


def format_crosscheck(report: CrosscheckReport, *, title: str = "") -> str:
    lines = [title] if title else []
    lines.append(
        f"{report.runs} runs: CommonRoad's collision checker finds {report.contacts} contacts; "
        f"{len(report.contact_disagreements)} disagree with the simulator"
    )
    lines += [f"  {line}" for line in report.contact_disagreements]
    lines.append(
        f"{report.judged} collisions judged: braking from the judge's brake time in "
        f"CommonRoad's vehicle model disagrees with the judge on "
        f"{len(report.judge_disagreements)}"
    )
    lines += [f"  {line}" for line in report.judge_disagreements]
    return "\n".join(lines)
