"""OpenSCENARIO + OpenDRIVE export: schema-valid files that place the actors where ours are."""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

from conftest import shared_data_path
from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.driving.kinematics import simulate
from pytest_metamorphic.driving.osm import DRIVABLE_HIGHWAYS, load_roads
from pytest_metamorphic.driving.records import result_to_json, scenario_from_json, scenario_to_json
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import KINDS, euro_ncap

openscenario = pytest.importorskip("pytest_metamorphic.driving.openscenario")
pytest.importorskip("scenariogeneration", reason="the openscenario extra is not installed")


def _teleport(root: ElementTree.Element, entity: str) -> tuple[float, float, float]:
    for private in root.iter("Private"):
        if private.get("entityRef") == entity:
            for world in private.iter("WorldPosition"):
                return float(world.get("x")), float(world.get("y")), float(world.get("h"))
    raise AssertionError(f"no position for {entity}")


@pytest.mark.parametrize("kind", KINDS)
def test_every_euro_ncap_test_exports_schema_valid_files(kind: str, tmp_path: Path) -> None:
    scenario = euro_ncap(kind, ego_speed_kmh=35)
    files = openscenario.write_openscenario(scenario, tmp_path, name="case", description="why")
    openscenario.validate_openscenario(files.xosc)
    root = ElementTree.parse(files.xosc).getroot()
    header = root.find("FileHeader")
    assert header.get("revMinor") == str(openscenario.OSC_MINOR_VERSION)
    assert header.get("description") == "why"
    assert root.find("RoadNetwork/LogicFile").get("filepath") == "case.xodr"
    # The car's reference point (rear axle) sits 0.9 m ahead of its tail, on its lane.
    x, y, heading = _teleport(root, "ego")
    expected = scenario.road.point(
        scenario.ego_start_s - scenario.vehicle.length + 0.9, scenario.ego_offset
    )
    assert (x, y, heading) == pytest.approx(expected, abs=1e-6)
    motion = scenario.pedestrian()
    s0, d0 = motion.road_position(0.0)
    assert _teleport(root, "pedestrian")[:2] == pytest.approx(
        scenario.road.point(float(s0), float(d0))[:2], abs=1e-6
    )
    parked = [p for p in root.iter("ScenarioObject") if p.get("name").startswith("parked")]
    assert len(parked) == len(scenario.obstructions())
    speed = next(root.iter("AbsoluteTargetSpeed"))
    assert float(speed.get("value")) == pytest.approx(35 / 3.6)


def test_an_osm_street_becomes_an_opendrive_polyline_of_its_length(tmp_path: Path) -> None:
    path = shared_data_path("osm_osmnx", "West-Oakland.osm.bz2")
    road = max(
        load_roads(path, highway=DRIVABLE_HIGHWAYS),
        key=lambda r: (len(r.centerline) >= 4, r.length),
    )
    geometry = RoadGeometry.from_osm(road)
    scenario = euro_ncap(
        "CPNA-75", ego_speed_kmh=30, road=geometry, conflict_s=min(geometry.length - 10, 150)
    )
    files = openscenario.write_openscenario(scenario, tmp_path)
    openscenario.validate_openscenario(files.xosc)
    drive = ElementTree.parse(files.xodr).getroot()
    assert drive.find("header").get("revMajor") == "1"
    lines = list(drive.iter("geometry"))
    assert len(lines) >= 2  # a real street bends
    assert sum(float(g.get("length")) for g in lines) == pytest.approx(geometry.length, rel=1e-6)
    lanes = next(iter(drive.iter("right"))).findall("lane")
    assert len(lanes) == geometry.lanes
    assert all(
        float(lane.find("width").get("a")) == pytest.approx(geometry.lane_width) for lane in lanes
    )
    offset = next(drive.iter("laneOffset"))
    assert float(offset.get("a")) == pytest.approx(geometry.width / 2)


def test_cycle_lanes_and_the_dummys_own_timing_are_exported(tmp_path: Path) -> None:
    road = RoadGeometry.straight(length=200, width=9, lanes=2, margins=(1.5, 1.5))
    source = euro_ncap("CPNCO-50", ego_speed_kmh=20, road=road)
    early = source.with_ego_speed(25, keep="pedestrian")
    files = openscenario.write_openscenario(early, tmp_path)
    openscenario.validate_openscenario(files.xosc)
    lanes = next(iter(ElementTree.parse(files.xodr).getroot().iter("right"))).findall("lane")
    kinds = [(lane.get("type"), float(lane.find("width").get("a"))) for lane in lanes]
    assert kinds == [("shoulder", 1.5), ("driving", 3.0), ("driving", 3.0), ("shoulder", 1.5)]
    # The dummy starts where and when it did in the source, the car sooner there.
    root = ElementTree.parse(files.xosc).getroot()
    original = openscenario.write_openscenario(source, tmp_path / "source").xosc
    before = ElementTree.parse(original).getroot()
    assert _teleport(root, "pedestrian") == pytest.approx(_teleport(before, "pedestrian"))
    assert _teleport(root, "ego") == pytest.approx(_teleport(before, "ego"))


def test_a_file_that_breaks_the_schema_is_named(tmp_path: Path) -> None:
    files = openscenario.write_openscenario(euro_ncap("CPNA-25", ego_speed_kmh=20), tmp_path)
    text = files.xosc.read_text().replace("<Storyboard>", "<Storyboard><Nonsense/>", 1)
    files.xosc.write_text(text)
    with pytest.raises(DataError, match=r"scenario\.xosc.*schema violation"):
        openscenario.validate_openscenario(files.xosc)
    (tmp_path / "plain.xml").write_text("<Other/>")
    with pytest.raises(DataError, match=r"not an OpenSCENARIO 1\.x file"):
        openscenario.validate_openscenario(tmp_path / "plain.xml")


def test_bad_arguments_are_named(tmp_path: Path) -> None:
    with pytest.raises(Exception, match="must be a Scenario"):
        openscenario.write_openscenario("CPNA-25", tmp_path)
    with pytest.raises(Exception, match="name='a b'"):
        openscenario.write_openscenario(
            euro_ncap("CPNA-25", ego_speed_kmh=20), tmp_path, name="a b"
        )


def test_scenarios_round_trip_through_json_exactly() -> None:
    road = RoadGeometry(
        np.array([[0.0, 0.0], [80.0, 5.0], [160.0, -3.0]]), 12.0, 3, "bent", (1.5, 0.5)
    )
    scenario = euro_ncap("CPFA-50", ego_speed_kmh=42, road=road, conflict_s=120.0, ego_lane=1)
    again = scenario_from_json(json.loads(json.dumps(scenario_to_json(scenario))))
    assert again == scenario and again.road.margins == (1.5, 0.5)
    early = scenario.with_ego_speed(50, keep="pedestrian")
    again = scenario_from_json(json.loads(json.dumps(scenario_to_json(early))))
    assert again == early and again.dummy_arrival_time == early.dummy_arrival_time
    assert math.isclose(again.pedestrian().start_time, scenario.pedestrian().start_time)
    with pytest.raises(DataError, match="not a recorded AEB scenario"):
        scenario_from_json({"kind": "CPNA-25"})
    outcome = result_to_json(simulate(euro_ncap("CPNA-25", ego_speed_kmh=40)))
    assert outcome["collided"] and outcome["collision"]["location"] == "front"
