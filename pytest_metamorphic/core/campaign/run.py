"""Running a campaign in this process: one source at a time, logged as it finishes."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from pytest_metamorphic.core.batching import SystemCalls
from pytest_metamorphic.core.campaign.log import LogLike, as_logs, shard_indices
from pytest_metamorphic.core.campaign.results import CampaignResult, tally
from pytest_metamorphic.core.campaign.spec import Campaign, draw_followup
from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, unjudged_changes
from pytest_metamorphic.core.timeout import check_timeout

__all__ = ["CampaignProgress", "InProcess", "run_campaign", "run_source"]


def _count(elements: Any, category: Callable[[Any], str] | None) -> tuple[int, dict[str, int]]:
    items = list(elements)
    if category is None:
        return len(items), {}
    by_category: dict[str, int] = {}
    for item in items:
        key = str(category(item))
        by_category[key] = by_category.get(key, 0) + 1
    return len(items), by_category


def _counted(campaign: Campaign, output: Any, input_: Any) -> Any:
    return output if campaign.counted is None else campaign.counted(output, input_)


def run_source(campaign: Campaign, index: int, timeout: float | None = None) -> dict[str, Any]:
    """All pairs of one source, as one JSON-ready record.

    A system with ``run_batch`` (:mod:`pytest_metamorphic.core.batching`) gets the source
    and its first follow-ups in one batch, then the remaining follow-ups in batches of its
    ``batch_size``; the record is the same as from one call per input.
    """
    rng = campaign.source_rng(index)
    record: dict[str, Any] = {"source": index, "pairs": [], "sut_calls": 0}
    try:
        source_input = campaign.source(rng, index)
    except Exception as error:
        record["sut_calls"] = 1
        record["crash"] = f"{type(error).__name__}: {error}"
        return record
    calls = SystemCalls(campaign.system, timeout)
    pairs = [
        (size_index, size, f)
        for size_index, size in enumerate(campaign.sizes)
        for f in range(campaign.followups)
    ]
    source_output: Any = None
    n_source, source_categories = 0, {}
    start = 0
    first = True
    while first or start < len(pairs):
        # The source goes with the first batch; a plain system gets one input per call.
        chunk = pairs[start : start + calls.batch_size - first]
        start += len(chunk)
        drawn: list[Any] = []
        for size_index, _, f in chunk:
            try:
                drawn.append(draw_followup(campaign, source_input, index, size_index, f))
            except Exception as error:
                drawn.append(error)
        values = [source_input] if first else []
        whats = [f"source {index}"] if first else []
        for (_, size, f), item in zip(chunk, drawn, strict=True):
            if not isinstance(item, Exception):
                values.append(item[0])
                whats.append(f"source {index}, size {size}, follow-up {f}")
        outcomes = iter(calls.run(values, whats))
        if first:
            first = False
            source_output, error = next(outcomes)
            record["sut_calls"] = 1
            if error is not None:
                record["crash"] = f"{type(error).__name__}: {error}"
                return record
            n_source, source_categories = _count(
                _counted(campaign, source_output, source_input), campaign.category
            )
        for (_, size, f), item in zip(chunk, drawn, strict=True):
            pair: dict[str, Any] = {"size": size, "followup": f}
            record["pairs"].append(pair)
            record["sut_calls"] += 1
            if isinstance(item, Exception):
                pair["crash"] = f"{type(item).__name__}: {item}"
                continue
            followup_output, error = next(outcomes)
            if error is not None:
                pair["crash"] = f"{type(error).__name__}: {error}"
                continue
            source = (source_input, source_output, n_source, source_categories)
            _judge(campaign, pair, source, item, followup_output, f)
    return record


def _judge(
    campaign: Campaign,
    pair: dict[str, Any],
    source: tuple[Any, Any, int, dict[str, int]],
    followup: tuple[Any, Any],
    followup_output: Any,
    f: int,
) -> None:
    """Counts, categories and the relation's verdict on one pair, into its record
    (``source``: input, output, counted size, categories)."""
    source_input, source_output, n_source, source_categories = source
    followup_input, params = followup
    n_followup, followup_categories = _count(
        _counted(campaign, followup_output, followup_input), campaign.category
    )
    verdict = campaign.relation.check(
        source_output, followup_output, CheckContext(source_input, followup_input, params, f)
    )
    pair["o"], pair["o2"] = n_source, n_followup
    pair["holds"] = verdict.holds
    outside = unjudged_changes(verdict)
    if outside:
        pair["unjudged_changes"] = outside
    if source_categories or followup_categories:
        pair["categories"] = {
            key: [source_categories.get(key, 0), followup_categories.get(key, 0)]
            for key in sorted(set(source_categories) | set(followup_categories))
        }
    if not verdict.holds:
        pair["explanation"] = verdict.explanation
        pair["source_output"] = describe_value(source_output)


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
    resume: bool = False,
    shard: int = 0,
    shards: int = 1,
    keep_examples: int = 20,
    progress: Callable[[CampaignProgress], None] | None = None,
    timeout: float | None = None,
    cluster: Any = None,
    batch_size: int | None = None,
) -> CampaignResult:
    """Run (a shard of) a campaign and return its aggregated result.

    Parameters
    ----------
    log : path or ShardLogs, optional
        JSONL file: a header line, then one record per finished source, flushed as it
        comes; or a :class:`~pytest_metamorphic.core.campaign.log.ShardLogs` folder (one
        file per shard, the pytest plugin's layout). An existing log is renamed aside
        unless ``resume`` is true.
    resume : bool
        Continue the run recorded in ``log``: finished sources are read back, not redone.
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
    """
    timeout = check_timeout(timeout)
    if not isinstance(campaign, Campaign):
        raise InvalidArgument(f"campaign={campaign!r} must be a Campaign")
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
    with engine.session(campaign, timeout) as session:
        if not resume:
            logs.set_aside(indices)
        result = logs.read(campaign, indices, keep_examples=keep_examples)
        resumed = len(result.sources_done)
        todo = [index for index in indices if index not in result.sources_done]
        started = time.monotonic()
        ran = failed = 0
        with logs.open(campaign.header()) as write:
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
