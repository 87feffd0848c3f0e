"""Iqbal's protocol as a campaign: every speed from 15 to 100 km/h against a few sources.

Iqbal (MT of ADAS on Euro NCAP scenarios and OpenStreetMap roads) ran the speed MR
exhaustively: three source scenarios (the Euro NCAP child-nearside test on a straight
10 m road and two real streets), the car at 20 km/h in the source, and one follow-up per
speed from 15 to 100 km/h in 1 km/h steps (85 follow-ups per source). Every follow-up
collision is a *violation* when the source avoided the collision; each is then judged
physically avoidable or not (:func:`~pytest_metamorphic.driving.kinematics.physically_avoidable`).

:func:`iqbal_campaign` returns one :class:`CampaignRow` per (source, controller), and
:func:`format_campaign` prints them like the paper's Table II. Run the whole study, with an
artifact (record, picture, OpenSCENARIO files) per violation, with::

    python -m pytest_metamorphic.reports.aeb_campaign --data ../shared/data
"""

from __future__ import annotations

import itertools
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.driving.aeb import mutant_fixed_lane, reference_controller
from pytest_metamorphic.driving.kinematics import (
    Avoidability,
    BrakeCommand,
    Observation,
    physically_avoidable,
)
from pytest_metamorphic.driving.osm import DRIVABLE_HIGHWAYS, load_roads
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import (
    PROTOCOLS,
    Keep,
    Scenario,
    euro_ncap,
    euro_ncap_road,
)
from pytest_metamorphic.driving.simulators import Simulator, check_simulator, run_simulator

__all__ = [
    "OSM_STREETS",
    "CampaignCollision",
    "CampaignRow",
    "CampaignSource",
    "Street",
    "default_sources",
    "format_campaign",
    "iqbal_campaign",
]

ControllerFactory = Callable[[], Callable[[Observation], "float | BrakeCommand"]]


@dataclass(frozen=True)
class Street:
    """A real street for a campaign source: the longest drivable way called ``name`` in
    the OSM file ``path`` (relative to the data folder), the car in lane ``ego_lane``."""

    path: str
    name: str
    place: str
    ego_lane: int = 0


#: The two real streets of the default campaign, both wide enough for the 3.6 m-lane
#: fault to matter (the carriageway reaches more than 1.8 m beyond the car's path on the
#: near side, where the child comes from): 8th Street is a two-way residential street
#: with a painted cycle lane on each side (``cycleway=lane``: 2 x 3 m lanes + 2 x 1.5 m,
#: the kerb 3 m right of the car's path); 7th Street a one-way arterial (``secondary``,
#: ``lanes=2``: 2 x 3.25 m), the car in the left lane, the kerb 4.9 m right of its path.
OSM_STREETS: tuple[Street, ...] = (
    Street("osm_osmnx/West-Oakland.osm.bz2", "8th Street", "West Oakland, CA"),
    Street("osm_osmnx/West-Oakland.osm.bz2", "7th Street", "West Oakland, CA", ego_lane=1),
)
#: Room left between the collision point and the end of a real street (m).
_STREET_END_MARGIN = 10.0
_MAX_CONFLICT_S = 200.0


@dataclass(frozen=True)
class CampaignSource:
    """A named source scenario (at the source speed)."""

    name: str
    scenario: Scenario


@dataclass(frozen=True)
class CampaignCollision:
    """One follow-up that collided.

    ``violation``: the source avoided the collision; ``avoidability``: could full braking
    have avoided it (computed for every collision, violation or not).
    """

    speed_kmh: float
    location: str
    side: str | None
    impact_speed_kmh: float
    violation: bool
    avoidability: Avoidability

    @property
    def avoidable(self) -> bool:
        return self.avoidability.avoidable


@dataclass(frozen=True)
class CampaignRow:
    """The outcome of one source against one controller over all follow-up speeds."""

    source: str
    controller: str
    kind: str
    keep: str
    source_speed_kmh: float
    source_collided: bool
    followups: int
    collisions: tuple[CampaignCollision, ...]

    @property
    def front(self) -> int:
        return sum(c.location == "front" for c in self.collisions)

    @property
    def side(self) -> int:
        return sum(c.location in ("side", "rear") for c in self.collisions)

    @property
    def violations(self) -> tuple[CampaignCollision, ...]:
        return tuple(c for c in self.collisions if c.violation)

    @property
    def avoidable_violations(self) -> tuple[CampaignCollision, ...]:
        return tuple(c for c in self.violations if c.avoidable)

    @property
    def lowest_violating_speed_kmh(self) -> float | None:
        return min((c.speed_kmh for c in self.violations), default=None)

    @property
    def lowest_avoidable_violation_kmh(self) -> float | None:
        return min((c.speed_kmh for c in self.avoidable_violations), default=None)

    @property
    def violation_rate(self) -> float:
        return len(self.violations) / self.followups if self.followups else 0.0

    @property
    def avoidable_rate(self) -> float:
        return len(self.avoidable_violations) / self.followups if self.followups else 0.0


def _street(data_dir: Path, street: Street) -> tuple[RoadGeometry, int]:
    """The longest drivable way called ``street.name`` and its OSM id."""
    path = data_dir / street.path
    roads = [r for r in load_roads(path, highway=DRIVABLE_HIGHWAYS) if r.name == street.name]
    if not roads:
        raise DataError(f"has no drivable way named {street.name!r}", path=path)
    road = max(roads, key=lambda road: road.length)
    return RoadGeometry.from_osm(road), road.way_id


def default_sources(
    data_dir: str | Path,
    *,
    kind: str = "CPNCO-50",
    speed_kmh: float = 20.0,
    streets: Sequence[Street] = OSM_STREETS,
) -> list[CampaignSource]:
    """Iqbal's three sources: the Euro NCAP straight 10 m road and two real OSM streets.

    On a street the car drives in the centre of the street's lane, and the collision
    point sits ``min(length - 10 m, 200 m)`` along the way, so that the car's start is on
    the real street.

    Parameters
    ----------
    data_dir : str or Path
        The shared data folder (with ``osm_osmnx/``).
    kind : str
        The Euro NCAP test (Iqbal: the child nearside test, CPNCO-50).
    speed_kmh : float
        The source speed (Iqbal: 20 km/h).
    streets : sequence of Street
    """
    if kind not in PROTOCOLS:
        raise InvalidArgument(f"kind={kind!r} must be one of {list(PROTOCOLS)}")
    data_dir = Path(data_dir)
    sources = [CampaignSource(euro_ncap_road().name, euro_ncap(kind, ego_speed_kmh=speed_kmh))]
    for street in streets:
        if not isinstance(street, Street):
            raise InvalidArgument(f"streets must hold Street entries, got {street!r}")
        road, way_id = _street(data_dir, street)
        conflict = min(road.length - _STREET_END_MARGIN, _MAX_CONFLICT_S)
        scenario = euro_ncap(
            kind, ego_speed_kmh=speed_kmh, road=road, conflict_s=conflict,
            ego_lane=street.ego_lane,
        )  # fmt: skip
        label = f"{street.name}, {street.place} (OSM way {way_id})"
        sources.append(CampaignSource(label, scenario))
    return sources


def iqbal_campaign(
    sources: Iterable[CampaignSource],
    controllers: Mapping[str, ControllerFactory] | None = None,
    *,
    speeds_kmh: Iterable[float] = range(15, 101),
    keep: Keep = "pedestrian",
    slack: float = 0.1,
    relevance: Literal["lane", "road"] = "road",
    progress: Callable[[str], None] | None = None,
    simulator: Simulator | None = None,
    on_violation: Callable[[str, str, CampaignCollision], None] | None = None,
) -> list[CampaignRow]:
    """Run every source at every speed with every controller.

    Parameters
    ----------
    sources : iterable of CampaignSource
        E.g. :func:`default_sources`.
    controllers : mapping of name -> factory, optional
        Zero-argument callables returning a fresh controller; default the reference AEB and
        the 3.6 m-lane mutant.
    speeds_kmh : iterable of float
        Follow-up speeds; the source's own speed is skipped (Iqbal: 15..100 km/h, 85
        follow-ups around a 20 km/h source).
    keep : {"pedestrian", "ego_start", "time"}
        What a follow-up keeps (:meth:`Scenario.with_ego_speed`). Default Iqbal's: the car's
        start and the pedestrian's own timing, so a faster car reaches the collision point
        early and the pedestrian may walk into its side.
    slack, relevance
        Passed to :func:`physically_avoidable`.
    progress : callable(str), optional
        Called once per finished row.
    simulator : callable(scenario, controller) -> SimulationResult, optional
        Where the controllers drive (:mod:`pytest_metamorphic.driving.simulators`):
        default the built-in simulator; e.g. ``HighwayEnvSimulator()``. Physical
        avoidability is always judged in the built-in one.
    on_violation : callable(source name, controller name, CampaignCollision), optional
        Called as soon as each violation is found (e.g. to save it:
        ``python -m pytest_metamorphic.reports.aeb_campaign`` writes artifacts this way).

    Returns
    -------
    list of CampaignRow
        Sources in order, controllers in order within each source.
    """
    sources = list(sources)
    if not sources or not all(isinstance(s, CampaignSource) for s in sources):
        raise InvalidArgument("sources must be a non-empty iterable of CampaignSource")
    if controllers is None:
        controllers = {
            "reference": reference_controller,
            "3.6 m lane mutant": mutant_fixed_lane,
        }
    if not controllers or not all(callable(f) for f in controllers.values()):
        raise InvalidArgument("controllers must map names to zero-argument controller factories")
    simulator = check_simulator(simulator)
    speeds = sorted({float(v) for v in speeds_kmh})
    if not speeds or min(speeds) <= 0:
        raise InvalidArgument("speeds_kmh must hold positive speeds")
    rows = []
    avoidability_cache: dict[tuple[str, float], Avoidability] = {}
    for source, (name, factory) in itertools.product(sources, controllers.items()):
        controller = factory()
        base = source.scenario
        source_result = run_simulator(simulator, base, controller)
        collisions = []
        followups = 0
        for speed in speeds:
            if speed == base.ego_speed_kmh:
                continue
            followups += 1
            scenario = base.with_ego_speed(speed, keep=keep)
            result = run_simulator(simulator, scenario, controller)
            if result.collision is None:
                continue
            key = (source.name, speed)
            if key not in avoidability_cache:
                avoidability_cache[key] = physically_avoidable(
                    scenario, slack=slack, relevance=relevance
                )
            collision = CampaignCollision(
                speed_kmh=speed,
                location=result.collision.location,
                side=result.collision.side,
                impact_speed_kmh=result.collision.impact_speed_kmh,
                violation=source_result.avoided,
                avoidability=avoidability_cache[key],
            )
            collisions.append(collision)
            if collision.violation and on_violation is not None:
                on_violation(source.name, name, collision)
        row = CampaignRow(
            source=source.name,
            controller=name,
            kind=base.kind,
            keep=keep,
            source_speed_kmh=base.ego_speed_kmh,
            source_collided=source_result.collided,
            followups=followups,
            collisions=tuple(collisions),
        )
        rows.append(row)
        if progress is not None:
            progress(f"{row.source} / {row.controller}: {len(row.collisions)} collision(s)")
    return rows


def _ranges(speeds: Sequence[float]) -> str:
    """``[15, 16, 17, 30]`` -> ``"15-17, 30"`` (runs of 1 km/h steps)."""
    runs: list[list[float]] = []
    for speed in sorted(speeds):
        if runs and speed - runs[-1][-1] <= 1.0 + 1e-9:
            runs[-1].append(speed)
        else:
            runs.append([speed])
    return ", ".join(f"{r[0]:g}" if len(r) == 1 else f"{r[0]:g}-{r[-1]:g}" for r in runs)


def format_campaign(rows: Sequence[CampaignRow], *, title: str | None = None) -> str:
    """A plain-text table like Iqbal's Table II, then every collision grouped by speed range.

    Columns: source, controller, source outcome, follow-ups, collisions (front/side),
    violations (follow-up collisions after an avoided source), of which physically
    avoidable, the lowest violating speed and the two rates.
    """
    header = (
        "source",
        "controller",
        "source",
        "runs",
        "front",
        "side",
        "violations",
        "avoidable",
        "lowest viol. km/h",
        "viol. rate",
        "avoidable rate",
    )
    table = [header]
    for row in rows:
        lowest = row.lowest_violating_speed_kmh
        table.append(
            (
                row.source,
                row.controller,
                "collided" if row.source_collided else "avoided",
                str(row.followups),
                str(row.front),
                str(row.side),
                str(len(row.violations)),
                str(len(row.avoidable_violations)),
                "-" if lowest is None else f"{lowest:g}",
                f"{row.violation_rate:.1%}",
                f"{row.avoidable_rate:.1%}",
            )
        )
    widths = [max(len(line[i]) for line in table) for i in range(len(header))]
    lines = []
    if title:
        lines += [title, "=" * len(title)]
    for index, line in enumerate(table):
        cells = (cell.ljust(width) for cell, width in zip(line, widths, strict=True))
        lines.append("  ".join(cells).rstrip())
        if index == 0:
            lines.append("  ".join("-" * width for width in widths))
    total = sum(row.followups for row in rows)
    violations = sum(len(row.violations) for row in rows)
    avoidable = sum(len(row.avoidable_violations) for row in rows)
    lines.append("")
    lines.append(
        f"{total} follow-ups, {violations} violation(s), {avoidable} physically avoidable"
        + (f" ({avoidable / total:.1%})" if total else "")
    )
    lines.append("")
    lines.append("Collisions (speed ranges in km/h; avoidable = full braking from the moment")
    lines.append("the pedestrian became relevant would have stopped the car in time):")
    for row in rows:
        if not row.collisions:
            lines.append(f"  {row.source} / {row.controller}: none")
            continue
        groups: dict[tuple[str, bool, bool], list[float]] = {}
        for c in row.collisions:
            where = c.location if c.side is None else f"{c.side} {c.location}"
            groups.setdefault((where, c.violation, c.avoidable), []).append(c.speed_kmh)
        parts = []
        for (where, violation, avoidable), speeds in groups.items():
            tag = "avoidable" if avoidable else "unavoidable"
            kind = "violation" if violation else "source collided too"
            parts.append(f"{where} at {_ranges(speeds)} ({tag}, {kind})")
        lines.append(f"  {row.source} / {row.controller}: " + "; ".join(parts))
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(
        "the campaign's command line (with artifacts per violation) is now\n"
        "    python -m pytest_metamorphic.reports.aeb_campaign --data ../shared/data"
    )
