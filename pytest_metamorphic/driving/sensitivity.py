"""Table II over what the paper left unstated: start distance, brakes, latency.

Iqbal's campaign result depends on parameters the paper does not give: how far (in time)
before the collision point the car starts, how long the brakes take to act, how hard they
can brake, how old the AEB's view of the world is. :func:`sensitivity_campaign` runs the
whole campaign (:func:`~pytest_metamorphic.driving.campaign.iqbal_campaign`) once per
:class:`Setting` and :func:`format_sensitivity` prints, per setting, each controller's
violations and avoidable violations on each source, then the range over all settings, so
a user sees where the correct controllers stay clean and where the fault shows.

The settings vary one parameter at a time around the defaults (the protocol's 6 s start
and :data:`~pytest_metamorphic.driving.vehicle.TYPICAL_CAR`), over :data:`RANGES`, plus
the ideal car of the MATLAB example (9.8 m/s^2 at once, no latency).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.driving.campaign import (
    CONTROLLERS,
    OSM_STREETS,
    CampaignRow,
    ControllerFactory,
    Street,
    default_sources,
    iqbal_campaign,
)
from pytest_metamorphic.driving.judge import Relevance
from pytest_metamorphic.driving.scenario import INITIAL_TTC, Keep
from pytest_metamorphic.driving.simulators import Simulator
from pytest_metamorphic.driving.vehicle import EURO_NCAP_CAR, TYPICAL_CAR, VehicleSpec

__all__ = [
    "RANGES",
    "SensitivityResult",
    "Setting",
    "format_sensitivity",
    "sensitivity_campaign",
    "sensitivity_settings",
]

#: The ranges of the unstated parameters: start distance as time to the collision point
#: (s), brake delay (s), peak deceleration (m/s^2), sensor latency (s).
RANGES: Mapping[str, tuple[float, ...]] = {
    "initial_ttc": (2.0, 3.0, 4.0, 5.0, 6.0),
    "brake_delay": (0.0, 0.1, 0.2, 0.3),
    "max_deceleration": (8.0, 8.5, 9.0, 9.8),
    "sensor_latency": (0.0, 0.1, 0.2),
}
_LABELS = {
    "initial_ttc": ("start", "s"),
    "brake_delay": ("brake delay", "s"),
    "max_deceleration": ("deceleration", "m/s^2"),
    "sensor_latency": ("latency", "s"),
}


@dataclass(frozen=True)
class Setting:
    """One point of the sensitivity study: the car's start (``initial_ttc``) and the car."""

    name: str
    initial_ttc: float
    vehicle: VehicleSpec

    def describe(self) -> str:
        return f"{self.initial_ttc:g} s start, {self.vehicle.describe()}"


def sensitivity_settings(
    *,
    initial_ttc: float = INITIAL_TTC,
    vehicle: VehicleSpec = TYPICAL_CAR,
    ranges: Mapping[str, Iterable[float]] = RANGES,
) -> list[Setting]:
    """The default setting, then one parameter at a time over ``ranges``, then the ideal car.

    ``ranges`` maps ``"initial_ttc"`` or a :class:`VehicleSpec` field (``brake_delay``,
    ``max_deceleration``, ``sensor_latency``) to the values to try.
    """
    if not isinstance(vehicle, VehicleSpec):
        raise InvalidArgument(f"vehicle={vehicle!r} must be a VehicleSpec")
    default = Setting("default", initial_ttc, vehicle)
    settings = [default]
    for parameter, values in ranges.items():
        if parameter not in _LABELS:
            raise InvalidArgument(f"ranges: unknown parameter {parameter!r}; use {list(_LABELS)}")
        label, unit = _LABELS[parameter]
        for value in values:
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise InvalidArgument(f"ranges[{parameter!r}] holds {value!r}, not a number")
            if parameter == "initial_ttc":
                if value == initial_ttc:
                    continue
                setting = Setting(f"{label} {value:g} {unit}", float(value), vehicle)
            else:
                if getattr(vehicle, parameter) == value:
                    continue
                car = dataclasses.replace(vehicle, **{parameter: float(value)})
                setting = Setting(f"{label} {value:g} {unit}", initial_ttc, car)
            settings.append(setting)
    if vehicle != EURO_NCAP_CAR:
        settings.append(Setting("ideal car (9.8 m/s^2, no delays)", initial_ttc, EURO_NCAP_CAR))
    return settings


@dataclass(frozen=True)
class SensitivityResult:
    """The campaign's rows under one setting."""

    setting: Setting
    rows: tuple[CampaignRow, ...]


def sensitivity_campaign(
    data_dir: str | Path,
    *,
    kind: str = "CPNCO-50",
    settings: Sequence[Setting] | None = None,
    controllers: Mapping[str, ControllerFactory] | None = None,
    streets: Sequence[Street] = OSM_STREETS,
    speeds_kmh: Iterable[float] = range(15, 101),
    keep: Keep = "pedestrian",
    relevance: Relevance = "carriageway",
    simulator: Simulator | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[SensitivityResult]:
    """Iqbal's campaign on the default sources once per setting (default
    :func:`sensitivity_settings`); the arguments as in
    :func:`~pytest_metamorphic.driving.campaign.iqbal_campaign`."""
    settings = sensitivity_settings() if settings is None else list(settings)
    if not settings or not all(isinstance(s, Setting) for s in settings):
        raise InvalidArgument("settings must be a non-empty sequence of Setting")
    speeds = tuple(speeds_kmh)
    results = []
    for setting in settings:
        sources = default_sources(
            data_dir, kind=kind, streets=streets, initial_ttc=setting.initial_ttc,
            vehicle=setting.vehicle,
        )  # fmt: skip
        rows = iqbal_campaign(
            sources, controllers or CONTROLLERS, speeds_kmh=speeds, keep=keep,
            relevance=relevance, simulator=simulator, retimed=False,
        )  # fmt: skip
        results.append(SensitivityResult(setting, tuple(rows)))
        if progress is not None:
            progress(setting.name)
    return results


def _cell(row: CampaignRow) -> str:
    """``violations/avoidable`` with the lowest violating speed, or ``-`` when clean."""
    if not row.violations:
        return "-"
    return (
        f"{len(row.violations)}/{len(row.avoidable_violations)} @{row.lowest_violating_speed_kmh:g}"
    )


def _short(source: str) -> str:
    return source.split(",")[0].split(" (")[0]


def format_sensitivity(results: Sequence[SensitivityResult]) -> str:
    """Per setting and controller a line with one cell per source (``violations/avoidable
    @ lowest violating km/h``, ``-`` for none), then per controller the range over all
    settings: "clean" means no avoidable violation; settings with collisions that no
    braking could have avoided are named."""
    if not results:
        return "no settings"
    sources = list(dict.fromkeys(_short(row.source) for row in results[0].rows))
    controllers = list(dict.fromkeys(row.controller for row in results[0].rows))
    table = [["setting", "controller", *sources]]
    for result in results:
        cells = {(r.controller, _short(r.source)): _cell(r) for r in result.rows}
        for index, controller in enumerate(controllers):
            name = result.setting.name if index == 0 else ""
            table.append([name, controller, *(cells[controller, s] for s in sources)])
    widths = [max(len(line[i]) for line in table) for i in range(len(table[0]))]
    lines = [
        f"{results[0].setting.name}: {results[0].setting.describe()}",
        "cells: violations/avoidable @ lowest violating km/h ('-': none)",
        "",
    ]
    for index, line in enumerate(table):
        lines.append(
            "  ".join(cell.ljust(w) for cell, w in zip(line, widths, strict=True)).rstrip()
        )
        if index == 0:
            lines.append("  ".join("-" * w for w in widths))
    lines += ["", "Range over the settings:"]
    for controller in controllers:
        counts = [
            sum(len(r.avoidable_violations) for r in result.rows if r.controller == controller)
            for result in results
        ]
        dirty = [result.setting.name for result, n in zip(results, counts, strict=True) if n]
        clean = len(results) - len(dirty)
        summary = (
            f"  {controller}: {min(counts)}-{max(counts)} avoidable violations per setting, "
            f"clean in {clean} of {len(results)}"
        )
        if dirty and clean:
            summary += f"; avoidable violations with {', '.join(dirty)}"
        unavoidable = [
            result.setting.name
            for result in results
            if any(r.violations for r in result.rows if r.controller == controller)
            and result.setting.name not in dirty
        ]
        if unavoidable:
            summary += f"; unavoidable violations only, with {', '.join(unavoidable)}"
        lines.append(summary)
    return "\n".join(lines)
