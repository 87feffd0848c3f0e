"""Simulator physics against closed forms; scenarios against the protocol's synchronisation."""

from __future__ import annotations

import dataclasses
import math

import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.core.comparison import first_difference
from pytest_metamorphic.driving.aeb import mutant_fixed_lane, reference_controller
from pytest_metamorphic.driving.kinematics import (
    BrakeCommand,
    Observation,
    Sensor,
    physically_avoidable,
    simulate,
    stopping_distance,
)
from pytest_metamorphic.driving.kinematics.geometry import _corners
from pytest_metamorphic.driving.kinematics.simulator import _classify
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import (
    CHILD,
    EURO_NCAP_CAR,
    KINDS,
    KMH,
    OBSTRUCTION_SMALL,
    VehicleSpec,
    euro_ncap,
)


class ConstantBraking:
    """Brakes at ``deceleration`` from ``start`` seconds on."""

    def __init__(self, deceleration: float, start: float = 0.0) -> None:
        self.deceleration, self.start = deceleration, start

    def __call__(self, observation: Observation) -> float:
        return self.deceleration if observation.time >= self.start - 1e-9 else 0.0


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("speed", [10, 35, 60])
def test_unbraked_car_hits_exactly_at_the_time_to_collision_point(kind: str, speed: int) -> None:
    scenario = euro_ncap(kind, ego_speed_kmh=speed)
    assert scenario.time_to_collision_point == pytest.approx(6.0)
    result = simulate(scenario)
    assert result.collision is not None
    assert result.collision.time == pytest.approx(6.0, abs=1e-6)
    assert result.collision.location == "front"
    assert result.collision.impact_speed_kmh == pytest.approx(speed)
    assert result.collision.ego_s == pytest.approx(scenario.contact_s, abs=1e-5)


def test_contact_time_does_not_depend_on_the_step() -> None:
    scenario = euro_ncap("CPFA-50", ego_speed_kmh=47, initial_ttc=4.321)
    times = {dt: simulate(scenario, dt=dt).collision.time for dt in (0.003, 0.01, 0.05, 0.1)}
    assert max(times.values()) - min(times.values()) < 1e-6
    assert times[0.01] == pytest.approx(4.321, abs=1e-6)


@pytest.mark.parametrize(
    ("kind", "walked"),
    [("CPNA-25", 4 - 0.45375), ("CPNA-75", 4 + 0.45375), ("CPFA-50", 6.0), ("CPLA-50", 11.0)],
)
def test_dummy_is_synchronised_with_the_protocol_impact_point(kind: str, walked: float) -> None:
    scenario = euro_ncap(kind, ego_speed_kmh=30)
    motion = scenario.pedestrian()
    t = scenario.time_to_collision_point
    assert float(motion.walked(t)) == pytest.approx(walked)
    protocol = scenario.protocol
    v, g = protocol.dummy_speed_kmh * KMH, protocol.acceleration_distance
    assert motion.start_time == pytest.approx(t - (2 * g / v + (walked - g) / v))
    s, d = motion.road_position(t)
    if protocol.motion == "longitudinal":
        assert (float(s), float(d)) == pytest.approx((scenario.conflict_s, 0.0))
    else:
        # Impact at pct % of the car's width counted from the side the dummy comes from.
        sign = 1 if protocol.motion == "near" else -1
        assert float(d) == pytest.approx(sign * scenario.impact_offset)


@pytest.mark.parametrize(
    ("speed_kmh", "deceleration", "delay"),
    [(20, 9.8, 0.0), (50, 9.8, 0.0), (50, 5.3, 0.2), (60, 3.8, 0.35), (10, 9.8, 1.0)],
)
def test_stopping_distance_matches_closed_form(
    speed_kmh: float, deceleration: float, delay: float
) -> None:
    vehicle = VehicleSpec(brake_delay=delay)
    scenario = euro_ncap("CPNA-75", ego_speed_kmh=speed_kmh, vehicle=vehicle, initial_ttc=8)
    result = simulate(scenario, ConstantBraking(deceleration))
    assert result.avoided and result.final_speed == 0.0
    travelled = result.ego_s - scenario.ego_start_s
    v = speed_kmh * KMH
    assert travelled == pytest.approx(v * delay + v**2 / (2 * deceleration), abs=1e-9)
    assert travelled == pytest.approx(stopping_distance(v, deceleration, delay), abs=1e-9)
    assert result.end_time == pytest.approx(delay + v / deceleration, abs=0.011)
    assert result.first_brake_time == 0.0


def test_impact_speed_matches_closed_form() -> None:
    # Light braking from t = 0: the car reaches the dummy's near face slower and a bit
    # late, while the dummy is still in front of it.
    scenario = euro_ncap("CPNA-25", ego_speed_kmh=50)
    a, v, distance = 0.2, 50 * KMH, scenario.ego_distance
    result = simulate(scenario, ConstantBraking(a))
    impact = math.sqrt(v**2 - 2 * a * distance)
    assert result.collision is not None and result.collision.location == "front"
    assert result.collision.impact_speed == pytest.approx(impact, abs=1e-6)
    assert result.collision.time == pytest.approx((v - impact) / a, abs=1e-6)


def test_braking_late_enough_lets_the_dummy_clear_the_path() -> None:
    # Full braking just early enough stops the car short of the dummy's path; 0.3 s later
    # it no longer does (and the dummy, at 25 % impact, has not cleared the car's width).
    scenario = euro_ncap("CPNA-25", ego_speed_kmh=20)
    v = 20 * KMH
    start = 6.0 - stopping_distance(v, 9.8) / v - 0.1
    assert simulate(scenario, ConstantBraking(9.8, start)).avoided
    assert simulate(scenario, ConstantBraking(9.8, start + 0.3)).collided


def test_curved_osm_like_road_keeps_the_synchronisation() -> None:
    road = RoadGeometry([[0, 0], [40, 0], [80, 8], [140, 30]], width=6.0, lanes=2, name="bent")
    scenario = euro_ncap("CPFA-50", ego_speed_kmh=40, road=road, conflict_s=90.0)
    result = simulate(scenario)
    assert result.collision is not None and result.collision.location == "front"
    assert result.collision.time == pytest.approx(6.0, abs=0.02)


def test_parked_cars_hide_the_child_until_it_steps_out() -> None:
    scenario = euro_ncap("CPNCO-50", ego_speed_kmh=30)
    small, large = scenario.obstructions()
    assert small.footprint == OBSTRUCTION_SMALL
    # 1 m between the small car's front and the child's path, 1 m between the cars.
    assert small.s + small.footprint.length / 2 == pytest.approx(
        scenario.conflict_s - CHILD.width / 2 - 1
    )
    assert small.s - small.footprint.length / 2 - (
        large.s + large.footprint.length / 2
    ) == pytest.approx(1.0)
    assert small.d == pytest.approx(-(1 + scenario.vehicle.width / 2 + 1.82 / 2))

    def first_seen(sensor: Sensor) -> float:
        seen: list[float] = []

        def probe(observation: Observation) -> float:
            if any(track.kind == "pedestrian" for track in observation.tracks):
                seen.append(observation.time)
            return 0.0

        simulate(scenario, probe, sensor=sensor)
        return seen[0]

    assert first_seen(Sensor(occlusion=False)) == 0.0
    hidden_until = first_seen(Sensor())
    start = scenario.pedestrian_start_time
    assert start + 1.0 < hidden_until < scenario.time_to_collision_point


@pytest.mark.parametrize("clockwise", [False, True])
def test_an_occluder_hides_whichever_way_its_corners_run(clockwise: bool) -> None:
    # highway-env lists a body's corners clockwise; the sensor used to treat every box as
    # counter-clockwise, so in the highway-env adapter no parked car hid the child
    car = [(34.23, -3.71), (38.54, -3.71), (38.54, -1.93), (34.23, -1.93)]
    occluder = tuple(reversed(car)) if clockwise else tuple(car)
    child = ((39.54, -4.36), (39.84, -4.36), (39.84, -3.64), (39.54, -3.64))
    assert not Sensor().sees((6.2, 0.0), 0.0, child, [occluder])  # type: ignore[arg-type]
    assert Sensor().sees((6.2, 0.0), 0.0, child, [])  # type: ignore[arg-type]
    # far enough back, the child's outer corners show past the car's outer side
    assert Sensor().sees((-60.0, 0.0), 0.0, child, [occluder])  # type: ignore[arg-type]


def test_face_classification() -> None:
    ego = _corners(0, 0, 0.3, 4.0, 2.0)
    c, s = math.cos(0.3), math.sin(0.3)

    def at(x: float, y: float) -> tuple:
        return _corners(x * c - y * s, x * s + y * c, 0.3, 0.5, 0.5)

    assert _classify(ego, 0.3, at(2.2, 0.1)) == ("front", None)
    assert _classify(ego, 0.3, at(-2.2, 0.0)) == ("rear", None)
    assert _classify(ego, 0.3, at(0.5, 1.2)) == ("side", "left")
    assert _classify(ego, 0.3, at(-1.0, -1.24)) == ("side", "right")


def test_runs_are_deterministic_and_comparable() -> None:
    scenario = euro_ncap("CPNCO-50", ego_speed_kmh=40)
    first, second = (
        simulate(scenario, ConstantBraking(5.0, 3.0)),
        simulate(scenario, ConstantBraking(5.0, 3.0)),
    )
    assert first_difference(first, second) is None
    assert "CPNCO-50 at 40 km/h" in first.describe()


def test_physically_avoidable_matches_the_stopping_distance() -> None:
    # At these speeds the adult is already walking in the 10 m lane at t = 0, so it is
    # relevant at once and the gap is the start distance minus the stopping distance.
    source = euro_ncap("CPNA-25", ego_speed_kmh=20)
    for speed in (60, 85, 88, 89, 95):
        scenario = source.with_ego_speed(speed)
        result = physically_avoidable(scenario, slack=0.1)
        v = speed * KMH
        gap = scenario.ego_distance - stopping_distance(v, 9.8, 0.1)
        assert result.relevant_time == 0.0
        assert result.avoidable == (gap > 0)
        if gap > 0:
            assert result.gap == pytest.approx(gap, abs=1e-9)


def test_physically_avoidable_waits_for_relevance() -> None:
    scenario = euro_ncap("CPNCO-50", ego_speed_kmh=40)
    result = physically_avoidable(scenario)
    assert result.avoidable
    # Not before the child steps out from behind the parked cars.
    assert result.relevant_time > scenario.pedestrian_start_time + 1.0
    assert "avoidable" in result.describe()


def test_relevance_on_the_road_or_only_in_the_lane() -> None:
    # A far-side adult on a 6 m two-lane street steps onto the road 4.5 m from the car's
    # path but enters its lane only 1.5 m from it.
    street = RoadGeometry.straight(width=6.0, lanes=2)
    scenario = euro_ncap("CPFA-50", ego_speed_kmh=20, road=street).with_ego_speed(80)
    road, lane = physically_avoidable(scenario), physically_avoidable(scenario, relevance="lane")
    assert road.avoidable and not lane.avoidable
    assert road.relevant_time < lane.relevant_time
    with pytest.raises(InvalidArgument, match="relevance"):
        physically_avoidable(scenario, relevance="kerb")  # type: ignore[arg-type]


def test_controller_contract_is_checked() -> None:
    scenario = euro_ncap("CPNA-25")
    with pytest.raises(InvalidArgument, match="deceleration"):
        simulate(scenario, lambda observation: "brake!")
    with pytest.raises(InvalidArgument, match="dt"):
        simulate(scenario, dt=0.5)
    with pytest.raises(InvalidArgument, match="scenario"):
        simulate("CPNA-25")  # type: ignore[arg-type]
    result = simulate(scenario, lambda observation: BrakeCommand(100.0, "max"))
    assert result.stages == ((0.0, "max"),)
    # Requests beyond the brakes' capability are clipped to max_deceleration.
    assert result.decelerations.max() == scenario.vehicle.max_deceleration


def test_scenario_validation_and_transforms() -> None:
    scenario = euro_ncap("CPFA-50", ego_speed_kmh=20)
    faster = scenario.with_ego_speed(40)
    assert faster.ego_start_s == scenario.ego_start_s
    assert faster.time_to_collision_point == pytest.approx(3.0)
    same_time = scenario.with_ego_speed(40, keep="time")
    assert same_time.time_to_collision_point == pytest.approx(6.0)
    assert same_time.pedestrian_start_time == pytest.approx(scenario.pedestrian_start_time)
    assert faster.pedestrian_start_time == pytest.approx(scenario.pedestrian_start_time - 3.0)
    with pytest.raises(InvalidArgument, match="keep"):
        scenario.with_ego_speed(40, keep="distance")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="dummy_arrival_time"):
        dataclasses.replace(scenario, dummy_arrival_time=0.0)
    with pytest.raises(InvalidArgument, match="kind"):
        euro_ncap("CPXX-50")
    with pytest.raises(InvalidArgument, match="ego_speed_kmh"):
        dataclasses.replace(scenario, ego_speed_kmh=-5)
    with pytest.raises(InvalidArgument, match="lane"):
        euro_ncap("CPFA-50", ego_lane=1)
    with pytest.raises(InvalidArgument, match="brake_delay"):
        VehicleSpec(brake_delay=-1)


def test_keeping_the_pedestrian_timing_makes_a_faster_car_early() -> None:
    """Iqbal's follow-up: car start and pedestrian motion kept, only the speed changes."""
    source = euro_ncap("CPNCO-50", ego_speed_kmh=20)
    early = source.with_ego_speed(25, keep="pedestrian")
    assert early.ego_start_s == source.ego_start_s
    assert early.time_to_collision_point == pytest.approx(source.time_to_collision_point * 0.8)
    assert early.pedestrian() == source.pedestrian()
    assert early.dummy_arrival == pytest.approx(6.0)
    # Kept again in a follow-up of the follow-up, not re-derived from the new speed.
    assert early.with_ego_speed(30, keep="pedestrian").pedestrian() == source.pedestrian()
    assert "dummy at the impact position at 6.00 s" in early.describe()
    # Without braking, a car 1.2 s early is still beside the dummy's path when the dummy
    # arrives; at 40 km/h it is through before.
    assert simulate(early).collision.location == "side"  # type: ignore[union-attr]
    assert simulate(source.with_ego_speed(40, keep="pedestrian")).avoided
    # The 3.6 m-lane AEB ignores the child until it is 1.8 m from the car's path: by then
    # the car is beside it, and the child walks into its right side.
    result = simulate(early, mutant_fixed_lane())
    assert result.collision is not None
    assert (result.collision.location, result.collision.side) == ("side", "right")
    assert result.collision.time > early.time_to_collision_point
    assert simulate(early, reference_controller()).avoided
    assert physically_avoidable(early).avoidable


def test_a_car_standing_in_the_dummys_path_is_not_a_collision() -> None:
    """Euro NCAP ends a test at standstill: a dummy walking into the standing car later
    is no collision of the car (the reference stops late but stands before the contact)."""
    early = euro_ncap("CPNCO-50", ego_speed_kmh=20).with_ego_speed(41, keep="pedestrian")
    result = simulate(early, reference_controller())
    assert result.avoided and result.final_speed == 0
    motion = early.pedestrian()
    assert result.end_time < early.dummy_arrival
    # The car stopped across the dummy's path (its front beyond the crossing line).
    assert result.ego_s > motion.s0


def test_sensor_latency_shows_the_controller_an_old_world() -> None:
    """With 0.1 s latency at 10 ms steps the controller sees the first observation for
    ten steps, then each one ten steps late: the car's speed as it was, too."""
    seen: list[tuple[float, float]] = []

    def recorder(observation: Observation) -> float:
        seen.append((observation.time, observation.ego_speed))
        return 9.8 if observation.time >= 0.5 else 0.0

    car = dataclasses.replace(EURO_NCAP_CAR, sensor_latency=0.1)
    result = simulate(euro_ncap("CPNA-25", ego_speed_kmh=30, vehicle=car), recorder)
    times = [t for t, _ in seen]
    assert times[:11] == [0.0] * 11 and times[11] == pytest.approx(0.01)
    assert times[70] == pytest.approx(0.6)
    # It asked for braking on the observation of t = 0.5 s, which it saw at 0.6 s.
    assert result.first_brake_time == pytest.approx(0.6)
    assert result.avoided
    with pytest.raises(InvalidArgument, match="sensor_latency"):
        dataclasses.replace(EURO_NCAP_CAR, sensor_latency=-0.1)
    assert car.system_delay == pytest.approx(0.1)
