"""Campaign tests gate a build: the plugin judges each campaign's merged result (default:
no violation; a threshold; expected violations; a baseline) and fails the campaign's
test, the same with and without pytest-xdist; a job summary for CI; shards sized to the
workers and sources; campaign violations saved as cases that replay."""

from __future__ import annotations

import json
import shutil
import sys

import pytest

CAMPAIGN = """
import os
import numpy as np
from pytest_metamorphic import relations
from pytest_metamorphic.core.campaign import Campaign, campaign_test

def source(rng, index):
    return tuple(int(x) for x in rng.integers(0, 1000, size=5))

def followup(xs, size, rng):
    return xs + tuple(int(x) for x in rng.integers(1000, 2000, size=size))

def system(xs):
    # MT_FAULT: the share of follow-ups on which the first element is lost
    share = float(os.environ.get("MT_FAULT", "0"))
    lossy = len(xs) > 5 and (sum(xs) * 2654435761 % 10007) < share * 10007
    return sorted(xs)[1:] if lossy else sorted(xs)

test_dedupe = campaign_test(
    Campaign("dedupe", source, followup, system, relations.subset(), sizes=(1, 10),
             sources=SOURCES, seed=SEED, system_name="dedupe"),
    GATE
)
"""


def _write(pytester: pytest.Pytester, gate: str = "", sources: int = 60, seed: int = 0) -> None:
    text = CAMPAIGN.replace("SOURCES", str(sources)).replace("SEED", str(seed))
    pytester.makepyfile(test_c=text.replace("GATE", gate.lstrip(", ")))


def _run(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch, *args: str, fault: float = 0.0
) -> pytest.RunResult:
    monkeypatch.setenv("MT_FAULT", str(fault))
    monkeypatch.delenv("GITHUB_STEP_SUMMARY", raising=False)
    return pytester.runpytest_subprocess("--mt-campaign", "-p", "no:cacheprovider", *args)


@pytest.mark.parametrize("workers", [[], ["-n", "2"]], ids=["one process", "xdist"])
def test_a_violating_campaign_fails_its_test(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester, workers: list
) -> None:
    if workers:
        pytest.importorskip("xdist")
    _write(pytester)
    passing = _run(pytester, monkeypatch, *workers)
    passing.assert_outcomes(passed=len(workers) or 1)  # a shard per worker
    passing.stdout.fnmatch_lines(["gate PASSED: campaign 'dedupe' (no violations)"])
    failing = _run(pytester, monkeypatch, *workers, fault=0.2)
    assert failing.ret == pytest.ExitCode.TESTS_FAILED
    failing.assert_outcomes(failed=1, passed=(len(workers) or 1) - 1)
    failing.stdout.fnmatch_lines(
        [
            "*campaign 'dedupe' failed its gate (no violations)",
            "* violating pair(s) where none is allowed*",
            "n=1: * of 60 pairs violate*",
            "gate FAILED: campaign 'dedupe' (no violations)",
            "FAILED test_c.py::test_dedupe* - campaign 'dedupe' failed its gate*",
        ]
    )
    report = json.loads((pytester.path / "mt-campaigns" / "dedupe" / "report.json").read_text())
    assert report["gate"]["passed"] is False
    assert "Gate FAILED" in (pytester.path / "mt-campaigns" / "dedupe" / "report.md").read_text()


def test_a_mutant_campaign_expects_violations(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    _write(pytester, gate=", expect_violations=True")
    found = _run(pytester, monkeypatch, fault=0.2)
    found.assert_outcomes(passed=1)
    found.stdout.fnmatch_lines(["*found the expected violations: * of 120 pairs*"])
    missed = _run(pytester, monkeypatch, fault=0.0)
    missed.assert_outcomes(failed=1)
    missed.stdout.fnmatch_lines(["*the relation did not detect this system's fault*"])


def test_a_threshold_fails_only_on_evidence(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    _write(pytester, gate=", max_rate=0.1", sources=200)
    # about 12% violate: above 10% to the eye, not by the 99% lower bound
    _run(pytester, monkeypatch, fault=0.12).assert_outcomes(passed=1)
    clearly = _run(pytester, monkeypatch, fault=0.4)
    clearly.assert_outcomes(failed=1)
    clearly.stdout.fnmatch_lines(["*lower bound *% is above the maximum 10.0%*"])


def test_a_regression_against_the_baseline_fails_and_main_passes(
    monkeypatch: pytest.MonkeyPatch,
    pytester: pytest.Pytester,
) -> None:
    """CI's recipe: main's campaign folder is kept, a pull request runs against it."""
    _write(pytester, gate=", max_rate=None", sources=150)
    _run(pytester, monkeypatch, fault=0.1).assert_outcomes(passed=1)  # main
    shutil.copytree(pytester.path / "mt-campaigns", pytester.path / "baseline")
    _write(pytester, gate=", max_rate=None", sources=150, seed=1)  # another draw
    same = _run(pytester, monkeypatch, "--mt-baseline", "baseline", fault=0.1)
    same.assert_outcomes(passed=1)
    same.stdout.fnmatch_lines(["*not significantly worse than the baseline baseline/dedupe/*"])
    worse = _run(pytester, monkeypatch, "--mt-baseline", "baseline", fault=0.4)
    worse.assert_outcomes(failed=1)
    worse.stdout.fnmatch_lines(
        [
            "*significantly worse than the baseline baseline/dedupe/report.json*",
            "n=1: */150 (*%) vs baseline */150 (*%): difference +*%, "
            "99.50% interval [[]+*] -> worse",
        ]
    )


def test_a_baseline_that_is_missing_or_broken_is_said(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    _write(pytester)
    missing = _run(pytester, monkeypatch, "--mt-baseline", "nowhere")
    missing.assert_outcomes(passed=1)
    missing.stdout.fnmatch_lines(["*not compared: no baseline at nowhere*"])
    broken = pytester.path / "broken" / "dedupe" / "report.json"
    broken.parent.mkdir(parents=True)
    broken.write_text('{"header": {"campaign": "dedupe"}}')
    result = _run(pytester, monkeypatch, "--mt-baseline", "broken")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*baseline unreadable: *broken/dedupe/report.json*'relation'*"])


def test_the_job_summary_is_markdown_for_ci(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    _write(pytester)
    summary = pytester.path / "summary.md"
    summary.write_text("earlier step\n")
    monkeypatch.setenv("MT_FAULT", "0.2")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    result = pytester.runpytest_subprocess("--mt-campaign", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    text = summary.read_text()
    assert text.startswith("earlier step\n## pytest-metamorphic campaigns")  # appended
    assert "| dedupe | **FAILED** | n=1<br>n=10 |" in text
    assert "### dedupe: gate failed" in text


def test_shards_follow_the_workers_and_the_sources(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    pytest.importorskip("xdist")
    _write(pytester, sources=2, gate=", shards=8")
    result = _run(pytester, monkeypatch, "--collect-only", "-q")
    result.stdout.fnmatch_lines(
        ["test_c.py::test_dedupe[shard0]", "test_c.py::test_dedupe[shard1]"]
    )
    assert "shard2" not in result.stdout.str()  # two sources, two shards: none empty
    _write(pytester, sources=10)
    one = _run(pytester, monkeypatch)
    one.assert_outcomes(passed=1)
    one.stdout.fnmatch_lines(["ran in one process (1 shard(s), 10 sources, *"])
    two = _run(pytester, monkeypatch, "-n", "2")
    two.assert_outcomes(passed=2)
    # a log folder written with two shards resumes without xdist (another layout)
    resumed = _run(pytester, monkeypatch, "--mt-resume")
    resumed.stdout.fnmatch_lines(["*10 sources read back from the logs*"])


def test_a_campaign_case_replays_until_the_fault_is_fixed(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    _write(pytester, gate=", expect_violations=True")
    _run(pytester, monkeypatch, "--mt-campaign-cases", "1", fault=0.3).assert_outcomes(passed=1)
    root = pytester.path / "mt-artifacts" / "test_c_py__test_dedupe" / "dedupe"
    cases = sorted(path.name for path in root.iterdir())
    assert [name.split("-")[0] for name in cases] == ["n1", "n10"]  # the first of each size
    record = json.loads((root / cases[0] / "record.json").read_text())
    assert record["campaign"]["name"] == "dedupe" and record["nodeid"] == "test_c.py::test_dedupe"
    monkeypatch.setenv("MT_FAULT", "0.3")
    still = pytester.runpytest_subprocess(
        "--mt-replay", str(root / cases[0]), "-p", "no:cacheprovider"
    )
    still.assert_outcomes(failed=1)
    still.stdout.fnmatch_lines(["*relation 'subset[[]equality[]]' still FAILS*"])
    monkeypatch.setenv("MT_FAULT", "0")
    fixed = pytester.runpytest_subprocess(
        "--mt-replay", str(root / cases[0]), "-p", "no:cacheprovider"
    )
    fixed.assert_outcomes(passed=1)
    fixed.stdout.fnmatch_lines(["*passes now (fixed)*"])


@pytest.mark.slow  # test_campaign_examples compares the main job's cases under xdist too
def test_cases_are_the_same_under_xdist(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    pytest.importorskip("xdist")
    _write(pytester, gate=", max_rate=None")
    root = pytester.path / "mt-artifacts" / "test_c_py__test_dedupe" / "dedupe"
    _run(pytester, monkeypatch, fault=0.3)
    single = sorted(path.name for path in root.iterdir())
    _run(pytester, monkeypatch, "-n", "2", fault=0.3)
    assert sorted(path.name for path in root.iterdir()) == single
    assert len(single) == 4  # the first two of each of the two sizes


@pytest.mark.slow  # a local cluster's start: 10 s
def test_the_gate_is_the_same_on_a_dask_cluster(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    pytest.importorskip("distributed")
    _write(pytester, gate=", max_rate=0.05", sources=60)
    alone = _run(pytester, monkeypatch, fault=0.3)
    alone.assert_outcomes(failed=1)
    cluster = _run(pytester, monkeypatch, "--mt-dask", "local:2", fault=0.3)
    cluster.assert_outcomes(failed=1)
    lines = [
        line
        for result in (alone, cluster)
        for line in result.stdout.lines
        if line.startswith("gate FAILED") or line.lstrip().startswith(("ok ", "FAIL", "n="))
    ]
    assert lines[: len(lines) // 2] == lines[len(lines) // 2 :]


FULL_DISK = """
import errno
import pytest
from pytest_metamorphic.core.campaign import log

class Full:
    # the log's file on a disk that fills up after 10 records
    def __init__(self, handle):
        self.handle, self.left = handle, 10
    def write(self, text):
        self.left -= 1
        if self.left < 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return self.handle.write(text)
    def __getattr__(self, name):
        return getattr(self.handle, name)

if WHEN == "run":
    opened = log._Writer.__init__
    def full(self, path, header):
        opened(self, path, header)
        self.handle = Full(self.handle)
    log._Writer.__init__ = full

@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session):
    if WHEN == "report":  # the report cannot be put in place (as on a full disk)
        (session.config.rootpath / "mt-campaigns" / "dedupe" / "report.json").mkdir()
"""


@pytest.mark.parametrize("when", ["run", "report"])
def test_a_full_disk_fails_clearly_and_keeps_the_logs(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester, when: str
) -> None:
    # Before: a raw OSError traceback from pytest_sessionfinish and no summary line.
    _write(pytester, sources=60)
    pytester.makeconftest(FULL_DISK.replace("WHEN", repr(when)))
    result = _run(pytester, monkeypatch)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    if when == "run":
        result.assert_outcomes(failed=1)
        result.stdout.fnmatch_lines(
            [
                "*campaign 'dedupe': could not write the campaign log *shard-0-of-1.jsonl "
                "(No space left on device)*"
            ]
        )
        assert "Traceback" not in result.stdout.str()
    else:
        result.assert_outcomes(passed=1)
        result.stdout.fnmatch_lines(
            [
                "*metamorphic reports NOT written*",
                "--mt-campaign-dir: *dedupe/report.json: could not write the campaign report "
                "(Is a directory): a folder stands where the file must be*",
                "*once the folder can be written, run again with --mt-campaign --mt-resume*",
            ]
        )
        (pytester.path / "mt-campaigns" / "dedupe" / "report.json").rmdir()
    pytester.makeconftest("")
    resumed = _run(pytester, monkeypatch, "--mt-resume")
    resumed.assert_outcomes(passed=1)
    resumed.stdout.fnmatch_lines(["*(complete)*", "*sources read back from the logs*"])


def test_a_campaign_folder_that_cannot_be_made_fails_clearly(
    monkeypatch: pytest.MonkeyPatch, pytester: pytest.Pytester
) -> None:
    # Before: a raw OSError with 143 lines of traceback, and advice to free the space.
    _write(pytester, sources=20)
    (pytester.path / "runs").write_text("a file where the campaign folder must be")
    result = _run(pytester, monkeypatch, "--mt-campaign-dir", "runs/campaigns")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*campaign 'dedupe': runs/campaigns/dedupe: could not write campaign log *"
            "a file stands where a folder must be*(--mt-campaign-dir names the folder*",
            "*metamorphic reports NOT written*",
            "--mt-campaign-dir: runs/campaigns/dedupe/report.json: could not write the "
            "campaign report*",
            "*ran: nothing (no source ran or was read back from the logs)*",
        ]
    )
    said = result.stdout.str()
    assert "Traceback" not in said and "free" not in said and "--mt-resume" not in said


PASSING = """
def test_plain():
    assert True
"""


def test_a_report_that_cannot_be_written_without_a_campaign_names_the_option(
    pytester: pytest.Pytester,
) -> None:
    # Before: the footer advised freeing the space and --mt-resume in a session with no
    # campaign, and named the report's hidden temporary file.
    pytester.makepyfile(test_p=PASSING)
    (pytester.path / "out").write_text("a file where the report's folder must be")
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "--mt-report", "out/r.json")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(
        [
            "*metamorphic reports NOT written*",
            "--mt-report: out/r.json: could not write the JSON report (*): a file stands "
            "where a folder must be*",
        ]
    )
    said = result.stdout.str()
    assert "campaign logs" not in said and "--mt-resume" not in said and ".tmp" not in said


def test_a_campaign_on_a_read_only_mount_says_read_only(pytester: pytest.Pytester) -> None:
    from tests.read_only import run_on_a_read_only_mount

    _write(pytester, sources=20)
    (pytester.path / "ro").mkdir()
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--mt-campaign"]
    said = run_on_a_read_only_mount(
        pytester.path / "ro", [*command, "--mt-campaign-dir", "ro/camp"], cwd=pytester.path
    )
    assert "1 failed" in said, said
    assert (
        "campaign 'dedupe': ro/camp/dedupe: could not write campaign log "
        "ro/camp/dedupe/shard-0-of-1.jsonl (Read-only file system): it is on a read-only file "
        "system: choose a folder on a writable one (--mt-campaign-dir names" in said
    )
    assert "Traceback" not in said and "free" not in said and "--mt-resume" not in said
