"""Running a campaign in this process: one source at a time, logged as it finishes."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.campaign.log import (
    open_log,
    read_campaign_log,
    set_aside,
    shard_indices,
)
from pytest_metamorphic.core.campaign.results import CampaignResult, tally
from pytest_metamorphic.core.campaign.spec import Campaign, draw_followup
from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, unjudged_changes
from pytest_metamorphic.core.timeout import call_with_timeout, check_timeout

__all__ = ["run_campaign", "run_source"]


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
    """All pairs of one source, as one JSON-ready record."""
    rng = campaign.source_rng(index)
    record: dict[str, Any] = {"source": index, "pairs": [], "sut_calls": 0}

    def system(value: Any, what: str) -> Any:
        return call_with_timeout(campaign.system, value, seconds=timeout, what=what)

    try:
        source_input = campaign.source(rng, index)
        source_output = system(source_input, f"source {index}")
    except Exception as error:
        record["sut_calls"] = 1
        record["crash"] = f"{type(error).__name__}: {error}"
        return record
    record["sut_calls"] = 1
    n_source, source_categories = _count(
        _counted(campaign, source_output, source_input), campaign.category
    )
    for size_index, size in enumerate(campaign.sizes):
        for f in range(campaign.followups):
            pair: dict[str, Any] = {"size": size, "followup": f}
            record["pairs"].append(pair)
            record["sut_calls"] += 1
            try:
                followup_input, params = draw_followup(campaign, source_input, index, size_index, f)
                followup_output = system(
                    followup_input, f"source {index}, size {size}, follow-up {f}"
                )
            except Exception as error:
                pair["crash"] = f"{type(error).__name__}: {error}"
                continue
            n_followup, followup_categories = _count(
                _counted(campaign, followup_output, followup_input), campaign.category
            )
            verdict = campaign.relation.check(
                source_output,
                followup_output,
                CheckContext(source_input, followup_input, params, f),
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
    return record


def run_campaign(
    campaign: Campaign,
    *,
    log: Path | str | None = None,
    resume: bool = False,
    shard: int = 0,
    shards: int = 1,
    keep_examples: int = 20,
    progress: Callable[[int, int], None] | None = None,
    timeout: float | None = None,
) -> CampaignResult:
    """Run (a shard of) a campaign and return its aggregated result.

    Parameters
    ----------
    log : path, optional
        JSONL file: a header line, then one record per finished source, flushed as it
        comes. An existing log is renamed aside unless ``resume`` is true.
    resume : bool
        Continue the run recorded in ``log``: finished sources are read back, not redone.
    shard, shards : int
        Run only the sources ``shard, shard + shards, ...``; results of all shards merge
        (:meth:`CampaignResult.merge`) into exactly the one-process result.
    keep_examples : int
        How many violating pairs to keep in the result for reports.
    progress : callable(done, total), optional
    timeout : float, optional
        Seconds one call of the system may take; a call past it is recorded as a crash
        of that pair (or source), ``SystemTimeout: ...``, and the campaign goes on.
    """
    timeout = check_timeout(timeout)
    if not isinstance(campaign, Campaign):
        raise InvalidArgument(f"campaign={campaign!r} must be a Campaign")
    header = campaign.header()
    indices = shard_indices(campaign.sources, shard, shards)
    path = None if log is None else Path(log)
    if path is not None and path.exists() and path.stat().st_size and not resume:
        set_aside(path)
    result = read_campaign_log(
        campaign, path, shard=shard, shards=shards, keep_examples=keep_examples
    )
    done = set(result.sources_done)
    todo = [index for index in indices if index not in done]
    with open_log(path, header) as write:
        for count, index in enumerate(todo, start=1):
            record = run_source(campaign, index, timeout)
            write(record)
            tally(result, record)
            result._trim_examples()
            if progress:
                progress(len(done) + count, len(indices))
    result._trim_examples()
    return result
