"""An AEB violation found by a test is saved like a LiDAR one: record, bird's-eye picture of
both runs, OpenSCENARIO + OpenDRIVE of both scenarios, and ``--mt-replay`` re-runs it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("matplotlib")
pytest.importorskip("scenariogeneration", reason="the openscenario extra is not installed")

AEB_TEST = """
from hypothesis import Phase, settings
from pytest_metamorphic import metamorphic
from pytest_metamorphic.driving.aeb import mutant_fixed_lane, reference_controller
from pytest_metamorphic.driving.kinematics import simulate
from pytest_metamorphic.relations.driving import speed_relation
from pytest_metamorphic.strategies import aeb_scenarios, straight_roads

CONTROLLER = mutant_fixed_lane

@settings(max_examples=40, database=None, deadline=None, derandomize=True,
          phases=[Phase.generate])
@metamorphic(
    source=aeb_scenarios(kinds=["CPNA-25", "CPNA-75", "CPNCO-50", "CPFA-50"],
                         roads=straight_roads(min_width=3.5, max_width=12.0)),
    relations=[speed_relation(min_speed_kmh=15, max_speed_kmh=100)],
    followups=3,
)
def test_aeb(scenario):
    return simulate(scenario, CONTROLLER())
"""


def test_an_aeb_violation_is_saved_with_picture_and_openscenario_and_replays(
    pytester: pytest.Pytester,
) -> None:
    from pytest_metamorphic.driving.openscenario import validate_openscenario
    from pytest_metamorphic.driving.records import scenario_from_json

    pytester.makepyfile(test_aeb=AEB_TEST)
    result = pytester.runpytest_subprocess("--mt-artifacts", "arts", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    (folder,) = sorted(p.parent for p in (pytester.path / "arts").rglob("record.json"))
    record = json.loads((folder / "record.json").read_text())
    assert record["source"]["kind"] == record["followup"]["kind"] == "aeb_scenario"
    source = scenario_from_json(record["source"]["scenario"])
    followup = scenario_from_json(record["followup"]["scenario"])
    assert followup.ego_speed_kmh != source.ego_speed_kmh
    assert followup.road.lane_width > 3.6  # where the hard-coded lane width matters
    aeb = record["aeb"]
    assert aeb["runs"]["followup"]["collided"] and not aeb["runs"]["source"]["collided"]
    assert record["picture"] == "birdseye.png" and (folder / "birdseye.png").stat().st_size > 0
    for name in ("source", "followup"):
        files = aeb["openscenario"][name]
        validate_openscenario(folder / files["xosc"])
        assert (folder / files["xodr"]).is_file()
    assert "avoidable: a hazard at" in record["explanation"]

    still = pytester.runpytest_subprocess("--mt-replay", str(folder), "-p", "no:cacheprovider")
    still.assert_outcomes(failed=1)
    still.stdout.fnmatch_lines(["*still fail*"])
    pytester.makepyfile(test_aeb=AEB_TEST.replace("= mutant_fixed_lane", "= reference_controller"))
    fixed = pytester.runpytest_subprocess("--mt-replay", str(folder), "-p", "no:cacheprovider")
    fixed.assert_outcomes(passed=1)


def test_a_corrupt_recorded_scenario_is_named(tmp_path: Path) -> None:
    from pytest_metamorphic.core.errors import DataError
    from pytest_metamorphic.reports.inputs import decode_input

    with pytest.raises(DataError, match=r"source: .*not a recorded AEB scenario"):
        decode_input({"kind": "aeb_scenario", "scenario": {"kind": "x"}}, tmp_path, "source")
