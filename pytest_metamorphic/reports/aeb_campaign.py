"""Iqbal's AEB campaign from the command line: the Table II, and an artifact per violation.

::

    python -m pytest_metamorphic.reports.aeb_campaign --data ../shared/data

runs :func:`~pytest_metamorphic.driving.campaign.iqbal_campaign` on the default sources
(the Euro NCAP 10 m road and two real OSM streets), prints the table and writes one
folder per violating follow-up under ``mt-artifacts/aeb-campaign/`` (``--artifacts``)::

    <source>/<controller>/<speed>-kmh/
        record.json       the campaign, both scenarios (exact JSON), both runs, the
                          collision, the avoidability judgement, how to replay
        birdseye.png      both runs: lanes, car path by braking stage, pedestrian path,
                          where it became relevant, the impact (matplotlib extra)
        source.xosc/.xodr, followup.xosc/.xodr
                          OpenSCENARIO 1.2 + OpenDRIVE for esmini or CARLA (openscenario
                          extra), validated against the ASAM schema by the tests

``--start``, ``--deceleration``, ``--brake-delay``, ``--latency`` set the car's start and
the car (default: 6 s and the typical car); ``--sensitivity`` runs the campaign over
their ranges instead (:mod:`~pytest_metamorphic.driving.sensitivity`) and prints where
each controller stays clean. ``--crosscheck`` adds CommonRoad's opinion on every run
(:mod:`~pytest_metamorphic.driving.commonroad`). ``--replay FOLDER`` re-runs a saved
violation with the same controller and simulator.
Folders are written atomically (complete or absent), each as soon as its violation is
found, so an interrupted campaign keeps what it found.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import read_json
from pytest_metamorphic.driving.campaign import (
    CONTROLLERS,
    CampaignCollision,
    CampaignSource,
    default_sources,
    format_campaign,
    iqbal_campaign,
)
from pytest_metamorphic.driving.judge import RELEVANCE_STANDARDS
from pytest_metamorphic.driving.kinematics import SimulationResult
from pytest_metamorphic.driving.records import scenario_from_json, scenario_to_json
from pytest_metamorphic.driving.scenario import KEEP_MODES, PROTOCOLS, Scenario
from pytest_metamorphic.driving.sensitivity import (
    format_sensitivity,
    sensitivity_campaign,
    sensitivity_settings,
)
from pytest_metamorphic.driving.simulators import Simulator, check_simulator, run_simulator
from pytest_metamorphic.driving.vehicle import TYPICAL_CAR, VehicleSpec
from pytest_metamorphic.reports.aeb_artifacts import write_aeb_files
from pytest_metamorphic.reports.artifacts import _slug, write_folder_atomically
from pytest_metamorphic.reports.inputs import RECORD

__all__ = [
    "CONTROLLERS",
    "load_campaign_violation",
    "main",
    "replay_campaign_violation",
    "write_campaign_violation",
]

FORMAT = "pytest-metamorphic AEB campaign violation"
VERSION = 1
DEFAULT_FOLDER = Path("mt-artifacts") / "aeb-campaign"
_KEEP_TITLES = {
    "pedestrian": "car start and pedestrian timing kept",
    "ego_start": "car start kept, pedestrian re-timed",
    "time": "time to collision kept",
}


def write_campaign_violation(
    folder: str | Path,
    *,
    source: CampaignSource,
    controller: str,
    collision: CampaignCollision,
    keep: str,
    source_result: SimulationResult,
    followup_result: SimulationResult,
    simulator: str = "built-in",
) -> Path:
    """Write one violation's folder (atomically) and return it."""
    followup = followup_result.scenario
    title = (
        f"{source.name} / {controller}: {source.scenario.ego_speed_kmh:g} -> "
        f"{collision.speed_kmh:g} km/h\n{followup_result.describe()}"
    )

    def fill(staging: Path) -> None:
        files = write_aeb_files(
            staging,
            source=source.scenario,
            followup=followup,
            source_output=source_result,
            followup_output=followup_result,
            relevant_time=collision.avoidability.relevant_time,
            title=title,
        )
        avoidability = collision.avoidability
        document = {
            "format": FORMAT,
            "version": VERSION,
            "source_name": source.name,
            "controller": controller,
            "simulator": simulator,
            "keep": keep,
            "source_speed_kmh": source.scenario.ego_speed_kmh,
            "followup_speed_kmh": collision.speed_kmh,
            "explanation": (
                f"the source avoided the collision ({source_result.describe()}) but the "
                f"follow-up at {collision.speed_kmh:g} km/h did not: "
                f"{followup_result.describe()}; {avoidability.describe()}"
            ),
            "avoidability": {
                "avoidable": avoidability.avoidable,
                "standard": avoidability.standard,
                "visible_time": avoidability.visible_time,
                "relevant_time": avoidability.relevant_time,
                "brake_time": avoidability.brake_time,
                "gap": avoidability.gap,
                "avoidable_by_lane_standard": (
                    None if collision.in_lane is None else collision.in_lane.avoidable
                ),
                "avoided_with_the_pedestrian_retimed": collision.retimed_avoided,
            },
            "source": scenario_to_json(source.scenario),
            "followup": scenario_to_json(followup),
            "runs": files.get("runs"),
            "picture": files["picture"],
            "openscenario": files["openscenario"],
            "notes": files["notes"],
            "replay": f"python -m pytest_metamorphic.reports.aeb_campaign --replay {folder}",
        }
        with (staging / RECORD).open("w", encoding="utf-8") as handle:
            json.dump(document, handle, indent=1, allow_nan=False)

    return write_folder_atomically(folder, fill)


def load_campaign_violation(folder: str | Path) -> tuple[dict[str, Any], Scenario, Scenario]:
    """The record of a saved violation and its source and follow-up scenarios."""
    path = Path(folder)
    record_path = path / RECORD if path.is_dir() else path
    record = read_json(record_path, what="AEB violation record")
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise DataError("not an AEB campaign violation record", path=record_path)
    scenarios = []
    for key in ("source", "followup"):
        try:
            scenarios.append(scenario_from_json(record.get(key)))  # type: ignore[arg-type]
        except DataError as error:
            raise DataError(f"{key}: {error}", path=record_path) from None
    return record, scenarios[0], scenarios[1]


def replay_campaign_violation(
    folder: str | Path,
    controllers: Mapping[str, Callable[[], Any]] = CONTROLLERS,
    *,
    simulator: Simulator | None = None,
) -> tuple[SimulationResult, SimulationResult]:
    """Re-run a saved violation's source and follow-up with its controller (by name)."""
    record, source, followup = load_campaign_violation(folder)
    name = record["controller"]
    if name not in controllers:
        raise InvalidArgument(
            f"the violation was found with controller {name!r}; pass controllers= with a "
            f"factory for it (known here: {sorted(controllers)})"
        )
    simulator = check_simulator(simulator)
    factory = controllers[name]
    return (
        run_simulator(simulator, source, factory()),
        run_simulator(simulator, followup, factory()),
    )


def _artifact_writer(
    folder: Path,
    sources: Sequence[CampaignSource],
    controllers: Mapping[str, Callable[[], Any]],
    keep: str,
    simulator: Simulator,
    simulator_name: str,
    written: list[Path],
) -> Callable[[str, str, CampaignCollision], None]:
    by_name = {source.name: source for source in sources}

    def on_violation(source_name: str, controller: str, collision: CampaignCollision) -> None:
        source = by_name[source_name]
        factory = controllers[controller]
        source_result = run_simulator(simulator, source.scenario, factory())
        followup = source.scenario.with_ego_speed(collision.speed_kmh, keep=keep)  # type: ignore[arg-type]
        followup_result = run_simulator(simulator, followup, factory())
        target = folder / _slug(source_name) / _slug(controller) / f"{collision.speed_kmh:g}-kmh"
        written.append(
            write_campaign_violation(
                target,
                source=source,
                controller=controller,
                collision=collision,
                keep=keep,
                source_result=source_result,
                followup_result=followup_result,
                simulator=simulator_name,
            )
        )

    return on_violation


def _simulator(name: str) -> tuple[Simulator, str]:
    if name in ("highway-env", "highway-env-lidar"):
        from pytest_metamorphic.driving.simulators.highway_env import HighwayEnvSimulator

        simulator = HighwayEnvSimulator(visibility="lidar" if name.endswith("lidar") else "sensor")
        return simulator, repr(simulator)
    return check_simulator(None), "built-in"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m pytest_metamorphic.reports.aeb_campaign",
        description="Iqbal's AEB speed campaign: Table II and an artifact per violation.",
    )
    parser.add_argument("--data", default="../shared/data", help="shared data folder")
    parser.add_argument(
        "--kind", action="append", choices=sorted(PROTOCOLS), help="Euro NCAP test(s)"
    )
    parser.add_argument(
        "--keep",
        action="append",
        choices=KEEP_MODES,
        help="what a follow-up keeps (default pedestrian: Iqbal's; see Scenario.with_ego_speed)",
    )
    parser.add_argument("--source-speed", type=float, default=20.0)
    parser.add_argument("--min-speed", type=int, default=15, help="lowest follow-up km/h")
    parser.add_argument("--max-speed", type=int, default=100, help="highest follow-up km/h")
    parser.add_argument(
        "--relevance",
        choices=RELEVANCE_STANDARDS,
        default="carriageway",
        help="the judge's standard: the pedestrian is a hazard once it walks on the "
        "carriageway towards the car's path (default), enters its lane, or its swept path",
    )
    car = parser.add_argument_group("the car and its start (defaults: the typical car)")
    car.add_argument(
        "--start",
        type=float,
        default=6.0,
        help="seconds from the car's start to the collision point",
    )
    car.add_argument(
        "--deceleration", type=float, default=TYPICAL_CAR.max_deceleration, help="peak m/s^2"
    )
    car.add_argument("--brake-delay", type=float, default=TYPICAL_CAR.brake_delay, help="seconds")
    car.add_argument(
        "--latency", type=float, default=TYPICAL_CAR.sensor_latency, help="sensor latency, seconds"
    )
    parser.add_argument(
        "--crosscheck",
        action="store_true",
        help="also check every run with CommonRoad's collision checker and vehicle model "
        "(the commonroad extra, in an environment without onnxruntime)",
    )
    parser.add_argument(
        "--sensitivity",
        action="store_true",
        help="run the campaign over the ranges of start, brake delay, deceleration and "
        "latency (one at a time around the car above) and print the range; no artifacts",
    )
    parser.add_argument(
        "--simulator",
        choices=("built-in", "highway-env", "highway-env-lidar"),
        default="built-in",
        help="where the controllers drive (highway-env needs its extra; -lidar: what the "
        "car sees is decided by highway-env's LidarObservation, not the sensor's occlusion "
        "test)",
    )
    parser.add_argument(
        "--artifacts",
        type=Path,
        default=DEFAULT_FOLDER,
        help=f"where violations are saved (default {DEFAULT_FOLDER})",
    )
    parser.add_argument("--no-artifacts", action="store_true", help="save no artifacts")
    parser.add_argument("--replay", type=Path, help="re-run a saved violation and exit")
    return parser


def _replay(folder: Path, simulator: Simulator) -> int:
    record, _, _ = load_campaign_violation(folder)
    source, followup = replay_campaign_violation(folder, simulator=simulator)
    print(f"{record['source_name']} / {record['controller']}")
    print(f"  source:    {source.describe()}")
    print(f"  follow-up: {followup.describe()}")
    still = source.avoided and followup.collided
    print("  the violation " + ("still occurs" if still else "no longer occurs"))
    return 1 if still else 0


def _sensitivity(
    args: argparse.Namespace, vehicle: VehicleSpec, simulator: Simulator, speeds: range
) -> int:
    settings = sensitivity_settings(initial_ttc=args.start, vehicle=vehicle)
    for kind, keep in itertools.product(args.kind or ["CPNCO-50"], args.keep or ["pedestrian"]):
        title = f"{kind}, source {args.source_speed:g} km/h, {_KEEP_TITLES[keep]}: sensitivity"
        results = sensitivity_campaign(
            args.data, kind=kind, settings=settings, speeds_kmh=speeds, keep=keep,
            relevance=args.relevance, simulator=simulator,
        )  # fmt: skip
        print(f"{title}\n{'=' * len(title)}\n{format_sensitivity(results)}\n")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the campaign, print the tables, save the violations."""
    args = _parser().parse_args(argv)
    simulator, simulator_name = _simulator(args.simulator)
    if args.replay is not None:
        return _replay(args.replay, simulator)
    speeds = range(args.min_speed, args.max_speed + 1)
    try:
        vehicle = VehicleSpec(
            max_deceleration=args.deceleration, brake_delay=args.brake_delay,
            sensor_latency=args.latency,
        )  # fmt: skip
    except InvalidArgument as error:
        raise SystemExit(f"error: {error}") from None
    if args.sensitivity:
        return _sensitivity(args, vehicle, simulator, speeds)
    written: list[Path] = []
    for kind, keep in itertools.product(args.kind or ["CPNCO-50"], args.keep or ["pedestrian"]):
        sources = default_sources(
            args.data, kind=kind, speed_kmh=args.source_speed, initial_ttc=args.start,
            vehicle=vehicle,
        )  # fmt: skip
        folder = args.artifacts / _slug(f"{kind}-{keep}")
        on_violation = None
        if not args.no_artifacts:
            on_violation = _artifact_writer(
                folder, sources, CONTROLLERS, keep, simulator, simulator_name, written
            )
        rows = iqbal_campaign(
            sources,
            CONTROLLERS,
            speeds_kmh=speeds,
            keep=keep,
            relevance=args.relevance,
            simulator=simulator,
            on_violation=on_violation,
        )
        title = (
            f"{kind}, source {args.source_speed:g} km/h, {_KEEP_TITLES[keep]}, start "
            f"{args.start:g} s, {vehicle.describe()}"
        )
        if args.simulator != "built-in":
            title += f", in {args.simulator}"
        print(format_campaign(rows, title=title, sources=sources))
        if args.crosscheck:
            from pytest_metamorphic.driving.commonroad import crosscheck_campaign, format_crosscheck

            report = crosscheck_campaign(
                sources, CONTROLLERS, speeds_kmh=speeds, keep=keep, simulator=simulator
            )
            print(f"\n{format_crosscheck(report, title='CommonRoad cross-check:')}")
        print()
    if written:
        print(f"{len(written)} violation(s) saved under {args.artifacts}/ (record.json, "
              "birdseye.png, OpenSCENARIO files)")  # fmt: skip
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
