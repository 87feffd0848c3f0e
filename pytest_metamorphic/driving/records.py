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

__all__ = ["result_to_json", "scenario_from_json", "scenario_to_json"]

FORMAT = "pytest-metamorphic/aeb-scenario"


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
            "centerline": np.asarray(road.centerline, dtype=float).tolist(),
        },
        "ego_speed_kmh": scenario.ego_speed_kmh,
        "conflict_s": scenario.conflict_s,
        "ego_distance": scenario.ego_distance,
        "ego_lane": scenario.ego_lane,
        "dummy_speed_kmh": scenario.dummy_speed_kmh,
        "dummy_arrival_time": scenario.dummy_arrival_time,
        "vehicle": dataclasses.asdict(scenario.vehicle),
        "description": scenario.describe(),
    }


def scenario_from_json(data: Mapping[str, Any]) -> Scenario:
    """The scenario :func:`scenario_to_json` recorded (DataError when it is not one)."""
    if not isinstance(data, Mapping) or data.get("format") != FORMAT:
        raise DataError(f"not a recorded AEB scenario (format {FORMAT!r} expected)")
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
            ),
            ego_speed_kmh=data["ego_speed_kmh"],
            conflict_s=data["conflict_s"],
            ego_distance=data["ego_distance"],
            ego_lane=data["ego_lane"],
            dummy_speed_kmh=data["dummy_speed_kmh"],
            vehicle=VehicleSpec(**data["vehicle"]),
            dummy_arrival_time=data.get("dummy_arrival_time"),
        )
    except (KeyError, TypeError) as error:
        raise DataError(f"recorded AEB scenario is incomplete: {error!r}") from None


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
