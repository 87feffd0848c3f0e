"""Aggregating per-test metamorphic counts into the session summary.

Each test report carries its counts as one JSON ``user_property`` (so they survive
pytest-xdist, which ships reports from workers to the controller); :class:`SessionSummary`
merges them on whichever process prints the summary.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.stats import Recorder, RelationStats

__all__ = ["PROPERTY", "SessionSummary", "junit_properties"]

PROPERTY = "metamorphic"
COLUMNS = ("sources", "followups", "sut_calls", "violations", "crashes")
SCOPE_COLUMN = "unjudged_changes"  # shown only when some relation saw such changes


def junit_properties(recorder: Recorder) -> list[tuple[str, object]]:
    """``(name, value)`` pairs for ``item.user_properties``: one JSON blob for aggregation,
    plus flat numbers that read well as JUnit ``<property>`` elements."""
    properties: list[tuple[str, object]] = [(PROPERTY, json.dumps(recorder.to_json()))]
    properties.append(("mt.sut_calls", recorder.sut_calls))
    properties.append(("mt.source_crashes", recorder.source_crashes))
    for name, stats in recorder.relations.items():
        for column in (*COLUMNS, "nondeterministic", SCOPE_COLUMN):
            properties.append((f"mt.{name}.{column}", getattr(stats, column)))
    return properties


@dataclass
class TestSummary:
    nodeid: str
    outcome: str = "passed"
    source_calls: int = 0
    source_crashes: int = 0
    relations: dict[str, RelationStats] = field(default_factory=dict)
    reruns: RelationStats = field(default_factory=RelationStats)

    @property
    def sut_calls(self) -> int:
        relations = sum(stats.sut_calls for stats in self.relations.values())
        return self.source_calls + relations + self.reruns.sut_calls


@dataclass
class SessionSummary:
    """Counts of every metamorphic test seen in this session, keyed by node id."""

    tests: dict[str, TestSummary] = field(default_factory=dict)

    def add_report(self, nodeid: str, outcome: str, properties: list[tuple[str, Any]]) -> bool:
        """Merge one test report's counts; False when the report carries none."""
        blob = next((value for name, value in properties if name == PROPERTY), None)
        if blob is None:
            return False
        data = json.loads(blob)
        test = self.tests.setdefault(nodeid, TestSummary(nodeid))
        test.outcome = outcome
        test.source_calls += data["source_calls"]
        test.source_crashes += data["source_crashes"]
        for name, counts in data["relations"].items():
            test.relations.setdefault(name, RelationStats()).add(RelationStats(**counts))
        test.reruns.add(RelationStats(**data.get("reruns", {})))
        return True

    def rows(self) -> list[dict[str, Any]]:
        rows = []
        for test in self.tests.values():
            for name, stats in test.relations.items():
                rows.append({"test": test.nodeid, "relation": name, **asdict(stats)})
        return rows

    def format_table(self) -> list[str]:
        """The terminal summary: one line per (test, relation)."""
        rows = self.rows()
        scoped = any(row[SCOPE_COLUMN] for row in rows)
        columns = (*COLUMNS, SCOPE_COLUMN) if scoped else COLUMNS
        header: tuple[str, ...] = (
            "test",
            "relation",
            "sources",
            "follow-ups",
            "SUT calls",
            "violations",
            "crashes",
        )
        header += ("out of scope",) if scoped else ()
        body = [(row["test"], row["relation"], *(str(row[c]) for c in columns)) for row in rows]
        for test in self.tests.values():
            if test.source_crashes:
                line = (test.nodeid, "(source)", "", "", str(test.source_calls), "")
                body.append((*line, str(test.source_crashes), *([""] if scoped else [])))
        widths = [max(len(line[i]) for line in (header, *body)) for i in range(len(header))]

        def fmt(line: tuple[str, ...]) -> str:
            left = [line[i].ljust(widths[i]) for i in range(2)]
            right = [line[i].rjust(widths[i]) for i in range(2, len(line))]
            return "  ".join(left + right)

        total_calls = sum(test.sut_calls for test in self.tests.values())
        cached = sum(
            stats.followups for test in self.tests.values() for stats in test.relations.values()
        )
        source_calls = sum(test.source_calls for test in self.tests.values())
        rerun_calls = sum(test.reruns.sut_calls for test in self.tests.values())
        lines = [fmt(header), *(fmt(line) for line in body)]
        rerun = f"; {rerun_calls} re-running failing cases while Hypothesis shrank them" * bool(
            rerun_calls
        )
        lines.append(
            f"{len(self.tests)} metamorphic test(s), {total_calls} SUT calls "
            f"({source_calls} on sources, each output reused by its follow-ups; "
            f"{cached} follow-up runs{rerun})"
        )
        if rerun_calls:
            lines.append(
                "sources and violations are distinct cases: Hypothesis's shrinking steps and "
                "the final replay of a failure are not counted again"
            )
        if scoped:
            lines.append(
                "out of scope: follow-ups whose output changed only outside what the relation "
                "judges (obstacles outside the ROI scope); information, not violations"
            )
        return lines

    def to_json(self) -> dict[str, Any]:
        return {
            "tests": [
                {
                    "nodeid": test.nodeid,
                    "outcome": test.outcome,
                    "source_calls": test.source_calls,
                    "source_crashes": test.source_crashes,
                    "sut_calls": test.sut_calls,
                    "relations": {name: asdict(s) for name, s in test.relations.items()},
                    "reruns": asdict(test.reruns),
                }
                for test in self.tests.values()
            ]
        }

    def write_json(self, path: Path) -> None:
        """Write atomically: a crash mid-write never leaves a truncated report."""
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                json.dump(self.to_json(), handle, indent=2)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
