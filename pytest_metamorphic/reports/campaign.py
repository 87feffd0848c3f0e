"""Campaign reports: the paper's table, Markdown, JSON and a Fig. 3-style chart."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.campaign import CampaignResult
from pytest_metamorphic.core.intervals import wilson

__all__ = [
    "ChartColumn",
    "chart_columns",
    "describe_execution",
    "format_table",
    "to_markdown",
    "write_chart",
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
                    _cell(lost, total),
                    _cell(kept, total),
                    _cell(gained, total),
                ]
            )
    return rows


def _status(result: CampaignResult) -> str:
    done, total = len(result.sources_done), result.header["sources"]
    state = "complete" if result.complete else f"PARTIAL: {done} of {total} sources"
    return (
        f"campaign {result.header['campaign']!r}, seed {result.header['seed']}, "
        f"{done} sources x {len(result.sizes)} sizes x {result.header['followups']} follow-up(s) "
        f"({state}); {result.sut_calls} SUT calls, {result.sut_calls_saved} saved by reusing "
        f"source outputs; rates with Wilson 95% intervals"
    )


def describe_execution(entries: list[dict[str, Any]]) -> str:
    """How the sources ran, in words: on a Dask cluster, in pytest-xdist shards, in one process.

    For example ``ran on a Dask cluster tcp://... (2 workers, 63 tasks, ...)``,
    ``ran in 8 shards on pytest-xdist workers gw0, gw1`` or ``ran in one process``.
    """
    if not entries:
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
    categories = _category_rows(result)
    if categories:
        lines.append("per category (pairs whose count of that category fell / stayed / rose):")
        heading = [size_label(result), "category", "pairs", "fewer", "same", "more"]
        lines.extend(_align([heading, *categories]))
    if _scoped(result):
        lines.append(_SCOPE_NOTE)
    if result.source_crashes:
        lines.append(f"{result.source_crashes} source(s) crashed the system and were skipped")
    lines.extend(_not_applicable_lines(result))
    lines.append(describe_execution(result.execution))
    if result.examples:
        shown = result.examples[:_SHOWN_EXAMPLES]
        lines.append(f"first violations ({len(shown)} of the {len(result.examples)} kept):")
        lines.extend(f"  {_example_line(example, size_label(result))}" for example in shown)
    return lines


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


def _example_line(example: dict[str, Any], label: str) -> str:
    return (
        f"source {example['source']}, {label}={example['size']}, "
        f"follow-up {example['followup']}: "
        f"{example.get('explanation', '')}"
    )


def _markdown_table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out.extend("| " + " | ".join(row) + " |" for row in rows)
    return "\n".join(out)


def to_markdown(result: CampaignResult) -> str:
    parts = [f"# Campaign {result.header['campaign']}", "", _status(result), ""]
    parts.append(_markdown_table(_header(result), _rows(result)))
    if _scoped(result):
        parts += ["", _SCOPE_NOTE]
    categories = _category_rows(result)
    if categories:
        parts += ["", "## Per category", ""]
        parts.append(
            _markdown_table(
                [size_label(result), "category", "pairs", "fewer", "same", "more"], categories
            )
        )
    parts += ["", describe_execution(result.execution)]
    if result.examples:
        parts += ["", "## First violations", ""]
        parts.extend(
            f"- {_example_line(example, size_label(result))}" for example in result.examples
        )
    return "\n".join(parts) + "\n"


def _atomic_write(path: Path, write: Callable[[Path], object]) -> None:
    """Write to a temporary file and rename: an interruption never leaves half a report."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_json(result: CampaignResult, path: Path) -> None:
    _atomic_write(path, lambda p: p.write_text(json.dumps(result.to_json(), indent=2)))


def write_markdown(result: CampaignResult, path: Path) -> None:
    _atomic_write(path, lambda p: p.write_text(to_markdown(result), encoding="utf-8"))


@dataclass(frozen=True)
class ChartColumn:
    """One column of the Fig. 3 chart: a category at one noise size."""

    category: str
    size: int
    position: float
    percentages: tuple[float, float, float]  # fewer, same, more; sum 100 (or all 0)


def chart_columns(result: CampaignResult) -> list[ChartColumn]:
    """The chart's columns: one group per category (sizes side by side), a gap between.

    Without categories there is one group, "all", of the overall ``|O|`` vs ``|O'|`` counts.
    """
    sizes = sorted(result.sizes)
    categories = sorted({c for counts in result.sizes.values() for c in counts.categories})
    columns = []
    for index, category in enumerate(categories or ["all"]):
        for offset, size in enumerate(sizes):
            counts = result.sizes[size]
            values = (
                counts.categories.get(category, [0, 0, 0])
                if categories
                else [counts.fewer, counts.equal, counts.more]
            )
            total = sum(values)
            shares = tuple(100.0 * v / total if total else 0.0 for v in values)
            position = float(index * (len(sizes) + 1) + offset)
            columns.append(ChartColumn(category, size, position, shares))  # type: ignore[arg-type]
    return columns


def write_chart(result: CampaignResult, path: Path) -> None:
    """100% stacked columns per category and n, like the paper's Fig. 3 (needs matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = chart_columns(result)
    sizes = sorted(result.sizes)
    names = list(dict.fromkeys(column.category for column in columns))
    positions = [column.position for column in columns]
    centres = [
        sum(c.position for c in columns if c.category == name) / len(sizes) for name in names
    ]
    figure, axes = plt.subplots(figsize=(max(6.0, 0.45 * len(positions) + 2.5), 4.5))
    bottoms = [0.0] * len(columns)
    colours = {"fewer": "#d62728", "equal": "#bbbbbb", "more": "#1f77b4"}
    labels = {"fewer": "fewer in O'", "equal": "same", "more": "more in O'"}
    for slot, name in enumerate(_OUTCOMES):
        heights = [column.percentages[slot] for column in columns]
        axes.bar(positions, heights, bottom=bottoms, color=colours[name], label=labels[name])
        bottoms = [b + h for b, h in zip(bottoms, heights, strict=True)]
    axes.set_xticks(positions, [str(column.size) for column in columns], fontsize=7)
    for centre, category in zip(centres, names, strict=True):
        axes.annotate(
            category,
            (centre, 0),
            xycoords=("data", "axes fraction"),
            xytext=(0, -24),
            textcoords="offset points",
            ha="center",
            va="top",
            fontsize=9,
        )
    label = size_label(result)
    axes.set_xlabel(
        "noise points n, per category" if label == "n" else f"{label}, per category",
        labelpad=22,
    )
    axes.set_ylabel("% of source/follow-up pairs")
    axes.set_ylim(0, 100)
    title = f"{result.header['campaign']}: objects per category, O vs O'"
    if not result.complete:
        title += " (PARTIAL)"
    axes.set_title(title)
    axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    figure.tight_layout()
    _atomic_write(path, lambda p: figure.savefig(p, dpi=110, format="png"))
    plt.close(figure)
