"""One source of a campaign: its input, its follow-ups, the system's outputs and the
relation's verdicts, as one JSON-ready record (the unit every engine runs)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from pytest_metamorphic.core.batching import SystemCalls
from pytest_metamorphic.core.campaign.identity import input_digest, output_digest
from pytest_metamorphic.core.campaign.spec import Campaign, draw_followup
from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.relations import (
    CheckContext,
    Verdict,
    judged_count,
    unjudged_changes,
)

__all__ = ["run_source"]


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
    except Exception as source_crash:
        record["sut_calls"] = 1
        record["crash"] = f"{type(source_crash).__name__}: {source_crash}"
        return record
    # Which input this source is: sources that load the same frame twice count once.
    record["input"] = input_digest(source_input)
    calls = SystemCalls(campaign.system, timeout)
    pairs = [
        (size_index, size, f)
        for size_index, size in enumerate(campaign.sizes)
        for f in range(campaign.followups)
    ]
    source_output: Any = None
    n_source, source_categories = 0, dict[str, int]()
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
            except Exception as draw_error:
                drawn.append(draw_error)
        values = [source_input] if first else []
        whats = [f"source {index}"] if first else []
        for (_, size, f), item in zip(chunk, drawn, strict=True):
            if not isinstance(item, Exception) and not _skipped(item):
                values.append(item[0])
                whats.append(f"source {index}, size {size}, follow-up {f}")
        outcomes = iter(calls.run(values, whats))
        if first:
            first = False
            source_output, source_error = next(outcomes)
            record["sut_calls"] = 1
            if source_error is not None:
                record["crash"] = f"{type(source_error).__name__}: {source_error}"
                return record
            n_source, source_categories = _count(
                _counted(campaign, source_output, source_input), campaign.category
            )
        for (_, size, f), item in zip(chunk, drawn, strict=True):
            pair: dict[str, Any] = {"size": size, "followup": f}
            record["pairs"].append(pair)
            if not isinstance(item, Exception) and _skipped(item):
                pair["not_applicable"] = str(item[1]["not_applicable"])  # the system not run
                continue
            record["sut_calls"] += 1
            if isinstance(item, Exception):
                pair["crash"] = f"{type(item).__name__}: {item}"
                continue
            followup_output, error = next(outcomes)
            if error is not None:
                pair["crash"] = f"{type(error).__name__}: {error}"
                continue
            if len(record["pairs"]) == 1:
                # What a resume re-runs to tell the same system from another (identity.py).
                record["digest"] = output_digest((source_output, followup_output))
            source = (source_input, source_output, n_source, source_categories)
            _judge(campaign, pair, source, item, followup_output, f)
    return record


def _skipped(item: tuple[Any, Any]) -> bool:
    """A follow-up the transform could not make (``Followup.not_applicable``)."""
    params = item[1]
    return isinstance(params, dict) and "not_applicable" in params


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
    judged = judged_count(verdict)
    pair["judged"] = n_source if judged is None else judged  # elements the relation judged
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
        pair["violated"] = _violated(campaign, verdict, source_output, followup_output)


_MAX_VIOLATED = 20  # elements described per pair; the rest are counted


def _violated(
    campaign: Campaign, verdict: Verdict, source_output: Any, followup_output: Any
) -> list[dict[str, Any]]:
    """The source elements a violation blames: what each is, its category and fate.

    The relation's details name them (``blamed``, else ``unmatched``); a relation that
    names none (a count, an exact comparison) gives an empty list.
    """
    details = verdict.details if isinstance(verdict.details, Mapping) else {}
    named = details.get("blamed", details.get("unmatched"))
    try:
        elements = list(source_output)
    except TypeError:
        return []
    if not isinstance(named, (list, tuple)):
        return []
    indices = [i for i in named if isinstance(i, int) and 0 <= i < len(elements)]
    indices = indices[:_MAX_VIOLATED]
    fates: Sequence[str] = ()
    if campaign.fate is not None and indices:
        try:
            fates = [str(f) for f in campaign.fate(source_output, followup_output, indices)]
        except Exception:
            # A fate explains a verdict the relation already gave; one that cannot be
            # told (outputs it does not understand) leaves the pair counted as "other".
            fates = ()
    violated = []
    for number, i in enumerate(indices):
        entry: dict[str, Any] = {"index": i, "what": describe_value(elements[i])}
        if campaign.category is not None:
            entry["category"] = str(campaign.category(elements[i]))
        if number < len(fates):
            entry["fate"] = fates[number]
        violated.append(entry)
    return violated
