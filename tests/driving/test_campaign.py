"""Iqbal's campaign: sources on the test road and real OSM streets, table, verdicts."""

from __future__ import annotations

from pathlib import Path

import pytest

from pytest_metamorphic import DataError, InvalidArgument
from pytest_metamorphic.driving.aeb import mutant_fixed_lane
from pytest_metamorphic.driving.campaign import (
    CampaignSource,
    default_sources,
    format_campaign,
    iqbal_campaign,
    main,
)
from pytest_metamorphic.driving.scenario import euro_ncap

#: A few speeds around the interesting range, so the default suite stays fast.
SPEEDS = (15, 20, 40, 60, 70, 80, 90, 100)


def test_default_sources_are_the_test_road_and_two_real_streets(shared_data: Path) -> None:
    sources = default_sources(shared_data)
    assert [s.scenario.road.name for s in sources] == [
        "Euro NCAP straight 10 m road",
        "Goethestraße",
        "8th Street",
    ]
    for source in sources:
        scenario = source.scenario
        assert (scenario.kind, scenario.ego_speed_kmh) == ("CPNCO-50", 20.0)
        assert scenario.time_to_collision_point == pytest.approx(6.0)
        assert 0 <= scenario.ego_start_s < scenario.conflict_s <= scenario.road.length
    assert sources[2].name == "8th Street, West Oakland, CA (OSM way 6358365)"
    street = sources[1].scenario
    assert street.road.width == 6.0 and street.road.lanes == 2
    assert street.ego_offset == pytest.approx(-1.5)  # right-hand lane of a two-way street
    with pytest.raises(DataError, match="no drivable way named"):
        default_sources(shared_data, streets=[("osm_osmnx/West-Oakland.osm.bz2", "Nowhere Rd", "")])


def test_campaign_catches_the_mutant_and_clears_the_reference(shared_data: Path) -> None:
    rows = iqbal_campaign(default_sources(shared_data, kind="CPFA-50"), speeds_kmh=SPEEDS)
    assert [(r.source.split(" (")[0], r.controller) for r in rows][:2] == [
        ("Euro NCAP straight 10 m road", "reference"),
        ("Euro NCAP straight 10 m road", "3.6 m lane mutant"),
    ]
    for row in rows:
        assert row.followups == len(SPEEDS) - 1  # the source speed is not a follow-up
        assert not row.source_collided
        # Whatever else happens, the reference never misses an avoidable collision.
        if row.controller == "reference":
            assert row.avoidable_violations == ()
    # On the real streets (6 m, two 3 m lanes) the far-side adult crosses the oncoming lane
    # first: the reference brakes as it steps onto the road, the mutant only 1.8 m out.
    street_mutants = [row for row in rows[2:] if row.controller == "3.6 m lane mutant"]
    assert all(len(row.avoidable_violations) == 4 for row in street_mutants)
    ncap_mutant = rows[1]
    assert [c.speed_kmh for c in ncap_mutant.avoidable_violations] == [60, 70, 80, 90]
    assert ncap_mutant.lowest_violating_speed_kmh == 60
    assert ncap_mutant.violation_rate == pytest.approx(5 / 7)
    assert ncap_mutant.avoidable_rate == pytest.approx(4 / 7)
    assert ncap_mutant.front == 5 and ncap_mutant.side == 0
    text = format_campaign(rows, title="CPFA-50")
    assert text.startswith("CPFA-50\n=======")
    assert "3.6 m lane mutant  avoided  7     5      0     5           4          60" in text
    assert "front at 60, 70, 80, 90 (avoidable, violation)" in text
    assert "42 follow-ups" in text


def test_campaign_reports_collisions_of_colliding_sources(shared_data: Path) -> None:
    source = CampaignSource("fast source", euro_ncap("CPFA-50", ego_speed_kmh=80))
    (row,) = iqbal_campaign([source], {"mutant": mutant_fixed_lane}, speeds_kmh=(70, 90))
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


def test_command_line(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--data", str(shared_data), "--kind", "CPNA-25", "--min-speed", "85",
                 "--max-speed", "88"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "CPNA-25, source 20 km/h, car start kept, pedestrian re-timed" in out
    assert "24 follow-ups" in out


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["CPNCO-50", "CPNA-25", "CPFA-50"])
@pytest.mark.parametrize("keep", ["ego_start", "time"])
def test_full_iqbal_campaign(shared_data: Path, kind: str, keep: str) -> None:
    """85 follow-ups per source: the reference never has an avoidable violation."""
    sources = default_sources(shared_data, kind=kind)
    rows = iqbal_campaign(sources, keep=keep)  # type: ignore[arg-type]
    assert all(row.followups == 85 for row in rows)
    for row in rows:
        if row.controller == "reference":
            assert row.avoidable_violations == (), format_campaign([row])
    mutant_on_test_road = rows[1]
    if kind != "CPNCO-50" or keep == "time":
        assert mutant_on_test_road.avoidable_violations, format_campaign(rows)
