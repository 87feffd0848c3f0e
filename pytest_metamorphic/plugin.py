"""The pytest plugin (entry point ``pytest_metamorphic_mt``).

Thin on purpose: options, markers, a recorder around each metamorphic test call, and the
session summary. Imports of numpy/scipy/Hypothesis internals happen only when a
metamorphic test actually runs.
"""

from __future__ import annotations

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


@dataclass(frozen=True)
class Options:
    followups: int
    check_determinism: bool
    report: Path | None


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
    parser.addini("mt_followups", "follow-ups per source and relation", default=None)
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
    return Options(followups, bool(check), report)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "metamorphic: a test built with @metamorphic (added automatically)"
    )
    config.stash[_OPTIONS] = _options(config)
    config.stash[_SUMMARY] = SessionSummary()
    config.pluginmanager.register(_SessionReporter(config), "pytest-metamorphic-reporter")


def _is_metamorphic(item: pytest.Item) -> bool:
    return hasattr(getattr(item, "obj", None), "_metamorphic")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if _is_metamorphic(item):
            item.add_marker("metamorphic")


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, Any, Any]:
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
    return (yield)


class _SessionReporter:
    """Collects counts from test reports and prints/writes the summary.

    Registered as an object so its hooks can reach the config (``pytest_runtest_logreport``
    gets only the report). Under xdist the controller receives every worker's reports here.
    """

    def __init__(self, config: pytest.Config) -> None:
        self.config = config

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when == "call":
            self.config.stash[_SUMMARY].add_report(
                report.nodeid, report.outcome, report.user_properties
            )

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        summary = self.config.stash[_SUMMARY]
        if summary.tests and not hasattr(self.config, "workerinput"):
            terminalreporter.write_sep("=", "metamorphic relations")
            for line in summary.format_table():
                terminalreporter.write_line(line)

    def pytest_sessionfinish(self) -> None:
        report = self.config.stash[_OPTIONS].report
        if report is not None and not hasattr(self.config, "workerinput"):
            self.config.stash[_SUMMARY].write_json(report)
