"""Scenarios and simulation results as JSON: what an artifact records and replays."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.driving.kinematics import SimulationResult
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import KMH, Scenario, VehicleSpec

__all__ = ["LIMITS", "result_to_json", "scenario_from_json", "scenario_to_json"]

FORMAT = "pytest-metamorphic/aeb-scenario"

# What a replayed record may ask for: far beyond any AEB test (Euro NCAP: 10-60 km/h, a few
# hundred metres of road), far below what would exhaust memory (a 1e9 m approach is a
# 39 GiB trace) or overflow (1e308 km/h). A record past them was not written by us.
LIMITS = {
    "ego_speed_kmh": 300.0,
    "dummy_speed_kmh": 60.0,
    "ego_distance": 5_000.0,
    "conflict_s": 50_000.0,
    "road.width": 100.0,
    "road.lanes": 20,
    "road.vertices": 100_000,
    "road.extent": 50_000.0,
    "vehicle.length": 30.0,
    "vehicle.width": 10.0,
    "vehicle.wheelbase": 30.0,
    "vehicle.max_deceleration": 50.0,
    "vehicle.brake_delay": 10.0,
    "vehicle.sensor_latency": 10.0,
    "dummy_arrival_time": 3_600.0,
}


def scenario_to_json(scenario: Scenario) -> dict[str, Any]:
    """Every parameter of ``scenario``; :func:`scenario_from_json` rebuilds it exactly."""
    road = scenario.road
    return {
        "format": FORMAT,
        "kind": scenario.kind,
        "road": {
            "name": road.name,
            "width": road.width,
            "lanes": road.lanes,
            "margins": list(road.margins),
            "parking": list(road.parking),
            "sidewalks": list(road.sidewalks),
            "centerline": np.asarray(road.centerline, dtype=float).tolist(),
        },
        "ego_speed_kmh": scenario.ego_speed_kmh,
        "conflict_s": scenario.conflict_s,
        "ego_distance": scenario.ego_distance,
        "ego_lane": scenario.ego_lane,
        "dummy_speed_kmh": scenario.dummy_speed_kmh,
        "dummy_arrival_time": scenario.dummy_arrival_time,
        "placement": scenario.placement,
        "vehicle": dataclasses.asdict(scenario.vehicle),
        "description": scenario.describe(),
    }


def _check_limits(data: Mapping[str, Any]) -> None:
    """Every recorded quantity a number within :data:`LIMITS` (DataError naming it)."""
    road: Mapping[str, Any] = data["road"] if isinstance(data.get("road"), Mapping) else {}
    vehicle: Mapping[str, Any] = data["vehicle"] if isinstance(data.get("vehicle"), Mapping) else {}
    values = {
        **{key: data.get(key) for key in LIMITS if "." not in key},
        "road.width": road.get("width"),
        "road.lanes": road.get("lanes"),
        **{f"vehicle.{k}": vehicle.get(k) for k in ("length", "width", "wheelbase")},
        "vehicle.max_deceleration": vehicle.get("max_deceleration"),
        "vehicle.brake_delay": vehicle.get("brake_delay"),
        "vehicle.sensor_latency": vehicle.get("sensor_latency"),
    }
    for key, value in values.items():
        if value is None:
            continue  # missing keys are reported when the scenario is built
        number = value if isinstance(value, (int, float)) and not isinstance(value, bool) else None
        if number is None or not abs(number) <= LIMITS[key]:
            raise DataError(
                f"recorded AEB scenario: {key} = {str(value)[:40]} is not a number within "
                f"±{LIMITS[key]}"
            )
    centerline = road.get("centerline")
    if isinstance(centerline, list):
        if len(centerline) > LIMITS["road.vertices"]:
            raise DataError(
                f"recorded AEB scenario: road.centerline has {len(centerline)} vertices, "
                f"more than {LIMITS['road.vertices']}"
            )
        try:
            extent = float(np.abs(np.asarray(centerline, dtype=float)).max(initial=0.0))
        except (TypeError, ValueError):
            raise DataError(
                "recorded AEB scenario: road.centerline is not (k, 2) numbers"
            ) from None
        if not extent <= LIMITS["road.extent"]:
            raise DataError(
                "recorded AEB scenario: road.centerline reaches beyond "
                f"{LIMITS['road.extent']:.0f} m"
            )


def scenario_from_json(data: Mapping[str, Any]) -> Scenario:
    """The scenario :func:`scenario_to_json` recorded.

    Raises
    ------
    DataError
        Not a recorded scenario, a field missing or of the wrong type, or a quantity
        beyond :data:`LIMITS` (a record from outside is never simulated at any size).
    """
    if not isinstance(data, Mapping) or data.get("format") != FORMAT:
        raise DataError(f"not a recorded AEB scenario (format {FORMAT!r} expected)")
    _check_limits(data)
    try:
        road = data["road"]
        return Scenario(
            kind=data["kind"],
            road=RoadGeometry(
                np.asarray(road["centerline"], dtype=float),
                road["width"],
                road["lanes"],
                road["name"],
                tuple(road.get("margins", (0.0, 0.0))),
                tuple(road.get("parking", (0.0, 0.0))),
                tuple(road.get("sidewalks", (0.0, 0.0))),
            ),
            ego_speed_kmh=data["ego_speed_kmh"],
            conflict_s=data["conflict_s"],
            ego_distance=data["ego_distance"],
            ego_lane=data["ego_lane"],
            dummy_speed_kmh=data["dummy_speed_kmh"],
            vehicle=VehicleSpec(**data["vehicle"]),
            dummy_arrival_time=data.get("dummy_arrival_time"),
            placement=data.get("placement", "protocol"),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        # ValueError covers the scenario's own InvalidArgument checks
        detail = f"{type(error).__name__}: {error}"[:200]
        raise DataError(f"recorded AEB scenario cannot be rebuilt ({detail})") from None


def result_to_json(result: SimulationResult) -> dict[str, Any]:
    """The outcome of a run (collision, braking, stages), without the per-step traces."""
    collision = result.collision
    return {
        "collided": result.collided,
        "collision": None
        if collision is None
        else {
            "time": collision.time,
            "actor": collision.actor,
            "location": collision.location,
            "side": collision.side,
            "impact_speed_kmh": collision.impact_speed_kmh,
        },
        "end_time": result.end_time,
        "final_speed_kmh": result.final_speed / KMH,
        "first_brake_time": result.first_brake_time,
        "stages": [list(stage) for stage in result.stages],
        "description": result.describe(),
    }
