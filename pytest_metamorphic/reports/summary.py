"""Aggregating per-test metamorphic counts into the session summary.

Each test report carries its counts as one JSON ``user_property`` (so they survive
pytest-xdist, which ships reports from workers to the controller); :class:`SessionSummary`
merges them on whichever process prints the summary.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.files import write_atomically
from pytest_metamorphic.core.stats import Recorder, RelationStats, nothing_tested, reasons_of
from pytest_metamorphic.lidar.judging.coverage import BANDS

__all__ = ["PROPERTY", "SessionSummary", "junit_properties"]

PROPERTY = "metamorphic"
COLUMNS = ("sources", "followups", "sut_calls", "violations", "crashes")
SCOPE_COLUMN = "unjudged_changes"  # shown only when some relation saw such changes
TESTED_COLUMNS = ("judged", "unchanged", "not_applicable")  # what the follow-ups tested


def junit_properties(recorder: Recorder) -> list[tuple[str, object]]:
    """``(name, value)`` pairs for ``item.user_properties``: one JSON blob for aggregation,
    plus flat numbers that read well as JUnit ``<property>`` elements."""
    properties: list[tuple[str, object]] = [(PROPERTY, json.dumps(recorder.to_json()))]
    properties.append(("mt.sut_calls", recorder.sut_calls))
    properties.append(("mt.source_crashes", recorder.source_crashes))
    for name, stats in recorder.relations.items():
        for column in (*COLUMNS, "nondeterministic", SCOPE_COLUMN, *TESTED_COLUMNS):
            properties.append((f"mt.{name}.{column}", getattr(stats, column)))
        reason = nothing_tested(stats, *reasons_of(recorder.reasons, name))
        if reason is not None:
            properties.append((f"mt.{name}.nothing_tested", reason))
    return properties


@dataclass
class TestSummary:
    nodeid: str
    outcome: str = "passed"
    source_calls: int = 0
    source_crashes: int = 0
    relations: dict[str, RelationStats] = field(default_factory=dict)
    reruns: RelationStats = field(default_factory=RelationStats)
    reasons: dict[str, str] = field(default_factory=dict)

    def nothing_tested(self, relation: str) -> str | None:
        """Why ``relation`` tested nothing in this test, or None."""
        return nothing_tested(self.relations[relation], *reasons_of(self.reasons, relation))

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
            test.relations.setdefault(name, RelationStats()).add(RelationStats.from_json(counts))
        test.reruns.add(RelationStats.from_json(data.get("reruns", {})))
        for name, reason in data.get("reasons", {}).items():
            test.reasons.setdefault(name, str(reason))
        return True

    def rows(self) -> list[dict[str, Any]]:
        rows = []
        for test in self.tests.values():
            for name, stats in test.relations.items():
                reason = test.nothing_tested(name)
                rows.append(
                    {
                        "test": test.nodeid,
                        "relation": name,
                        **asdict(stats),
                        "nothing_tested": reason,
                    }
                )
        return rows

    def _calls_line(self) -> str:
        """Every SUT call of the run, in parts that add up to the total: the table's column
        counts a relation's own calls (follow-ups, determinism re-checks, reductions)."""
        tests = list(self.tests.values())
        relations = [stats for test in tests for stats in test.relations.values()]
        parts = {
            "on sources, each output reused by its follow-ups": sum(t.source_calls for t in tests),
            "follow-up runs": sum(stats.followups for stats in relations),
            "earlier inputs run before history follow-ups": sum(
                stats.history_calls for stats in relations
            ),
            "re-running sources to check determinism": sum(
                stats.sut_calls - stats.followups - stats.minimize_calls - stats.history_calls
                for stats in relations
            ),
            "reducing violations": sum(stats.minimize_calls for stats in relations),
            "re-running failing cases while Hypothesis shrank them": sum(
                t.reruns.sut_calls for t in tests
            ),
        }
        total = sum(test.sut_calls for test in tests)
        shown = [
            f"{count} {what}" for what, count in parts.items() if count or what.startswith("on ")
        ]
        return f"{len(tests)} metamorphic test(s), {total} SUT calls: " + " + ".join(shown)

    def format_table(self) -> list[str]:
        """The terminal summary: one line per (test, relation)."""
        rows = self.rows()
        scoped = any(row[SCOPE_COLUMN] for row in rows)
        counted = any(row["counted"] for row in rows)
        skipped = any(row["not_applicable"] for row in rows)
        columns: tuple[str, ...] = COLUMNS
        header: tuple[str, ...] = (
            "test",
            "relation",
            "sources",
            "follow-ups",
            "SUT calls",
            "violations",
            "crashes",
        )
        if counted:
            columns, header = (*columns, "judged"), (*header, "judged")
        if skipped:
            columns, header = (*columns, "not_applicable"), (*header, "n/a")
        if scoped:
            columns, header = (*columns, SCOPE_COLUMN), (*header, "out of scope")
        body = [
            (row["test"], row["relation"], *(self._cell(row, c) for c in columns)) for row in rows
        ]
        for test in self.tests.values():
            if test.source_crashes:
                line = (test.nodeid, "(source)", "", "", str(test.source_calls), "")
                body.append((*line, str(test.source_crashes), *([""] * (len(header) - 7))))
        widths = [max(len(line[i]) for line in (header, *body)) for i in range(len(header))]

        def fmt(line: tuple[str, ...]) -> str:
            left = [line[i].ljust(widths[i]) for i in range(2)]
            right = [line[i].rjust(widths[i]) for i in range(2, len(line))]
            return "  ".join(left + right)

        lines = [fmt(header), *(fmt(line) for line in body), self._calls_line()]
        if any(test.reruns.sut_calls for test in self.tests.values()):
            lines.append(
                "sources and violations are distinct cases: Hypothesis's shrinking steps and "
                "the final replay of a failure are not counted again"
            )
        if counted:
            lines.append(
                "judged: obstacles (elements) the checks judged over all follow-ups; a "
                "relation that judged none tested nothing"
            )
        if skipped:
            lines.append("n/a: follow-ups the transform could not make (the system was not run)")
        if scoped:
            lines.append(
                "out of scope: follow-ups whose output changed only outside what the relation "
                "judges (obstacles outside the ROI scope); information, not violations"
            )
        lines += self._coverage_lines()
        nothing = [row for row in rows if row["nothing_tested"]]
        if nothing:
            lines.append(
                f"NOTHING TESTED by {len(nothing)} relation(s) (a pass that proves nothing):"
            )
            lines += [
                f"  {row['test']} :: {row['relation']}: {row['nothing_tested']}" for row in nothing
            ]
        return lines

    def _coverage_lines(self) -> list[str]:
        """The bands of the operating domain no follow-up of the run reached, among the
        relations that vary that dimension (per relation, counts per band: the JSON
        report). A band one relation reached is tested; a relation that never varies a
        dimension is not named for it."""
        reached: dict[str, dict[str, int]] = {}
        for test in self.tests.values():
            for name, stats in test.relations.items():
                cells = reached.setdefault(name, {})
                for cell, count in stats.coverage.items():
                    cells[cell] = cells.get(cell, 0) + count
        lines = []
        for dimension, bands in BANDS.items():
            varying = [
                name for name, cells in reached.items()
                if any(cell.startswith(dimension + ": ") for cell in cells)
            ]  # fmt: skip
            if not varying:
                continue
            seen = {cell.split(": ", 1)[1] for name in varying for cell in reached[name]
                    if cell.startswith(dimension + ": ")}  # fmt: skip
            for band in bands:
                if band in seen:
                    continue
                more = f"; and {len(varying) - 3} more" if len(varying) > 3 else ""
                lines.append(
                    f"  {dimension} {band}: none of the {len(varying)} relation(s) that vary it "
                    f"({'; '.join(varying[:3])}{more})"
                )
        if not lines:
            return []
        return [
            "operating domain not reached (a band no follow-up of the run judged or placed an "
            "object in; counts per relation and band in the --mt-report JSON, 'coverage'):",
            *lines,
        ]

    @staticmethod
    def _cell(row: dict[str, Any], column: str) -> str:
        if column == "judged" and not row["counted"]:
            return "-"  # the relation does not say what it judged
        if column == "judged" and row["nothing_tested"]:
            return f"{row[column]}!"
        return str(row[column])

    def to_json(self) -> dict[str, Any]:
        return {
            "tests": [
                {
                    "nodeid": test.nodeid,
                    "outcome": test.outcome,
                    "source_calls": test.source_calls,
                    "source_crashes": test.source_crashes,
                    "sut_calls": test.sut_calls,
                    "relations": {
                        name: {**asdict(s), "nothing_tested": test.nothing_tested(name)}
                        for name, s in test.relations.items()
                    },
                    "reruns": asdict(test.reruns),
                }
                for test in self.tests.values()
            ]
        }

    def write_json(self, path: Path) -> None:
        """Write atomically: a crash mid-write never leaves a truncated report."""
        data = self.to_json()
        write_atomically(
            path,
            lambda tmp: tmp.write_text(json.dumps(data, indent=2), encoding="utf-8"),
            what="the JSON report",
        )
