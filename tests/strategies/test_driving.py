"""aeb_scenarios(), straight_roads() and ego_speed_changes(): validity, shrinking, errors."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pytest_metamorphic import Followup, InvalidArgument
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.driving.osm import DRIVABLE_HIGHWAYS, load_roads
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import KINDS, PROTOCOLS, Scenario, euro_ncap
from pytest_metamorphic.strategies import aeb_scenarios, ego_speed_changes, straight_roads
from tests.deterministic import find


def test_names_are_found_through_the_strategies_package() -> None:
    assert mst.aeb_scenarios is aeb_scenarios
    assert mst.ego_speed_changes is ego_speed_changes
    assert {"aeb_scenarios", "ego_speed_changes", "straight_roads"} <= set(dir(mst))


@settings(max_examples=60)
@given(scenario=aeb_scenarios())
def test_scenarios_are_protocol_valid(scenario: Scenario) -> None:
    protocol = PROTOCOLS[scenario.kind]
    assert scenario.ego_speed_kmh in protocol.speeds_kmh
    assert scenario.time_to_collision_point == pytest.approx(6.0)
    road = scenario.road
    assert 3.0 <= road.width <= 12.0 and (road.width * 4).is_integer()
    assert road.lane_width >= 2.5 and 0 <= scenario.ego_lane < road.lanes
    assert scenario.ego_start_s >= 0


def test_scenarios_shrink_to_the_plain_protocol_case() -> None:
    fast = find(aeb_scenarios(), lambda s: s.ego_speed_kmh >= 30)
    assert (fast.kind, fast.ego_speed_kmh, fast.ego_lane) == (KINDS[0], 30, 0)
    assert (fast.road.width, fast.road.lanes) == (10.0, 1)
    narrow = find(aeb_scenarios(kinds=["CPFA-50"]), lambda s: s.road.width < 6)
    assert narrow.road.width == 5.75 and narrow.kind == "CPFA-50"


def test_scenarios_on_real_streets(shared_data: Path) -> None:
    path = shared_data / "osm_osmnx/West-Oakland.osm.bz2"
    streets = [RoadGeometry.from_osm(r) for r in load_roads(path, highway=DRIVABLE_HIGHWAYS)]
    long_streets = [road for road in streets if road.length > 300]
    scenario = find(
        aeb_scenarios(roads=long_streets, speeds_kmh=[40]), lambda s: s.road.name == "8th Street"
    )
    assert scenario.ego_speed_kmh == 40 and scenario.ego_start_s >= 0


@settings(max_examples=40)
@given(data=st.data(), source=aeb_scenarios())
def test_speed_follow_ups_stay_in_range_and_resynchronise(
    data: st.DataObject, source: Scenario
) -> None:
    followup = data.draw(ego_speed_changes(source, min_speed_kmh=15, max_speed_kmh=100))
    assert isinstance(followup, Followup)
    scenario, params = followup.input, followup.params
    assert 15 <= scenario.ego_speed_kmh <= 100 and scenario.ego_speed_kmh != source.ego_speed_kmh
    assert params["delta_kmh"] == pytest.approx(scenario.ego_speed_kmh - source.ego_speed_kmh)
    assert scenario.ego_start_s == pytest.approx(source.ego_start_s)
    # Still synchronised: the dummy is at the impact position when the bumper gets there.
    motion = scenario.pedestrian()
    walked = float(motion.walked(scenario.time_to_collision_point))
    before = float(source.pedestrian().walked(source.time_to_collision_point))
    assert walked == pytest.approx(before)
    assert params["time_to_collision_point_s"] == round(scenario.time_to_collision_point, 3)


def test_speed_follow_ups_shrink_to_one_step() -> None:
    source = euro_ncap("CPNA-25", ego_speed_kmh=20)
    assert find(ego_speed_changes(source), lambda f: True).params["delta_kmh"] in (1, -1)
    big = find(ego_speed_changes(source, step_kmh=5), lambda f: f.params["delta_kmh"] > 30)
    assert big.params["ego_speed_kmh"] == 55
    kept = find(ego_speed_changes(source, keep="time"), lambda f: True).input
    assert kept.time_to_collision_point == pytest.approx(6.0)


SOURCE = euro_ncap("CPFA-50")


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: aeb_scenarios(kinds=[]), "kinds"),
        (lambda: aeb_scenarios(kinds=["CPXX-50"]), "unknown"),
        (lambda: aeb_scenarios(roads=[]), "roads"),
        (lambda: aeb_scenarios(speeds_kmh=[0]), "speeds_kmh"),
        (lambda: aeb_scenarios(initial_ttc=-1), "initial_ttc"),
        (lambda: straight_roads(min_width=8, max_width=4), "min_width"),
        (lambda: straight_roads(min_width=1), "min_width"),
        (lambda: straight_roads(max_lanes=0), "max_lanes"),
        (lambda: ego_speed_changes("CPFA-50"), "source"),
        (lambda: ego_speed_changes(SOURCE, min_speed_kmh=30, max_speed_kmh=20), "min_speed"),
        (lambda: ego_speed_changes(SOURCE, min_speed_kmh=20, max_speed_kmh=20), "no speed change"),
        (lambda: ego_speed_changes(SOURCE, step_kmh=0), "step_kmh"),
        (lambda: ego_speed_changes(SOURCE, keep="nothing"), "keep"),
    ],
)  # fmt: skip
def test_bad_arguments_fail_at_construction(call, message: str) -> None:
    with pytest.raises(InvalidArgument, match=message):
        call()
