"""OpenSCENARIO 1.x + OpenDRIVE export of a scenario, for esmini, CARLA and the like.

ADAS engineers replay failures in their own simulators, which read the ASAM exchange
formats: an OpenDRIVE road (``.xodr``) and an OpenSCENARIO storyboard (``.xosc``) that
references it. :func:`write_openscenario` writes both for a :class:`Scenario`:

* the road: its centreline as a chain of straight geometries (OSM streets are polylines),
  every lane a right-hand driving lane of ``width / lanes`` metres (a lane offset puts the
  reference line on the road's left edge, so the lanes cover the same strip as ours);
* the car under test (the Euro NCAP car's footprint) at its start, at its initial speed
  (the AEB under test is what drives it from there on);
* the dummy (child or adult) where it stands at t = 0, and, when its start time comes,
  its walk: a straight trajectory with the protocol's acceleration then constant speed;
* CPNCO's parked cars;
* a stop trigger at the end of our simulation's time window.

World coordinates are the road's own (metres); :func:`validate_openscenario` checks a file
against the standard's XML schema (the ASAM XSDs shipped with ``scenariogeneration``).
Needs the ``openscenario`` extra: ``pip install 'pytest-metamorphic[openscenario]'``.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.driving.scenario import CHILD, Scenario

__all__ = ["OSC_MINOR_VERSION", "OpenScenarioFiles", "validate_openscenario", "write_openscenario"]

#: OpenSCENARIO 1.2: read by esmini and by CARLA's ScenarioRunner (1.0 features only here).
OSC_MINOR_VERSION = 2
_INSTALL = "pip install 'pytest-metamorphic[openscenario]'"
_EGO, _DUMMY = "ego", "pedestrian"


@dataclass(frozen=True)
class OpenScenarioFiles:
    """The two files written: the storyboard and the road it references."""

    xosc: Path
    xodr: Path


def _modules() -> tuple[Any, Any]:
    try:
        from scenariogeneration import xodr, xosc
    except ImportError:
        raise InvalidArgument(f"OpenSCENARIO export needs scenariogeneration: {_INSTALL}") from None
    return xosc, xodr


def write_openscenario(
    scenario: Scenario,
    folder: str | os.PathLike[str],
    *,
    name: str = "scenario",
    description: str = "",
    duration: float | None = None,
) -> OpenScenarioFiles:
    """Write ``folder/name.xosc`` and ``folder/name.xodr`` for ``scenario``.

    Parameters
    ----------
    scenario : Scenario
    folder : path
        Created if missing.
    name : str
        File stem (letters, digits, ``-`` and ``_``).
    description : str
        Goes into the file header (e.g. what our simulation saw).
    duration : float, optional
        Seconds until the stop trigger; default the time to the collision point + 5 s.

    Returns
    -------
    OpenScenarioFiles
    """
    if not isinstance(scenario, Scenario):
        raise InvalidArgument(f"scenario={scenario!r} must be a Scenario")
    if not name or not all(ch.isalnum() or ch in "-_" for ch in name):
        raise InvalidArgument(f"name={name!r} must be letters, digits, '-' or '_'")
    xosc, xodr = _modules()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    road_file = folder / f"{name}.xodr"
    _opendrive(scenario, xodr).write_xml(str(road_file))
    end = scenario.time_to_collision_point + 5.0 if duration is None else float(duration)
    storyboard = _storyboard(scenario, xosc, end)
    document = xosc.Scenario(
        name=name,
        author="pytest-metamorphic",
        parameters=xosc.ParameterDeclarations(),
        entities=_entities(scenario, xosc),
        storyboard=storyboard,
        # Relative to the .xosc, so the pair can be moved together.
        roadnetwork=xosc.RoadNetwork(roadfile=road_file.name),
        catalog=xosc.Catalog(),
        osc_minor_version=OSC_MINOR_VERSION,
    )
    if description:
        document.header.description = description
    scenario_file = folder / f"{name}.xosc"
    document.write_xml(str(scenario_file))
    return OpenScenarioFiles(scenario_file, road_file)


def _opendrive(scenario: Scenario, xodr: Any) -> Any:
    road = scenario.road
    points = road.centerline
    planview = xodr.PlanView()
    for (x0, y0), (x1, y1) in itertools.pairwise(points):
        length = math.hypot(x1 - x0, y1 - y0)
        if length > 1e-9:
            planview.add_fixed_geometry(
                xodr.Line(length), float(x0), float(y0), math.atan2(y1 - y0, x1 - x0)
            )
    centre = xodr.Lane(a=0)
    centre.add_roadmark(xodr.RoadMark(xodr.RoadMarkType.solid, 0.12))
    section = xodr.LaneSection(0, centre)
    # The reference line is the left kerb (lane offset width / 2): right lanes from there
    # outward are the left margin, our lanes from the leftmost, then the right margin.
    right_margin, left_margin = road.margins
    if left_margin:
        section.add_right_lane(_margin_lane(xodr, left_margin))
    for lane in reversed(range(road.lanes)):
        driving = xodr.Lane(a=road.lane_width)
        edge = lane == 0 or (lane == road.lanes - 1 and left_margin)
        mark = xodr.RoadMarkType.solid if edge else xodr.RoadMarkType.broken
        driving.add_roadmark(xodr.RoadMark(mark, 0.12))
        section.add_right_lane(driving)
    if right_margin:
        section.add_right_lane(_margin_lane(xodr, right_margin))
    lanes = xodr.Lanes()
    lanes.add_laneoffset(xodr.LaneOffset(a=road.width / 2))
    lanes.add_lanesection(section)
    network = xodr.OpenDrive(road.name or "road")
    network.add_road(xodr.Road(1, planview, lanes, name=road.name or None))
    network.adjust_roads_and_lanes()
    return network


def _margin_lane(xodr: Any, width: float) -> Any:
    """A cycle or parking lane at the kerb: on the carriageway, not for driving."""
    return xodr.Lane(lane_type=xodr.LaneType.shoulder, a=width)


def _world(scenario: Scenario, xosc: Any, s: float, d: float, turn: float = 0.0) -> Any:
    x, y, heading = scenario.road.point(s, d)
    return xosc.WorldPosition(x, y, 0.0, heading + turn, 0.0, 0.0)


def _entities(scenario: Scenario, xosc: Any) -> Any:
    vehicle = scenario.vehicle
    entities = xosc.Entities()
    entities.add_scenario_object(_EGO, _car(xosc, "car under test", vehicle.length, vehicle.width,
                                            1.5, vehicle.max_deceleration))  # fmt: skip
    dummy = scenario.pedestrian().footprint
    box = xosc.BoundingBox(dummy.width, dummy.length, dummy.height, 0, 0, dummy.height / 2)
    model = "child" if dummy == CHILD else "adult"
    mass = 23.0 if dummy == CHILD else 75.0
    entities.add_scenario_object(
        _DUMMY, xosc.Pedestrian(model, mass, xosc.PedestrianCategory.pedestrian, box, model)
    )
    for index, parked in enumerate(scenario.obstructions(), start=1):
        f = parked.footprint
        entities.add_scenario_object(
            f"parked_car_{index}", _car(xosc, f.name, f.length, f.width, f.height, 9.8)
        )
    return entities


def _car(xosc: Any, name: str, length: float, width: float, height: float, brake: float) -> Any:
    box = xosc.BoundingBox(width, length, height, length / 2 - 0.9, 0, height / 2)
    front = xosc.Axle(0.0, 0.65, width - 0.2, length - 0.9 - 0.8, 0.3)
    rear = xosc.Axle(0.0, 0.65, width - 0.2, 0.0, 0.3)
    return xosc.Vehicle(name, xosc.VehicleCategory.car, box, front, rear, 70.0, 10.0, brake)


def _storyboard(scenario: Scenario, xosc: Any, end: float) -> Any:
    init = xosc.Init()
    vehicle = scenario.vehicle
    # OpenSCENARIO positions a vehicle by its reference point (rear axle); ours is the
    # front bumper: the bounding box above puts the rear axle 0.9 m ahead of the tail.
    rear_axle_s = scenario.ego_start_s - vehicle.length + 0.9
    init.add_init_action(_EGO, xosc.TeleportAction(_world(scenario, xosc, rear_axle_s,
                                                          scenario.ego_offset)))  # fmt: skip
    step = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)
    init.add_init_action(_EGO, xosc.AbsoluteSpeedAction(scenario.ego_speed, step))
    for index, parked in enumerate(scenario.obstructions(), start=1):
        rear = parked.s - parked.footprint.length / 2 + 0.9
        init.add_init_action(
            f"parked_car_{index}", xosc.TeleportAction(_world(scenario, xosc, rear, parked.d))
        )
    motion = scenario.pedestrian()
    turn = math.atan2(motion.dd, motion.ds)
    start_s, start_d = (float(v) for v in motion.road_position(0.0))
    init.add_init_action(_DUMMY, xosc.TeleportAction(_world(scenario, xosc, start_s, start_d,
                                                            turn)))  # fmt: skip
    walking = float(motion.velocity(0.0))  # a dummy that started before t = 0
    init.add_init_action(_DUMMY, xosc.AbsoluteSpeedAction(walking, step))
    board = xosc.StoryBoard(
        init,
        xosc.ValueTrigger(
            "end", 0, xosc.ConditionEdge.rising,
            xosc.SimulationTimeCondition(end, xosc.Rule.greaterThan), "stop",
        ),
    )  # fmt: skip
    board.add_maneuver(_walk(scenario, xosc, motion, start_s, start_d, end), _DUMMY)
    return board


def _walk(scenario: Scenario, xosc: Any, motion: Any, s0: float, d0: float, end: float) -> Any:
    """The dummy's walk: from where it stands at t = 0 along its path, at its speed."""
    begin = max(motion.start_time, 0.0)
    already = float(motion.velocity(0.0))
    far = motion.speed * max(end - begin, 1.0) + 5.0
    s1, d1 = s0 + motion.ds * far, d0 + motion.dd * far
    turn = math.atan2(motion.dd, motion.ds)
    path = xosc.Trajectory("walk", False)
    path.add_shape(
        xosc.Polyline(
            [], [_world(scenario, xosc, s0, d0, turn), _world(scenario, xosc, s1, d1, turn)]
        )
    )
    event = xosc.Event("walk", xosc.Priority.override)
    event.add_action("follow path", xosc.FollowTrajectoryAction(
        path, xosc.FollowingMode.position, xosc.ReferenceContext.relative, 1, 0))  # fmt: skip
    remaining = motion.speed - already
    seconds = remaining / motion.acceleration if motion.acceleration > 0 else 0.0
    accelerate = xosc.TransitionDynamics(
        xosc.DynamicsShapes.linear, xosc.DynamicsDimension.time, max(seconds, 0.0)
    )
    event.add_action("walk speed", xosc.AbsoluteSpeedAction(motion.speed, accelerate))
    event.add_trigger(
        xosc.ValueTrigger(
            "start walking", 0, xosc.ConditionEdge.none,
            xosc.SimulationTimeCondition(begin, xosc.Rule.greaterOrEqual),
        )
    )  # fmt: skip
    maneuver = xosc.Maneuver("pedestrian crossing")
    maneuver.add_event(event)
    return maneuver


def _schema(minor: int) -> Path:
    import scenariogeneration

    name = f"OpenSCENARIO_1_{minor}.xsd" if minor < 3 else "OpenSCENARIO_1_3_1.xsd"
    path = Path(scenariogeneration.__file__).resolve().parent.parent / "schemas" / name
    if not path.is_file():
        raise InvalidArgument(f"the OpenSCENARIO schema {name} is not installed ({path})")
    return path


def validate_openscenario(path: str | os.PathLike[str]) -> None:
    """Check an ``.xosc`` file against the OpenSCENARIO 1.x XML schema of its version.

    Raises DataError naming the file and the first schema violations.
    """
    _modules()
    import xml.etree.ElementTree as ElementTree

    import xmlschema

    path = Path(path)
    try:
        header = ElementTree.parse(path).getroot().find("FileHeader")
    except (OSError, ElementTree.ParseError) as error:
        raise DataError(f"not a readable XML file: {error}", path=path) from None
    if header is None or header.get("revMajor") != "1":
        raise DataError("not an OpenSCENARIO 1.x file (no FileHeader revMajor=1)", path=path)
    schema = xmlschema.XMLSchema(str(_schema(int(header.get("revMinor", "0")))))
    errors = list(schema.iter_errors(str(path)))
    if errors:
        shown = "; ".join(str(e.reason or e.message) for e in errors[:3])
        raise DataError(f"{len(errors)} OpenSCENARIO schema violation(s): {shown}", path=path)
