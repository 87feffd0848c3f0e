"""The pytest plugin (entry point ``pytest_metamorphic_mt``).

Thin on purpose: options, markers, a recorder around each metamorphic test call (which
saves violation artifacts through :mod:`pytest_metamorphic.reports.artifacts`), replay of
saved artifacts (``--mt-replay``), and the session summary. Imports of numpy/scipy/Hypothesis
internals happen only when a metamorphic test actually runs.
"""

from __future__ import annotations

import contextlib
import inspect
import json
from collections.abc import Generator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from pytest_metamorphic.core.stats import (
    DEFAULT_FOLLOWUPS,
    DEFAULT_MINIMIZE_BUDGET,
    Recorder,
    recording,
)
from pytest_metamorphic.reports.summary import SessionSummary, junit_properties

_OPTIONS = pytest.StashKey["Options"]()
_SUMMARY = pytest.StashKey[SessionSummary]()
_RECORDER = pytest.StashKey[Recorder]()


_CAMPAIGN_RESULT = pytest.StashKey[Any]()
_CAMPAIGNS = pytest.StashKey[dict]()
_WRITER = pytest.StashKey[Any]()
_REPLAYS = pytest.StashKey[list]()
_REPLAY_RESULTS = pytest.StashKey[list]()
_ARTIFACT_LIST = pytest.StashKey[list]()
_DASK_CLIENT = pytest.StashKey[Any]()
CAMPAIGN_PROPERTY = "metamorphic_campaign"
ARTIFACT_PROPERTY = "metamorphic_artifact"
REPLAY_PROPERTY = "metamorphic_replay"
DEFAULT_ARTIFACTS = Path("mt-artifacts")


@dataclass(frozen=True)
class Options:
    followups: int
    check_determinism: bool
    report: Path | None
    campaign: bool = False
    campaign_dir: Path = Path("mt-campaigns")
    resume: bool = False
    artifacts: Path | None = DEFAULT_ARTIFACTS
    minimize_budget: int = DEFAULT_MINIMIZE_BUDGET
    replay: tuple[Path, ...] = ()
    timeout: float | None = None
    dask: str | None = None
    dask_batch: int | None = None


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("metamorphic", "metamorphic testing (pytest-metamorphic)")
    group.addoption(
        "--mt-followups",
        type=int,
        default=None,
        metavar="N",
        help=f"follow-ups per source and relation, for tests that do not set followups= "
        f"(ini: mt_followups; default {DEFAULT_FOLLOWUPS})",
    )
    group.addoption(
        "--mt-report",
        default=None,
        metavar="PATH",
        help="write a JSON report of per-relation counts to PATH (ini: mt_report)",
    )
    group.addoption(
        "--mt-no-determinism-check",
        action="store_true",
        default=None,
        help="do not re-run the system on the source before reporting a violation "
        "(ini: mt_check_determinism = false)",
    )
    group.addoption(
        "--mt-campaign",
        action="store_true",
        default=False,
        help="run campaign tests (violation rates by independent sampling); skipped otherwise",
    )
    group.addoption(
        "--mt-campaign-dir",
        default=None,
        metavar="DIR",
        help="where campaigns write logs and reports (ini: mt_campaign_dir; default mt-campaigns)",
    )
    group.addoption(
        "--mt-resume",
        action="store_true",
        default=False,
        help="continue interrupted campaigns from their logs instead of starting afresh",
    )
    group.addoption(
        "--mt-artifacts",
        default=None,
        metavar="DIR",
        help="save each violation (clouds, minimal perturbation, JSON record, bird's-eye "
        f"PNG) under DIR (ini: mt_artifacts; default {DEFAULT_ARTIFACTS})",
    )
    group.addoption(
        "--mt-no-artifacts",
        action="store_true",
        default=False,
        help="do not save violation artifacts",
    )
    group.addoption(
        "--mt-minimize-budget",
        type=int,
        default=None,
        metavar="N",
        help="SUT calls allowed for reducing a violating follow-up to a proven 1-minimal one "
        f"(ini: mt_minimize_budget; default {DEFAULT_MINIMIZE_BUDGET}; 0: do not reduce)",
    )
    group.addoption(
        "--mt-replay",
        action="append",
        default=[],
        metavar="ARTIFACT",
        help="re-run a saved violation (an artifact folder) against the current system: "
        "runs only its test, fails while the violation persists; repeatable",
    )
    group.addoption(
        "--mt-timeout",
        default=None,
        metavar="SECONDS",
        help="time limit of one call of the system under test, in metamorphic tests and "
        "campaigns; a call past it is a crash, not a violation (ini: mt_timeout; default none)",
    )
    group.addoption(
        "--mt-dask",
        default=None,
        metavar="ADDRESS",
        help="run campaigns on a Dask cluster: a scheduler address (tcp://host:8786) or "
        "local:N for N local worker processes (ini: mt_dask; needs the dask extra)",
    )
    group.addoption(
        "--mt-dask-batch",
        default=None,
        metavar="N",
        help="sources per Dask task (ini: mt_dask_batch; default guided: up to 8, fewer "
        "towards the end)",
    )
    parser.addini("mt_dask", "Dask scheduler address or local:N for campaigns", default=None)
    parser.addini("mt_dask_batch", "sources per Dask task", default=None)
    parser.addini("mt_timeout", "seconds one call of the system under test may take", default=None)
    parser.addini("mt_artifacts", "where violation artifacts are saved", default=None)
    parser.addini("mt_minimize_budget", "SUT calls allowed per reduction", default=None)
    parser.addini("mt_followups", "follow-ups per source and relation", default=None)
    parser.addini("mt_campaign_dir", "where campaigns write logs and reports", default=None)
    parser.addini("mt_report", "path of the JSON report", default=None)
    parser.addini(
        "mt_check_determinism",
        "re-run the source before reporting a violation",
        type="bool",
        default=True,
    )


def _options(config: pytest.Config) -> Options:
    raw = config.getoption("mt_followups")
    source = "--mt-followups"
    if raw is None:
        raw, source = config.getini("mt_followups"), "ini mt_followups"
    if raw in (None, ""):
        followups = DEFAULT_FOLLOWUPS
    else:
        try:
            followups = int(raw)
        except (TypeError, ValueError):
            raise pytest.UsageError(f"{source}={raw!r} must be an integer") from None
        if not 1 <= followups <= 100:
            raise pytest.UsageError(f"{source}={followups} must be between 1 and 100")
    report = config.getoption("mt_report") or config.getini("mt_report") or None
    if report is not None:
        report = Path(report)
        if report.is_dir():
            raise pytest.UsageError(f"--mt-report={report} is a directory; give a file path")
    check = not config.getoption("mt_no_determinism_check") and config.getini(
        "mt_check_determinism"
    )
    campaign_dir = Path(
        config.getoption("mt_campaign_dir") or config.getini("mt_campaign_dir") or "mt-campaigns"
    )
    if campaign_dir.exists() and not campaign_dir.is_dir():
        raise pytest.UsageError(f"--mt-campaign-dir={campaign_dir} exists and is not a directory")
    resume = bool(config.getoption("mt_resume"))
    campaign = bool(config.getoption("mt_campaign"))
    if resume and not campaign:
        raise pytest.UsageError("--mt-resume only makes sense with --mt-campaign")
    dask, dask_batch = _dask_options(config, campaign)
    return Options(
        followups,
        bool(check),
        report,
        campaign,
        campaign_dir,
        resume,
        artifacts=_artifacts_option(config),
        minimize_budget=_budget_option(config),
        replay=tuple(_replay_option(config)),
        timeout=_timeout_option(config),
        dask=dask,
        dask_batch=dask_batch,
    )


def _dask_options(config: pytest.Config, campaign: bool) -> tuple[str | None, int | None]:
    address, source = config.getoption("mt_dask"), "--mt-dask"
    if address is None:
        address, source = config.getini("mt_dask") or None, "ini mt_dask"
    raw, batch_source = config.getoption("mt_dask_batch"), "--mt-dask-batch"
    if raw is None:
        raw, batch_source = config.getini("mt_dask_batch") or None, "ini mt_dask_batch"
    if address is None:
        if raw is not None and batch_source.startswith("--"):
            raise pytest.UsageError("--mt-dask-batch only makes sense with --mt-dask")
        return None, None
    if source.startswith("--") and not campaign:
        raise pytest.UsageError("--mt-dask runs campaigns: give --mt-campaign too")
    from pytest_metamorphic.core.campaign.cluster import check_address
    from pytest_metamorphic.core.errors import InvalidArgument

    try:
        address = check_address(address)
    except InvalidArgument as error:
        raise pytest.UsageError(f"{source}: {error}") from None
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise pytest.UsageError(
            f"{source}={address} needs Dask distributed: pip install 'pytest-metamorphic[dask]'"
        ) from None
    batch = None
    if raw is not None:
        try:
            batch = int(raw)
        except (TypeError, ValueError):
            raise pytest.UsageError(f"{batch_source}={raw!r} must be an integer") from None
        if batch < 1:
            raise pytest.UsageError(f"{batch_source}={batch} must be >= 1")
    return address, batch


def _timeout_option(config: pytest.Config) -> float | None:
    raw = config.getoption("mt_timeout")
    source = "--mt-timeout"
    if raw is None:
        raw, source = config.getini("mt_timeout"), "ini mt_timeout"
    if raw in (None, ""):
        return None
    try:
        seconds = float(raw)
    except (TypeError, ValueError):
        raise pytest.UsageError(f"{source}={raw!r} must be a number of seconds") from None
    if not (seconds > 0 and seconds != float("inf")):
        raise pytest.UsageError(f"{source}={raw!r} must be a positive number of seconds")
    return seconds


def _artifacts_option(config: pytest.Config) -> Path | None:
    if config.getoption("mt_no_artifacts"):
        return None
    raw = config.getoption("mt_artifacts")
    source = "--mt-artifacts"
    if raw is None:
        raw, source = config.getini("mt_artifacts"), "ini mt_artifacts"
    folder = Path(raw) if raw else DEFAULT_ARTIFACTS
    if folder.exists() and not folder.is_dir():
        raise pytest.UsageError(f"{source}={folder} exists and is not a directory")
    return folder


def _budget_option(config: pytest.Config) -> int:
    raw = config.getoption("mt_minimize_budget")
    source = "--mt-minimize-budget"
    if raw is None:
        raw, source = config.getini("mt_minimize_budget"), "ini mt_minimize_budget"
    if raw in (None, ""):
        return DEFAULT_MINIMIZE_BUDGET
    try:
        budget = int(raw)
    except (TypeError, ValueError):
        raise pytest.UsageError(f"{source}={raw!r} must be an integer") from None
    if budget < 0:
        raise pytest.UsageError(f"{source}={budget} must be >= 0 (0 switches reduction off)")
    return budget


def _replay_option(config: pytest.Config) -> list[Path]:
    folders = []
    for raw in config.getoption("mt_replay") or ():
        path = Path(raw)
        folder = path.parent if path.name == "record.json" else path
        if not (folder / "record.json").is_file():
            raise pytest.UsageError(
                f"--mt-replay={raw}: not a violation artifact folder (no record.json in it)"
            )
        folders.append(folder)
    return folders


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "metamorphic: a test built with @metamorphic (added automatically)"
    )
    config.stash[_OPTIONS] = _options(config)
    config.stash[_SUMMARY] = SessionSummary()
    config.stash[_CAMPAIGNS] = {}
    config.stash[_REPLAY_RESULTS] = []
    config.stash[_ARTIFACT_LIST] = []
    config.stash[_REPLAYS] = _load_replays(config.stash[_OPTIONS].replay)
    config.pluginmanager.register(_SessionReporter(config), "pytest-metamorphic-reporter")


def _load_replays(folders: tuple[Path, ...]) -> list[Any]:
    if not folders:
        return []
    from pytest_metamorphic.core.errors import DataError
    from pytest_metamorphic.reports.artifacts import load_artifact

    artifacts = []
    for folder in folders:
        try:
            artifacts.append(load_artifact(folder))
        except DataError as error:
            raise pytest.UsageError(f"--mt-replay: {error}") from None
    return artifacts


def _is_metamorphic(item: pytest.Item) -> bool:
    return hasattr(getattr(item, "obj", None), "_metamorphic")


def _campaign_of(item: pytest.Item) -> Any:
    return getattr(getattr(item, "obj", None), "_metamorphic_campaign", None)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.stash[_REPLAYS]:
        _select_replayed(config, items)
    enabled = config.stash[_OPTIONS].campaign
    if enabled and config.stash[_OPTIONS].dask:
        _one_item_per_campaign(config, items)
    owners: dict[str, str] = {}  # campaign name -> the test defining it
    for item in items:
        if _is_metamorphic(item):
            item.add_marker("metamorphic")
        if _campaign_of(item) is not None:
            item.add_marker("metamorphic")
            _claim_campaign_name(owners, item)
            if not enabled:
                item.add_marker(pytest.mark.skip(reason="campaign: run with --mt-campaign"))


def _one_item_per_campaign(config: pytest.Config, items: list[pytest.Item]) -> None:
    """On a Dask cluster, shard 0's test runs the whole campaign: the cluster spreads the
    sources, and the other shards' tests would have nothing left to do."""
    dropped = [
        item
        for item in items
        if _campaign_of(item) is not None and item.callspec.params.get("mt_shard", 0) != 0
    ]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = [item for item in items if item not in set(dropped)]


def _claim_campaign_name(owners: dict[str, str], item: pytest.Item) -> None:
    """Campaign names key logs and reports: two campaigns must not share one."""
    name = _campaign_of(item)[0].name
    test = item.nodeid.split("[")[0]
    owner = owners.setdefault(_slug(name), test)
    if owner != test:
        raise pytest.UsageError(
            f"campaign name {name!r} is used by both {owner} and {test}; their logs and "
            "reports would mix. Give each campaign its own name."
        )


def _select_replayed(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Keep only the tests that saved the replayed artifacts."""
    wanted = {artifact.nodeid for artifact in config.stash[_REPLAYS]}
    collected = {item.nodeid for item in items}
    missing = sorted(wanted - collected)
    if missing:
        folders = [str(a.folder) for a in config.stash[_REPLAYS] if a.nodeid in missing]
        raise pytest.UsageError(
            f"--mt-replay: the test(s) {missing} that saved {folders} were not collected; "
            "run pytest from the same root directory, with the test file on the command line"
        )
    keep = [item for item in items if item.nodeid in wanted]
    dropped = [item for item in items if item.nodeid not in wanted]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
    items[:] = keep


def _replayed_here(item: pytest.Item) -> list[Any]:
    return [a for a in item.config.stash[_REPLAYS] if a.nodeid == item.nodeid]


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    __tracebackhide__ = True
    artifacts = _replayed_here(pyfuncitem)
    if not artifacts:
        return None
    spec = getattr(pyfuncitem.obj, "_metamorphic", None)
    if spec is None:
        raise pytest.UsageError(f"--mt-replay: {pyfuncitem.nodeid} is not a @metamorphic test")
    from pytest_metamorphic.core.errors import MetamorphicViolation
    from pytest_metamorphic.reports.replay import replay

    names = list(inspect.signature(spec.function).parameters)[1:]
    fixtures = {name: pyfuncitem.funcargs[name] for name in names}
    results = [replay(artifact, spec, fixtures) for artifact in artifacts]
    pyfuncitem.stash[_REPLAY_RESULTS] = results
    failing = [result for result in results if result.still_fails]
    if failing:
        lines = [line for result in failing for line in result.lines()]
        raise MetamorphicViolation(
            "replayed violation(s) still fail:\n" + "\n".join(lines),
            relation=failing[0].artifact.relation,
            verdict=failing[0].verdict,
        )
    return True


def _run_campaign_shard(item: pytest.Item) -> None:
    from pytest_metamorphic.core.campaign import ShardLogs, run_campaign

    campaign, shards = _campaign_of(item)
    shard = item.callspec.params["mt_shard"]
    options = item.config.stash[_OPTIONS]
    logs = ShardLogs(options.campaign_dir / _slug(campaign.name), shards)
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
            _merge_campaign(item.config, _read_back(campaign, logs, run))
        raise
    finally:
        if bar:
            bar.close()
    worker = getattr(item.config, "workerinput", {}).get("workerid", "main")
    result.execution[-1]["pytest_worker"] = worker
    item.stash[_CAMPAIGN_RESULT] = result


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


def _dask_client(config: pytest.Config) -> Any:
    """One connection (and for local:N one local cluster) for the whole session."""
    client = config.stash.get(_DASK_CLIENT, None)
    if client is None:
        from pytest_metamorphic.core.campaign.cluster import ClusterError, connect

        stack = contextlib.ExitStack()
        try:
            client = stack.enter_context(connect(config.stash[_OPTIONS].dask))
        except ClusterError as error:
            stack.close()
            raise pytest.UsageError(f"--mt-dask: {error}") from None
        config.stash[_DASK_CLIENT] = client
        config.add_cleanup(stack.close)
    return client


def _merge_campaign(config: pytest.Config, shard: Any) -> None:
    """Add one shard's result to the session's merged result of its campaign."""
    campaigns = config.stash[_CAMPAIGNS]
    name = shard.header["campaign"]
    if name in campaigns:
        campaigns[name].merge(shard)
    else:
        campaigns[name] = shard


def _slug(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name) or "campaign"


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, Any, Any]:
    __tracebackhide__ = True
    if _campaign_of(item) is not None:
        _run_campaign_shard(item)
        return (yield)
    if not _is_metamorphic(item) or _replayed_here(item):
        return (yield)
    options = item.config.stash[_OPTIONS]
    recorder = Recorder(
        followups=options.followups,
        check_determinism=options.check_determinism,
        minimize_budget=options.minimize_budget,
        timeout=options.timeout,
        nodeid=item.nodeid,
    )
    if options.artifacts is not None:
        recorder.on_violation = _ArtifactSink(options.artifacts, item, recorder)
    item.stash[_RECORDER] = recorder
    with recording(recorder):
        return (yield)


class _ArtifactSink:
    """Saves a test's violations; imports the writer only when the first one happens."""

    def __init__(self, root: Path, item: pytest.Item, recorder: Recorder) -> None:
        self.root, self.item, self.recorder = root, item, recorder

    def __call__(self, record: Any, final: bool) -> str | None:
        writer = self.item.stash.get(_WRITER, None)
        if writer is None:
            from pytest_metamorphic.reports.artifacts import ArtifactWriter

            writer = ArtifactWriter(self.root, self.item.nodeid, self.recorder)
            self.item.stash[_WRITER] = writer
        return writer(record, final)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    if call.when == "call":
        recorder = item.stash.get(_RECORDER, None)
        if recorder is not None:
            # user_properties travel with the report: to JUnit XML and across xdist.
            item.user_properties.extend(junit_properties(recorder))
        writer = item.stash.get(_WRITER, None)
        if writer is not None:
            for folder in dict.fromkeys(writer.written):
                item.user_properties.append((ARTIFACT_PROPERTY, str(folder)))
        for result in item.stash.get(_REPLAY_RESULTS, []):
            item.user_properties.append((REPLAY_PROPERTY, json.dumps(result.to_json())))
        result = item.stash.get(_CAMPAIGN_RESULT, None)
        if result is not None:
            item.user_properties.append((CAMPAIGN_PROPERTY, json.dumps(result.to_json())))
            for size, counts in sorted(result.sizes.items()):
                item.user_properties.append((f"mt.campaign.n{size}.pairs", counts.pairs))
                item.user_properties.append((f"mt.campaign.n{size}.violations", counts.violations))
    return (yield)


class _SessionReporter:
    """Collects counts from test reports and prints/writes the summary.

    Registered as an object so its hooks can reach the config (``pytest_runtest_logreport``
    gets only the report). Under xdist the controller receives every worker's reports here.
    """

    def __init__(self, config: pytest.Config) -> None:
        self.config = config

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when != "call":
            return
        self.config.stash[_SUMMARY].add_report(
            report.nodeid, report.outcome, report.user_properties
        )
        for key, value in report.user_properties:
            if key == ARTIFACT_PROPERTY:
                self.config.stash[_ARTIFACT_LIST].append((report.nodeid, value))
            elif key == REPLAY_PROPERTY:
                self.config.stash[_REPLAY_RESULTS].append(json.loads(value))
        blob = next((v for k, v in report.user_properties if k == CAMPAIGN_PROPERTY), None)
        if blob is not None:
            from pytest_metamorphic.core.campaign import result_from_json

            _merge_campaign(self.config, result_from_json(json.loads(blob)))

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if hasattr(self.config, "workerinput"):
            return
        summary = self.config.stash[_SUMMARY]
        if summary.tests:
            terminalreporter.write_sep("=", "metamorphic relations")
            for line in summary.format_table():
                terminalreporter.write_line(line)
        artifacts = self.config.stash[_ARTIFACT_LIST]
        if artifacts:
            terminalreporter.write_sep("=", "metamorphic violation artifacts")
            for nodeid, folder in artifacts:
                terminalreporter.write_line(f"{nodeid}: {folder}")
            terminalreporter.write_line("replay one: pytest --mt-replay <folder>")
        replays = self.config.stash[_REPLAY_RESULTS]
        if replays:
            terminalreporter.write_sep("=", "metamorphic replay")
            for result in replays:
                for line in result["lines"]:
                    terminalreporter.write_line(line)
        campaigns = self.config.stash[_CAMPAIGNS]
        if campaigns:
            from pytest_metamorphic.reports.campaign import format_table

            for name, result in campaigns.items():
                terminalreporter.write_sep("=", f"campaign {name}")
                for line in format_table(result):
                    terminalreporter.write_line(line)
                folder = self.config.stash[_OPTIONS].campaign_dir / _slug(name)
                terminalreporter.write_line(f"reports and logs: {folder}/")

    def pytest_sessionfinish(self) -> None:
        if hasattr(self.config, "workerinput"):
            return
        options = self.config.stash[_OPTIONS]
        if options.report is not None:
            self.config.stash[_SUMMARY].write_json(options.report)
        for name, result in self.config.stash[_CAMPAIGNS].items():
            _write_campaign_reports(result, options.campaign_dir / _slug(name))


def _write_campaign_reports(result: Any, folder: Path) -> None:
    from pytest_metamorphic.reports import campaign as reports

    reports.write_json(result, folder / "report.json")
    reports.write_markdown(result, folder / "report.md")
    # matplotlib is an optional extra: without it the other reports still stand.
    with contextlib.suppress(ImportError):
        reports.write_chart(result, folder / "categories.png")
