"""Campaign tests in the plugin: shards (pytest-xdist) or one test per campaign (Dask),
their logs, the merged result across shards and workers, and the reports."""

from __future__ import annotations

import contextlib
import threading
from pathlib import Path
from typing import Any

import pytest

from pytest_metamorphic.plugin.options import OPTIONS

__all__ = [
    "CAMPAIGNS",
    "CAMPAIGN_PROPERTY",
    "CAMPAIGN_RESULT",
    "campaign_of",
    "claim_campaign_name",
    "merge_campaign",
    "one_item_per_campaign",
    "run_campaign_shard",
    "slug",
    "start_cluster_early",
    "write_campaign_reports",
]

CAMPAIGN_RESULT = pytest.StashKey[Any]()
CAMPAIGNS = pytest.StashKey[dict[str, Any]]()  # campaign name: its merged result
DASK_CLIENT = pytest.StashKey[Any]()
STARTING_CLUSTER = pytest.StashKey[Any]()
CAMPAIGN_PROPERTY = "metamorphic_campaign"


def campaign_of(item: pytest.Item) -> Any:
    return getattr(getattr(item, "obj", None), "_metamorphic_campaign", None)


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
    name = campaign_of(item)[0].name
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


def run_campaign_shard(item: pytest.Item) -> None:
    from pytest_metamorphic.core.campaign import ShardLogs, run_campaign

    campaign, shards = campaign_of(item)
    shard = _shard(item)
    options = item.config.stash[OPTIONS]
    logs = ShardLogs(options.campaign_dir / slug(campaign.name), shards)
    # On a cluster this test runs every source, each logged in its own shard's file:
    # the same logs as without it, so either can resume the other's run.
    run = {"shard": shard, "shards": shards}
    if options.dask:
        run = {"cluster": _dask_client(item.config), "batch_size": options.dask_batch}
    bar = _progress_bar(item, campaign.name, where=options.dask or f"{shard + 1}/{shards}")
    try:
        result = run_campaign(
            campaign,
            log=logs,
            resume=options.resume,
            progress=bar.update if bar else None,
            timeout=options.timeout,
            **run,
        )
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
    worker = getattr(item.config, "workerinput", {}).get("workerid", "main")
    result.execution[-1]["pytest_worker"] = worker
    item.stash[CAMPAIGN_RESULT] = result


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


def merge_campaign(config: pytest.Config, shard: Any) -> None:
    """Add one shard's result to the session's merged result of its campaign."""
    campaigns = config.stash[CAMPAIGNS]
    name = shard.header["campaign"]
    if name in campaigns:
        campaigns[name].merge(shard)
    else:
        campaigns[name] = shard


def slug(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name) or "campaign"


def write_campaign_reports(result: Any, folder: Path) -> None:
    from pytest_metamorphic.reports import campaign as reports

    reports.write_json(result, folder / "report.json")
    reports.write_markdown(result, folder / "report.md")
    # matplotlib is an optional extra: without it the other reports still stand.
    with contextlib.suppress(ImportError):
        reports.write_chart(result, folder / "categories.png")
