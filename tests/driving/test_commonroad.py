"""CommonRoad's second opinion: its collision checker and vehicle model on our AEB runs.

Runs where the ``commonroad`` extra is installed (``.ci/run`` gives it an environment of
its own: commonroad-io pins protobuf 3.20, which onnxruntime refuses); elsewhere only the
missing-extra message is checked.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.driving.aeb import mutant_fixed_lane, reference_controller
from pytest_metamorphic.driving.campaign import default_sources
from pytest_metamorphic.driving.commonroad import (
    braking_avoids,
    crime_stops_short,
    crosscheck_campaign,
    first_contact,
    format_crosscheck,
    write_commonroad,
)
from pytest_metamorphic.driving.judge import judge_avoidable
from pytest_metamorphic.driving.kinematics import simulate
from pytest_metamorphic.driving.scenario import TYPICAL_CAR, euro_ncap

HAVE_COMMONROAD = importlib.util.find_spec("commonroad_dc") is not None
needs_commonroad = pytest.mark.skipif(
    not HAVE_COMMONROAD, reason="the commonroad extra is not installed (see .ci/run)"
)


def test_without_the_extra_the_message_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(sys.modules, "commonroad_dc.pycrcc", None)
    result = simulate(euro_ncap("CPNA-25"), reference_controller())
    with pytest.raises(InvalidArgument, match=r"pytest-metamorphic\[commonroad\]"):
        first_contact(result)
    with pytest.raises(InvalidArgument, match="SimulationResult"):
        first_contact("a run")  # type: ignore[arg-type]


@needs_commonroad
def test_commonroads_checker_finds_our_contacts_and_no_others() -> None:
    base = euro_ncap("CPNCO-50", ego_speed_kmh=20)
    avoided = simulate(base, mutant_fixed_lane())
    assert avoided.avoided and first_contact(avoided) is None
    hit = simulate(base.with_ego_speed(25, keep="pedestrian"), mutant_fixed_lane())
    assert hit.collision is not None and hit.collision.location == "side"
    theirs = first_contact(hit)
    assert theirs is not None
    assert hit.collision.time <= theirs <= hit.collision.time + 0.01 + 1e-9


@needs_commonroad
def test_commonroads_vehicle_model_agrees_with_the_judge() -> None:
    base = euro_ncap("CPNCO-50", ego_speed_kmh=20, vehicle=TYPICAL_CAR)
    for speed, avoidable in ((24, True), (26, False)):
        scenario = base.with_ego_speed(speed, keep="pedestrian")
        verdict = judge_avoidable(scenario)
        assert verdict.avoidable is avoidable and verdict.brake_time is not None
        assert braking_avoids(scenario, verdict.brake_time) is avoidable
        # Braking a second later never avoids what braking on time could not.
        assert not braking_avoids(scenario, verdict.brake_time + 1.0)


@needs_commonroad
def test_the_default_campaign_has_no_disagreement(shared_data: Path) -> None:
    speeds = (20, 23, 24, 25, 26, 27, 40, 80)
    report = crosscheck_campaign(default_sources(shared_data), speeds_kmh=speeds)
    assert report.runs == 3 * 3 * len(speeds)
    assert report.contacts == 12 and report.judged == 12
    assert report.contact_disagreements == [] and report.judge_disagreements == []
    assert report.lane_judged == 12 and report.crime_disagreements == []
    text = format_crosscheck(report, title="CPNCO-50")
    assert "12 contacts; 0 disagree" in text and "disagrees with the judge on 0" in text
    assert "CriMe's headway" in text


@needs_commonroad
def test_crimes_headway_agrees_with_the_lane_standard_on_a_turned_street(
    shared_data: Path,
) -> None:
    """8th Street heads 164 degrees: CriMe's headway is only right in a frame where the
    lane heads along +x, which commonroad_scenario turns the world into."""
    street = default_sources(shared_data)[1].scenario
    for speed, stops in ((23, False), (24, False)):
        scenario = street.with_ego_speed(speed, keep="pedestrian")
        lane = judge_avoidable(scenario, relevance="lane")
        crime = crime_stops_short(scenario, reaction=0.4, visible_from=lane.visible_time or 0.0)
        assert crime.time == pytest.approx(lane.relevant_time, abs=0.011)
        # The true headway then: bumper to the child's near face along the road.
        motion = scenario.pedestrian()
        front = scenario.ego_start_s + scenario.ego_speed * crime.time
        true = float(motion.road_position(crime.time)[0]) - motion.extent_along_road / 2 - front
        assert crime.headway == pytest.approx(true, abs=0.25)
        assert crime.stops_short is stops
    test_road = euro_ncap("CPNCO-50", ego_speed_kmh=20, vehicle=TYPICAL_CAR)
    verdict = crime_stops_short(test_road.with_ego_speed(23, keep="pedestrian"), reaction=0.4)
    assert verdict.stops_short and verdict.ttc > 0


@needs_commonroad
def test_a_run_is_written_as_a_commonroad_scenario(tmp_path: Path) -> None:
    from commonroad.common.file_reader import CommonRoadFileReader

    run = simulate(euro_ncap("CPNCO-50", ego_speed_kmh=30), reference_controller())
    path = write_commonroad(run, tmp_path / "run.xml")
    scenario, _ = CommonRoadFileReader(str(path)).open()
    kinds = sorted(o.obstacle_type.value for o in scenario.obstacles)
    assert kinds == ["car", "parkedVehicle", "parkedVehicle", "pedestrian"]
    car = scenario.obstacle_by_id(100)
    assert len(car.prediction.trajectory.state_list) == len(run.times) - 1
    assert len(scenario.lanelet_network.lanelets) == 1


@needs_commonroad
def test_the_command_line_adds_the_crosscheck(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pytest_metamorphic.reports.aeb_campaign import main

    argv = ["--data", str(shared_data), "--min-speed", "24", "--max-speed", "26"]
    assert main([*argv, "--no-artifacts", "--crosscheck"]) == 0
    out = capsys.readouterr().out
    assert "CommonRoad cross-check:" in out and "9 contacts; 0 disagree" in out
