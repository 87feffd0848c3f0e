"""Per-test counters the engine fills in and the pytest plugin reports.

The plugin opens a :class:`Recorder` around each test call (:func:`recording`); the engine
finds it with :func:`current_recorder`. Without the plugin there is no recorder and nothing
is counted, which costs nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import asdict, dataclass, field
from typing import Any

__all__ = [
    "UNJUDGED",
    "Recorder",
    "RelationStats",
    "current_recorder",
    "nothing_tested",
    "reasons_of",
    "recording",
]

UNJUDGED = " (judged none)"
"""Suffix of a relation's name in :attr:`Recorder.reasons` under which the first reason a
check gave for judging nothing (``details["unjudged_reason"]``) is kept."""

DEFAULT_FOLLOWUPS = 2
DEFAULT_MINIMIZE_BUDGET = 500
"""SUT calls one violation's reduction to a 1-minimal follow-up may spend."""

DEFAULT_MINIMIZE_SECONDS = 120.0
"""Seconds one reduction may take: a slow system's violation is reported with the smallest
failing set found by then (500 calls of a 1 s detector would take over 8 minutes)."""


@dataclass
class RelationStats:
    """Counts for one metamorphic relation of one test.

    ``sut_calls`` counts the follow-up executions, determinism re-runs and reduction runs
    this relation caused; the source execution is shared by all relations of a test and
    counted once in :attr:`Recorder.source_calls`. ``minimize_calls`` is the part of
    ``sut_calls`` spent reducing violations to 1-minimal follow-ups, ``history_calls``
    the part spent on the earlier inputs of history follow-ups (``Followup.before``).
    ``unjudged_changes`` counts follow-ups whose output changed only outside what the
    relation judges (obstacles outside the ROI scope): information, never violations.
    ``coverage`` counts, per cell of the operating domain (``"distance: 0-5 m"``), the
    follow-ups that reached it (the relation's ``coverage`` function says which).

    What was tested: ``judged`` sums the elements (obstacles) the checks judged, over the
    ``counted`` follow-ups whose verdict says how many (``details["judged"]``), of which
    ``judged_followups`` judged at least one; ``unchanged`` counts follow-ups equal to
    their source; ``not_applicable`` the follow-ups a transform could not make (the
    system is not run on them). See :func:`nothing_tested`.

    Counts are per distinct case: :attr:`Recorder.reruns` collects, in the same fields,
    the cases Hypothesis re-ran while shrinking or replaying a failure (``sources``: the
    re-run cases; ``sut_calls``: every system call they made, source ones included).
    """

    sources: int = 0
    followups: int = 0
    sut_calls: int = 0
    violations: int = 0
    crashes: int = 0
    nondeterministic: int = 0
    minimize_calls: int = 0
    history_calls: int = 0
    unjudged_changes: int = 0
    judged: int = 0
    counted: int = 0
    judged_followups: int = 0
    unchanged: int = 0
    not_applicable: int = 0
    coverage: dict[str, int] = field(default_factory=dict)

    def add(self, other: RelationStats) -> None:
        for name, value in asdict(other).items():
            if name == "coverage":
                for cell, count in value.items():
                    self.coverage[cell] = self.coverage.get(cell, 0) + count
            else:
                setattr(self, name, getattr(self, name) + value)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> RelationStats:
        """From :func:`dataclasses.asdict` output (keys this version does not know ignored,
        missing ones 0: reports of other versions merge)."""
        known = {
            name: int(value)
            for name, value in data.items()
            if name in _FIELDS and name != "coverage"
        }
        cells = data.get("coverage") or {}
        return cls(**known, coverage={str(k): int(v) for k, v in dict(cells).items()})


_FIELDS = frozenset(RelationStats.__dataclass_fields__)


def nothing_tested(stats: RelationStats, reason: str = "", unjudged: str = "") -> str | None:
    """Why a relation tested nothing over a whole test, or None when it tested something.

    Nothing was tested when every follow-up was not applicable (``reason``: the
    transform's), when every follow-up run equalled its source, or when the checks said
    how many obstacles they judged and that was none (``unjudged``: why, when a check
    said).
    """
    ran = stats.followups
    if ran == 0 and stats.not_applicable:
        return f"no follow-up could be made ({reason or 'not applicable'})"
    if ran and stats.unchanged == ran:
        return f"every follow-up ({ran}) equalled its source"
    if stats.counted and stats.counted == ran and stats.judged == 0:
        why = f": {unjudged}" if unjudged else ""
        return f"no obstacle (element) was judged in {ran} follow-up(s){why}"
    return None


def reasons_of(reasons: dict[str, str], relation: str) -> tuple[str, str]:
    """``(reason, unjudged)`` for :func:`nothing_tested` from a recorder's ``reasons``."""
    return reasons.get(relation, ""), reasons.get(relation + UNJUDGED, "")


@dataclass
class Recorder:
    """Everything counted while one test ran, plus the options it ran under.

    ``on_violation(record, final)`` is called by the engine for every violation it is
    about to raise (``final``: Hypothesis's last replay of the shrunk example, or a run
    outside Hypothesis' search); it returns where the violation was saved, or None.
    """

    followups: int = DEFAULT_FOLLOWUPS
    check_determinism: bool = True
    minimize_budget: int = DEFAULT_MINIMIZE_BUDGET
    minimize_seconds: float | None = DEFAULT_MINIMIZE_SECONDS
    timeout: float | None = None
    nodeid: str = ""
    on_violation: Callable[[Any, bool], str | None] | None = field(default=None, repr=False)
    source_calls: int = 0
    source_crashes: int = 0
    relations: dict[str, RelationStats] = field(default_factory=dict)
    # Why a relation's transform could not make a follow-up (the first reason seen).
    reasons: dict[str, str] = field(default_factory=dict)
    # Cases Hypothesis ran again while shrinking, explaining or replaying a failure
    # (core/search_phase.py): their system calls are cost, not new sources or violations.
    reruns: RelationStats = field(default_factory=RelationStats)
    # The violations raised to the user (one per failing case Hypothesis reports).
    violations: list[dict[str, Any]] = field(default_factory=list)
    # The first call past its time limit: its case's digest and its error. The rest of the
    # search does not call the system again (engine.py, _Runner.__call__).
    timed_out: tuple[str, BaseException] | None = None

    def relation(self, name: str) -> RelationStats:
        return self.relations.setdefault(name, RelationStats())

    @property
    def sut_calls(self) -> int:
        relations = sum(stats.sut_calls for stats in self.relations.values())
        return self.source_calls + relations + self.reruns.sut_calls

    def to_json(self) -> dict[str, Any]:
        return {
            "source_calls": self.source_calls,
            "source_crashes": self.source_crashes,
            "sut_calls": self.sut_calls,
            "relations": {name: asdict(stats) for name, stats in self.relations.items()},
            "reruns": asdict(self.reruns),
            "reasons": dict(self.reasons),
        }


_CURRENT: ContextVar[Recorder | None] = ContextVar("pytest_metamorphic_recorder", default=None)


def current_recorder() -> Recorder | None:
    """The recorder of the test running now, or None outside the plugin."""
    return _CURRENT.get()


@contextmanager
def recording(recorder: Recorder) -> Iterator[Recorder]:
    token = _CURRENT.set(recorder)
    try:
        yield recorder
    finally:
        _CURRENT.reset(token)
