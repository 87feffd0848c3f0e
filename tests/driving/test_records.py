"""Recorded AEB scenarios replay exactly, and a record from outside is range-checked
before anything is simulated (issue: inputs from outside)."""

from __future__ import annotations

from typing import Any

import pytest

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.driving.records import LIMITS, scenario_from_json, scenario_to_json
from pytest_metamorphic.driving.scenario import euro_ncap


def record(**changes: Any) -> dict[str, Any]:
    data = scenario_to_json(euro_ncap("CPNA-25", ego_speed_kmh=40))
    for key, value in changes.items():
        target = data
        *parents, last = key.split(".")
        for parent in parents:
            target = target[parent]
        target[last] = value
    return data


def test_a_record_replays_the_same_scenario() -> None:
    scenario = euro_ncap("CPNA-25", ego_speed_kmh=40)
    assert scenario_from_json(scenario_to_json(scenario)).describe() == scenario.describe()


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("ego_distance", 1e9),  # before: a 38.9 GiB allocation, MemoryError
        ("ego_speed_kmh", 1e308),  # before: replayed as "passes now (fixed)"
        ("vehicle.brake_delay", 1e9),
        ("road.width", 1e6),
        ("road.lanes", 10**6),
        ("conflict_s", float("nan")),
        ("ego_speed_kmh", "fast"),
        ("ego_speed_kmh", True),
    ],
)
def test_a_quantity_beyond_its_limit_is_refused_before_simulation(key: str, value: Any) -> None:
    with pytest.raises(DataError, match=key.replace(".", r"\.")):
        scenario_from_json(record(**{key: value}))


def test_a_road_beyond_its_limits_is_refused() -> None:
    far = LIMITS["road.extent"] * 2
    with pytest.raises(DataError, match="reaches beyond"):
        scenario_from_json(record(**{"road.centerline": [[0, 0], [far, 0]]}))
    with pytest.raises(DataError, match="not \\(k, 2\\) numbers"):
        scenario_from_json(record(**{"road.centerline": [[0, "a"], [1, 0]]}))


def test_a_broken_record_is_a_data_error() -> None:
    data = record()
    del data["vehicle"]
    with pytest.raises(DataError, match="cannot be rebuilt"):
        scenario_from_json(data)
    with pytest.raises(DataError, match="not a recorded AEB scenario"):
        scenario_from_json([])  # type: ignore[arg-type]


def test_placement_cross_section_and_delays_are_recorded() -> None:
    from pytest_metamorphic.driving.roads import RoadGeometry
    from pytest_metamorphic.driving.scenario import TYPICAL_CAR

    road = RoadGeometry.straight(
        width=10.0, lanes=2, margins=(2.0, 0.0), parking=(2.0, 0.0), sidewalks=(1.5, 0.0)
    )
    scenario = euro_ncap("CPNCO-50", road=road, vehicle=TYPICAL_CAR, placement="road")
    data = scenario_to_json(scenario)
    assert data["placement"] == "road" and data["vehicle"]["sensor_latency"] == 0.1
    again = scenario_from_json(data)
    assert again == scenario and again.obstructions() == scenario.obstructions()
    data["vehicle"]["sensor_latency"] = 1e9
    with pytest.raises(DataError, match=r"vehicle\.sensor_latency"):
        scenario_from_json(data)
