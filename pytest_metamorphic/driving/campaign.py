"""Iqbal's protocol as a campaign: every speed from 15 to 100 km/h against a few sources.

Iqbal (MT of ADAS on Euro NCAP scenarios and OpenStreetMap roads) ran the speed MR
exhaustively: three source scenarios (the Euro NCAP child-nearside test on a straight
10 m road and two real streets), the car at 20 km/h in the source, and one follow-up per
speed from 15 to 100 km/h in 1 km/h steps (85 follow-ups per source). Every follow-up
collision is a *violation* when the source avoided the collision; each is then judged
physically avoidable or not by a judge that shares no code or rule with the controllers
(:func:`~pytest_metamorphic.driving.judge.judge_avoidable`), and by the paper's own test:
does the same controller avoid it when the pedestrian is re-timed to meet the car?

:func:`iqbal_campaign` returns one :class:`CampaignRow` per (source, controller), and
:func:`format_campaign` prints them like the paper's Table II. Run the whole study, with an
artifact (record, picture, OpenSCENARIO files) per violation, with::

    python -m pytest_metamorphic.reports.aeb_campaign --data ../shared/data
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.driving.aeb import mutant_fixed_lane, reference_controller, ttc_controller
from pytest_metamorphic.driving.judge import (
    RELEVANCE_STANDARDS,
    Judgement,
    Relevance,
    judge_avoidable,
)
from pytest_metamorphic.driving.kinematics import BrakeCommand, Observation
from pytest_metamorphic.driving.osm import DRIVABLE_HIGHWAYS, load_roads
from pytest_metamorphic.driving.roads import RoadGeometry
from pytest_metamorphic.driving.scenario import (
    INITIAL_TTC,
    PROTOCOLS,
    Keep,
    Scenario,
    euro_ncap,
    euro_ncap_road,
)
from pytest_metamorphic.driving.simulators import Simulator, check_simulator, run_simulator
from pytest_metamorphic.driving.vehicle import TYPICAL_CAR, VehicleSpec

__all__ = [
    "CONTROLLERS",
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
    the OSM file ``path`` (relative to the data folder), the car in lane ``ego_lane``.

    ``assumed_tags`` are OSM tags the way lacks but the scenario needs (a parking lane for
    CPNCO's parked cars), stated here and printed with the source instead of edited into
    the map; ``note`` says why.
    """

    path: str
    name: str
    place: str
    ego_lane: int = 0
    assumed_tags: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))
    note: str = ""


#: The two real streets of the default campaign (West Oakland, CA). Both carry the car in
#: a lane with more than 1.8 m of carriageway beyond its path on the child's side (else a
#: 3.6 m corridor sees the child as early as the map does, and the fault cannot show), and
#: neither has parking mapped, so a parallel-parking lane is stated for CPNCO's parked cars:
#:
#: * 8th Street: two-way residential, ``cycleway=lane``; with parking both sides the near
#:   side reads kerb | 2 m parking | 1.5 m cycle lane | 3 m lane: the parked cars stand
#:   4 m from the car's path (the protocol: 2.8 m), the child starts 5.5 m from it;
#: * 7th Street: one-way arterial (``highway=secondary``, ``lanes=2``, 3.25 m), the car
#:   in the left lane; with parking on the right the child first crosses the live right
#:   lane: parked cars 5.9 m from the car's path, the child starts 7.4 m from it.
OSM_STREETS: tuple[Street, ...] = (
    Street(
        "osm_osmnx/West-Oakland.osm.bz2", "8th Street", "West Oakland, CA",
        assumed_tags=MappingProxyType({"parking:both": "lane"}),
        note="parallel parking both sides (not mapped)",
    ),
    Street(
        "osm_osmnx/West-Oakland.osm.bz2", "7th Street", "West Oakland, CA", ego_lane=1,
        assumed_tags=MappingProxyType({"parking:right": "lane"}),
        note="parallel parking on the right (not mapped)",
    ),
)  # fmt: skip
#: Room left between the collision point and the end of a real street (m).
_STREET_END_MARGIN = 10.0
_MAX_CONFLICT_S = 200.0


@dataclass(frozen=True)
class CampaignSource:
    """A named source scenario (at the source speed); ``note`` states its assumptions."""

    name: str
    scenario: Scenario
    note: str = ""


@dataclass(frozen=True)
class CampaignCollision:
    """One follow-up that collided.

    ``violation``: the source avoided the collision; ``avoidability``: could braking from
    the moment the pedestrian became a hazard have avoided it (the independent judge,
    computed for every collision); ``in_lane``: the same judge with the stricter lane
    standard; ``retimed_avoided``: the paper's test, the same controller avoided the
    collision with the pedestrian re-timed to meet the car (None when not run).
    """

    speed_kmh: float
    location: str
    side: str | None
    impact_speed_kmh: float
    violation: bool
    avoidability: Judgement
    in_lane: Judgement | None = None
    retimed_avoided: bool | None = None

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
    def lane_avoidable_violations(self) -> tuple[CampaignCollision, ...]:
        return tuple(c for c in self.violations if c.in_lane is not None and c.in_lane.avoidable)

    @property
    def retimed_avoidable_violations(self) -> tuple[CampaignCollision, ...]:
        return tuple(c for c in self.violations if c.retimed_avoided)

    @property
    def lowest_violating_speed_kmh(self) -> float | None:
        return min((c.speed_kmh for c in self.violations), default=None)

    @property
    def lowest_avoidable_violation_kmh(self) -> float | None:
        return min((c.speed_kmh for c in self.avoidable_violations), default=None)

    @property
    def least_avoidable_gap(self) -> float | None:
        """Of the avoidable violations, the least distance (m) by which full braking from
        the moment the pedestrian became a hazard stops short of it: how early the road
        let the controller see what it had to brake for (None: no avoidable violation)."""
        return min((c.avoidability.gap for c in self.avoidable_violations), default=None)

    @property
    def violation_rate(self) -> float:
        return len(self.violations) / self.followups if self.followups else 0.0

    @property
    def avoidable_rate(self) -> float:
        return len(self.avoidable_violations) / self.followups if self.followups else 0.0


def _street(data_dir: Path, street: Street) -> tuple[RoadGeometry, int]:
    """The longest drivable way called ``street.name`` (with its assumed tags) and its id."""
    path = data_dir / street.path
    roads = [r for r in load_roads(path, highway=DRIVABLE_HIGHWAYS) if r.name == street.name]
    if not roads:
        raise DataError(f"has no drivable way named {street.name!r}", path=path)
    road = max(roads, key=lambda road: road.length)
    if street.assumed_tags:
        road = road.with_tags(street.assumed_tags)
    return RoadGeometry.from_osm(road), road.way_id


def describe_source(scenario: Scenario) -> str:
    """The cross-section that decides the fault: kerb, parked cars and the child's start,
    each as a distance from the car's path on the child's side."""
    road, path = scenario.road, scenario.ego_offset
    near = scenario.protocol.motion != "far"
    kerb = path - road.kerb("right") if near else road.kerb("left") - path
    parts = [
        f"lane {road.lane_width:.2f} m",
        f"kerb {kerb:.2f} m beyond the car's path",
        f"child starts {scenario.lateral_start:.2f} m from it",
    ]
    parked = scenario.obstructions()
    if parked:
        inner = abs(parked[0].d - path) - parked[0].footprint.width / 2 - scenario.vehicle.width / 2
        parts.append(f"parked cars {inner:.2f} m beside the car's body")
    return ", ".join(parts)


def default_sources(
    data_dir: str | Path,
    *,
    kind: str = "CPNCO-50",
    speed_kmh: float = 20.0,
    streets: Sequence[Street] = OSM_STREETS,
    initial_ttc: float = INITIAL_TTC,
    vehicle: VehicleSpec = TYPICAL_CAR,
) -> list[CampaignSource]:
    """Iqbal's three sources: the Euro NCAP straight 10 m road and two real OSM streets.

    On the test road the actors stand where the protocol puts them; on a street where its
    cross-section does (``placement="road"``: the child beyond the kerb, parked cars in
    the parking lane), the car in the centre of its lane, the collision point
    ``min(length - 10 m, 200 m)`` along the way, so that the car's start is on the street.

    Parameters
    ----------
    data_dir : str or Path
        The shared data folder (with ``osm_osmnx/``).
    kind : str
        The Euro NCAP test (Iqbal: the child nearside test, CPNCO-50).
    speed_kmh : float
        The source speed (Iqbal: 20 km/h).
    streets : sequence of Street
    initial_ttc : float
        Seconds between the car's start and the collision point (the protocol's 6 s).
    vehicle : VehicleSpec
        The car: default :data:`~pytest_metamorphic.driving.vehicle.TYPICAL_CAR`
        (9.0 m/s^2, 0.2 s brake delay, 0.1 s sensor latency).
    """
    if kind not in PROTOCOLS:
        raise InvalidArgument(f"kind={kind!r} must be one of {list(PROTOCOLS)}")
    data_dir = Path(data_dir)
    options = {"ego_speed_kmh": speed_kmh, "initial_ttc": initial_ttc, "vehicle": vehicle}
    test_road = euro_ncap(kind, **options)  # type: ignore[arg-type]
    sources = [CampaignSource(euro_ncap_road().name, test_road, describe_source(test_road))]
    for street in streets:
        if not isinstance(street, Street):
            raise InvalidArgument(f"streets must hold Street entries, got {street!r}")
        road, way_id = _street(data_dir, street)
        conflict = min(road.length - _STREET_END_MARGIN, _MAX_CONFLICT_S)
        scenario = euro_ncap(
            kind, road=road, conflict_s=conflict, ego_lane=street.ego_lane, placement="road",
            **options,  # type: ignore[arg-type]
        )  # fmt: skip
        label = f"{street.name}, {street.place} (OSM way {way_id})"
        note = describe_source(scenario)
        if street.note:
            note += f"; assumed: {street.note}"
        sources.append(CampaignSource(label, scenario, note))
    return sources


#: The controllers of the default campaign, by the names the table and records use: the
#: reference (MATLAB staging, corridor from the map), the 3.6 m-lane mutant (Iqbal's
#: fault) and an independently designed TTC AEB (predicted paths, no staging).
CONTROLLERS: Mapping[str, ControllerFactory] = MappingProxyType(
    {
        "reference": reference_controller,
        "3.6 m lane mutant": mutant_fixed_lane,
        "TTC AEB": ttc_controller,
    }
)


def iqbal_campaign(
    sources: Iterable[CampaignSource],
    controllers: Mapping[str, ControllerFactory] | None = None,
    *,
    speeds_kmh: Iterable[float] = range(15, 101),
    keep: Keep = "pedestrian",
    relevance: Relevance = "carriageway",
    decision_time: float = 0.1,
    retimed: bool = True,
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
        Zero-argument callables returning a fresh controller; default :data:`CONTROLLERS`
        (the reference AEB, the 3.6 m-lane mutant and the TTC AEB).
    speeds_kmh : iterable of float
        Follow-up speeds; the source's own speed is skipped (Iqbal: 15..100 km/h, 85
        follow-ups around a 20 km/h source).
    keep : {"pedestrian", "ego_start", "time"}
        What a follow-up keeps (:meth:`Scenario.with_ego_speed`). Default Iqbal's: the car's
        start and the pedestrian's own timing, so a faster car reaches the collision point
        early and the pedestrian may walk into its side.
    relevance, decision_time
        The judge's standard (:func:`~pytest_metamorphic.driving.judge.judge_avoidable`);
        every collision is also judged with ``relevance="lane"`` (``in_lane``).
    retimed : bool
        Also run the paper's test for every violation: the follow-up again with the
        pedestrian re-timed to meet the car (``dummy_arrival_time=None``).
    progress : callable(str), optional
        Called once per finished row.
    simulator : callable(scenario, controller) -> SimulationResult, optional
        Where the controllers drive (:mod:`pytest_metamorphic.driving.simulators`):
        default the built-in simulator; e.g. ``HighwayEnvSimulator()``. Physical
        avoidability is judged from the scenario alone, never in the simulator.
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
        controllers = CONTROLLERS
    if relevance not in RELEVANCE_STANDARDS:
        raise InvalidArgument(f"relevance={relevance!r} must be one of {list(RELEVANCE_STANDARDS)}")
    if not controllers or not all(callable(f) for f in controllers.values()):
        raise InvalidArgument("controllers must map names to zero-argument controller factories")
    simulator = check_simulator(simulator)
    speeds = sorted({float(v) for v in speeds_kmh})
    if not speeds or min(speeds) <= 0:
        raise InvalidArgument("speeds_kmh must hold positive speeds")
    rows = []
    judgements: dict[tuple[int, float], tuple[Judgement, Judgement]] = {}
    for index, source in enumerate(sources):
        for name, factory in controllers.items():
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
                key = (index, speed)
                if key not in judgements:
                    judgements[key] = (
                        judge_avoidable(scenario, relevance=relevance, decision_time=decision_time),
                        judge_avoidable(scenario, relevance="lane", decision_time=decision_time),
                    )
                retimed_avoided = None
                if retimed and source_result.avoided:
                    again = dataclasses.replace(scenario, dummy_arrival_time=None)
                    retimed_avoided = run_simulator(simulator, again, controller).avoided
                collision = CampaignCollision(
                    speed_kmh=speed,
                    location=result.collision.location,
                    side=result.collision.side,
                    impact_speed_kmh=result.collision.impact_speed_kmh,
                    violation=source_result.avoided,
                    avoidability=judgements[key][0],
                    in_lane=judgements[key][1],
                    retimed_avoided=retimed_avoided,
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


def format_campaign(
    rows: Sequence[CampaignRow],
    *,
    title: str | None = None,
    sources: Sequence[CampaignSource] = (),
) -> str:
    """A plain-text table like Iqbal's Table II, then every collision grouped by speed range.

    Columns: source, controller, source outcome, follow-ups, collisions (front/side),
    violations (follow-up collisions after an avoided source), of which physically
    avoidable (the judge's standard), avoidable by the lane standard ("in lane") and by
    the paper's re-timed run ("re-timed"), the least stopping gap of the avoidable
    violations ("min. gap m", :attr:`CampaignRow.least_avoidable_gap`), the lowest
    violating speed and the two rates. ``sources``, when given, adds each source's cross-section.
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
        "in lane",
        "re-timed",
        "min. gap m",
        "lowest viol. km/h",
        "viol. rate",
        "avoidable rate",
    )
    table = [header]
    for row in rows:
        lowest, gap = row.lowest_violating_speed_kmh, row.least_avoidable_gap
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
                str(len(row.lane_avoidable_violations)),
                str(len(row.retimed_avoidable_violations)),
                "-" if gap is None else f"{gap:.1f}",
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
    if sources:
        lines += ["", "Sources (on the child's side, from the car's path):"]
        lines += [f"  {source.name}: {source.note}" for source in sources]
    lines.append("")
    lines.append("Collisions (speed ranges in km/h; avoidable = full braking from the moment")
    lines.append("the pedestrian became a hazard would have stopped the car in time):")
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
