"""The pytest plugin (entry point ``pytest_metamorphic_mt``).

Thin on purpose: the hooks, a recorder around each metamorphic test call (which saves
violation artifacts through :mod:`pytest_metamorphic.reports.artifacts`), replay of saved
artifacts (``--mt-replay``), and the session summary; options live in :mod:`.options`,
campaign tests (xdist shards, Dask) in :mod:`.campaigns`. Imports of numpy/scipy/Hypothesis
internals happen only when a metamorphic test actually runs.
"""

from __future__ import annotations

import inspect
import json
import warnings
from collections.abc import Callable, Generator, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_metamorphic.core.errors import NothingTestedWarning, WriteError
from pytest_metamorphic.core.files import write_error
from pytest_metamorphic.core.stats import Recorder, nothing_tested, reasons_of, recording
from pytest_metamorphic.core.tracebacks import explain_the_users_code, start_at_the_users_test
from pytest_metamorphic.plugin.campaigns import (
    CAMPAIGN_PROPERTY,
    CAMPAIGN_RESULT,
    CAMPAIGNS,
    GATES,
    campaign_of,
    campaign_property,
    claim_campaign_name,
    gate_on_report,
    one_item_per_campaign,
    parametrize_shards,
    run_campaign_shard,
    slug,
    start_cluster_early,
    write_campaign_reports,
)
from pytest_metamorphic.plugin.options import OPTIONS, add_options, parse_options
from pytest_metamorphic.reports.summary import SessionSummary, junit_properties

if TYPE_CHECKING:  # imported when a replay or an artifact happens, not with the plugin
    from pytest_metamorphic.reports.artifacts import Artifact, ArtifactWriter
    from pytest_metamorphic.reports.replay import ReplayResult

_SUMMARY = pytest.StashKey[SessionSummary]()
_RECORDER = pytest.StashKey[Recorder]()
_WRITER: pytest.StashKey[ArtifactWriter] = pytest.StashKey()
_REPLAYS: pytest.StashKey[list[Artifact]] = pytest.StashKey()  # config: --mt-replay's artifacts
_ITEM_REPLAYS: pytest.StashKey[list[ReplayResult]] = pytest.StashKey()  # item: its replays
_REPLAY_RESULTS: pytest.StashKey[list[dict[str, Any]]] = pytest.StashKey()  # config: all, as JSON
_ARTIFACT_LIST: pytest.StashKey[list[tuple[str, str]]] = pytest.StashKey()  # (nodeid, folder)
# What could not be written at the session's end, and why (the option, the error).
_REPORT_ERROR: pytest.StashKey[list[str]] = pytest.StashKey()
ARTIFACT_PROPERTY = "metamorphic_artifact"
REPLAY_PROPERTY = "metamorphic_replay"


def pytest_addoption(parser: pytest.Parser) -> None:
    add_options(parser)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "metamorphic: a test built with @metamorphic (added automatically)"
    )
    config.stash[OPTIONS] = parse_options(config)
    config.stash[_SUMMARY] = SessionSummary()
    config.stash[CAMPAIGNS] = {}
    config.stash[GATES] = {}
    config.stash[_REPLAY_RESULTS] = []
    config.stash[_ARTIFACT_LIST] = []
    config.stash[_REPLAYS] = _load_replays(config.stash[OPTIONS].replay)
    config.pluginmanager.register(_SessionReporter(config), "pytest-metamorphic-reporter")
    start_cluster_early(config)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    parametrize_shards(metafunc)


def _load_replays(folders: tuple[Path, ...]) -> list[Artifact]:
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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.stash[_REPLAYS]:
        _select_replayed(config, items)
    enabled = config.stash[OPTIONS].campaign
    if enabled and config.stash[OPTIONS].dask:
        one_item_per_campaign(config, items)
    owners: dict[str, str] = {}  # campaign name -> the test defining it
    for item in items:
        if _is_metamorphic(item):
            item.add_marker("metamorphic")
        if campaign_of(item) is not None:
            item.add_marker("metamorphic")
            claim_campaign_name(owners, item)
            if not enabled and not _replayed_here(item):
                item.add_marker(pytest.mark.skip(reason="campaign: run with --mt-campaign"))


def _select_replayed(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Keep only the tests that saved the replayed artifacts (one shard of a campaign)."""
    wanted = {artifact.nodeid for artifact in config.stash[_REPLAYS]}
    keep: list[pytest.Item] = []
    found: set[str] = set()
    for item in items:
        name = _replay_name(item)
        if name in wanted and name not in found:
            found.add(name)
            keep.append(item)
    missing = sorted(wanted - found)
    if missing:
        folders = [str(a.folder) for a in config.stash[_REPLAYS] if a.nodeid in missing]
        raise pytest.UsageError(
            f"--mt-replay: the test(s) {missing} that saved {folders} were not collected; "
            "run pytest from the same root directory, with the test file on the command line"
        )
    dropped = [item for item in items if item not in keep]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
    items[:] = keep


def _replay_name(item: pytest.Item) -> str:
    """The node id an artifact names: a campaign's cases name its test without the shard
    (shards follow the number of workers)."""
    return item.nodeid.split("[")[0] if campaign_of(item) is not None else item.nodeid


def _replayed_here(item: pytest.Item) -> list[Any]:
    replays = item.config.stash[_REPLAYS]
    return [a for a in replays if a.nodeid == _replay_name(item)] if replays else []


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    __tracebackhide__ = True
    artifacts = _replayed_here(pyfuncitem)
    if not artifacts:
        return None
    from pytest_metamorphic.core.errors import MetamorphicViolation

    results = _replay_all(pyfuncitem, artifacts)
    pyfuncitem.stash[_ITEM_REPLAYS] = results
    failing = [result for result in results if result.still_fails]
    if failing:
        lines = [line for result in failing for line in result.lines()]
        raise MetamorphicViolation(
            "replayed violation(s) still fail:\n" + "\n".join(lines),
            relation=failing[0].artifact.relation,
            verdict=failing[0].verdict,
        )
    return True


def _replay_all(item: pytest.Function, artifacts: list[Any]) -> list[Any]:
    """Re-run each artifact against the test's system: a ``@metamorphic`` test's, or a
    campaign's (its cases)."""
    campaign = campaign_of(item)
    if campaign is not None:
        from pytest_metamorphic.reports.campaign_cases import replay_case

        return [replay_case(artifact, campaign.campaign) for artifact in artifacts]
    spec = getattr(item.obj, "_metamorphic", None)
    if spec is None:
        raise pytest.UsageError(f"--mt-replay: {item.nodeid} is not a @metamorphic test")
    from pytest_metamorphic.reports.replay import replay

    names = list(inspect.signature(spec.function).parameters)[1:]
    fixtures = {name: item.funcargs[name] for name in names}
    return [replay(artifact, spec, fixtures) for artifact in artifacts]


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, Any, Any]:
    __tracebackhide__ = True
    if _replayed_here(item):
        return (yield)
    if campaign_of(item) is not None:
        run_campaign_shard(item)
        return (yield)
    if not _is_metamorphic(item):
        return (yield)
    options = item.config.stash[OPTIONS]
    recorder = Recorder(
        followups=options.followups,
        check_determinism=options.check_determinism,
        minimize_budget=options.minimize_budget,
        minimize_seconds=options.minimize_seconds,
        timeout=options.timeout,
        nodeid=item.nodeid,
    )
    if options.artifacts is not None:
        recorder.on_violation = _ArtifactSink(options.artifacts, item, recorder)
    item.stash[_RECORDER] = recorder
    with recording(recorder):
        result = yield
    _report_nothing_tested(recorder, options.strict_tested)
    return result


def _report_nothing_tested(recorder: Recorder, strict: bool) -> None:
    """A relation that tested nothing passed vacuously: say so (fail under strict)."""
    __tracebackhide__ = True
    lines = []
    for name, stats in recorder.relations.items():
        reason = nothing_tested(stats, *reasons_of(recorder.reasons, name))
        if reason is not None:
            lines.append(f"relation {name!r} tested nothing: {reason}")
    if not lines:
        return
    message = "\n".join(lines)
    if strict:
        pytest.fail(message + "\n(--mt-strict-tested)", pytrace=False)
    warnings.warn(NothingTestedWarning(message), stacklevel=2)


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
    if call.when == "call" and call.excinfo is not None and _is_metamorphic(item):
        explain_the_users_code(call.excinfo.value)
        start_at_the_users_test(call.excinfo)
    if call.when == "call":
        recorder = item.stash.get(_RECORDER, None)
        if recorder is not None:
            # user_properties travel with the report: to JUnit XML and across xdist.
            item.user_properties.extend(junit_properties(recorder))
        writer = item.stash.get(_WRITER, None)
        if writer is not None:
            for folder in dict.fromkeys(writer.written):
                item.user_properties.append((ARTIFACT_PROPERTY, str(folder)))
        for replayed in item.stash.get(_ITEM_REPLAYS, []):
            item.user_properties.append((REPLAY_PROPERTY, json.dumps(replayed.to_json())))
        campaign = campaign_property(item)
        if campaign is not None:
            item.user_properties.append(campaign)
            result = item.stash[CAMPAIGN_RESULT]
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

    @pytest.hookimpl(tryfirst=True)  # a failed gate fails the report before others see it
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when != "call":
            return
        self.config.stash[_SUMMARY].add_report(
            report.nodeid, report.outcome, report.user_properties
        )
        for key, value in report.user_properties:
            if key == ARTIFACT_PROPERTY:
                self.config.stash[_ARTIFACT_LIST].append((report.nodeid, str(value)))
            elif key == REPLAY_PROPERTY:
                self.config.stash[_REPLAY_RESULTS].append(json.loads(str(value)))
        blob = next((v for k, v in report.user_properties if k == CAMPAIGN_PROPERTY), None)
        # Only where the shards meet: an xdist worker sees its own shard alone.
        if blob is not None and not hasattr(self.config, "workerinput"):
            gate_on_report(self.config, report, str(blob))

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if hasattr(self.config, "workerinput"):
            return
        errors = self.config.stash.get(_REPORT_ERROR, [])
        if errors:
            terminalreporter.write_sep("=", "metamorphic reports NOT written", red=True)
            for line in errors:
                terminalreporter.write_line(line)
            if any(result.sources_done for result in self.config.stash[CAMPAIGNS].values()):
                terminalreporter.write_line(
                    "The campaign logs hold every finished source: once the folder can be "
                    "written, run again with --mt-campaign --mt-resume to write the reports."
                )
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
            for replayed in replays:
                for line in replayed["lines"]:
                    terminalreporter.write_line(line)
        campaigns = self.config.stash[CAMPAIGNS]
        if campaigns:
            from pytest_metamorphic.reports.campaign import format_table

            for name, result in campaigns.items():
                terminalreporter.write_sep("=", f"campaign {name}")
                for line in format_table(result):
                    terminalreporter.write_line(line)
                reports = self.config.stash[OPTIONS].campaign_dir / slug(name)
                terminalreporter.write_line(f"reports and logs: {reports}/")
                for line in self._case_lines(name):
                    terminalreporter.write_line(line)
                for line in self._gate_lines(name):
                    terminalreporter.write_line(line, bold=True)

    def _case_lines(self, name: str) -> list[str]:
        state = self.config.stash[GATES].get(name)
        if state is None or not state.cases:
            return []
        saved = [case for case in state.cases if case.folder]
        lines = [f"violation cases ({len(saved)} saved; replay one: pytest --mt-replay <folder>):"]
        lines += [f"  {case.folder}" for case in saved]
        lines += [
            f"  source {case.source}, size {case.size}, follow-up {case.followup}: not saved: "
            f"{case.note}"
            for case in state.cases
            if not case.folder
        ]
        return lines

    def _gate_lines(self, name: str) -> list[str]:
        state = self.config.stash[GATES].get(name)
        if state is not None and state.verdict is not None:
            return list(state.verdict.lines())
        seen = 0 if state is None else state.seen
        expected = "?" if state is None else state.expected
        return [
            f"gate NOT JUDGED: campaign {name!r}: {seen} of {expected} shard test(s) "
            "reported a result (a shard failed, was deselected, or the run was interrupted)"
        ]

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        if hasattr(self.config, "workerinput"):
            return
        errors = [error for error in self._write_reports() if error]
        if errors:
            # A read-only folder or a full disk at the report step: each report that could
            # not be written is named in the summary and the session fails (campaign logs
            # are complete; a --mt-resume run rewrites the campaign reports).
            self.config.stash[_REPORT_ERROR] = errors
            session.exitstatus = pytest.ExitCode.TESTS_FAILED

    def _write_reports(self) -> Iterator[str | None]:
        """Write every report asked for, each apart: one that fails (said as a line) does
        not cost the others."""
        options = self.config.stash[OPTIONS]
        if options.report is not None:
            summary = self.config.stash[_SUMMARY]
            yield _written("--mt-report", options.report, "the JSON report", summary.write_json)
            yield _written(
                "--mt-report",
                options.report.with_suffix(".coverage.png"),
                "the coverage picture",
                lambda path: _write_coverage_picture(summary.rows(), path),
            )
        gates = self.config.stash[GATES]
        judged = [
            (result, gates[name].verdict if name in gates else None)
            for name, result in self.config.stash[CAMPAIGNS].items()
        ]
        for result, verdict in judged:
            name = result.header["campaign"]
            cases = gates[name].cases if name in gates else []
            yield _written(
                "--mt-campaign-dir",
                options.campaign_dir / slug(name),
                f"the reports of campaign {name!r}",
                lambda folder: write_campaign_reports(result, folder, verdict, cases),  # noqa: B023
            )
        if judged and options.job_summary is not None:
            from pytest_metamorphic.reports.campaign import write_job_summary

            yield _written(
                "--mt-job-summary (or $GITHUB_STEP_SUMMARY)",
                options.job_summary,
                "the job summary",
                lambda path: write_job_summary(path, judged, options.campaign_dir),
            )


def _written(option: str, path: Path, what: str, write: Callable[[Path], object]) -> str | None:
    """None once ``write(path)`` has written ``what``; else the line saying why not."""
    try:
        write(path)
    except OSError as error:
        if not isinstance(error, WriteError):
            error = write_error(error, path, what=what)
        return f"{option}: {error}"
    return None


def _write_coverage_picture(rows: list[dict[str, Any]], path: Path) -> None:
    """The coverage picture beside the JSON report, when matplotlib is installed (the
    ``plot`` extra); without it the JSON's ``coverage`` counts are all there is."""
    try:
        from pytest_metamorphic.reports.coverage_chart import write_coverage_chart

        write_coverage_chart(rows, path)
    except ImportError:
        return
