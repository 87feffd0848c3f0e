"""Running a campaign in this process: one source at a time, logged as it finishes."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

from pytest_metamorphic.core.batching import SystemCalls
from pytest_metamorphic.core.campaign.identity import input_digest, output_digest
from pytest_metamorphic.core.campaign.log import (
    Check,
    LogLike,
    as_logs,
    logged_digest,
    shard_indices,
)
from pytest_metamorphic.core.campaign.results import CampaignResult, tally
from pytest_metamorphic.core.campaign.source import run_source
from pytest_metamorphic.core.campaign.spec import Campaign, draw_followup
from pytest_metamorphic.core.errors import InvalidArgument, OtherSystemError
from pytest_metamorphic.core.timeout import check_timeout

__all__ = ["CampaignProgress", "InProcess", "run_campaign"]


def _check_same_outputs(campaign: Campaign, logs: Any, index: int, timeout: float | None) -> None:
    """Re-run the system on one logged source and its first follow-up and compare the
    outputs with the log's digest: a system changed in place (a model retrained under the
    same name and parameters) is not resumed as if it were the same."""
    logged = logged_digest(logs, campaign, index)
    if logged is None:
        return  # a log of 0.4 or earlier, or a source whose first pair crashed
    source = campaign.source(campaign.source_rng(index), index)
    followup, _ = draw_followup(campaign, source, index, 0, 0)
    calls = SystemCalls(campaign.system, timeout)
    outcomes = calls.run([source, followup], [f"source {index}", f"source {index}, pair 0"])
    errors = [error for _, error in outcomes if error is not None]
    now = output_digest(tuple(output for output, _ in outcomes))
    if not errors and now == logged:
        return
    gives = "crashes" if errors else f"gives outputs {now}"
    raise OtherSystemError(
        f"the campaign log records outputs {logged} of the system on source {index} and its "
        f"first follow-up; the system now {gives}. Resuming would blend two systems' results "
        "(or the system is not deterministic): use another log, run without resume, or pass "
        'resume="any-system" (--mt-resume-any-system) if the change is intended.'
    )


class _SourceCheck:
    """A resume's check of a logged record: its source, drawn again from the seed, must
    be the input it recorded (a log of other frames, a cache of another dataset, is not
    resumed as if it were this campaign's)."""

    def __init__(self, campaign: Campaign) -> None:
        self.campaign = campaign

    def __call__(self, record: dict[str, Any]) -> str | None:
        logged = record.get("input")
        if logged is None or "crash" in record:
            return None  # a log of 0.6 or earlier, or a source that could not be drawn
        index = record["source"]
        try:
            now = input_digest(self.campaign.source(self.campaign.source_rng(index), index))
        except Exception as error:
            return f"source {index} cannot be drawn again ({type(error).__name__}: {error})"
        if now != logged:
            return (
                f"it records source {index} as input {logged}, but the campaign's source "
                f"{index} is now {now} (the log is of other data: frames changed on disk, or "
                "a cache of another run)"
            )
        return None


@dataclass(frozen=True)
class CampaignProgress:
    """Where a running campaign stands, given to ``run_campaign(progress=...)``."""

    done: int  # sources finished, those read back from the log included
    total: int  # sources of this run (of its shard)
    in_flight: int = 0  # sent to workers and not back yet (cluster runs)
    failed: int = 0  # finished as a crash: of the system on the source, or of its worker
    ran: int = 0  # finished by this run
    elapsed: float = 0.0  # seconds since this run started

    @property
    def rate(self) -> float:
        """Sources per second finished by this run."""
        return self.ran / self.elapsed if self.elapsed > 0 else 0.0


class InProcess:
    """Runs the sources here, one after another."""

    def describe(self) -> dict[str, Any]:
        return {"engine": "process", "workers": 1}

    @contextmanager
    def session(self, campaign: Campaign, timeout: float | None) -> Iterator[InProcess]:
        self.campaign, self.timeout = campaign, timeout
        yield self

    def records(self, todo: list[int]) -> Iterator[tuple[dict[str, Any], int]]:
        """Each finished source's record, with how many sources are still in flight."""
        for index in todo:
            yield run_source(self.campaign, index, self.timeout), 0


def run_campaign(
    campaign: Campaign,
    *,
    log: LogLike = None,
    resume: bool | Literal["any-system"] = False,
    shard: int = 0,
    shards: int = 1,
    keep_examples: int = 20,
    progress: Callable[[CampaignProgress], None] | None = None,
    timeout: float | None = None,
    cluster: Any = None,
    batch_size: int | None = None,
    unverified: Literal["error", "rerun"] = "error",
) -> CampaignResult:
    """Run (a shard of) a campaign and return its aggregated result.

    Parameters
    ----------
    log : path or ShardLogs, optional
        JSONL file: a header line, then one record per finished source, flushed as it
        comes; or a :class:`~pytest_metamorphic.core.campaign.log.ShardLogs` folder (one
        file per shard, the pytest plugin's layout). An existing log is renamed aside
        unless ``resume`` is true. While the run writes it, the log is locked: a second
        run on it fails at once with
        :class:`~pytest_metamorphic.core.errors.FolderInUse`, naming the first.
    resume : bool or "any-system"
        Continue the run recorded in ``log``: finished sources are read back, not redone.
        The log must be of the same system under test
        (:mod:`~pytest_metamorphic.core.campaign.identity`: its name and fingerprint, and
        its output on the first logged source, re-run once), else
        :class:`~pytest_metamorphic.core.errors.OtherSystemError`; ``"any-system"``
        resumes anyway.
    shard, shards : int
        Run only the sources ``shard, shard + shards, ...``; results of all shards merge
        (:meth:`CampaignResult.merge`) into exactly the one-process result.
    keep_examples : int
        How many violating pairs to keep in the result for reports.
    progress : callable(CampaignProgress), optional
        Called after each finished source.
    timeout : float, optional
        Seconds one call of the system may take; a call past it is recorded as a crash
        of that pair (or source), ``SystemTimeout: ...``, and the campaign goes on.
    cluster : str or distributed.Client, optional
        Run the sources on a Dask cluster (:mod:`pytest_metamorphic.core.campaign.cluster`):
        a scheduler address, ``"local:N"`` for a local cluster of N worker processes, or
        a connected client. The result is identical to a run in this process.
    batch_size : int, optional
        Sources per cluster task; by default guided (several sources per task early on,
        to amortise the engine's ~1 ms per task, one per task towards the end).
    unverified : "error" or "rerun"
        On a resume, every record read back is verified
        (:mod:`~pytest_metamorphic.core.campaign.records`: its shape, its check against
        the log's header, and its source input, drawn again from the seed and compared
        with the input digest it recorded). A record that does not verify is a
        ``DataError`` naming the file and line; ``"rerun"`` drops it instead, runs its
        source again, and lists it in the result's ``dropped``.
    """
    timeout = check_timeout(timeout)
    if not isinstance(campaign, Campaign):
        raise InvalidArgument(f"campaign={campaign!r} must be a Campaign")
    if resume not in (True, False, "any-system"):
        raise InvalidArgument(f"resume={resume!r} must be True, False or 'any-system'")
    if unverified not in ("error", "rerun"):
        raise InvalidArgument(f"unverified={unverified!r} must be 'error' or 'rerun'")
    system = campaign.system_identity()
    logs = as_logs(log)
    indices = shard_indices(campaign.sources, shard, shards)
    if cluster is None:
        if batch_size is not None:
            raise InvalidArgument("batch_size= is for cluster runs; give cluster= too")
        engine: Any = InProcess()
    else:
        from pytest_metamorphic.core.campaign.cluster import DaskEngine

        engine = DaskEngine(cluster, batch_size=batch_size)
    # The engine checks the campaign (can it be sent?) before the log is touched.
    with engine.session(campaign, timeout) as session, logs.lock(indices):
        if not resume:
            logs.set_aside(indices)
        checked = system if resume is True else None
        check = Check(_SourceCheck(campaign), rerun=unverified == "rerun") if resume else None
        result = logs.read(
            campaign, indices, keep_examples=keep_examples, system=checked, check=check
        )
        if checked is not None and result.sources_done:
            _check_same_outputs(campaign, logs, min(result.sources_done), timeout)
        resumed = len(result.sources_done)
        todo = [index for index in indices if index not in result.sources_done]
        started = time.monotonic()
        ran = failed = 0
        with logs.open({**campaign.header(), "system": system}) as write:
            for record, in_flight in session.records(todo):
                write(record)
                tally(result, record)
                result._trim_examples()
                ran += 1
                failed += "crash" in record
                if progress:
                    progress(
                        CampaignProgress(
                            resumed + ran,
                            len(indices),
                            in_flight,
                            failed,
                            ran,
                            time.monotonic() - started,
                        )
                    )
        entry = session.describe()
    entry.update(
        shard=[shard, shards],
        sources=ran,
        resumed=resumed,
        seconds=round(time.monotonic() - started, 3),
    )
    result.execution.append(entry)
    return result
