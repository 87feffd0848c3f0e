"""``pytest --mt-campaign --mt-dask``: a campaign test run on a Dask LocalCluster."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.plugin.test_engine_plugin import CAMPAIGN, outcome

pytest.importorskip("distributed", reason="the dask extra is not installed")

# The same campaign, slow enough to be interrupted half-way when MT_SLOW is set (the
# runs that resume it need not wait: the outcome does not depend on the time taken).
SLOW_CAMPAIGN = CAMPAIGN.replace(
    "def system(xs):\n",
    "def system(xs):\n    import os, time\n    time.sleep(float(os.environ.get('MT_SLOW', 0)))\n",
)


def report(pytester: pytest.Pytester, folder: str = "mt-campaigns") -> dict:
    return json.loads((pytester.path / folder / "dedupe" / "report.json").read_text())


def test_a_campaign_on_a_local_cluster_equals_the_one_process_run(
    pytester: pytest.Pytester,
) -> None:
    pytester.makepyfile(test_c=CAMPAIGN)
    alone = pytester.runpytest_subprocess("--mt-campaign", "--mt-campaign-dir", "one")
    alone.assert_outcomes(passed=4)
    result = pytester.runpytest_subprocess(
        "--mt-campaign", "--mt-campaign-dir", "two", "--mt-dask", "local:2"
    )
    # Shard 0's test runs the whole campaign; the cluster spreads its sources.
    result.assert_outcomes(passed=1, deselected=3)
    result.stdout.fnmatch_lines(
        [
            "*(complete)*",
            "ran on the Dask cluster tcp://127.0.0.1:* (2 workers, * tasks of guided "
            "sources, 40 sources in * s)",
        ]
    )
    on_cluster = report(pytester, "two")
    assert outcome(on_cluster) == outcome(report(pytester, "one"))
    assert on_cluster["execution"][0]["engine"] == "dask"
    logs = sorted(p.name for p in (pytester.path / "two" / "dedupe").glob("*.jsonl"))
    assert logs == [f"shard-{k}-of-4.jsonl" for k in range(4)]  # the same layout as xdist's
    markdown = (pytester.path / "two" / "dedupe" / "report.md").read_text()
    assert "ran on the Dask cluster" in markdown


def test_a_run_interrupted_on_the_cluster_resumes_without_it(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_c=SLOW_CAMPAIGN)
    folder = pytester.path / "mt-campaigns" / "dedupe"
    command = [sys.executable, "-m", "pytest", "--mt-campaign", "--mt-dask", "local:2"]
    process = subprocess.Popen(
        [*command, "-p", "no:cacheprovider"],
        cwd=pytester.path,
        env={**os.environ, "MT_SLOW": "0.2"},
        # pytest-xdist workers ignore SIGINT and children inherit that: a user's shell does not.
        preexec_fn=_default_sigint,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    deadline = time.monotonic() + 120
    while _records(folder) < 12:
        assert process.poll() is None, process.communicate()[0]
        assert time.monotonic() < deadline, "the cluster run made no progress"
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)  # Ctrl-C
    output, _ = process.communicate(timeout=60)
    assert process.returncode == pytest.ExitCode.INTERRUPTED, output
    partial = report(pytester)
    assert not partial["complete"] and partial["sources_done"] >= 12, output
    assert "PARTIAL" in output
    resumed = pytester.runpytest_subprocess("--mt-campaign", "--mt-resume")
    resumed.assert_outcomes(passed=4)
    resumed.stdout.fnmatch_lines(["*(complete)*", "*sources read back from the logs*"])
    after = report(pytester)
    sources = [
        json.loads(line)["source"]
        for path in folder.glob("shard-*.jsonl")
        for line in path.read_text().splitlines()[1:]
    ]
    assert sorted(sources) == list(range(40))  # nothing lost, nothing twice
    fresh = pytester.runpytest_subprocess("--mt-campaign", "--mt-campaign-dir", "fresh")
    fresh.assert_outcomes(passed=4)
    assert outcome(after) == outcome(report(pytester, "fresh"))


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _records(folder) -> int:
    return sum(
        max(len(path.read_text().splitlines()) - 1, 0) for path in folder.glob("shard-*.jsonl")
    )


def test_a_run_without_the_cluster_resumes_on_it(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_c=CAMPAIGN)
    first = pytester.runpytest_subprocess("--mt-campaign", "-k", "shard0 or shard1")
    first.stdout.fnmatch_lines(["*PARTIAL: 20 of 40 sources*"])
    resumed = pytester.runpytest_subprocess("--mt-campaign", "--mt-resume", "--mt-dask", "local:1")
    resumed.stdout.fnmatch_lines(["*(complete)*", "*20 sources read back from the logs"])
    execution = report(pytester)["execution"]
    assert execution[0]["sources"] == 20 and execution[0]["resumed"] == 20


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--mt-dask", "local:2"], "*--mt-dask runs campaigns: give --mt-campaign too*"),
        (["--mt-campaign", "--mt-dask", "local:0"], "*--mt-dask: *local:N* must be*>= 1*"),
        (["--mt-campaign", "--mt-dask", "nohost"], "*--mt-dask: *neither 'local:N' nor*"),
        (
            ["--mt-campaign", "--mt-dask", "local:1", "--mt-dask-batch", "0"],
            "*--mt-dask-batch=0 must be >= 1*",
        ),
        (["--mt-campaign", "--mt-dask-batch", "4"], "*--mt-dask-batch only makes sense with*"),
    ],
)
def test_bad_dask_options_are_usage_errors(
    pytester: pytest.Pytester, arguments: list[str], message: str
) -> None:
    pytester.makepyfile(test_x="def test_x():\n    pass\n")
    result = pytester.runpytest(*arguments)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([message])


def test_an_unreachable_scheduler_is_a_clear_error(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT", "2s")
    pytester.makepyfile(test_c=CAMPAIGN)
    pytester.makeini("[pytest]\nmt_dask = tcp://127.0.0.1:9\n")
    result = pytester.runpytest_subprocess("--mt-campaign", "-k", "shard0")
    # Before collection: the session starts by connecting.
    result.stderr.fnmatch_lines(["*could not reach the Dask scheduler at tcp://127.0.0.1:9*"])
    assert result.ret == pytest.ExitCode.USAGE_ERROR


def _scheduler_address(path: Path, *, deadline: float) -> str:
    """The address in a scheduler file once it is complete: the scheduler writes the file
    in place, so read too early it is missing, empty or cut short (seen on a loaded
    machine: "Expecting value: line 1 column 1")."""
    while True:
        try:
            return str(json.loads(path.read_text())["address"])
        except (FileNotFoundError, json.JSONDecodeError, KeyError):
            assert time.monotonic() < deadline, "dask scheduler did not start"
            time.sleep(0.1)


def test_a_campaign_runs_on_a_cluster_started_with_the_dask_command_line(
    pytester: pytest.Pytester, tmp_path_factory: pytest.TempPathFactory
) -> None:
    # What the documented multi-machine recipe does, on one machine: `python -m dask scheduler`
    # and `python -m dask worker ADDRESS` (from the folder of the tests) as separate processes.
    folder = tmp_path_factory.mktemp("scheduler")
    scheduler_file = folder / "scheduler.json"
    started = []
    # The documented advice for remote workers (without it they warn, and -W error fails).
    (folder / "dask.yaml").write_text(
        "distributed:\n  nanny:\n    pre-spawn-environ:\n      MALLOC_TRIM_THRESHOLD_: null\n"
    )
    env = {**os.environ, "DASK_CONFIG": str(folder)}
    try:
        started.append(
            subprocess.Popen(
                [sys.executable, "-m", "dask", "scheduler", "--port", "0",
                 "--dashboard-address", ":0", "--scheduler-file", str(scheduler_file)],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
            )
        )  # fmt: skip
        address = _scheduler_address(scheduler_file, deadline=time.monotonic() + 60)
        started.append(
            subprocess.Popen(
                [sys.executable, "-m", "dask", "worker", address, "--nworkers", "2",
                 "--nthreads", "1", "--dashboard-address", ":0"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
                cwd=pytester.path,  # the workers import the test module from here
            )
        )  # fmt: skip
        pytester.makepyfile(test_c=CAMPAIGN)
        alone = pytester.runpytest_subprocess("--mt-campaign", "--mt-campaign-dir", "one")
        alone.assert_outcomes(passed=4)
        # -p no:dash: Dash (Open3D, of the components extra, brings it) registers a pytest
        # plugin that pytest 9 warns about, an error under -W error.
        result = pytester.runpytest_subprocess(
            "--mt-campaign", "--mt-campaign-dir", "two", "--mt-dask", address, "-W", "error",
            "-p", "no:dash",
        )  # fmt: skip
        result.assert_outcomes(passed=1, deselected=3)
        on_cluster = report(pytester, "two")
        assert outcome(on_cluster) == outcome(report(pytester, "one"))
        (run,) = on_cluster["execution"]
        assert run["scheduler"] == address and run["workers"] == 2
    finally:
        for process in reversed(started):
            process.terminate()
            process.wait(timeout=30)
