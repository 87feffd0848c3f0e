"""Campaign tallies: what one source's record adds, and results that merge exactly."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.intervals import Rate, wilson

__all__ = [
    "FATE_ORDER",
    "CampaignResult",
    "SizeCounts",
    "merge_results",
    "pair_fate",
    "result_from_json",
    "tally",
]

_TALLIES = (
    "pairs",
    "fewer",
    "equal",
    "more",
    "violations",
    "crashes",
    "unjudged_changes",
    "not_applicable",
    "judged",
)


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
    # follow-ups the transform could not make (no object to insert): never pairs, never run
    not_applicable: int = 0
    # pairs in which the relation judged at least one element (an obstacle in scope)
    judged: int = 0
    # category -> [pairs where that category lost elements, kept count, gained]
    categories: dict[str, list[int]] = field(default_factory=dict)
    # category -> violating pairs that blame an element of that category
    category_violations: dict[str, int] = field(default_factory=dict)
    # fate ("lost", "merged", "split", ...) -> violating pairs counted under it (pair_fate):
    # the values add up to ``violations``
    fates: dict[str, int] = field(default_factory=dict)

    def add(self, other: SizeCounts) -> None:
        for name in _TALLIES:
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for category, counts in other.categories.items():
            slots = self.categories.setdefault(category, [0, 0, 0])
            for i in range(3):
                slots[i] += counts[i]
        for tally, theirs in (
            (self.category_violations, other.category_violations),
            (self.fates, other.fates),
        ):
            for key, count in theirs.items():
                tally[key] = tally.get(key, 0) + count

    def category_pairs(self, category: str) -> int:
        """Pairs whose source or follow-up holds an element of ``category``."""
        return sum(self.categories.get(category, [0, 0, 0]))

    def category_rate(self, category: str) -> Rate:
        """Violating pairs that blame a ``category`` element, among the pairs holding one."""
        pairs = self.category_pairs(category)
        return wilson(min(self.category_violations.get(category, 0), pairs), pairs)

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
            **({"not_applicable": self.not_applicable} if self.not_applicable else {}),
            "judged": self.judged,
            "categories": {k: list(v) for k, v in sorted(self.categories.items())},
            "category_violations": dict(sorted(self.category_violations.items())),
            "fates": dict(sorted(self.fates.items())),
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> SizeCounts:
        mappings = ("categories", "category_violations", "fates")
        counts = cls(**{k: v for k, v in data.items() if k not in mappings})
        counts.categories = {k: list(v) for k, v in data.get("categories", {}).items()}
        counts.category_violations = dict(data.get("category_violations", {}))
        counts.fates = dict(data.get("fates", {}))
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
    keep_examples: int = 20  # per size
    # digests of the source inputs: how many distinct inputs the sources were
    inputs: set[str] = field(default_factory=set)
    # logged records that did not verify on a resume and whose sources ran again
    # ("file:line: reason"; resume with unverified="rerun")
    dropped: list[str] = field(default_factory=list)
    # How the sources were run (engine, workers, seconds): one entry per run or shard.
    # Reported, never compared: the outcome is the same whichever engine ran it.
    execution: list[dict[str, Any]] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return len(self.sources_done) == self.header["sources"]

    @property
    def sut_calls_saved(self) -> int:
        """SUT runs caching avoided: without it every pair would re-run its source (a
        source that crashed has no pairs, and saved nothing)."""
        pairs = sum(counts.pairs for counts in self.sizes.values())
        return max(pairs - (len(self.sources_done) - self.source_crashes), 0)

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
        self.execution.extend(other.execution)
        self.inputs |= other.inputs
        self.dropped.extend(other.dropped)
        self._trim_examples()

    def _trim_examples(self) -> None:
        # The first violations of each size in (source, follow-up) order: the same set
        # whichever way the sources were split over shards, and a rare size's first
        # violation is kept however many the other sizes have.
        self.examples.sort(key=lambda e: (e["source"], e["size"], e["followup"]))
        kept: dict[int, int] = {}
        trimmed = []
        for example in self.examples:
            if kept.get(example["size"], 0) < self.keep_examples:
                kept[example["size"]] = kept.get(example["size"], 0) + 1
                trimmed.append(example)
        self.examples[:] = trimmed

    @property
    def distinct_inputs(self) -> int:
        """How many different source inputs the finished sources were (logs written
        before 0.7 record none: then every source counts as its own)."""
        recorded = len(self.inputs)
        return recorded if recorded else len(self.sources_done)

    def outcome_json(self) -> dict[str, Any]:
        """:meth:`to_json` without how it ran: equal for any split, engine or resume."""
        data = self.to_json()
        del data["execution"]
        return data

    def to_json(self) -> dict[str, Any]:
        return {
            "header": self.header,
            "complete": self.complete,
            "source_indices": sorted(self.sources_done),
            "sources_done": len(self.sources_done),
            "distinct_inputs": self.distinct_inputs,
            "input_digests": sorted(self.inputs),
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
            "keep_examples": self.keep_examples,
            **({"dropped": self.dropped} if self.dropped else {}),
            "execution": self.execution,
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
        keep_examples=int(data.get("keep_examples", max(20, len(data["examples"])))),
        execution=list(data.get("execution", [])),
        inputs=set(data.get("input_digests", [])),
        dropped=list(data.get("dropped", [])),
    )


def tally(result: CampaignResult, record: dict[str, Any]) -> None:
    result.sources_done.add(record["source"])
    result.sut_calls += record["sut_calls"]
    if isinstance(record.get("input"), str):
        result.inputs.add(record["input"])
    if "crash" in record:
        result.source_crashes += 1
        return
    for pair in record["pairs"]:
        counts = result.sizes.setdefault(pair["size"], SizeCounts())
        if "not_applicable" in pair:
            counts.not_applicable += 1
            continue
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
        if pair.get("judged", o) > 0:  # logs of 0.6 and earlier: the counted source elements
            counts.judged += 1
        if not pair["holds"]:
            counts.violations += 1
            result.examples.append({"source": record["source"], **pair})
            _tally_violated(counts, pair.get("violated", []))
        for category, (a, b) in pair.get("categories", {}).items():
            slot = counts.categories.setdefault(category, [0, 0, 0])
            slot[0 if a > b else 1 if a == b else 2] += 1


# Fates from the worst: a violating pair is counted under the first fate one of its
# blamed elements met (a word outside this list after these; none at all: "other").
FATE_ORDER = ("lost", "merged", "split", "relabelled", "changed")


def pair_fate(violated: list[dict[str, Any]]) -> str:
    """The one fate a violating pair is counted under (see :data:`FATE_ORDER`)."""
    fates = sorted({str(entry["fate"]) for entry in violated if "fate" in entry})
    for fate in FATE_ORDER:
        if fate in fates:
            return fate
    return fates[0] if fates else "other"


def _tally_violated(counts: SizeCounts, violated: list[dict[str, Any]]) -> None:
    """One violating pair: each blamed category once, and the pair under one fate."""
    for category in {str(entry["category"]) for entry in violated if "category" in entry}:
        counts.category_violations[category] = counts.category_violations.get(category, 0) + 1
    fate = pair_fate(violated)
    counts.fates[fate] = counts.fates.get(fate, 0) + 1


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
