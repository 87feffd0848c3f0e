"""What an AEB violation's artifact holds beside its record: the scenarios as JSON (so
``--mt-replay`` rebuilds them), a bird's-eye picture of both runs, and OpenSCENARIO +
OpenDRIVE files of both scenarios for esmini, CARLA and other simulators.

Each part needs an optional extra (matplotlib, scenariogeneration); a missing one is noted
in the record instead of failing the test run that found the violation.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["decode_scenario", "encode_scenario", "is_scenario", "write_aeb_files"]

KIND = "aeb_scenario"


def is_scenario(value: Any) -> bool:
    from pytest_metamorphic.driving.scenario import Scenario

    return isinstance(value, Scenario)


def encode_scenario(value: Any) -> dict[str, Any]:
    from pytest_metamorphic.driving.records import scenario_to_json

    return {"kind": KIND, "scenario": scenario_to_json(value)}


def decode_scenario(spec: Mapping[str, Any]) -> Any:
    from pytest_metamorphic.driving.records import scenario_from_json

    return scenario_from_json(spec["scenario"])


def write_aeb_files(
    folder: Path,
    *,
    source: Any,
    followup: Any,
    source_output: Any,
    followup_output: Any,
    relevant_time: float | None,
    title: str,
) -> dict[str, Any]:
    """Write the picture and the OpenSCENARIO files; returns what the record says of them."""
    from pytest_metamorphic.driving.kinematics import SimulationResult
    from pytest_metamorphic.driving.records import result_to_json

    notes: dict[str, Any] = {"picture": None, "openscenario": {}, "notes": []}
    results = (source_output, followup_output)
    if all(isinstance(r, SimulationResult) for r in results):
        notes["runs"] = {
            "source": result_to_json(results[0]),
            "followup": result_to_json(results[1]),
        }
        try:
            from pytest_metamorphic.reports.aeb_picture import Run, draw_aeb_runs

            draw_aeb_runs(
                folder / "birdseye.png",
                [Run("source", results[0]), Run("follow-up", results[1], relevant_time)],
                title=title,
            )
            notes["picture"] = "birdseye.png"
        except ImportError as error:  # matplotlib is an optional extra
            notes["notes"].append(f"no picture: {error}")
    try:
        import scenariogeneration  # noqa: F401  (the openscenario extra)
    except ImportError as error:
        notes["notes"].append(f"no OpenSCENARIO files: {error}")
        return notes
    from pytest_metamorphic.driving.openscenario import write_openscenario

    pairs = (("source", source, results[0]), ("followup", followup, results[1]))
    for name, scenario, output in pairs:
        run = getattr(output, "describe", lambda: "")()
        files = write_openscenario(
            scenario, folder, name=name, description=f"{scenario.describe()}. Our run: {run}"
        )
        notes["openscenario"][name] = {"xosc": files.xosc.name, "xodr": files.xodr.name}
    return notes
