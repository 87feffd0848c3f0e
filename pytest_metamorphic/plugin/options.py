"""The plugin's options: command line and ini, read and checked once at configure time."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import pytest

from pytest_metamorphic.core.stats import (
    DEFAULT_FOLLOWUPS,
    DEFAULT_MINIMIZE_BUDGET,
    DEFAULT_MINIMIZE_SECONDS,
)

__all__ = [
    "DEFAULT_ARTIFACTS",
    "DEFAULT_CAMPAIGN_CASES",
    "OPTIONS",
    "Options",
    "add_options",
    "parse_options",
]

OPTIONS = pytest.StashKey["Options"]()
DEFAULT_ARTIFACTS = Path("mt-artifacts")
DEFAULT_CAMPAIGN_CASES = 2  # violations per size saved as artifacts by a campaign


@dataclass(frozen=True)
class Options:
    followups: int
    check_determinism: bool
    report: Path | None
    campaign: bool = False
    campaign_dir: Path = Path("mt-campaigns")
    resume: bool | Literal["any-system"] = False
    rerun_unverified: bool = False
    artifacts: Path | None = DEFAULT_ARTIFACTS
    minimize_budget: int = DEFAULT_MINIMIZE_BUDGET
    minimize_seconds: float | None = DEFAULT_MINIMIZE_SECONDS
    replay: tuple[Path, ...] = ()
    timeout: float | None = None
    dask: str | None = None
    dask_batch: int | None = None
    strict_tested: bool = False
    baseline: Path | None = None
    job_summary: Path | None = None
    campaign_cases: int = DEFAULT_CAMPAIGN_CASES


def add_options(parser: pytest.Parser) -> None:
    """The plugin's command-line options (one group) and ini settings."""
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
        "--mt-baseline",
        default=None,
        metavar="PATH",
        help="compare each campaign with its report under PATH (a campaign folder kept "
        "from another run, e.g. main's, or one report.json): a rate significantly worse "
        "fails it (ini: mt_baseline)",
    )
    group.addoption(
        "--mt-campaign-cases",
        default=None,
        metavar="K",
        help="violations per size a campaign saves as replayable artifacts, reduced "
        f"within --mt-minimize-budget (ini: mt_campaign_cases; default "
        f"{DEFAULT_CAMPAIGN_CASES}; 0: none)",
    )
    group.addoption(
        "--mt-job-summary",
        default=None,
        metavar="PATH",
        help="append a Markdown summary of the campaigns and their gates to PATH (default: "
        "$GITHUB_STEP_SUMMARY when GitHub Actions sets it)",
    )
    group.addoption(
        "--mt-resume",
        action="store_true",
        default=False,
        help="continue interrupted campaigns from their logs instead of starting afresh",
    )
    group.addoption(
        "--mt-resume-rerun-unverified",
        action="store_true",
        default=False,
        help="on --mt-resume, run again the sources whose logged records do not verify "
        "(edited, of another campaign or system, of other input data), listing them in the "
        "report; by default such a record is an error naming its file and line",
    )
    group.addoption(
        "--mt-resume-any-system",
        action="store_true",
        default=False,
        help="resume even when a log records another system under test (its results and "
        "this run's are then blended; by default that is an error)",
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
        "--mt-minimize-seconds",
        default=None,
        metavar="SECONDS",
        help="time one reduction may take; when it runs out the smallest failing follow-up "
        f"found so far is reported and saved (ini: mt_minimize_seconds; default "
        f"{DEFAULT_MINIMIZE_SECONDS:g}; 0: no limit)",
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
    group.addoption(
        "--mt-strict-tested",
        action="store_true",
        default=None,
        help="fail a metamorphic test in which a relation tested nothing (no follow-up "
        "could be made, every follow-up equalled its source, or no obstacle was judged); "
        "by default that is a warning (ini: mt_strict_tested)",
    )
    parser.addini(
        "mt_strict_tested",
        "fail tests in which a relation tested nothing (default: warn)",
        type="bool",
        default=False,
    )
    parser.addini("mt_baseline", "campaign reports to compare with", default=None)
    parser.addini("mt_campaign_cases", "violations per size a campaign saves", default=None)
    parser.addini("mt_dask", "Dask scheduler address or local:N for campaigns", default=None)
    parser.addini("mt_dask_batch", "sources per Dask task", default=None)
    parser.addini("mt_timeout", "seconds one call of the system under test may take", default=None)
    parser.addini("mt_artifacts", "where violation artifacts are saved", default=None)
    parser.addini("mt_minimize_budget", "SUT calls allowed per reduction", default=None)
    parser.addini("mt_minimize_seconds", "seconds allowed per reduction", default=None)
    parser.addini("mt_followups", "follow-ups per source and relation", default=None)
    parser.addini("mt_campaign_dir", "where campaigns write logs and reports", default=None)
    parser.addini("mt_report", "path of the JSON report", default=None)
    parser.addini(
        "mt_check_determinism",
        "re-run the source before reporting a violation",
        type="bool",
        default=True,
    )


def parse_options(config: pytest.Config) -> Options:
    """Options from the command line, then the ini file; bad values are UsageErrors."""
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
    resume: bool | Literal["any-system"] = bool(config.getoption("mt_resume"))
    campaign = bool(config.getoption("mt_campaign"))
    if resume and not campaign:
        raise pytest.UsageError("--mt-resume only makes sense with --mt-campaign")
    if config.getoption("mt_resume_any_system"):
        if not resume:
            raise pytest.UsageError("--mt-resume-any-system only makes sense with --mt-resume")
        resume = "any-system"
    rerun_unverified = bool(config.getoption("mt_resume_rerun_unverified"))
    if rerun_unverified and not resume:
        raise pytest.UsageError("--mt-resume-rerun-unverified only makes sense with --mt-resume")
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
        minimize_seconds=_minimize_seconds_option(config),
        replay=tuple(_replay_option(config)),
        timeout=_timeout_option(config),
        dask=dask,
        dask_batch=dask_batch,
        strict_tested=bool(
            config.getoption("mt_strict_tested") or config.getini("mt_strict_tested")
        ),
        baseline=_baseline_option(config, campaign),
        job_summary=_job_summary_option(config),
        campaign_cases=_cases_option(config),
        rerun_unverified=rerun_unverified,
    )


def _baseline_option(config: pytest.Config, campaign: bool) -> Path | None:
    raw, source = config.getoption("mt_baseline"), "--mt-baseline"
    if raw is None:
        raw, source = config.getini("mt_baseline") or None, "ini mt_baseline"
    if raw is None:
        return None
    if source.startswith("--") and not campaign:
        raise pytest.UsageError("--mt-baseline compares campaigns: give --mt-campaign too")
    path = Path(raw)
    if path.exists() and not (path.is_dir() or path.is_file()):
        raise pytest.UsageError(f"{source}={path} is neither a folder nor a report file")
    # A missing path is not an error: the first run on main has no baseline yet; each
    # campaign's gate then says "not compared: no baseline at ...".
    return path


def _job_summary_option(config: pytest.Config) -> Path | None:
    raw = config.getoption("mt_job_summary") or os.environ.get("GITHUB_STEP_SUMMARY") or None
    if raw is None:
        return None
    path = Path(raw)
    if path.is_dir():
        raise pytest.UsageError(f"--mt-job-summary={path} is a directory; give a file path")
    return path


def _cases_option(config: pytest.Config) -> int:
    raw, source = config.getoption("mt_campaign_cases"), "--mt-campaign-cases"
    if raw is None:
        raw, source = config.getini("mt_campaign_cases"), "ini mt_campaign_cases"
    if raw in (None, ""):
        return DEFAULT_CAMPAIGN_CASES
    try:
        cases = int(raw)
    except (TypeError, ValueError):
        raise pytest.UsageError(f"{source}={raw!r} must be an integer") from None
    if not 0 <= cases <= 1000:
        raise pytest.UsageError(f"{source}={cases} must be between 0 and 1000")
    return cases


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


def _minimize_seconds_option(config: pytest.Config) -> float | None:
    raw, source = config.getoption("mt_minimize_seconds"), "--mt-minimize-seconds"
    if raw is None:
        raw, source = config.getini("mt_minimize_seconds"), "ini mt_minimize_seconds"
    if raw in (None, ""):
        return DEFAULT_MINIMIZE_SECONDS
    try:
        seconds = float(raw)
    except (TypeError, ValueError):
        raise pytest.UsageError(f"{source}={raw!r} must be a number of seconds") from None
    if not (seconds >= 0 and seconds != float("inf")):
        raise pytest.UsageError(f"{source}={raw!r} must be >= 0 seconds (0: no limit)")
    return seconds or None


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
