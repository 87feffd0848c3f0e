"""Campaign tests in the plugin: shards (pytest-xdist) or one test per campaign (Dask),
their logs, the merged result across shards and workers, its gate, and the reports.

The gate needs every shard's result, and under pytest-xdist only the controller sees them
all: it merges each shard's result as its report arrives, and when the last shard of a
campaign reports, judges the merged result and, if the gate fails, turns that report into
the campaign's failure (so it counts as a failed test in the terminal, the exit status
and JUnit XML, with the gate's reasons as its message).
"""

from __future__ import annotations

import contextlib
import json
import threading
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from pytest_metamorphic.plugin.options import OPTIONS

__all__ = [
    "CAMPAIGNS",
    "CAMPAIGN_PROPERTY",
    "CAMPAIGN_RESULT",
    "GATES",
    "campaign_of",
    "campaign_property",
    "claim_campaign_name",
    "gate_on_report",
    "merge_campaign",
    "one_item_per_campaign",
    "parametrize_shards",
    "run_campaign_shard",
    "slug",
    "start_cluster_early",
    "write_campaign_reports",
]

CAMPAIGN_RESULT = pytest.StashKey[Any]()
CAMPAIGN_CASES = pytest.StashKey[list[Any]]()  # item: the cases its shard saved
CAMPAIGNS = pytest.StashKey[dict[str, Any]]()  # campaign name: its merged result
GATES = pytest.StashKey[dict[str, "GateState"]]()  # campaign name: its gate's progress
DASK_CLIENT = pytest.StashKey[Any]()
STARTING_CLUSTER = pytest.StashKey[Any]()
CAMPAIGN_PROPERTY = "metamorphic_campaign"


def campaign_of(item: pytest.Item) -> Any:
    """The item's :class:`~pytest_metamorphic.core.campaign.CampaignTest`, or None."""
    return getattr(getattr(item, "obj", None), "_metamorphic_campaign", None)


def _workers(config: pytest.Config) -> int:
    """Processes that run tests: xdist's workers (a Dask run is one test per campaign)."""
    if config.stash[OPTIONS].dask:
        return 1
    return int(getattr(config, "workerinput", {}).get("workercount", 1))


def parametrize_shards(metafunc: pytest.Metafunc) -> None:
    """A campaign test's shards: one per worker, at most one per source. Every xdist
    worker computes the same list (same worker count), as xdist requires."""
    spec = getattr(metafunc.function, "_metamorphic_campaign", None)
    if spec is None or "mt_shard" not in metafunc.fixturenames:
        return
    shards = spec.shard_count(_workers(metafunc.config))
    metafunc.parametrize("mt_shard", range(shards), ids=[f"shard{i}" for i in range(shards)])


def one_item_per_campaign(config: pytest.Config, items: list[pytest.Item]) -> None:
    """On a Dask cluster, shard 0's test runs the whole campaign: the cluster spreads the
    sources, and the other shards' tests would have nothing left to do."""
    dropped = [item for item in items if campaign_of(item) is not None and _shard(item) != 0]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        gone = set(dropped)
        items[:] = [item for item in items if item not in gone]


def claim_campaign_name(owners: dict[str, str], item: pytest.Item) -> None:
    """Campaign names key logs and reports: two campaigns must not share one."""
    name = campaign_of(item).campaign.name
    test = item.nodeid.split("[")[0]
    owner = owners.setdefault(slug(name), test)
    if owner != test:
        raise pytest.UsageError(
            f"campaign name {name!r} is used by both {owner} and {test}; their logs and "
            "reports would mix. Give each campaign its own name."
        )


def _shard(item: pytest.Item) -> int:
    """The shard a campaign test's item runs (its ``mt_shard`` parameter)."""
    callspec = getattr(item, "callspec", None)  # parametrized items (pytest.Function) only
    return int(callspec.params.get("mt_shard", 0)) if callspec is not None else 0


_FOLDER_OPTION = " (--mt-campaign-dir names the folder campaigns write to)"


def run_campaign_shard(item: pytest.Item) -> None:
    __tracebackhide__ = True
    from pytest_metamorphic.core.campaign import ShardLogs, run_campaign
    from pytest_metamorphic.core.errors import CampaignLogError, DataError, WriteError

    spec = campaign_of(item)
    campaign, shards = spec.campaign, spec.shard_count(_workers(item.config))
    shard = _shard(item)
    options = item.config.stash[OPTIONS]
    logs = ShardLogs(options.campaign_dir / slug(campaign.name), shards)
    # On a cluster this test runs every source, each logged in its own shard's file:
    # the same logs as without it, so either can resume the other's run.
    run = {"shard": shard, "shards": shards}
    if options.dask:
        run = {"cluster": _dask_client(item.config), "batch_size": options.dask_batch}
    bar = _progress_bar(item, campaign.name, where=options.dask or f"{shard + 1}/{shards}")
    failure = None
    try:
        result = run_campaign(
            campaign,
            log=logs,
            resume=options.resume,
            keep_examples=max(20, _cases_wanted(item, spec)),
            progress=bar.update if bar else None,
            timeout=options.timeout,
            unverified="rerun" if options.rerun_unverified else "error",
            **run,
        )
    except (WriteError, DataError) as error:
        # A log that cannot be written (a full disk, a read-only mount) or read back (a
        # record that does not verify): the message says what to do; the plugin's frames
        # would only hide it.
        if not hasattr(item.config, "workerinput"):
            with contextlib.suppress(Exception):
                merge_campaign(item.config, _read_back(campaign, logs, run))
        where = "" if isinstance(error, CampaignLogError | DataError) else _FOLDER_OPTION
        failure = f"campaign {campaign.name!r}: {error}{where}"
    except BaseException:
        # Interrupted (Ctrl-C, a crash in the plugin): pytest makes no report for this
        # test, so the sources this shard finished would be missing from the partial
        # report. They are in the logs; merge them here, where the report is printed.
        if not hasattr(item.config, "workerinput"):
            merge_campaign(item.config, _read_back(campaign, logs, run))
        raise
    finally:
        if bar:
            bar.close()
    if failure is not None:  # out of the handler: no chained OSError shown above it
        pytest.fail(failure, pytrace=False)
    worker = getattr(item.config, "workerinput", {}).get("workerid", "main")
    result.execution[-1]["pytest_worker"] = worker
    item.stash[CAMPAIGN_RESULT] = result
    item.stash[CAMPAIGN_CASES] = _save_cases(item, spec, result)


def _cases_wanted(item: pytest.Item, spec: Any) -> int:
    options = item.config.stash[OPTIONS]
    if options.artifacts is None:
        return 0
    return options.campaign_cases if spec.cases is None else spec.cases


def _save_cases(item: pytest.Item, spec: Any, result: Any) -> list[Any]:
    """The first violations of each size of this shard, as artifact folders."""
    k = _cases_wanted(item, spec)
    artifacts = item.config.stash[OPTIONS].artifacts
    if not k or not result.examples or artifacts is None:
        return []
    from pytest_metamorphic.reports.campaign_cases import campaign_root, save_cases

    options = item.config.stash[OPTIONS]
    nodeid = item.nodeid.split("[")[0]
    return save_cases(
        spec.campaign,
        result,
        root=campaign_root(artifacts, nodeid, spec.campaign.name),
        nodeid=nodeid,
        k=k,
        budget=options.minimize_budget,
        seconds=options.minimize_seconds,
        timeout=options.timeout,
    )


def _read_back(campaign: Any, logs: Any, run: dict[str, Any]) -> Any:
    from pytest_metamorphic.core.campaign import read_campaign_log

    return read_campaign_log(campaign, logs, shard=run.get("shard", 0), shards=run.get("shards", 1))


def _progress_bar(item: pytest.Item, name: str, *, where: str) -> Any:
    if hasattr(item.config, "workerinput"):
        return None
    from pytest_metamorphic.reports.progress import ProgressBar

    return ProgressBar.for_terminal(
        item.config.pluginmanager.get_plugin("terminalreporter"),
        name,
        shard=where,
        capture=item.config.pluginmanager.get_plugin("capturemanager"),
    )


def start_cluster_early(config: pytest.Config) -> None:
    """Connect at configure time, so that the cluster is ready when the campaign test runs.

    A local cluster starts in a background thread while pytest collects (its worker
    processes start on the other cores), and its workers then import the package; a
    remote scheduler is reached at once, so an unreachable address is a usage error before
    anything is collected. Only in the process that runs the tests (not an xdist
    controller).
    """
    options = config.stash[OPTIONS]
    if not (options.campaign and options.dask) or config.getoption("numprocesses", None):
        return
    from pytest_metamorphic.core.campaign.cluster import LOCAL_PREFIX

    if options.dask.startswith(LOCAL_PREFIX):
        starting = _StartingCluster(options.dask)
        config.stash[STARTING_CLUSTER] = starting
        config.add_cleanup(starting.close)
        return
    _warm_up(_dask_client(config))


def _warm_up(client: Any) -> None:
    from pytest_metamorphic.core.campaign import _worker

    client.run(_worker.warm_up, wait=False)


class _StartingCluster:
    """A local cluster started in a thread of its own, which also closes it (the client's
    context belongs to that thread); :meth:`wait` returns the client."""

    def __init__(self, address: str) -> None:
        self.client: Any = None
        self.error: BaseException | None = None
        self.ready = threading.Event()
        self.closing = threading.Event()
        self.thread = threading.Thread(
            target=self._run, args=(address,), name="pytest-metamorphic dask", daemon=True
        )
        self.thread.start()

    def _run(self, address: str) -> None:
        from pytest_metamorphic.core.campaign.cluster import connect

        try:
            with connect(address) as client:
                self.client = client
                _warm_up(client)
                self.ready.set()
                self.closing.wait()
        except BaseException as error:  # re-raised in the thread that asks for the client
            self.error = error
        finally:
            self.ready.set()

    def wait(self) -> Any:
        self.ready.wait()
        if self.client is None:
            assert self.error is not None
            raise self.error
        return self.client

    def close(self) -> None:
        self.closing.set()
        self.thread.join()


def _dask_client(config: pytest.Config) -> Any:
    """One connection (and for local:N one local cluster) for the whole session."""
    client = config.stash.get(DASK_CLIENT, None)
    if client is not None:
        return client
    from pytest_metamorphic.core.campaign.cluster import ClusterError, connect

    starting = config.stash.get(STARTING_CLUSTER, None)
    try:
        if starting is not None:
            client = starting.wait()
        else:
            stack = contextlib.ExitStack()
            config.add_cleanup(stack.close)
            client = stack.enter_context(connect(config.stash[OPTIONS].dask))
    except ClusterError as error:
        raise pytest.UsageError(f"--mt-dask: {error}") from None
    config.stash[DASK_CLIENT] = client
    return client


def slug(name: str) -> str:
    """A campaign's folder name (imported here, not with the plugin: it pulls in numpy)."""
    from pytest_metamorphic.core.campaign.baseline import slug as campaign_slug

    return campaign_slug(name)


@dataclass
class GateState:
    """A campaign's gate while its shards report: judged when the last one has."""

    gate: Any  # Gate
    expected: int  # shard tests that will report a result
    nodeid: str  # the campaign test, without its shard
    cases_wanted: int = 0  # violations per size saved as artifacts
    seen: int = 0
    verdict: Any = None  # GateVerdict, once judged
    cases: list[Any] = field(default_factory=list)  # SavedCase, the kept ones once judged


def campaign_property(item: pytest.Item) -> tuple[str, str] | None:
    """What a shard test's report carries to the process that merges (JSON): its result,
    the gate, and how many shard tests of its campaign report."""
    result = item.stash.get(CAMPAIGN_RESULT, None)
    if result is None:
        return None
    spec = campaign_of(item)
    reports = 1 if item.config.stash[OPTIONS].dask else spec.shard_count(_workers(item.config))
    blob = {
        "result": result.to_json(),
        "gate": spec.gate.to_json(),
        "reports": reports,
        "nodeid": item.nodeid.split("[")[0],
        "cases_wanted": _cases_wanted(item, spec),
        "cases": [case.to_json() for case in item.stash.get(CAMPAIGN_CASES, [])],
    }
    return CAMPAIGN_PROPERTY, json.dumps(blob)


def gate_on_report(config: pytest.Config, report: pytest.TestReport, blob: str) -> None:
    """Merge one shard's result; on the campaign's last shard, judge the gate and let a
    failed gate fail this report."""
    from pytest_metamorphic.core.campaign import Gate, result_from_json

    data = json.loads(blob)
    result = result_from_json(data["result"])
    merge_campaign(config, result)
    name = result.header["campaign"]
    state = config.stash[GATES].setdefault(
        name,
        GateState(
            Gate.from_json(data["gate"]),
            int(data["reports"]),
            data["nodeid"],
            int(data.get("cases_wanted", 0)),
        ),
    )
    state.seen += 1
    if data.get("cases"):
        from pytest_metamorphic.reports.campaign_cases import SavedCase

        state.cases.extend(SavedCase.from_json(case) for case in data["cases"])
    if state.seen < state.expected:
        return
    merged = config.stash[CAMPAIGNS][name]
    state.verdict = judge_gate(config, merged, state.gate)
    state.cases = _keep_first_cases(config, state, merged)
    if not state.verdict.passed and report.passed:
        report.outcome = "failed"
        report.longrepr = state.verdict.failure_message()


def _keep_first_cases(config: pytest.Config, state: GateState, merged: Any) -> list[Any]:
    """The first cases of each size over all shards; the other shards' later ones go."""
    artifacts = config.stash[OPTIONS].artifacts
    if artifacts is None or not state.cases_wanted:
        return []
    from pytest_metamorphic.reports.campaign_cases import campaign_root, keep_first

    root = campaign_root(artifacts, state.nodeid, merged.header["campaign"])
    return keep_first(merged, state.cases, state.cases_wanted, root)


def judge_gate(config: pytest.Config, result: Any, gate: Any) -> Any:
    """The gate's verdict, against the ``--mt-baseline`` report of the campaign if any."""
    from pytest_metamorphic.core.campaign import find_baseline, judge_campaign
    from pytest_metamorphic.core.campaign.gate import GateCheck, GateVerdict
    from pytest_metamorphic.core.errors import DataError

    where = config.stash[OPTIONS].baseline
    name = result.header["campaign"]
    if where is None:
        return judge_campaign(result, gate)
    if not where.exists():
        return judge_campaign(result, gate, baseline_note=f"no baseline at {where}")
    try:
        baseline, path, note = find_baseline(where, name)
    except DataError as error:
        verdict = judge_campaign(result, gate)
        unreadable = GateCheck("baseline", False, (f"baseline unreadable: {error}",))
        return GateVerdict(verdict.campaign, gate, (*verdict.checks, unreadable))
    return judge_campaign(result, gate, baseline=baseline, baseline_where=path, baseline_note=note)


def merge_campaign(config: pytest.Config, shard: Any) -> None:
    """Add one shard's result to the session's merged result of its campaign."""
    campaigns = config.stash[CAMPAIGNS]
    name = shard.header["campaign"]
    if name in campaigns:
        campaigns[name].merge(shard)
    else:
        campaigns[name] = shard


def write_campaign_reports(
    result: Any, folder: Path, verdict: Any = None, cases: list[Any] | None = None
) -> None:
    from pytest_metamorphic.reports import campaign as reports

    reports.write_json(result, folder / "report.json", verdict=verdict, cases=cases)
    try:
        reports.write_chart(result, folder / reports.CHART_NAME)
    except ImportError:
        pass  # matplotlib is an optional extra: without it the other reports still stand
    except Exception as error:  # a picture must never cost the reports
        warnings.warn(f"campaign chart not drawn: {type(error).__name__}: {error}", stacklevel=1)
    reports.write_markdown(result, folder / "report.md", verdict=verdict, cases=cases)
