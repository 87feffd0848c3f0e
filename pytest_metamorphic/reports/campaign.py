"""Campaign reports: the paper's table, the gate's verdict, violations grouped by
obstacle, Markdown, JSON, a CI job summary; the chart is :mod:`.campaign_chart`."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.campaign import CampaignResult
from pytest_metamorphic.core.campaign.baseline import slug
from pytest_metamorphic.core.campaign.results import FATE_ORDER
from pytest_metamorphic.core.files import write_atomically
from pytest_metamorphic.core.intervals import wilson
from pytest_metamorphic.reports.campaign_chart import (
    CHART_NAME,
    ChartColumn,
    chart_columns,
    write_chart,
)

__all__ = [
    "CHART_NAME",
    "ChartColumn",
    "chart_columns",
    "describe_execution",
    "format_table",
    "grouped_violations",
    "job_summary",
    "to_markdown",
    "write_chart",
    "write_job_summary",
    "write_json",
    "write_markdown",
]

_OUTCOMES = ("fewer", "equal", "more")
_SHOWN_EXAMPLES = 3  # in the terminal; report.md lists every kept one
_SCOPE_NOTE = (
    "out of scope: pairs whose output changed only outside what the relation judges "
    "(obstacles outside the ROI scope); information, not violations; |O| counts judged ones"
)
_HEADINGS = {"fewer": "|O| > |O'|", "equal": "|O| = |O'|", "more": "|O| < |O'|"}


def _cell(k: int, n: int) -> str:
    return f"{k} ({wilson(k, n)})"


def _rows(result: CampaignResult) -> list[list[str]]:
    rows = []
    for size, counts in sorted(result.sizes.items()):
        rows.append(
            [
                str(size),
                str(counts.pairs),
                *(_cell(getattr(counts, name), counts.pairs) for name in _OUTCOMES),
                _cell(counts.violations, counts.pairs),
                str(counts.crashes),
                *([str(counts.unjudged_changes)] if _scoped(result) else []),
            ]
        )
    return rows


def _scoped(result: CampaignResult) -> bool:
    """Whether any pair changed outside the relation's scope (the column is shown then)."""
    return any(counts.unjudged_changes for counts in result.sizes.values())


def size_label(result: CampaignResult) -> str:
    """What the campaign's sizes are (``"n"`` noise points unless it says otherwise)."""
    return str(result.header.get("size_label", "n"))


def _header(result: CampaignResult) -> list[str]:
    return [
        size_label(result),
        "pairs",
        *(_HEADINGS[name] for name in _OUTCOMES),
        f"violations of {result.header['relation']}",
        "crashes",
        *(["out of scope"] if _scoped(result) else []),
    ]


def _category_rows(result: CampaignResult) -> list[list[str]]:
    rows = []
    for size, counts in sorted(result.sizes.items()):
        for category, (lost, kept, gained) in sorted(counts.categories.items()):
            total = lost + kept + gained
            rows.append(
                [
                    str(size),
                    category,
                    str(total),
                    _cell(min(counts.category_violations.get(category, 0), total), total),
                    _cell(lost, total),
                    _cell(kept, total),
                    _cell(gained, total),
                ]
            )
    return rows


def _category_header(result: CampaignResult) -> list[str]:
    return [size_label(result), "category", "pairs", "violating", "fewer", "same", "more"]


def _status(result: CampaignResult) -> str:
    done, total = len(result.sources_done), result.header["sources"]
    state = "complete" if result.complete else f"PARTIAL: {done} of {total} sources"
    distinct = result.distinct_inputs
    inputs = "" if distinct == done else f" ({distinct} distinct source inputs)"
    return (
        f"campaign {result.header['campaign']!r}, seed {result.header['seed']}, "
        f"{done} sources{inputs} x {len(result.sizes)} sizes x {result.header['followups']} "
        f"follow-up(s) ({state}); {result.sut_calls} SUT calls, {result.sut_calls_saved} "
        f"saved by reusing source outputs; rates with Wilson 95% intervals"
    )


def _fate_lines(result: CampaignResult) -> list[str]:
    """Per size, the violating pairs by what became of the obstacles they blame."""
    lines = []
    for size, counts in sorted(result.sizes.items()):
        if not counts.violations or not counts.fates:
            continue
        order = [f for f in FATE_ORDER if f in counts.fates]
        order += sorted(f for f in counts.fates if f not in FATE_ORDER)
        parts = ", ".join(f"{counts.fates[fate]} {fate}" for fate in order)
        lines.append(f"{size_label(result)}={size}: {counts.violations} violating pair(s): {parts}")
    return lines


def grouped_violations(result: CampaignResult) -> list[dict[str, Any]]:
    """The kept violations grouped by source and blamed element, most frequent first.

    Each group: ``source``, ``index`` (the element's, None when the relation names none),
    ``what`` (the element, or the explanation), ``fates`` (fate -> pairs), ``sizes``
    (size -> pairs) and ``count`` (pairs).
    """
    groups: dict[tuple[int, int, str], dict[str, Any]] = {}
    for example in result.examples:
        violated = example.get("violated") or [
            {"what": str(example.get("explanation", "")).split("; ")[0][:160]}
        ]
        for element in violated:
            index = element.get("index")
            key = (int(example["source"]), -1 if index is None else int(index), element["what"])
            group = groups.setdefault(
                key,
                {
                    "source": key[0],
                    "index": index,
                    "what": str(key[2]),
                    "fates": {},
                    "sizes": {},
                    "count": 0,
                },
            )
            group["count"] += 1
            size = int(example["size"])
            group["sizes"][size] = group["sizes"].get(size, 0) + 1
            fate = element.get("fate")
            if fate:
                group["fates"][fate] = group["fates"].get(fate, 0) + 1
    return sorted(groups.values(), key=lambda g: (-g["count"], g["source"], g["what"]))


def _group_line(group: dict[str, Any], label: str) -> str:
    sizes = ", ".join(f"{label}={size}: {n}" for size, n in sorted(group["sizes"].items()))
    if group["index"] is None:
        element = f"source {group['source']}: {group['what']}"
    else:
        element = f"source {group['source']}, element #{group['index']} ({group['what']})"
    fates = ", ".join(f"{fate} in {n}" for fate, n in group["fates"].items())
    how = f"{fates} of" if fates else "violated in"
    return f"{element}: {how} {group['count']} pair(s) ({sizes})"


def _violation_lines(result: CampaignResult, limit: int | None) -> list[str]:
    groups = grouped_violations(result)
    if not groups:
        return []
    shown = groups if limit is None else groups[:limit]
    kept = len(result.examples)
    head = (
        f"violations by obstacle ({len(shown)} of {len(groups)} group(s), from the first "
        f"{result.keep_examples} violating pairs of each {size_label(result)}: {kept} kept):"
    )
    return [head, *(f"  {_group_line(group, size_label(result))}" for group in shown)]


def describe_execution(entries: list[dict[str, Any]], *, read_back: int | None = None) -> str:
    """How the sources ran, in words: on a Dask cluster, in pytest-xdist shards, in one process.

    For example ``ran on a Dask cluster tcp://... (2 workers, 63 tasks, ...)``,
    ``ran in 8 shards on pytest-xdist workers gw0, gw1`` or ``ran in one process``.
    ``read_back``: how many sources the result holds (when nothing ran, they came from the
    logs; none at all is said as such).
    """
    if not entries:
        if read_back == 0:
            return "ran: nothing (no source ran or was read back from the logs)"
        return "ran: nothing this session (every source read back from the logs)"
    parts = []
    for entry in (e for e in entries if e.get("engine") == "dask"):
        # "workers_replaced" is what logs of 0.4 and earlier recorded for lost workers
        lost = entry.get("workers_lost", entry.get("workers_replaced", 0))
        joined = entry.get("workers_joined", 0)
        crashes = entry.get("worker_crashes", 0)
        parts.append(
            f"on the Dask cluster {entry.get('scheduler')} ({entry.get('workers')} workers, "
            f"{entry.get('units')} tasks of {entry.get('batch_size')} sources, "
            f"{entry.get('sources')} sources in {entry.get('seconds', 0):.1f} s"
            + (f", {lost} worker(s) lost" if lost else "")
            + (f", {joined} worker(s) joined" if joined else "")
            + (f", {crashes} source(s) killed their worker" if crashes else "")
            + ")"
        )
    local = [e for e in entries if e.get("engine") != "dask"]
    if local:
        shards = {tuple(e.get("shard", (0, 1))) for e in local}
        workers = sorted({e["pytest_worker"] for e in local if e.get("pytest_worker")})
        where = (
            f"on pytest-xdist workers {', '.join(workers)}"
            if any(w != "main" for w in workers)
            else "in one process"
        )
        seconds = sum(e.get("seconds", 0) for e in local)
        parts.append(
            f"{where} ({len(shards)} shard(s), {sum(e.get('sources', 0) for e in local)} "
            f"sources, {seconds:.1f} s of shard time)"
        )
    resumed = sum(e.get("resumed", 0) for e in entries)
    suffix = f"; {resumed} sources read back from the logs" if resumed else ""
    return "ran " + "; and ".join(parts) + suffix


def _align(rows: list[list[str]]) -> list[str]:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ["  ".join(cell.rjust(widths[i]) for i, cell in enumerate(row)) for row in rows]


def format_table(result: CampaignResult) -> list[str]:
    """Terminal lines: the paper's table per n, then the per-category breakdown."""
    lines = [_status(result), *_align([_header(result), *_rows(result)])]
    lines.extend(_fate_lines(result))
    categories = _category_rows(result)
    if categories:
        lines.append(
            "per category (pairs holding one; violating: a violation blames one; fewer / "
            "same / more: that category's count fell / stayed / rose):"
        )
        lines.extend(_align([_category_header(result), *categories]))
    if _scoped(result):
        lines.append(_SCOPE_NOTE)
    if result.source_crashes:
        lines.append(f"{result.source_crashes} source(s) crashed the system and were skipped")
    lines.extend(_not_applicable_lines(result))
    lines.extend(_dropped_lines(result, _SHOWN_EXAMPLES))
    lines.append(describe_execution(result.execution, read_back=len(result.sources_done)))
    lines.extend(_violation_lines(result, _SHOWN_EXAMPLES))
    return lines


def _dropped_lines(result: CampaignResult, limit: int | None) -> list[str]:
    """Logged records a resume did not trust, whose sources ran again."""
    if not result.dropped:
        return []
    shown = result.dropped if limit is None else result.dropped[:limit]
    more = len(result.dropped) - len(shown)
    return [
        f"{len(result.dropped)} logged record(s) did not verify and their sources were run "
        "again (--mt-resume-rerun-unverified):",
        *(f"  {line}" for line in shown),
        *([f"  ... and {more} more (report.json lists them)"] if more else []),
    ]


def _not_applicable_lines(result: CampaignResult) -> list[str]:
    """Sizes at which some follow-ups could not be made; NOTHING TESTED where none was."""
    lines = []
    for size, counts in sorted(result.sizes.items()):
        if not counts.not_applicable:
            continue
        label = f"{size_label(result)}={size}"
        if counts.pairs == 0:
            lines.append(
                f"NOTHING TESTED at {label}: none of its {counts.not_applicable} follow-ups "
                "could be made (not a pass)"
            )
        else:
            lines.append(
                f"{label}: {counts.not_applicable} follow-up(s) could not be made and are not "
                "counted as pairs"
            )
    return lines


def _markdown_table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out.extend("| " + " | ".join(row) + " |" for row in rows)
    return "\n".join(out)


def _gate_markdown(verdict: Any) -> list[str]:
    if verdict is None:
        return ["**Gate not judged** (a shard failed or the run was interrupted)."]
    state = "passed" if verdict.passed else "FAILED"
    parts = [f"**Gate {state}** ({verdict.gate.describe()}):", ""]
    for check in verdict.checks:
        mark = "ok" if check.passed else "**FAIL**"
        parts.append(f"- {mark} {check.lines[0]}")
        parts.extend(f"  - {line}" for line in check.lines[1:])
    return parts


def to_markdown(
    result: CampaignResult,
    verdict: Any = None,
    *,
    chart: bool = True,
    cases: Sequence[Any] | None = None,
) -> str:
    """The report as Markdown: the gate's verdict (when judged), the table, fates,
    categories, how it ran, the violations grouped by obstacle, and the saved cases."""
    parts = [f"# Campaign {result.header['campaign']}", ""]
    parts += [*_gate_markdown(verdict), ""] if verdict is not None else []
    parts += [_status(result), ""]
    parts.append(_markdown_table(_header(result), _rows(result)))
    fates = _fate_lines(result)
    if fates:
        parts += ["", "Violating pairs by what became of the obstacles they blame:", ""]
        parts += [f"- {line}" for line in fates]
    if chart:
        parts += ["", f"![violations and counts per size]({CHART_NAME})"]
    if _scoped(result):
        parts += ["", _SCOPE_NOTE]
    categories = _category_rows(result)
    if categories:
        parts += ["", "## Per category", ""]
        parts.append(_markdown_table(_category_header(result), categories))
    dropped = _dropped_lines(result, None)
    if dropped:
        parts += ["", dropped[0], "", *(f"- {line.strip()}" for line in dropped[1:])]
    parts += ["", describe_execution(result.execution, read_back=len(result.sources_done))]
    violations = _violation_lines(result, None)
    if violations:
        parts += ["", "## Violations by obstacle", "", violations[0], ""]
        parts.extend(f"- {line.strip()}" for line in violations[1:])
    if cases:
        parts += ["", "## Cases", "", "Replay one with `pytest --mt-replay <folder>`:", ""]
        label = size_label(result)
        for case in cases:
            where = f"`{case.folder}`" if case.folder else f"not saved: {case.note}"
            parts.append(
                f"- source {case.source}, {label}={case.size}, follow-up {case.followup}: {where}"
            )
    return "\n".join(parts) + "\n"


def job_summary(entries: Sequence[tuple[CampaignResult, Any]], folder: Path) -> str:
    """A short Markdown summary of campaigns and their gates, for a CI job's page."""
    parts = ["## pytest-metamorphic campaigns", ""]
    parts.append("| campaign | gate | sizes | violations (Wilson 95%) | reports |")
    parts.append("|---|---|---|---|---|")
    for result, verdict in entries:
        name = str(result.header["campaign"])
        state = "not judged" if verdict is None else ("passed" if verdict.passed else "**FAILED**")
        sizes = "<br>".join(f"{size_label(result)}={size}" for size in sorted(result.sizes))
        rates = "<br>".join(
            f"{counts.violations}/{counts.pairs} ({counts.rate('violations')})"
            for _, counts in sorted(result.sizes.items())
        )
        reports = os.fspath(folder / slug(name))
        parts.append(f"| {name} | {state} | {sizes} | {rates} | `{reports}/` |")
    for result, verdict in entries:
        if verdict is not None and not verdict.passed:
            parts += ["", f"### {result.header['campaign']}: gate failed", ""]
            parts += [*_gate_markdown(verdict)]
    return "\n".join(parts) + "\n"


def write_job_summary(
    path: Path, entries: Sequence[tuple[CampaignResult, Any]], folder: Path
) -> None:
    """Append :func:`job_summary` to ``path`` (GitHub Actions' ``$GITHUB_STEP_SUMMARY``
    is appended to by every step)."""
    with Path(path).open("a", encoding="utf-8") as handle:
        handle.write(job_summary(entries, folder))


def write_json(
    result: CampaignResult, path: Path, *, verdict: Any = None, cases: Sequence[Any] | None = None
) -> None:
    data = result.to_json()
    if verdict is not None:
        data["gate"] = verdict.to_json()
    if cases:
        data["cases"] = [case.to_json() for case in cases]
    write_atomically(
        path, lambda p: p.write_text(json.dumps(data, indent=2)), what="the campaign report"
    )


def write_markdown(
    result: CampaignResult, path: Path, *, verdict: Any = None, cases: Sequence[Any] | None = None
) -> None:
    chart = (Path(path).parent / CHART_NAME).exists()
    text = to_markdown(result, verdict, chart=chart, cases=cases)
    write_atomically(
        path, lambda p: p.write_text(text, encoding="utf-8"), what="the campaign report"
    )
