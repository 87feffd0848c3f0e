"""Bring your own simulator: the adapter contract, and highway-env (from PyPI) as one."""

from __future__ import annotations

from pathlib import Path

import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.driving.aeb import reference_controller
from pytest_metamorphic.driving.campaign import default_sources, format_campaign, iqbal_campaign
from pytest_metamorphic.driving.kinematics import simulate
from pytest_metamorphic.driving.scenario import KINDS, euro_ncap
from pytest_metamorphic.driving.simulators import builtin, check_simulator, run_simulator

pytest.importorskip("highway_env", reason="the highway-env extra is not installed")
from pytest_metamorphic.driving.simulators.highway_env import HighwayEnvSimulator

HIGHWAY = HighwayEnvSimulator()


def test_the_simulator_contract_is_checked() -> None:
    assert check_simulator(None) is builtin
    assert check_simulator(HIGHWAY) is HIGHWAY
    with pytest.raises(InvalidArgument, match="simulator=3 must be callable"):
        check_simulator(3)

    def broken(scenario: object, controller: object) -> str:
        return "collided"

    with pytest.raises(InvalidArgument, match="simulator broken returned str"):
        run_simulator(broken, euro_ncap("CPNA-25"), None)
    with pytest.raises(InvalidArgument, match="dt"):
        HighwayEnvSimulator(dt=0.5)
    with pytest.raises(InvalidArgument, match="must be a Scenario"):
        HIGHWAY("CPNA-25", None)  # type: ignore[arg-type]


@pytest.mark.parametrize("kind", KINDS)
def test_highway_env_finds_the_protocols_impact_without_braking(kind: str) -> None:
    """Synchronised dummy, no AEB: both simulators hit it at the front, at the same time
    (highway-env reports a contact at the end of the step it happens in)."""
    scenario = euro_ncap(kind, ego_speed_kmh=40)
    ours, theirs = simulate(scenario), HIGHWAY(scenario, None)
    assert ours.collision is not None and theirs.collision is not None
    assert theirs.collision.location == ours.collision.location == "front"
    assert theirs.collision.time == pytest.approx(ours.collision.time, abs=2 * HIGHWAY.dt)
    assert theirs.collision.impact_speed == pytest.approx(scenario.ego_speed, rel=1e-6)
    assert theirs.ego_s == pytest.approx(ours.collision.ego_s, abs=0.3)


@pytest.mark.parametrize("kind", ["CPNA-25", "CPNCO-50", "CPFA-50"])
def test_the_reference_aeb_stops_in_highway_env_as_in_ours(kind: str) -> None:
    scenario = euro_ncap(kind, ego_speed_kmh=20)
    ours = simulate(scenario, reference_controller())
    theirs = HIGHWAY(scenario, reference_controller())
    assert ours.avoided and theirs.avoided
    assert theirs.final_speed == 0.0
    assert theirs.first_brake_time == pytest.approx(ours.first_brake_time, abs=0.02)
    assert theirs.ego_s == pytest.approx(ours.ego_s, abs=0.1)
    assert [stage for _, stage in theirs.stages] == [stage for _, stage in ours.stages]


def _first_seen(simulator, scenario) -> float:  # type: ignore[no-untyped-def]
    seen: list[float] = []

    def probe(observation):  # type: ignore[no-untyped-def]
        if any(track.kind == "pedestrian" for track in observation.tracks):
            seen.append(observation.time)
        return 0.0

    run_simulator(simulator, scenario, probe)
    return seen[0]


@pytest.mark.parametrize("speed", [20, 40])
def test_highway_envs_lidar_hides_the_child_behind_the_parked_cars_as_our_sensor_does(
    speed: int,
) -> None:
    # highway-env's own LidarObservation decides visibility here: it agrees with our
    # line-of-sight sensor (built-in and in highway-env) to within two 10 ms steps
    scenario = euro_ncap("CPNCO-50", ego_speed_kmh=speed)
    built_in = _first_seen(check_simulator(None), scenario)
    ours = _first_seen(HighwayEnvSimulator(), scenario)
    lidar = _first_seen(HighwayEnvSimulator(visibility="lidar"), scenario)
    assert scenario.pedestrian_start_time + 1.0 < built_in < scenario.time_to_collision_point
    assert ours == pytest.approx(built_in, abs=0.021)
    assert lidar == pytest.approx(built_in, abs=0.021)


def test_highway_env_lidar_settings_are_checked() -> None:
    with pytest.raises(InvalidArgument, match="visibility"):
        HighwayEnvSimulator(visibility="radar")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="lidar_cells"):
        HighwayEnvSimulator(visibility="lidar", lidar_cells=2)
    assert "lidar_cells=1440" in repr(HighwayEnvSimulator(visibility="lidar"))


def test_highway_env_steers_along_a_real_street(shared_data: Path) -> None:
    """On 8th Street (12 vertices) highway-env's own lane keeping drives the car; the
    unbraked car still meets the dummy where ours does."""
    street = default_sources(shared_data)[1].scenario.with_ego_speed(30)
    ours, theirs = simulate(street), HIGHWAY(street, None)
    assert theirs.collision is not None and ours.collision is not None
    assert theirs.collision.location == "front"
    assert theirs.collision.time == pytest.approx(ours.collision.time, abs=0.05)


def test_iqbals_campaign_in_highway_env_finds_the_fault_on_every_source(
    shared_data: Path,
) -> None:
    # Where the built-in simulator finds the violations (24-26 km/h): the car ~1 s early.
    rows = iqbal_campaign(default_sources(shared_data), speeds_kmh=(24, 25, 26), simulator=HIGHWAY)
    for row in rows:
        assert not row.source_collided
        if row.controller != "3.6 m lane mutant":
            assert row.collisions == (), format_campaign([row])
        else:
            sides = [c for c in row.avoidable_violations if c.location == "side"]
            assert sides and all(c.side == "right" for c in sides), format_campaign([row])


@pytest.mark.slow
def test_the_full_campaign_in_highway_env_gives_the_built_in_table(shared_data: Path) -> None:
    """All 765 follow-ups: the same violations at the same speeds in both simulators
    (a contact at the corner may be classified front in one and side in the other)."""
    sources = default_sources(shared_data)
    ours, theirs = iqbal_campaign(sources), iqbal_campaign(sources, simulator=HIGHWAY)
    for a, b in zip(ours, theirs, strict=True):
        assert [c.speed_kmh for c in a.violations] == [c.speed_kmh for c in b.violations]
        assert [c.avoidable for c in a.violations] == [c.avoidable for c in b.violations]
        assert len(a.avoidable_violations) == len(b.avoidable_violations)
