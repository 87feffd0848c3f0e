"""The paper's full MR1 campaign against the reference pipeline, run as a user runs it.

Zhou & Sun's protocol (CACM 2019): S sources (default 1000 synthetic HDL-64E street
scenes), each with one follow-up per noise size n in {10, 100, 1000}, the system run once
per source and reused for its three follow-ups: 4S SUT runs (the paper's 6S without the
cache). A temporary test module defines the campaign with ``campaign_test``; pytest runs it
three times in subprocesses, ``pytest --mt-campaign`` single-process, with ``-n 2``
(pytest-xdist) and with ``--mt-dask local:2`` (a Dask LocalCluster of 2 worker processes),
each timed by the wall clock, start-up included. The merged JSON reports must be identical
(the campaign promises it); the bench exits 1 otherwise.

Then the Dask engine's own cost: a campaign of the same shape whose system sleeps 10 ms
(no CPU, so only the engine competes for the cores) runs in this process and on a 2-worker
LocalCluster. ``unit_overhead`` = (workers x cluster time - one-process time) / one-process
time: what the engine adds to the system's time (target <= 0.02), with the default guided
batches; ``task_ms`` is the cost of one task of one source (``--mt-dask-batch 1``).

Memory: the peak resident memory of the single-process run, and of two more single-process
campaigns over 120k-point sweeps (``--memory-sources`` sources) with 1 and 8 follow-ups per
source and size: a campaign keeps no follow-up once judged, so the peak must not grow with
the number of follow-ups (``rss_growth`` = peak with 8 / peak with 1, target <= 1.05).

Targets for S = 1000: at most 100 s single-process, speedup >= 1.7 with ``-n 2`` and >= 1.8
on the 2-worker cluster. They need an otherwise idle machine with at least 2 cores.

Where a source's ~75 ms go (cProfile of 30 sources, 2026-11-26): rendering the scene
27 ms (Embree 9 ms, see bench/strategies.py), the reference pipeline 4 x ~7 ms, laying out
the random scene and its ROI's bitmaps, free and interior cells ~15 ms (scan conversion,
dilations by 1-51 cells), three noise follow-ups ~2 ms. Before: 122-148 s, with ~10 MB of
cell corners built per ROI for sampling (now a ``CellSet`` of flat indices, corners only for
the cells drawn), a whole-grid difference array and cumsum per polygon scan (now the
filled runs' cells), and the render's numpy overhead.

    python bench/campaign.py [--sources N] [--seed S] [--overhead-sources N] [--memory-sources N]
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
from pytest_metamorphic.lidar.systems.perception.pipeline import ReferencePerception

# Timing another copy of the package would measure the wrong code.
assert Path(pytest_metamorphic.__file__).resolve().is_relative_to({root!r}), (
    pytest_metamorphic.__file__
)

reference = ReferencePerception()


def reference_system(frame):
    return reference(frame.cloud, frame.roi)


test_bench = campaign_test(
    mr1_campaign(
        reference_system,
        name="bench MR1 reference",
        sources={sources},
        seed={seed},
        followups={followups},
    ),
    shards={shards},
)
"""


@dataclass(frozen=True)
class Run:
    """One timed pytest run and the merged campaign report it wrote."""

    mode: str
    wall_s: float
    report: dict[str, Any]
    peak_rss_mb: float  # of the pytest process (its workers' not included)


def fail(message: str) -> NoReturn:
    print(f"bench/campaign.py: {message}", file=sys.stderr)
    sys.exit(1)


def write_project(folder: Path, *, sources: int, seed: int, followups: int = 1) -> Path:
    """A user's project: the campaign test and a ``pytest.ini`` that keeps it self-contained.

    The ini file makes ``folder`` the rootdir, so the repository's pytest options (addopts,
    markers) do not leak into the measurement.
    """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "pytest.ini").write_text("[pytest]\n", encoding="utf-8")
    module = folder / "test_bench_campaign.py"
    text = MODULE.format(
        root=str(ROOT), sources=sources, seed=seed, shards=SHARDS, followups=followups
    )
    module.write_text(text, encoding="utf-8")
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
    output = campaign_dir.parent / f"{campaign_dir.name}.log"
    start = time.perf_counter()
    with output.open("w+", encoding="utf-8") as log:
        process = subprocess.Popen(
            command, cwd=module.parent, env=subprocess_env(), stdout=log, stderr=log
        )
        # wait4, not wait: its resource usage gives the process's peak resident memory.
        _, status, usage = os.wait4(process.pid, 0)
        wall_s = time.perf_counter() - start
        process.returncode = os.waitstatus_to_exitcode(status)
        log.seek(0)
        text = log.read()
    if process.returncode != 0:
        tail = text.splitlines()[-OUTPUT_TAIL:]
        fail(f"{mode} run exited {process.returncode}: {' '.join(command)}\n" + "\n".join(tail))
    peak_mb = usage.ru_maxrss / 1024  # KiB on Linux
    return Run(mode, wall_s, read_report(campaign_dir, mode=mode), peak_mb)


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
        f"{'mode':<10}{'wall s':>10}{'sources/s':>11}{'SUT calls':>11}{'peak RSS MB':>13}"
        + "".join(f"{column:>13}" for column in violation_columns)
    )
    for run in runs:
        counts = run.report["sizes"]
        violations = [f"{counts[str(n)]['violations']}/{counts[str(n)]['pairs']}" for n in sizes]
        print(
            f"{run.mode:<10}{run.wall_s:>10.1f}{sources / run.wall_s:>11.2f}"
            f"{run.report['sut_calls']:>11}{run.peak_rss_mb:>13.0f}"
            + "".join(f"{v:>13}" for v in violations)
        )


MEMORY_FOLLOWUPS = (1, 8)
SLEEP_S = 0.010
OVERHEAD_WORKERS = 2


def sleeping_system(value: Any) -> list[int]:
    time.sleep(SLEEP_S)
    return [value[0]]


def toy_source(rng: Any, index: int) -> tuple[int, ...]:
    return (index, int(rng.integers(10**6)))


def toy_followup(value: tuple[int, ...], size: int, rng: Any) -> tuple[int, ...]:
    return (*value, size)


@dataclass(frozen=True)
class Overhead:
    process_s: float
    cluster_s: float  # guided batches
    single_task_s: float  # one source per task
    start_s: float
    sources: int
    calls: int

    @property
    def ratio(self) -> float:
        return (OVERHEAD_WORKERS * self.cluster_s - self.process_s) / self.process_s

    @property
    def task_ms(self) -> float:
        extra = OVERHEAD_WORKERS * self.single_task_s - self.process_s
        return 1000 * extra / self.sources


def measure_overhead(sources: int) -> Overhead:
    """The 10 ms sleeping system in this process, then on a 2-worker LocalCluster."""
    sys.path.insert(0, str(ROOT))
    from pytest_metamorphic import relations
    from pytest_metamorphic.core.campaign import Campaign, run_campaign
    from pytest_metamorphic.core.campaign.cluster import connect

    campaign = Campaign(
        name="bench overhead",
        source=toy_source,
        followup=toy_followup,
        system=sleeping_system,
        relation=relations.subset(),
        sizes=(10, 100, 1000),
        sources=sources,
    )
    process = run_campaign(campaign)
    started = time.perf_counter()
    with connect(f"local:{OVERHEAD_WORKERS}") as client:
        client.run(lambda: None)  # workers up and answering
        start_s = time.perf_counter() - started
        guided = run_campaign(campaign, cluster=client)
        single = run_campaign(campaign, cluster=client, batch_size=1)
    for result in (guided, single):
        if result.outcome_json() != process.outcome_json():
            fail("the overhead campaign's cluster result differs from the one-process one")
    return Overhead(
        process.execution[0]["seconds"],
        guided.execution[0]["seconds"],
        single.execution[0]["seconds"],
        start_s,
        sources,
        process.sut_calls,
    )


def print_overhead(overhead: Overhead) -> None:
    per_call = overhead.process_s / overhead.calls * 1000
    print(
        f"\nengine overhead: {overhead.sources} sources x 4 calls of a {SLEEP_S * 1000:.0f} ms "
        f"system ({per_call:.2f} ms per call in one process, {overhead.process_s:.1f} s)"
    )
    print(f"{'run':<34}{'wall s':>8}{'x workers / one process':>26}")
    print(f"{'one process':<34}{overhead.process_s:>8.2f}{1.0:>26.3f}")
    for label, seconds in (
        ("Dask, 2 workers, guided batches", overhead.cluster_s),
        ("Dask, 2 workers, 1 source a task", overhead.single_task_s),
    ):
        ratio = OVERHEAD_WORKERS * seconds / overhead.process_s
        print(f"{label:<34}{seconds:>8.2f}{ratio:>26.3f}")
    print(
        f"unit_overhead {overhead.ratio:.4f} (target <= 0.02); one task of one source costs "
        f"{overhead.task_ms:.2f} ms; the LocalCluster took {overhead.start_s:.2f} s to start"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sources", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--overhead-sources", type=int, default=300)
    parser.add_argument("--memory-sources", type=int, default=40)
    args = parser.parse_args()
    if min(args.sources, args.overhead_sources, args.memory_sources) < 1 or args.seed < 0:
        parser.error("--sources, --overhead-sources and --memory-sources must be >= 1, --seed >= 0")

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
        dask = run_pytest(module, folder / "dask", mode="dask 2", extra=["--mt-dask", "local:2"])
        memory = {
            count: run_pytest(
                write_project(
                    folder / f"memory-{count}",
                    sources=args.memory_sources,
                    seed=args.seed,
                    followups=count,
                ),
                folder / f"memory-{count}" / "campaigns",
                mode=f"memory F={count}",
                extra=[],
            )
            for count in MEMORY_FOLLOWUPS
        }
    for run in (single, parallel, dask):
        check_complete(run, sources=args.sources)
    for run in memory.values():
        check_complete(run, sources=args.memory_sources)
    check_identical(single, parallel)
    check_identical(single, dask)

    print_table([single, parallel, dask], sources=args.sources)
    running = sum(entry.get("seconds", 0) for entry in dask.report.get("execution", []))
    print(
        f"the Dask run spent {running:.1f} s running sources; the rest of its "
        f"{dask.wall_s:.1f} s is pytest, collection and the cluster's start"
    )
    speedup = single.wall_s / parallel.wall_s
    speedup_dask = single.wall_s / dask.wall_s
    print(
        f"speedup with -n 2: {speedup:.2f}x (target >= 1.7); on the Dask LocalCluster of 2 "
        f"workers: {speedup_dask:.2f}x (target >= 1.8); merged reports identical; "
        f"single-process target <= 100 s for 1000 sources"
    )
    low, high = (memory[count] for count in MEMORY_FOLLOWUPS)
    growth = high.peak_rss_mb / low.peak_rss_mb
    print(
        f"\npeak RSS over {args.memory_sources} sources of ~120k points: "
        f"{low.peak_rss_mb:.0f} MB with {MEMORY_FOLLOWUPS[0]} follow-up per source and size "
        f"({low.report['sut_calls']} SUT calls), {high.peak_rss_mb:.0f} MB with "
        f"{MEMORY_FOLLOWUPS[1]} ({high.report['sut_calls']} calls): x{growth:.3f} "
        "(target <= 1.05: nothing accumulates per follow-up)"
    )
    overhead = measure_overhead(args.overhead_sources)
    print_overhead(overhead)
    print(
        f"RESULT wall_s={single.wall_s:.1f} speedup_n2={speedup:.2f} "
        f"speedup_dask2={speedup_dask:.2f} unit_overhead={overhead.ratio:.4f} "
        f"task_ms={overhead.task_ms:.2f} cluster_start_s={overhead.start_s:.2f} "
        f"sut_calls={single.report['sut_calls']} peak_rss_mb={single.peak_rss_mb:.0f} "
        f"rss_f1_mb={low.peak_rss_mb:.0f} rss_f8_mb={high.peak_rss_mb:.0f} "
        f"rss_growth={growth:.3f}"
    )


if __name__ == "__main__":
    main()
