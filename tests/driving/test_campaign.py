"""Iqbal's campaign: sources on the test road and real OSM streets, table, verdicts."""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType

import pytest

from pytest_metamorphic import DataError, InvalidArgument
from pytest_metamorphic.driving.aeb import mutant_fixed_lane
from pytest_metamorphic.driving.campaign import (
    CampaignSource,
    Street,
    default_sources,
    format_campaign,
    iqbal_campaign,
)
from pytest_metamorphic.driving.scenario import euro_ncap
from pytest_metamorphic.driving.vehicle import TYPICAL_CAR

#: A few speeds around the interesting range, so the default suite stays fast.
SPEEDS = (15, 20, 40, 60, 70, 80, 90, 100)


def test_default_sources_are_the_test_road_and_two_real_streets(shared_data: Path) -> None:
    sources = default_sources(shared_data)
    assert [s.scenario.road.name for s in sources] == [
        "Euro NCAP straight 10 m road",
        "8th Street",
        "7th Street",
    ]
    for source in sources:
        scenario = source.scenario
        assert (scenario.kind, scenario.ego_speed_kmh) == ("CPNCO-50", 20.0)
        assert scenario.vehicle == TYPICAL_CAR
        assert scenario.time_to_collision_point == pytest.approx(6.0)
        assert 0 <= scenario.ego_start_s < scenario.conflict_s <= scenario.road.length
        # The fault can only show where the road reaches beyond the mutant's 1.8 m
        # half-corridor on the side the child comes from.
        kerb = scenario.ego_offset + scenario.road.width / 2
        assert kerb > 1.8
    assert [s.scenario.placement for s in sources] == ["protocol", "road", "road"]
    assert sources[1].name == "8th Street, West Oakland, CA (OSM way 6358365)"
    eighth, seventh = sources[1].scenario, sources[2].scenario
    # Mapped: two 3 m lanes and a painted cycle lane on each side (cycleway=lane);
    # stated: a 2 m parallel-parking lane at each kerb.
    assert (eighth.road.width, eighth.road.lanes) == (13.0, 2)
    assert (eighth.road.margins, eighth.road.parking) == ((3.5, 3.5), (2.0, 2.0))
    assert eighth.ego_offset == pytest.approx(-1.5)  # right-hand traffic lane
    assert eighth.lateral_start == pytest.approx(5.5)  # 0.5 m beyond the kerb
    # One-way arterial, lanes=2 (3.25 m each), the car in the left lane; parking stated
    # on the right, the footway mapped there (sidewalk=right).
    assert (seventh.road.width, seventh.road.lanes, seventh.ego_lane) == (8.5, 2, 1)
    assert seventh.road.sidewalks == (2.0, 0.0)
    assert seventh.ego_offset == pytest.approx(2.625)
    assert "assumed: parallel parking on the right (not mapped)" in sources[2].note
    assert "parked cars 4.08 m beside the car's body" in sources[2].note
    missing = Street("osm_osmnx/West-Oakland.osm.bz2", "Nowhere Rd", "")
    with pytest.raises(DataError, match="no drivable way named"):
        default_sources(shared_data, streets=[missing])
    with pytest.raises(InvalidArgument, match="Street"):
        default_sources(shared_data, streets=[("osm_osmnx/x.osm", "A", "")])  # type: ignore[list-item]


@pytest.mark.parametrize("kind", ["CPNCO-50", "CPNA-25", "CPFA-50"])
def test_actors_stand_where_the_road_puts_them(shared_data: Path, kind: str) -> None:
    """The child starts beyond the kerb on the protocol's side; parked cars stand in the
    parking lane: never in a traffic lane, never across the kerb."""
    for source in default_sources(shared_data, kind=kind)[1:]:
        scenario, road = source.scenario, source.scenario.road
        start = scenario.pedestrian().d0
        if scenario.protocol.motion == "near":
            assert float(start) == pytest.approx(-road.width / 2 - 0.5)
        else:
            assert float(start) == pytest.approx(road.width / 2 + 0.5)
        for parked in scenario.obstructions():
            low, high = parked.d - parked.footprint.width / 2, parked.d + parked.footprint.width / 2
            assert -road.width / 2 <= low < high <= -road.width / 2 + road.parking[0]
            assert road.lane_at(low) is None and road.lane_at(high) is None


def test_a_street_without_a_parking_lane_cannot_host_cpnco(shared_data: Path) -> None:
    bare = Street("osm_osmnx/West-Oakland.osm.bz2", "8th Street", "West Oakland, CA")
    with pytest.raises(InvalidArgument, match="no parking lane at the right kerb"):
        default_sources(shared_data, streets=[bare])
    # Tests without parked cars need none.
    assert len(default_sources(shared_data, kind="CPNA-25", streets=[bare])) == 2


#: Around the source speed (20 km/h), where a faster car arrives early, and a few above.
PAPER_SPEEDS = (*range(15, 32), 40, 60, 80, 100)


def test_default_campaign_is_the_papers_table(shared_data: Path) -> None:
    """Iqbal's result: the 3.6 m-lane controller lets the pedestrian walk into the car's
    right side on every source, avoidably; the correct controllers never collide."""
    sources = default_sources(shared_data)
    rows = iqbal_campaign(sources, speeds_kmh=PAPER_SPEEDS)
    assert len(rows) == 9
    for row in rows:
        assert row.keep == "pedestrian" and not row.source_collided
        if row.controller != "3.6 m lane mutant":
            assert row.collisions == (), format_campaign([row])
            continue
        assert row.avoidable_violations, format_campaign([row])
        sides = [c for c in row.avoidable_violations if c.location == "side"]
        assert sides and all(c.side == "right" for c in sides)
        # The car is early: violations only above the source speed.
        assert row.lowest_violating_speed_kmh > row.source_speed_kmh
        # The paper's own test: with the pedestrian re-timed the mutant avoids them all.
        assert len(row.retimed_avoidable_violations) == len(row.violations)
    test_road, eighth, seventh = (r for r in rows if r.controller == "3.6 m lane mutant")
    # The rows differ by the geometry: on the test road the parked cars stand 1 m from
    # the car and hide the child until 26 km/h is too fast to stop; on the streets they
    # stand in a parking lane 2.2 / 4.1 m from it and every violation is avoidable.
    unavoidable = [c.speed_kmh for c in test_road.violations if not c.avoidable]
    assert unavoidable == [26.0]
    assert all(c.avoidable for c in (*eighth.violations, *seventh.violations))
    # By the lane standard nothing on the streets is avoidable (the child enters the 3 m
    # lane too late); on the test road the lane is the whole road.
    assert len(test_road.lane_avoidable_violations) == 3
    assert eighth.lane_avoidable_violations == seventh.lane_avoidable_violations == ()
    # How early each road shows the child (parked cars 1.0 / 2.2 / 4.1 m beside the car's
    # body, on 7th Street the child first crosses a live lane) is the margin full braking
    # had: a few decimetres, 4.5 m, 13.8 m (at 25 / 26 / 26 km/h).
    gaps = [row.least_avoidable_gap for row in (test_road, eighth, seventh)]
    assert gaps == pytest.approx([0.27, 4.49, 13.79], abs=0.01)
    correct = [r for r in rows if r.controller != "3.6 m lane mutant"]
    assert [r.least_avoidable_gap for r in correct] == [None] * 6
    text = format_campaign(rows, sources=sources)
    assert "min. gap m" in text and " 13.8 " in text
    assert "right side at" in text and "(avoidable, violation)" in text
    assert "kerb 5.00 m beyond the car's path, child starts 5.50 m from it" in text


def test_parked_cars_next_to_the_lane_make_violations_that_no_controller_avoids(
    shared_data: Path,
) -> None:
    """Why no residential street without a cycle lane is a default source (docs/aeb.md):
    parked cars 0.7 m from the car hide the child until it is inside the mutant's 1.8 m
    corridor, so the counts change, but the correct controllers collide too, and the
    judge calls exactly those collisions unavoidable."""
    campbell = Street(
        "osm_osmnx/West-Oakland.osm.bz2", "Campbell Street", "West Oakland, CA",
        assumed_tags=MappingProxyType({"parking:both": "lane"}),
    )  # fmt: skip
    (_, source) = default_sources(shared_data, streets=[campbell])
    assert "parked cars 0.70 m beside the car's body" in source.note
    rows = iqbal_campaign([source], speeds_kmh=range(15, 32), retimed=False)
    reference, mutant, ttc = rows
    assert [c.speed_kmh for c in reference.violations] == [25.0, 26.0, 27.0]
    assert reference.avoidable_violations == ttc.avoidable_violations == ()
    assert [c.speed_kmh for c in ttc.violations] == [25.0, 26.0, 27.0]
    assert [c.speed_kmh for c in mutant.avoidable_violations] == [23.0, 24.0]
    assert len(mutant.violations) == 4


def test_campaign_catches_the_mutant_and_clears_the_reference(shared_data: Path) -> None:
    sources = default_sources(shared_data, kind="CPFA-50")
    rows = iqbal_campaign(sources, speeds_kmh=SPEEDS, keep="ego_start")
    assert [(r.source.split(" (")[0], r.controller) for r in rows][:2] == [
        ("Euro NCAP straight 10 m road", "reference"),
        ("Euro NCAP straight 10 m road", "3.6 m lane mutant"),
    ]
    for row in rows:
        assert row.followups == len(SPEEDS) - 1  # the source speed is not a follow-up
        assert not row.source_collided
        # Whatever else happens, the correct controllers never miss an avoidable collision.
        if row.controller != "3.6 m lane mutant":
            assert row.avoidable_violations == ()
    # On 8th Street the far-side adult crosses the oncoming lane first: the reference
    # brakes as it steps onto the road, the mutant only 1.8 m from the car's path.
    assert len(rows[4].avoidable_violations) == 4
    ncap_mutant = rows[1]
    assert [c.speed_kmh for c in ncap_mutant.avoidable_violations] == [40, 60, 70, 80]
    assert ncap_mutant.lowest_violating_speed_kmh == 40
    assert ncap_mutant.violation_rate == pytest.approx(6 / 7)
    assert ncap_mutant.avoidable_rate == pytest.approx(4 / 7)
    assert ncap_mutant.front == 6 and ncap_mutant.side == 0
    # On 7th Street the car drives in the left lane, 1.6 m from the left kerb: the adult
    # steps off it almost into the car's path and no controller can stop in time.
    assert all(not r.avoidable_violations for r in rows[6:])
    text = format_campaign(rows, title="CPFA-50")
    assert text.startswith("CPFA-50\n=======")
    assert "3.6 m lane mutant  avoided  7     6      0     6           4          4" in text
    assert "front at 40, 60, 70, 80 (avoidable, violation)" in text
    assert "63 follow-ups" in text


def test_campaign_reports_collisions_of_colliding_sources(shared_data: Path) -> None:
    source = CampaignSource("fast source", euro_ncap("CPFA-50", ego_speed_kmh=80))
    (row,) = iqbal_campaign(
        [source], {"mutant": mutant_fixed_lane}, speeds_kmh=(70, 90), keep="ego_start"
    )
    assert row.source_collided and row.violations == ()
    assert len(row.collisions) == 2 and all(not c.violation for c in row.collisions)
    assert "source collided too" in format_campaign([row])


def test_campaign_arguments_are_checked(shared_data: Path) -> None:
    with pytest.raises(InvalidArgument, match="sources"):
        iqbal_campaign([])
    with pytest.raises(InvalidArgument, match="controllers"):
        iqbal_campaign(default_sources(shared_data)[:1], {"x": 3})  # type: ignore[dict-item]
    with pytest.raises(InvalidArgument, match="kind"):
        default_sources(shared_data, kind="CPXX")


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["CPNCO-50", "CPNA-25", "CPFA-50"])
@pytest.mark.parametrize("keep", ["pedestrian", "ego_start", "time"])
def test_full_iqbal_campaign(shared_data: Path, kind: str, keep: str) -> None:
    """85 follow-ups per source: the reference never has an avoidable violation; the TTC
    AEB only its documented one."""
    sources = default_sources(shared_data, kind=kind)
    rows = iqbal_campaign(sources, keep=keep)  # type: ignore[arg-type]
    assert all(row.followups == 85 for row in rows)
    for row in rows:
        if row.controller == "reference":
            assert row.avoidable_violations == (), format_campaign([row])
        if row.controller == "TTC AEB" and (kind, keep) != ("CPNCO-50", "time"):
            assert row.avoidable_violations == (), format_campaign([row])
        if row.controller == "TTC AEB" and (kind, keep) == ("CPNCO-50", "time"):
            # Its weakness (docs/aeb.md): it extrapolates a pedestrian at its current
            # speed, and a child still accelerating from standstill looks too slow to
            # reach the car's path in time; at 94-100 km/h on the test road it brakes 2 s
            # after the child starts walking, too late.
            late = [(c.speed_kmh, c.location) for c in row.avoidable_violations]
            assert all(speed >= 94 and where == "front" for speed, where in late), late
    mutant_on_test_road = rows[1]
    if kind != "CPNCO-50" or keep != "ego_start":
        assert mutant_on_test_road.avoidable_violations, format_campaign(rows)
    if keep == "pedestrian":
        # Iqbal's follow-up: the fault shows on every source, the reference is clean.
        for row in rows:
            if row.controller == "3.6 m lane mutant" and not (
                kind == "CPFA-50" and "7th" in row.source
            ):
                assert row.avoidable_violations, format_campaign([row])
