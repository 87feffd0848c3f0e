"""The reference AEB controller's staging and object selection, and the 3.6 m-lane mutant."""

from __future__ import annotations

import dataclasses
import math

import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.driving.aeb import (
    AEBController,
    TTCController,
    mutant_fixed_lane,
    reference_controller,
    ttc_controller,
)
from pytest_metamorphic.driving.kinematics import Observation, Track, physically_avoidable, simulate
from pytest_metamorphic.driving.scenario import (
    KINDS,
    PROTOCOLS,
    TYPICAL_CAR,
    euro_ncap,
    euro_ncap_road,
)


def observe(speed: float, *tracks: Track, lane: tuple[float, float] = (-5.0, 5.0)) -> Observation:
    return Observation(0.0, 0.01, speed, 4.358, 1.815, *lane, *lane, tracks)


def walker(headway: float, d: float, *, vd: float = 1.4, vs: float = 0.0) -> Track:
    return Track(0, "pedestrian", headway + 0.25, d, vs, vd, 0.5, 0.6)


@pytest.mark.parametrize(
    ("ttc", "stage", "deceleration"),
    [(4.0, "off", 0.0), (3.5, "FCW", 0.0), (2.5, "PB1", 3.8), (1.5, "PB2", 5.3), (1.0, "FB", 9.8)],
)
def test_stages_follow_the_matlab_thresholds(ttc: float, stage: str, deceleration: float) -> None:
    # At 10 m/s: FCW 3.7 s, PB1 2.71 s, PB2 1.97 s, FB 1.10 s.
    controller = reference_controller()
    command = controller(observe(10.0, walker(10.0 * ttc, 0.0)))
    assert (command.stage, command.deceleration) == (stage, deceleration)
    assert controller.ttc == pytest.approx(ttc)


def test_braking_latches_and_escalates_but_warnings_do_not() -> None:
    controller = reference_controller()
    assert controller(observe(10.0, walker(35.0, 0.0))).stage == "FCW"
    assert controller(observe(10.0)).stage == "off"  # nothing ahead any more: warning drops
    assert controller(observe(10.0, walker(25.0, 0.0))).stage == "PB1"
    assert controller(observe(9.0)).stage == "PB1"  # object gone: keeps braking
    assert controller(observe(8.0, walker(5.0, 0.0))).stage == "FB"
    assert controller(observe(0.0, walker(30.0, 0.0))).deceleration == 9.8  # held at standstill
    controller.reset()
    assert controller.stage == "off" and controller.mio is None


def test_most_important_object_uses_the_real_lane_or_a_fixed_corridor() -> None:
    near, wide, behind = walker(30.0, -0.5), walker(10.0, 4.0), walker(-1.0, 0.0)
    parked = Track(1, "vehicle", 5.0, -2.8, 0.0, 0.0, 4.4, 1.8)
    reference = reference_controller()
    assert reference.most_important_object(observe(10.0, near, wide, behind, parked)) is wide
    # On a 3 m lane the same pedestrian 4 m away is not a candidate yet.
    narrow = observe(10.0, near, wide, parked, lane=(-1.5, 1.5))
    assert reference.most_important_object(narrow) is near
    mutant = mutant_fixed_lane()
    assert mutant.lane_width == 3.6
    assert mutant.most_important_object(observe(10.0, near, wide, parked)) is near
    assert mutant.most_important_object(observe(10.0, walker(10.0, 1.79))).d == 1.79
    assert mutant.most_important_object(observe(10.0, walker(10.0, 1.81))) is None
    # A standing object counts only in the swept path: parked cars beside it never do.
    standing = Track(2, "pedestrian", 12.0, 1.1, 0.0, 0.0, 0.5, 0.6)
    assert reference.most_important_object(observe(10.0, parked, standing)) is standing
    assert mutant.most_important_object(observe(10.0, parked)) is None


def test_reference_takes_pedestrians_from_the_whole_road_but_vehicles_from_its_lane() -> None:
    # The car in the right lane of a 6 m two-lane street: lane (-1.5, 1.5), road (-1.5, 4.5).
    observation = Observation(0.0, 0.01, 10.0, 4.358, 1.815, -1.5, 1.5, -1.5, 4.5, ())
    far_walker = walker(20.0, 4.0, vd=-1.4)
    oncoming = Track(3, "vehicle", 15.0, 3.0, -10.0, 0.0, 4.4, 1.8)
    reference = reference_controller()
    assert reference.in_corridor(far_walker, observation)
    assert not reference.in_corridor(oncoming, observation)
    assert not AEBController(pedestrian_region="lane").in_corridor(far_walker, observation)
    assert not mutant_fixed_lane().in_corridor(far_walker, observation)


def test_receding_objects_have_no_ttc() -> None:
    controller = reference_controller()
    command = controller(observe(5.0, walker(3.0, 0.0, vd=0.0, vs=6.0)))
    assert math.isinf(controller.ttc) and command.stage == "off"


@pytest.mark.parametrize("kind", KINDS)
def test_reference_passes_every_protocol_test_on_the_10m_road(kind: str) -> None:
    for speed in PROTOCOLS[kind].speeds_kmh:
        result = simulate(euro_ncap(kind, ego_speed_kmh=speed), reference_controller())
        assert result.avoided, result.describe()
        assert result.first_brake_time is not None


def test_mutant_collides_where_the_reference_stops_and_braking_could() -> None:
    scenario = euro_ncap("CPFA-50", ego_speed_kmh=20).with_ego_speed(70)
    assert simulate(scenario, reference_controller()).avoided
    crash = simulate(scenario, mutant_fixed_lane())
    assert crash.collision is not None and crash.collision.impact_speed_kmh > 20
    assert physically_avoidable(scenario).avoidable


def test_lane_width_is_validated() -> None:
    with pytest.raises(InvalidArgument, match="lane_width"):
        AEBController(lane_width=-3.6)
    with pytest.raises(InvalidArgument, match="pedestrian_region"):
        AEBController(pedestrian_region="sidewalk")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="fb_deceleration"):
        AEBController(fb_deceleration=0)
    assert euro_ncap_road().lane_width == 10.0


def test_the_staging_plans_with_the_cars_own_brakes_and_delays() -> None:
    """At 10 m/s a pedestrian 10 m ahead (TTC 1.0 s): the ideal car (9.8 m/s^2, no delay)
    needs 1.10 s to stop, so full braking; a car with 0.3 s of delays and 8 m/s^2 brakes
    needs 1.63 s: it already brakes fully at TTC 1.5 s, where the ideal car is in PB2."""
    ahead = walker(15.0, 0.0, vd=0.0)
    ideal = observe(10.0, ahead)
    slow = dataclasses.replace(ideal, max_deceleration=8.0, system_delay=0.3)
    assert reference_controller()(ideal).stage == "PB2"
    assert reference_controller()(slow).stage == "FB"
    command = reference_controller()(slow)
    assert command.deceleration == 9.8  # the request; the car's brakes clip it


def test_ttc_controller_brakes_for_a_predicted_crossing_only() -> None:
    controller = ttc_controller()
    # A pedestrian 2 m right of the path walking in at 1.4 m/s, 6 m ahead at 10 m/s:
    # it reaches the path before the car passes, and 0.6 s is within the stopping time.
    crossing = walker(6.0, -2.0, vd=1.4)
    assert controller(observe(10.0, crossing)).deceleration == 9.8
    # Braking holds until the car stands, whatever it sees next.
    assert controller(observe(5.0)).deceleration == 9.8
    controller.reset()
    # Standing beside the path, walking away, or far ahead: no braking.
    assert controller(observe(10.0, walker(6.0, -2.0, vd=0.0))).deceleration == 0.0
    assert controller(observe(10.0, walker(6.0, -2.0, vd=-1.4))).deceleration == 0.0
    assert controller(observe(10.0, walker(60.0, -2.0, vd=1.4))).deceleration == 0.0
    with pytest.raises(InvalidArgument, match="time_margin"):
        TTCController(time_margin=-1)


@pytest.mark.parametrize("kind", ["CPNA-25", "CPNA-75", "CPNCO-50", "CPFA-50", "CPLA-25"])
def test_ttc_controller_passes_the_protocol_tests_on_the_typical_car(kind: str) -> None:
    for speed in PROTOCOLS[kind].speeds_kmh:
        scenario = euro_ncap(kind, ego_speed_kmh=speed, vehicle=TYPICAL_CAR)
        assert simulate(scenario, ttc_controller()).avoided, scenario.describe()
