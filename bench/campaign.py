"""The paper's full MR1 campaign against the reference pipeline, run as a user runs it.

Zhou & Sun's protocol (CACM 2019): S sources (default 1000 synthetic HDL-64E street
scenes), each with one follow-up per noise size n in {10, 100, 1000}, the system run once
per source and reused for its three follow-ups: 4S SUT runs (the paper's 6S without the
cache). A temporary test module defines the campaign with ``campaign_test``; pytest runs it
twice in subprocesses, ``pytest --mt-campaign`` single-process and with ``-n 2``
(pytest-xdist), each timed by the wall clock, start-up included. The two merged JSON reports
must be identical (the campaign promises it); the bench exits 1 otherwise.

Targets for S = 1000: under 300 s single-process, speedup >= 1.7 with ``-n 2``. Both need an
otherwise idle machine with at least 2 cores.

    python bench/campaign.py [--sources N] [--seed S]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

ROOT = Path(__file__).resolve().parent.parent
SHARDS = 32  # ~31 sources per shard at S = 1000: xdist's tail imbalance stays a few seconds
# Everything in CampaignResult.to_json() is a pure function of the campaign: no timestamps.
DETERMINISTIC_KEYS = (
    "header",
    "complete",
    "source_indices",
    "sources_done",
    "sut_calls",
    "sut_calls_saved",
    "source_crashes",
    "sizes",
    "examples",
)
OUTPUT_TAIL = 40

MODULE = """\
from pathlib import Path

import pytest_metamorphic
from pytest_metamorphic.core.campaign import campaign_test
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.perception.pipeline import ReferencePerception

# Timing another copy of the package would measure the wrong code.
assert Path(pytest_metamorphic.__file__).resolve().is_relative_to({root!r}), (
    pytest_metamorphic.__file__
)

reference = ReferencePerception()


def reference_system(frame):
    return reference(frame.cloud, frame.roi)


test_bench = campaign_test(
    mr1_campaign(reference_system, name="bench MR1 reference", sources={sources}, seed={seed}),
    shards={shards},
)
"""


@dataclass(frozen=True)
class Run:
    """One timed pytest run and the merged campaign report it wrote."""

    mode: str
    wall_s: float
    report: dict[str, Any]


def fail(message: str) -> NoReturn:
    print(f"bench/campaign.py: {message}", file=sys.stderr)
    sys.exit(1)


def write_project(folder: Path, *, sources: int, seed: int) -> Path:
    """A user's project: the campaign test and a ``pytest.ini`` that keeps it self-contained.

    The ini file makes ``folder`` the rootdir, so the repository's pytest options (addopts,
    markers) do not leak into the measurement.
    """
    (folder / "pytest.ini").write_text("[pytest]\n", encoding="utf-8")
    module = folder / "test_bench_campaign.py"
    module.write_text(
        MODULE.format(root=str(ROOT), sources=sources, seed=seed, shards=SHARDS), encoding="utf-8"
    )
    return module


def subprocess_env() -> dict[str, str]:
    """This checkout first on the path; the plugin still loads through its entry point."""
    env = {
        key: value
        for key, value in os.environ.items()
        if key not in ("PYTEST_ADDOPTS", "PYTEST_DISABLE_PLUGIN_AUTOLOAD")
    }
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def run_pytest(module: Path, campaign_dir: Path, *, mode: str, extra: list[str]) -> Run:
    """Time one ``pytest --mt-campaign`` subprocess and read the report it wrote."""
    command = [
        sys.executable,
        "-m",
        "pytest",
        str(module),
        "--mt-campaign",
        "--mt-campaign-dir",
        str(campaign_dir),
        "-p",
        "no:cacheprovider",
        "-q",
        *extra,
    ]
    start = time.perf_counter()
    completed = subprocess.run(
        command,
        cwd=module.parent,
        env=subprocess_env(),
        capture_output=True,
        text=True,
        check=False,
    )
    wall_s = time.perf_counter() - start
    if completed.returncode != 0:
        tail = (completed.stdout + completed.stderr).splitlines()[-OUTPUT_TAIL:]
        fail(f"{mode} run exited {completed.returncode}: {' '.join(command)}\n" + "\n".join(tail))
    return Run(mode, wall_s, read_report(campaign_dir, mode=mode))


def read_report(campaign_dir: Path, *, mode: str) -> dict[str, Any]:
    reports = sorted(campaign_dir.glob("*/report.json"))
    if len(reports) != 1:
        fail(f"{mode} run: expected one report.json under {campaign_dir}, found {reports}")
    return json.loads(reports[0].read_text(encoding="utf-8"))


def check_complete(run: Run, *, sources: int) -> None:
    """Every source ran, and each ran the system once plus once per follow-up (the cache)."""
    report = run.report
    header = report["header"]
    expected_calls = sources * (1 + len(header["sizes"]) * header["followups"])
    if not report.get("complete") or report.get("sources_done") != sources:
        fail(f"{run.mode} run: {report.get('sources_done')} of {sources} sources done")
    if report.get("sut_calls") != expected_calls:
        fail(f"{run.mode} run: {report.get('sut_calls')} SUT calls, expected {expected_calls}")


def check_identical(single: Run, parallel: Run) -> None:
    differing = [
        key
        for key in DETERMINISTIC_KEYS
        if key not in single.report
        or key not in parallel.report
        or single.report[key] != parallel.report[key]
    ]
    if differing:
        fail(
            f"{single.mode} and {parallel.mode} runs differ in {differing}; "
            "a campaign's result must not depend on how its sources were split"
        )


def print_table(runs: list[Run], *, sources: int) -> None:
    sizes = runs[0].report["header"]["sizes"]
    violation_columns = [f"viol n={n}" for n in sizes]
    print(
        f"{'mode':<10}{'wall s':>10}{'sources/s':>11}{'SUT calls':>11}"
        + "".join(f"{column:>13}" for column in violation_columns)
    )
    for run in runs:
        counts = run.report["sizes"]
        violations = [f"{counts[str(n)]['violations']}/{counts[str(n)]['pairs']}" for n in sizes]
        print(
            f"{run.mode:<10}{run.wall_s:>10.1f}{sources / run.wall_s:>11.2f}"
            f"{run.report['sut_calls']:>11}" + "".join(f"{v:>13}" for v in violations)
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sources", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.sources < 1 or args.seed < 0:
        parser.error("--sources must be >= 1 and --seed >= 0")

    # The speedup is only meaningful on an idle machine: say what this one was doing.
    load = ", ".join(f"{value:.2f}" for value in os.getloadavg())
    print(
        f"MR1 campaign, reference pipeline: {args.sources} sources x n in (10, 100, 1000), "
        f"1 follow-up each, seed {args.seed}, {SHARDS} shards; {os.cpu_count()} CPUs, "
        f"load average {load}"
    )
    with tempfile.TemporaryDirectory(prefix="bench-campaign-") as tmp:
        folder = Path(tmp)
        module = write_project(folder, sources=args.sources, seed=args.seed)
        single = run_pytest(module, folder / "single", mode="single", extra=[])
        parallel = run_pytest(module, folder / "n2", mode="-n 2", extra=["-n", "2"])
    for run in (single, parallel):
        check_complete(run, sources=args.sources)
    check_identical(single, parallel)

    print_table([single, parallel], sources=args.sources)
    speedup = single.wall_s / parallel.wall_s
    print(
        f"speedup with -n 2: {speedup:.2f}x (target >= 1.7); merged reports identical; "
        f"single-process target < 300 s for 1000 sources"
    )
    print(
        f"RESULT wall_s={single.wall_s:.1f} speedup_n2={speedup:.2f} "
        f"sut_calls={single.report['sut_calls']}"
    )


if __name__ == "__main__":
    main()
