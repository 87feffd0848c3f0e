"""Campaigns: violation rates from independent sampling.

Hypothesis searches for failures; it does not sample independently, so it cannot say how
*often* a relation fails. A :class:`Campaign` does: S sources, each perturbed at every size
in ``sizes`` ``followups`` times, all drawn from NumPy generators seeded by
``(seed, source index, ...)``. Every unit of work therefore has its own random stream, so
the result does not depend on the order, the process (pytest-xdist shards) or on resuming
an interrupted run.

Results are appended to a JSONL log as each source finishes (flushed and fsynced): an
interrupted campaign loses at most the source in progress and resumes where it stopped.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.intervals import Rate, wilson
from pytest_metamorphic.core.relations import CheckContext, Relation, unjudged_changes
from pytest_metamorphic.core.timeout import call_with_timeout, check_timeout

__all__ = [
    "Campaign",
    "CampaignInput",
    "CampaignResult",
    "SizeCounts",
    "campaign_inputs",
    "campaign_test",
    "merge_results",
    "read_campaign_log",
    "result_from_json",
    "run_campaign",
    "shard_indices",
]

LOG_VERSION = 1


@dataclass(frozen=True)
class Campaign:
    """An i.i.d. violation-rate experiment on one system under test.

    Parameters
    ----------
    name : str
    source : callable(rng, index) -> source input
        Draws (or loads) source ``index`` using ``rng`` (a ``numpy.random.Generator``).
    followup : callable(source_input, size, rng) -> follow-up input
        Perturbs the source with ``size`` elements (e.g. injected points).
    system : callable(input) -> output
        The system under test; run once per source (the output is reused) and once per
        follow-up.
    relation : Relation
        The strict relation counted as a violation (e.g. ``subset`` for MR1).
    sizes : sequence of int
        Perturbation sizes, e.g. ``(10, 100, 1000)``.
    sources : int
        Number of sources S.
    followups : int
        Follow-ups per source and size F.
    seed : int
    category : callable(element) -> str, optional
        Category of an output element (e.g. a box's label) for per-category breakdowns.
    counted : callable(output, input) -> collection, optional
        The part of an output the table counts (|O| vs |O'|, categories): for a scoped
        relation, what it judges (e.g. obstacles inside the ROI). Default: all of it.
    """

    name: str
    source: Callable[[np.random.Generator, int], Any]
    followup: Callable[[Any, int, np.random.Generator], Any]
    system: Callable[[Any], Any]
    relation: Relation
    sizes: Sequence[int] = (10, 100, 1000)
    sources: int = 1000
    followups: int = 1
    seed: int = 0
    category: Callable[[Any], str] | None = None
    counted: Callable[[Any, Any], Any] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise InvalidArgument(f"name={self.name!r} must be a non-empty string")
        for argument in ("source", "followup", "system"):
            if not callable(getattr(self, argument)):
                raise InvalidArgument(f"{argument}={getattr(self, argument)!r} must be callable")
        for argument in ("category", "counted"):
            value = getattr(self, argument)
            if value is not None and not callable(value):
                raise InvalidArgument(f"{argument}={value!r} must be callable or None")
        if not isinstance(self.relation, Relation):
            raise InvalidArgument(f"relation={self.relation!r} must be a Relation")
        sizes = tuple(self.sizes)
        if not sizes or any(not isinstance(n, int) or n < 0 for n in sizes):
            raise InvalidArgument(f"sizes={self.sizes!r} must be a non-empty list of ints >= 0")
        object.__setattr__(self, "sizes", sizes)
        for argument in ("sources", "followups"):
            value = getattr(self, argument)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InvalidArgument(f"{argument}={value!r} must be an int >= 1")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidArgument(f"seed={self.seed!r} must be an int >= 0")

    def header(self) -> dict[str, Any]:
        """What identifies this campaign's results: a log is resumable only if it matches."""
        return {
            "version": LOG_VERSION,
            "campaign": self.name,
            "relation": self.relation.name,
            "seed": self.seed,
            "sources": self.sources,
            "sizes": list(self.sizes),
            "followups": self.followups,
        }

    def source_rng(self, index: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, index])

    def followup_rng(self, index: int, size_index: int, followup: int) -> np.random.Generator:
        # A longer entropy tuple than source_rng's, so the streams never coincide.
        return np.random.default_rng([self.seed, index, 1 + size_index, followup])


_TALLIES = ("pairs", "fewer", "equal", "more", "violations", "crashes", "unjudged_changes")


@dataclass
class SizeCounts:
    """Tallies for one perturbation size; all fields add up across shards."""

    pairs: int = 0
    fewer: int = 0  # |O| > |O'|
    equal: int = 0
    more: int = 0  # |O| < |O'|
    violations: int = 0
    crashes: int = 0
    unjudged_changes: int = 0  # pairs that changed only outside the relation's scope
    # category -> [pairs where that category lost elements, kept count, gained]
    categories: dict[str, list[int]] = field(default_factory=dict)

    def add(self, other: SizeCounts) -> None:
        for name in _TALLIES:
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for category, counts in other.categories.items():
            mine = self.categories.setdefault(category, [0, 0, 0])
            for i in range(3):
                mine[i] += counts[i]

    def rate(self, name: str) -> Rate:
        return wilson(getattr(self, name), self.pairs)

    def to_json(self) -> dict[str, Any]:
        return {
            "pairs": self.pairs,
            "fewer": self.fewer,
            "equal": self.equal,
            "more": self.more,
            "violations": self.violations,
            "crashes": self.crashes,
            "unjudged_changes": self.unjudged_changes,
            "categories": {k: list(v) for k, v in sorted(self.categories.items())},
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> SizeCounts:
        counts = cls(**{k: v for k, v in data.items() if k != "categories"})
        counts.categories = {k: list(v) for k, v in data.get("categories", {}).items()}
        return counts


@dataclass
class CampaignResult:
    """Aggregated campaign results; mergeable, and identical however the work was split."""

    header: dict[str, Any]
    sizes: dict[int, SizeCounts]
    sources_done: set[int] = field(default_factory=set)
    sut_calls: int = 0
    source_crashes: int = 0
    examples: list[dict[str, Any]] = field(default_factory=list)
    keep_examples: int = 20

    @property
    def complete(self) -> bool:
        return len(self.sources_done) == self.header["sources"]

    @property
    def sut_calls_saved(self) -> int:
        """SUT runs caching avoided: without it every pair would re-run its source."""
        return sum(counts.pairs for counts in self.sizes.values()) - len(self.sources_done)

    def merge(self, other: CampaignResult) -> None:
        if other.header != self.header:
            raise InvalidArgument("cannot merge results of different campaigns")
        overlap = self.sources_done & other.sources_done
        if overlap:
            raise InvalidArgument(f"sources counted twice when merging: {sorted(overlap)[:5]}")
        for size, counts in other.sizes.items():
            self.sizes.setdefault(size, SizeCounts()).add(counts)
        self.sources_done |= other.sources_done
        self.sut_calls += other.sut_calls
        self.source_crashes += other.source_crashes
        self.examples.extend(other.examples)
        self._trim_examples()

    def _trim_examples(self) -> None:
        # The first violations in (source, size, follow-up) order: the same set whichever
        # way the sources were split over shards.
        self.examples.sort(key=lambda e: (e["source"], e["size"], e["followup"]))
        del self.examples[self.keep_examples :]

    def to_json(self) -> dict[str, Any]:
        return {
            "header": self.header,
            "complete": self.complete,
            "source_indices": sorted(self.sources_done),
            "sources_done": len(self.sources_done),
            "sut_calls": self.sut_calls,
            "sut_calls_saved": self.sut_calls_saved,
            "source_crashes": self.source_crashes,
            "sizes": {
                str(size): {
                    **counts.to_json(),
                    "rates": {
                        name: counts.rate(name).to_json()
                        for name in ("fewer", "equal", "more", "violations")
                    },
                }
                for size, counts in sorted(self.sizes.items())
            },
            "examples": self.examples,
        }


def result_from_json(data: dict[str, Any]) -> CampaignResult:
    """Rebuild a result from :meth:`CampaignResult.to_json` (e.g. sent by an xdist worker)."""
    return CampaignResult(
        header=data["header"],
        sizes={
            int(k): SizeCounts.from_json({key: value for key, value in v.items() if key != "rates"})
            for k, v in data["sizes"].items()
        },
        sources_done=set(data["source_indices"]),
        sut_calls=data["sut_calls"],
        source_crashes=data["source_crashes"],
        examples=list(data["examples"]),
        keep_examples=max(20, len(data["examples"])),
    )


def campaign_test(campaign: Campaign, *, shards: int = 8) -> Callable[..., None]:
    """A pytest test that runs ``campaign`` under ``--mt-campaign`` (skipped otherwise).

    The test is parametrized over ``shards`` fixed shards of the sources, so pytest-xdist
    spreads them over workers; the plugin merges the shards into one result, identical to
    a one-process run. Assign it to a module-level name starting with ``test_``.
    """
    import pytest

    if not isinstance(campaign, Campaign):
        raise InvalidArgument(f"campaign={campaign!r} must be a Campaign")
    if isinstance(shards, bool) or not isinstance(shards, int) or not 1 <= shards <= 1000:
        raise InvalidArgument(f"shards={shards!r} must be an int between 1 and 1000")

    @pytest.mark.parametrize("mt_shard", range(shards), ids=[f"shard{i}" for i in range(shards)])
    def test(mt_shard: int) -> None:
        """Body intentionally empty: the plugin runs the shard around this call."""

    test._metamorphic_campaign = (campaign, shards)
    test.__name__ = test.__qualname__ = f"test_campaign_{_identifier(campaign.name)}"
    return test


def _identifier(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name).strip("_").lower() or "campaign"


def shard_indices(sources: int, shard: int, shards: int) -> range:
    """Source indices of one shard: every ``shards``-th index starting at ``shard``."""
    if not 0 <= shard < shards:
        raise InvalidArgument(f"shard={shard} must be in [0, {shards})")
    return range(shard, sources, shards)


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


def _followup(
    campaign: Campaign, source_input: Any, index: int, size_index: int, f: int
) -> tuple[Any, Mapping[str, Any]]:
    """Follow-up ``f`` of source ``index`` at ``sizes[size_index]``: (input, params)."""
    size = campaign.sizes[size_index]
    followup = campaign.followup(source_input, size, campaign.followup_rng(index, size_index, f))
    return getattr(followup, "input", followup), getattr(followup, "params", {})


@dataclass(frozen=True)
class CampaignInput:
    """One input a campaign runs its system on (see :func:`campaign_inputs`).

    ``size`` and ``followup`` are None for the source input itself.
    """

    source: int
    size: int | None
    followup: int | None
    input: Any
    params: Mapping[str, Any] = field(default_factory=dict)


def campaign_inputs(
    campaign: Campaign, sources: Iterable[int] | None = None
) -> Iterator[CampaignInput]:
    """Every input of the campaign (each source, then its follow-ups), as a run draws them.

    The same seeds as :func:`run_campaign`, so the inputs are exactly those a run gives
    its system: the basis of offline evaluation (export the inputs, run a detector over
    them anywhere, evaluate its predictions).
    """
    for index in range(campaign.sources) if sources is None else sources:
        source_input = campaign.source(campaign.source_rng(index), index)
        yield CampaignInput(index, None, None, source_input)
        for size_index, size in enumerate(campaign.sizes):
            for f in range(campaign.followups):
                value, params = _followup(campaign, source_input, index, size_index, f)
                yield CampaignInput(index, size, f, value, params)


def _run_source(campaign: Campaign, index: int, timeout: float | None = None) -> dict[str, Any]:
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
                followup_input, params = _followup(campaign, source_input, index, size_index, f)
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


def _tally(result: CampaignResult, record: dict[str, Any]) -> None:
    result.sources_done.add(record["source"])
    result.sut_calls += record["sut_calls"]
    if "crash" in record:
        result.source_crashes += 1
        return
    for pair in record["pairs"]:
        counts = result.sizes.setdefault(pair["size"], SizeCounts())
        counts.pairs += 1
        if "crash" in pair:
            counts.crashes += 1
            continue
        o, o2 = pair["o"], pair["o2"]
        if o > o2:
            counts.fewer += 1
        elif o == o2:
            counts.equal += 1
        else:
            counts.more += 1
        if pair.get("unjudged_changes"):
            counts.unjudged_changes += 1
        if not pair["holds"]:
            counts.violations += 1
            result.examples.append({"source": record["source"], **pair})
        for category, (a, b) in pair.get("categories", {}).items():
            slot = counts.categories.setdefault(category, [0, 0, 0])
            slot[0 if a > b else 1 if a == b else 2] += 1


def _read_log(path: Path, header: dict[str, Any]) -> Iterator[dict[str, Any]]:
    with path.open(encoding="utf-8") as handle:
        lines = handle.read().splitlines()
    if not lines:
        return
    try:
        found = json.loads(lines[0])
    except json.JSONDecodeError:
        raise InvalidArgument(f"{path}: first line is not a campaign header") from None
    if found != header:
        raise InvalidArgument(
            f"{path} holds results of a different campaign ({found}); expected {header}. "
            "Use another log path or the same seed and parameters."
        )
    for number, line in enumerate(lines[1:], start=2):
        try:
            yield json.loads(line)
        except json.JSONDecodeError:
            if number == len(lines):
                return  # a line cut off by an interruption: that source is simply redone
            raise InvalidArgument(f"{path}:{number}: corrupt campaign record") from None


def _set_aside(path: Path) -> None:
    """Keep an earlier log instead of overwriting it: nothing recorded is lost."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    target = path.with_name(f"{path.stem}.{stamp}{path.suffix}")
    counter = 1
    while target.exists():
        target = path.with_name(f"{path.stem}.{stamp}-{counter}{path.suffix}")
        counter += 1
    path.rename(target)


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
        _set_aside(path)
    result = read_campaign_log(
        campaign, path, shard=shard, shards=shards, keep_examples=keep_examples
    )
    done = set(result.sources_done)
    todo = [index for index in indices if index not in done]
    with _open_log(path, header) as write:
        for count, index in enumerate(todo, start=1):
            record = _run_source(campaign, index, timeout)
            write(record)
            _tally(result, record)
            result._trim_examples()
            if progress:
                progress(len(done) + count, len(indices))
    result._trim_examples()
    return result


def read_campaign_log(
    campaign: Campaign,
    log: Path | str | None,
    *,
    shard: int = 0,
    shards: int = 1,
    keep_examples: int = 20,
) -> CampaignResult:
    """The result of the sources of one shard that ``log`` records as finished.

    Nothing runs: this is what an interrupted run had done (an empty result when the log
    is absent or empty). Raises InvalidArgument when the log belongs to another campaign.
    """
    header = campaign.header()
    result = CampaignResult(
        header, {size: SizeCounts() for size in campaign.sizes}, keep_examples=keep_examples
    )
    path = None if log is None else Path(log)
    if path is None or not path.exists() or not path.stat().st_size:
        return result
    indices = shard_indices(campaign.sources, shard, shards)
    for record in _read_log(path, header):
        if record["source"] in indices and record["source"] not in result.sources_done:
            _tally(result, record)
    result._trim_examples()
    return result


@contextmanager
def _open_log(
    path: Path | None, header: dict[str, Any]
) -> Iterator[Callable[[dict[str, Any]], None]]:
    """Append records to ``path``, each flushed and fsynced before the next source runs."""
    if path is None:
        yield lambda record: None
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fresh = not path.exists() or path.stat().st_size == 0
    with path.open("a", encoding="utf-8") as handle:

        def write(record: dict[str, Any]) -> None:
            handle.write(json.dumps(record, separators=(",", ":")) + "\n")
            handle.flush()
            os.fsync(handle.fileno())

        if fresh:
            write(header)
        yield write


def merge_results(results: Iterable[CampaignResult]) -> CampaignResult:
    """Merge shard results into one (raises if they belong to different campaigns)."""
    results = list(results)
    if not results:
        raise InvalidArgument("merge_results() needs at least one result")
    first = results[0]
    merged = CampaignResult(
        first.header,
        {int(k): SizeCounts() for k in first.header["sizes"]},
        keep_examples=max(r.keep_examples for r in results),
    )
    for result in results:
        merged.merge(result)
    return merged
