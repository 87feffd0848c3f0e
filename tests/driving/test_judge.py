"""The independent avoidability judge: its standards, and agreement with the simulator."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.driving import judge as judge_module
from pytest_metamorphic.driving.judge import judge_avoidable
from pytest_metamorphic.driving.kinematics import Observation, simulate
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import TYPICAL_CAR, euro_ncap


def test_the_judge_shares_no_code_with_controllers_or_simulator() -> None:
    tree = ast.parse(Path(judge_module.__file__).read_text())
    imported = {
        node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module
    }
    assert not any(
        name.startswith(("pytest_metamorphic.driving.kinematics", "pytest_metamorphic.driving.aeb"))
        for name in imported
    ), imported


class _BrakeAt:
    """Open loop: the car's full deceleration from ``time`` on."""

    def __init__(self, time: float | None, deceleration: float) -> None:
        self.time, self.deceleration = time, deceleration

    def __call__(self, observation: Observation) -> float:
        if self.time is None or observation.time < self.time - 1e-9:
            return 0.0
        return self.deceleration


@pytest.mark.parametrize("kind", ["CPNA-25", "CPNA-75", "CPNCO-50", "CPFA-50"])
@pytest.mark.parametrize("width", [5.0, 10.0])
def test_verdicts_agree_with_braking_in_the_built_in_simulator(kind: str, width: float) -> None:
    """The judge computes on its own (road-aligned rectangles, 1 ms samples); the simulator
    braking open-loop at the judge's brake time must reach the same outcome."""
    road = RoadGeometry.straight(width=width)
    base = euro_ncap(kind, ego_speed_kmh=20, road=road, vehicle=TYPICAL_CAR)
    # The judge's reaction time already holds the car's delays: brake without them.
    prompt = dataclasses.replace(TYPICAL_CAR, brake_delay=0.0, sensor_latency=0.0)
    checked = 0
    for keep in ("ego_start", "pedestrian"):
        for speed in range(25, 101, 5):
            scenario = base.with_ego_speed(speed, keep=keep)  # type: ignore[arg-type]
            verdict = judge_avoidable(scenario)
            if verdict.relevant_time is None or abs(verdict.gap) < 0.05:
                continue  # never a hazard, or too close to the boundary to compare
            run = simulate(
                dataclasses.replace(scenario, vehicle=prompt),
                _BrakeAt(verdict.brake_time, prompt.max_deceleration),
            )
            passes_first = verdict.standard.endswith("passes first")
            assert run.avoided == (verdict.avoidable or passes_first), (
                scenario,
                verdict.describe(),
            )
            checked += 1
    assert checked >= 10


def test_a_hazard_needs_a_line_of_sight_past_the_parked_cars() -> None:
    hidden = euro_ncap("CPNCO-50", ego_speed_kmh=30)
    verdict = judge_avoidable(hidden)
    assert verdict.visible_time is not None and verdict.relevant_time is not None
    # CPNA-25 is the same walk (same side, E, G and speed) without the parked cars.
    open_road = judge_avoidable(euro_ncap("CPNA-25", ego_speed_kmh=30))
    assert open_road.visible_time == 0.0
    assert hidden.pedestrian().start_time < verdict.visible_time
    assert verdict.relevant_time >= verdict.visible_time


def test_standards_order_the_hazard_on_a_wide_road() -> None:
    """On a 12 m road with a 3 m lane: onto the carriageway, then into the lane, then
    into the swept path."""
    road = RoadGeometry.straight(width=12.0, lanes=4)
    scenario = euro_ncap("CPNA-25", ego_speed_kmh=40, road=road, ego_lane=1, placement="road")
    times = [
        judge_avoidable(scenario, relevance=standard).relevant_time
        for standard in ("carriageway", "lane", "path")
    ]
    assert times[0] < times[1] < times[2]  # type: ignore[operator]


def test_reaction_time_holds_the_cars_own_delays() -> None:
    ideal = euro_ncap("CPNA-25", ego_speed_kmh=40)
    typical = dataclasses.replace(ideal, vehicle=TYPICAL_CAR)
    a, b = judge_avoidable(ideal), judge_avoidable(typical, decision_time=0.0)
    assert a.brake_time == pytest.approx(a.relevant_time + 0.1, abs=1e-9)  # type: ignore[operator]
    assert b.brake_time == pytest.approx(b.relevant_time + 0.3, abs=1e-9)  # type: ignore[operator]
    assert "reaction 0.30 s, 9 m/s^2" in b.standard


def test_missing_only_by_passing_first_is_not_avoidance() -> None:
    """Start 2 s before the crossing at 20 km/h, follow-up at 60 km/h with the child's
    timing kept: full braking leaves the car passing before the child arrives."""
    source = euro_ncap("CPNCO-50", ego_speed_kmh=20, vehicle=TYPICAL_CAR, initial_ttc=2.0)
    verdict = judge_avoidable(source.with_ego_speed(60, keep="pedestrian"))
    assert not verdict.avoidable
    assert "only by passing before it arrives" in verdict.describe()


def test_judge_arguments_are_checked() -> None:
    scenario = euro_ncap("CPNA-25")
    with pytest.raises(InvalidArgument, match="relevance"):
        judge_avoidable(scenario, relevance="kerb")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="decision_time"):
        judge_avoidable(scenario, decision_time=-1)
    with pytest.raises(InvalidArgument, match="Scenario"):
        judge_avoidable("CPNA-25")  # type: ignore[arg-type]


def test_never_a_hazard_before_contact_is_unavoidable() -> None:
    # The car 1 s early, the child walking into its right side: by the swept-path
    # standard the child is in the car's way only when it touches the car.
    early = euro_ncap("CPNCO-50", ego_speed_kmh=20).with_ego_speed(25, keep="pedestrian")
    verdict = judge_avoidable(early, relevance="path")
    assert not verdict.avoidable and verdict.relevant_time is None
    assert "never visible and in the car's way" in verdict.describe()
    # By the default standard the child was a hazard when it stepped onto the road.
    assert judge_avoidable(early).avoidable
