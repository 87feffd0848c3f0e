"""The pytest plugin (entry point ``pytest_metamorphic_mt``).

Thin on purpose: options, markers, a recorder around each metamorphic test call, and the
session summary. Imports of numpy/scipy/Hypothesis internals happen only when a
metamorphic test actually runs.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Generator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from pytest_metamorphic.core.stats import DEFAULT_FOLLOWUPS, Recorder, recording
from pytest_metamorphic.reports.summary import SessionSummary, junit_properties

_OPTIONS = pytest.StashKey["Options"]()
_SUMMARY = pytest.StashKey[SessionSummary]()
_RECORDER = pytest.StashKey[Recorder]()


_CAMPAIGN_RESULT = pytest.StashKey[Any]()
_CAMPAIGNS = pytest.StashKey[dict]()
CAMPAIGN_PROPERTY = "metamorphic_campaign"


@dataclass(frozen=True)
class Options:
    followups: int
    check_determinism: bool
    report: Path | None
    campaign: bool = False
    campaign_dir: Path = Path("mt-campaigns")
    resume: bool = False


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
    return Options(followups, bool(check), report, campaign, campaign_dir, resume)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "metamorphic: a test built with @metamorphic (added automatically)"
    )
    config.stash[_OPTIONS] = _options(config)
    config.stash[_SUMMARY] = SessionSummary()
    config.stash[_CAMPAIGNS] = {}
    config.pluginmanager.register(_SessionReporter(config), "pytest-metamorphic-reporter")


def _is_metamorphic(item: pytest.Item) -> bool:
    return hasattr(getattr(item, "obj", None), "_metamorphic")


def _campaign_of(item: pytest.Item) -> Any:
    return getattr(getattr(item, "obj", None), "_metamorphic_campaign", None)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    enabled = config.stash[_OPTIONS].campaign
    for item in items:
        if _is_metamorphic(item):
            item.add_marker("metamorphic")
        if _campaign_of(item) is not None:
            item.add_marker("metamorphic")
            if not enabled:
                item.add_marker(pytest.mark.skip(reason="campaign: run with --mt-campaign"))


def _run_campaign_shard(item: pytest.Item) -> None:
    from pytest_metamorphic.core.campaign import run_campaign

    campaign, shards = _campaign_of(item)
    shard = item.callspec.params["mt_shard"]
    options = item.config.stash[_OPTIONS]
    log = options.campaign_dir / _slug(campaign.name) / f"shard-{shard}-of-{shards}.jsonl"
    reporter = item.config.pluginmanager.get_plugin("terminalreporter")
    show = reporter is not None and not hasattr(item.config, "workerinput")

    def progress(done: int, total: int) -> None:
        if show:
            reporter.write(f"\r  {campaign.name} shard {shard}/{shards}: {done}/{total} sources ")

    item.stash[_CAMPAIGN_RESULT] = run_campaign(
        campaign, log=log, resume=options.resume, shard=shard, shards=shards, progress=progress
    )


def _slug(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name) or "campaign"


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, Any, Any]:
    if _campaign_of(item) is not None:
        _run_campaign_shard(item)
        return (yield)
    if not _is_metamorphic(item):
        return (yield)
    options = item.config.stash[_OPTIONS]
    recorder = Recorder(followups=options.followups, check_determinism=options.check_determinism)
    item.stash[_RECORDER] = recorder
    with recording(recorder):
        return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    if call.when == "call":
        recorder = item.stash.get(_RECORDER, None)
        if recorder is not None:
            # user_properties travel with the report: to JUnit XML and across xdist.
            item.user_properties.extend(junit_properties(recorder))
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
        blob = next((v for k, v in report.user_properties if k == CAMPAIGN_PROPERTY), None)
        if blob is not None:
            from pytest_metamorphic.core.campaign import result_from_json

            shard = result_from_json(json.loads(blob))
            campaigns = self.config.stash[_CAMPAIGNS]
            name = shard.header["campaign"]
            if name in campaigns:
                campaigns[name].merge(shard)
            else:
                campaigns[name] = shard

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if hasattr(self.config, "workerinput"):
            return
        summary = self.config.stash[_SUMMARY]
        if summary.tests:
            terminalreporter.write_sep("=", "metamorphic relations")
            for line in summary.format_table():
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
