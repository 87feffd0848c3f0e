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
* :func:`commonroad_scenario`: a scenario and a run as a ``commonroad-io`` scenario (the
  car's lane as a lanelet, the car, the pedestrian, the parked cars), written with
  :func:`write_commonroad` for CommonRoad's own tools;
* :func:`crime_stops_short`: CommonRoad-CriMe's headway (``HW``) and time to collision
  (``TTC``) along the car's lanelet at the moment CommonRoad assigns the pedestrian to
  it, and whether the car, reacting then, stops within that headway: a lane-standard
  avoidability computed with their lanelets and measures;
* :func:`crosscheck_campaign`: all of these over a whole campaign, with every
  disagreement listed.

Extra ``commonroad`` (``commonroad-io``, ``commonroad-drivability-checker``,
``commonroad-vehicle-models``, ``commonroad-crime``). It needs an environment of its own:
``commonroad-io`` pins ``protobuf`` 3.20, which ``onnxruntime`` (the ``learned`` extra)
refuses.

Along curved roads the car is placed on its lane's centre line by the distance the model
travelled (its steering is not simulated); on straight roads the model's own straight-line
motion is the same thing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.campaign import CONTROLLERS, CampaignSource, ControllerFactory
from pytest_metamorphic.driving.judge import judge_avoidable
from pytest_metamorphic.driving.kinematics import SimulationResult
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import Keep, PedestrianMotion, Scenario
from pytest_metamorphic.driving.simulators import Simulator, check_simulator, run_simulator

__all__ = [
    "CrosscheckReport",
    "braking_avoids",
    "crosscheck_campaign",
    "first_contact",
    "format_crosscheck",
]

#: Stopping margins (m) below which the judge and CriMe are not compared: CriMe puts a
#: crossing child's rear ``length / 2`` = 0.36 m behind its centre, the judge its near
#: face 0.15 m (half its width, its extent along the road).
CRIME_MARGIN = 0.3
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


def _car_pose(scenario: Scenario, front_s: float) -> tuple[float, float, float]:
    """World ``(x, y, heading)`` of the car's centre with its bumper at ``front_s``."""
    vehicle, road = scenario.vehicle, scenario.road
    centre = front_s - vehicle.length / 2
    x, y, _ = road.point(centre, scenario.ego_offset)
    return x, y, road.chord_heading(centre, vehicle.wheelbase)


def _pedestrian_pose(
    road: RoadGeometry, motion: PedestrianMotion, t: float
) -> tuple[float, float, float]:
    """World ``(x, y, heading)`` of the dummy at time ``t``."""
    s, d = motion.road_position(t)
    x, y, heading = road.point(float(s), float(d))
    return x, y, heading + motion.facing


class _Boxes:
    """The scenario's actors as CommonRoad oriented boxes at any time."""

    def __init__(self, scenario: Scenario, pycrcc: Any) -> None:
        self.scenario, self.pycrcc = scenario, pycrcc
        self.motion = scenario.pedestrian()
        road = scenario.road
        self.parked = [
            self._box(*road.point(p.s, p.d), p.footprint.length, p.footprint.width)
            for p in scenario.obstructions()
        ]

    def _box(self, x: float, y: float, heading: float, length: float, width: float) -> Any:
        return self.pycrcc.RectOBB(length / 2, width / 2, heading, x, y)

    def car(self, front_s: float) -> Any:
        vehicle = self.scenario.vehicle
        return self._box(*_car_pose(self.scenario, front_s), vehicle.length, vehicle.width)

    def pedestrian(self, t: float) -> Any:
        footprint = self.motion.footprint
        return self._box(
            *_pedestrian_pose(self.scenario.road, self.motion, t), footprint.length, footprint.width
        )

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


_EGO_ID, _PEDESTRIAN_ID, _LANE_ID = 100, 200, 1


def commonroad_scenario(
    scenario: Scenario, fronts: Sequence[float], speeds: Sequence[float], *, dt: float = 0.01
) -> Any:
    """``scenario`` as a ``commonroad-io`` scenario, the car's bumper at ``fronts[k]`` with
    speed ``speeds[k]`` at time step ``k`` (``dt`` seconds each).

    The car's lane becomes one lanelet (its boundaries every metre along the road), the
    car obstacle 100, the pedestrian 200, parked cars 300 and up; obstacles are assigned
    to lanelets by their centres (``assign_obstacles_to_lanelets``).

    The world is turned so that the road heads along +x at the collision point: CriMe's
    headway (``HW``) moves the car's centre to its front by adding half its length to
    *both* coordinates (and the other's centre to its rear likewise), which is right only
    for a lane heading along +x; unturned, 8th Street (heading 164 degrees) read 4.1 m
    too much headway.
    """
    _pycrcc()
    from commonroad.geometry.shape import Rectangle
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.lanelet import Lanelet, LaneletNetwork
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType, StaticObstacle
    from commonroad.scenario.scenario import Scenario as CommonRoadScenario
    from commonroad.scenario.scenario import ScenarioID
    from commonroad.scenario.state import CustomState, InitialState
    from commonroad.scenario.trajectory import Trajectory

    road, vehicle = scenario.road, scenario.vehicle
    turn_x, turn_y, turn_h = road.point(scenario.conflict_s)
    cos, sin = math.cos(-turn_h), math.sin(-turn_h)

    def turned(x: Any, y: Any) -> tuple[Any, Any]:
        dx, dy = np.asarray(x) - turn_x, np.asarray(y) - turn_y
        return cos * dx - sin * dy, sin * dx + cos * dy

    def pose(world: tuple[float, float, float]) -> tuple[float, float, float]:
        tx, ty = turned(world[0], world[1])
        return float(tx), float(ty), world[2] - turn_h

    # The lanelet reaches past both ends of the road where the car starts before it
    # (positions extrapolate along the end segments), so CriMe finds the car on it.
    first = min(0.0, scenario.ego_start_s - vehicle.length - 10.0)
    last = max(road.length, scenario.conflict_s + 60.0)
    along = np.append(np.arange(first, last, 1.0), last)
    low, high = road.lane_bounds(scenario.ego_lane)
    bound = []
    for d in (high, (low + high) / 2, low):
        world = road.to_world(along, np.full_like(along, d))
        bound.append(np.stack(turned(world[:, 0], world[:, 1]), axis=1))
    lanelet = Lanelet(bound[0], bound[1], bound[2], _LANE_ID)
    result = CommonRoadScenario(dt, ScenarioID(map_name="pytest-metamorphic-aeb"))
    result.add_objects(LaneletNetwork.create_from_lanelet_list([lanelet]))

    def obstacle(
        oid: int,
        kind: Any,
        poses: list[tuple[float, float, float]],
        velocities: list[float],
        length: float,
        width: float,
    ) -> Any:
        states = [
            CustomState(position=np.array([x, y]), orientation=h, velocity=v, velocity_y=0.0,
                        acceleration=0.0, acceleration_y=0.0, time_step=k)
            for k, ((x, y, h), v) in enumerate(zip(poses, velocities, strict=True))
        ]  # fmt: skip
        first = states[0]
        initial = InitialState(position=first.position, orientation=first.orientation,
                               velocity=first.velocity, acceleration=0.0, yaw_rate=0.0,
                               slip_angle=0.0, time_step=0)  # fmt: skip
        initial.velocity_y = initial.acceleration_y = 0.0
        shape = Rectangle(length, width)
        trajectory = TrajectoryPrediction(Trajectory(1, states[1:]), shape)
        return DynamicObstacle(oid, kind, shape, initial, trajectory)

    car = [pose(_car_pose(scenario, f)) for f in fronts]
    motion = scenario.pedestrian()
    times = np.arange(len(fronts), dtype=np.float64) * dt
    walker = [pose(_pedestrian_pose(road, motion, t)) for t in times.tolist()]
    footprint = motion.footprint
    result.add_objects([
        obstacle(_EGO_ID, ObstacleType.CAR, car, list(speeds), vehicle.length, vehicle.width),
        obstacle(_PEDESTRIAN_ID, ObstacleType.PEDESTRIAN, walker,
                 motion.velocity(times).tolist(), footprint.length, footprint.width),
    ])  # fmt: skip
    for index, parked in enumerate(scenario.obstructions()):
        x, y, h = pose(road.point(parked.s, parked.d))
        initial = InitialState(
            position=np.array([x, y]), orientation=h, velocity=0.0, acceleration=0.0,
            yaw_rate=0.0, slip_angle=0.0, time_step=0,
        )  # fmt: skip
        shape = Rectangle(parked.footprint.length, parked.footprint.width)
        result.add_objects(StaticObstacle(300 + index, ObstacleType.PARKED_VEHICLE, shape, initial))
    result.assign_obstacles_to_lanelets(use_center_only=True)
    return result


def write_commonroad(result: SimulationResult, path: str | Path) -> Path:
    """A run as a CommonRoad XML scenario file (``commonroad-io``'s writer)."""
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.planning.planning_problem import PlanningProblemSet

    scenario = commonroad_scenario(
        result.scenario, result.positions.tolist(), result.speeds.tolist()
    )
    target = Path(path)
    writer = CommonRoadFileWriter(
        scenario, PlanningProblemSet(), author="pytest-metamorphic", affiliation="",
        source="pytest-metamorphic AEB campaign", tags=set(),
    )  # fmt: skip
    writer.write_to_file(str(target), OverwriteExistingFile.ALWAYS)
    return target


@dataclass(frozen=True)
class CrimeVerdict:
    """CommonRoad-CriMe's view of a scenario's pedestrian, from the unbraked car.

    ``time``: when CommonRoad first assigns the (visible) pedestrian to the car's lanelet
    (None: never before the car reaches it); ``headway`` (m) and ``ttc`` (s): CriMe's
    ``HW`` and ``TTC`` then (inf: the pedestrian is already beside the car);
    ``stops_short``: the car, reacting after ``reaction`` seconds and braking at its peak
    deceleration, stops within the headway. CriMe takes every obstacle as aligned with the
    lane (its rear is ``length / 2`` behind its centre), so for a crossing child its headway
    is 0.21 m shorter than the distance to the child's near face.
    """

    time: float | None
    headway: float
    ttc: float
    stops_short: bool


def crime_stops_short(
    scenario: Scenario, *, reaction: float, visible_from: float = 0.0, dt: float = 0.01
) -> CrimeVerdict:
    """CriMe's headway and TTC when the pedestrian enters the car's lanelet (see
    :class:`CrimeVerdict`); the unbraked car drives at its initial speed throughout."""
    from commonroad_crime.data_structure.configuration import CriMeConfiguration
    from commonroad_crime.measure import HW, TTC

    steps = math.ceil(scenario.time_to_collision_point / dt) + 1
    fronts = [scenario.ego_start_s + scenario.ego_speed * k * dt for k in range(steps)]
    crs = commonroad_scenario(scenario, fronts, [scenario.ego_speed] * steps, dt=dt)
    pedestrian = crs.obstacle_by_id(_PEDESTRIAN_ID)
    assignment = pedestrian.prediction.center_lanelet_assignment or {}
    first = next(
        (k for k in range(math.ceil(visible_from / dt), steps)
         if _LANE_ID in assignment.get(k, set())),
        None,
    )  # fmt: skip
    if first is None:
        return CrimeVerdict(None, math.inf, math.inf, False)
    config = CriMeConfiguration()
    config.update(ego_id=_EGO_ID, sce=crs)
    headway = float(HW(config).compute(_PEDESTRIAN_ID, first, verbose=False))
    ttc = float(TTC(config).compute(_PEDESTRIAN_ID, first, verbose=False))
    speed = scenario.ego_speed
    needed = speed * reaction + speed**2 / (2 * scenario.vehicle.max_deceleration)
    # CriMe's HW is inf when the pedestrian is behind the bumper: it entered the lane
    # beside the car, which no braking stops short of.
    return CrimeVerdict(first * dt, headway, ttc, math.isfinite(headway) and needed <= headway)


@dataclass
class CrosscheckReport:
    """What CommonRoad said about a campaign's runs and collisions."""

    runs: int = 0
    contacts: int = 0
    contact_disagreements: list[str] = field(default_factory=list)
    judged: int = 0
    judge_disagreements: list[str] = field(default_factory=list)
    lane_judged: int = 0
    crime_boundary: int = 0
    crime_disagreements: list[str] = field(default_factory=list)


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
    # The lane standard against CriMe: both ask whether the car, reacting when the
    # pedestrian enters its lane, stops short of it.
    lane = judge_avoidable(result.scenario, relevance="lane")
    reaction = 0.1 + result.scenario.vehicle.system_delay
    crime = crime_stops_short(
        result.scenario, reaction=reaction, visible_from=lane.visible_time or 0.0
    )
    report.lane_judged += 1
    judge_short = lane.avoidable and lane.gap >= 0
    if judge_short and lane.gap < CRIME_MARGIN:
        report.crime_boundary += 1  # within CriMe's approximation of the child's extent
    elif crime.stops_short != judge_short:
        report.crime_disagreements.append(
            f"{label}: judge (lane) {lane.describe()}; CriMe at t={crime.time} s: headway "
            f"{crime.headway:.2f} m, TTC {crime.ttc:.2f} s, "
            f"{'stops short' if crime.stops_short else 'cannot stop short'}"
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
    lines.append(
        f"{report.lane_judged} collisions by the lane standard: CommonRoad-CriMe's headway "
        f"when the pedestrian enters the car's lanelet disagrees with the judge on "
        f"{len(report.crime_disagreements)} ({report.crime_boundary} within "
        f"{CRIME_MARGIN} m of stopping not compared)"
    )
    lines += [f"  {line}" for line in report.crime_disagreements]
    return "\n".join(lines)
