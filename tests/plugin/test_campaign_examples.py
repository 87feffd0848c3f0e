"""The README's main job, examples/test_paper_campaign.py, run as a user runs it (fewer
sources): both tables and gates print, the reports and the mutant's cases are written, and
-n 2 gives the same result."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "test_paper_campaign.py"


@pytest.fixture
def paper_campaign(pytester: pytest.Pytester) -> pytest.Pytester:
    source = EXAMPLE.read_text(encoding="utf-8")
    assert "SOURCES = 200" in source  # the README promises 200 scenes
    pytester.makepyfile(test_paper_campaign=source.replace("SOURCES = 200", "SOURCES = 6"))
    return pytester


def test_main_job_prints_both_tables_and_writes_reports(paper_campaign: pytest.Pytester) -> None:
    result = paper_campaign.runpytest_subprocess(
        "--mt-campaign", "--mt-minimize-budget", "40", "-p", "no:cacheprovider"
    )
    result.assert_outcomes(passed=2)  # one test per campaign without xdist
    result.stdout.fnmatch_lines(
        [
            "*= campaign MR1 reference pipeline =*",
            "campaign 'MR1 reference pipeline', seed 0, 6 sources x 3 sizes x 1 follow-up(s) "
            "(complete); 24 SUT calls, 12 saved*",
            "*violations of subset*",
            "gate PASSED: campaign 'MR1 reference pipeline' (no violations)",
            "*= campaign MR1 mutant count_scaled_radius =*",
            "violation cases (* saved; replay one: pytest --mt-replay <folder>):",
            "gate PASSED: campaign 'MR1 mutant count_scaled_radius' (expects violations*",
            "*found the expected violations: *",
        ]
    )
    folder = paper_campaign.path / "mt-campaigns" / "MR1_reference_pipeline"
    report = json.loads((folder / "report.json").read_text())
    assert report["complete"] and report["sut_calls"] == 24
    assert all(size["violations"] == 0 for size in report["sizes"].values())
    assert (folder / "campaign.png").stat().st_size > 0
    assert (folder / "report.md").read_text().startswith("#")
    assert report["gate"]["passed"] is True


def test_main_job_is_identical_under_xdist(paper_campaign: pytest.Pytester) -> None:
    pytest.importorskip("xdist")
    single = paper_campaign.runpytest_subprocess(
        "--mt-campaign", "--mt-campaign-dir", "one", "-k", "count_scaled",
        "--mt-minimize-budget", "40", "-p", "no:cacheprovider",
    )  # fmt: skip
    single.assert_outcomes(passed=1, deselected=1)
    spread = paper_campaign.runpytest_subprocess(
        "--mt-campaign", "--mt-campaign-dir", "two", "-k", "count_scaled", "-n", "2",
        "--mt-minimize-budget", "40", "-p", "no:cacheprovider",
    )  # fmt: skip
    spread.assert_outcomes(passed=2)  # a shard per worker
    name = "MR1_mutant_count_scaled_radius"
    reports = [
        json.loads((paper_campaign.path / d / name / "report.json").read_text())
        for d in ("one", "two")
    ]
    assert reports[0]["execution"] != reports[1]["execution"]  # one process, two workers
    for report in reports:
        del report["execution"]
    assert reports[0] == reports[1]


def test_a_case_of_the_faulty_pipeline_replays_from_its_folder(
    paper_campaign: pytest.Pytester,
) -> None:
    """A campaign violation on rendered HDL-64E streets is a folder like a test's artifact
    (clouds, record, bird's-eye picture) and replays against the campaign's pipeline."""
    pytest.importorskip("matplotlib")
    run = paper_campaign.runpytest_subprocess(
        "--mt-campaign", "-k", "count_scaled", "--mt-campaign-cases", "1",
        "--mt-minimize-budget", "40", "-p", "no:cacheprovider",
    )  # fmt: skip
    run.assert_outcomes(passed=1, deselected=1)
    root = paper_campaign.path / "mt-artifacts"
    folders = sorted(path.parent for path in root.rglob("record.json"))
    assert folders, run.stdout.str()
    case = folders[0]
    assert {"source.pcd", "followup.pcd", "birdseye.png", "record.json"} <= {
        path.name for path in case.iterdir()
    }
    record = json.loads((case / "record.json").read_text())
    assert record["campaign"]["name"] == "MR1 mutant count_scaled_radius"
    assert record["minimization"]["sut_calls"] <= 40
    replayed = paper_campaign.runpytest_subprocess(
        "--mt-replay", str(case), "-p", "no:cacheprovider"
    )
    replayed.assert_outcomes(failed=1)
    replayed.stdout.fnmatch_lines(["*still FAILS*"])
