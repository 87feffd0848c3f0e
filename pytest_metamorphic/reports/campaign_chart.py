"""A campaign's chart: how often the relation failed and how, beside the paper's Fig. 3.

Left, what a CI reader needs first: the violation rate of the relation under test per
size, with its Wilson 95% interval, the bar split by what became of the obstacles the
violations blame (lost, merged, split, relabelled, changed: drawn in the colours of the
bird's-eye pictures, where a lost obstacle is red), then the rate per category. Right, the
paper's count metric: per category and size, the share of pairs whose count of that
category fell, stayed or rose. A campaign whose obstacles merge keeps its counts (all
"same" on the right) and still shows its violations on the left.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.campaign import CampaignResult
from pytest_metamorphic.core.campaign.results import FATE_ORDER
from pytest_metamorphic.core.files import write_atomically
from pytest_metamorphic.core.intervals import wilson

__all__ = ["CHART_NAME", "FATE_COLORS", "ChartColumn", "chart_columns", "write_chart"]

CHART_NAME = "campaign.png"
_OUTCOMES = ("fewer", "equal", "more")
_COUNT_COLORS = {"fewer": "#d62728", "equal": "#bbbbbb", "more": "#1f77b4"}
_COUNT_LABELS = {"fewer": "fewer in O'", "equal": "same", "more": "more in O'"}
# The bird's-eye picture's colours (reports.birdseye.COLORS): hidden obstacles are red,
# follow-up boxes orange, source boxes blue, minimal points magenta, unjudged grey.
FATE_COLORS = {
    "lost": "#e00000",
    "merged": "#d400ff",
    "split": "#e07b00",
    "relabelled": "#1f5fbf",
    "changed": "#6b0000",
    "other": "#9a9a9a",
}
_CATEGORY_COLOR = "#555555"


@dataclass(frozen=True)
class ChartColumn:
    """One column of the count chart: a category at one size."""

    category: str
    size: int
    position: float
    percentages: tuple[float, float, float]  # fewer, same, more; sum 100 (or all 0)


def chart_columns(result: CampaignResult) -> list[ChartColumn]:
    """The count chart's columns: one group per category (sizes side by side), a gap
    between. Without categories there is one group, "all", of ``|O|`` vs ``|O'|``."""
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


@dataclass(frozen=True)
class ViolationBar:
    """One bar of the violation chart: all pairs (``category`` None) or one category's."""

    size: int
    category: str | None
    position: float
    rate: float  # percent
    low: float
    high: float
    k: int
    n: int
    fates: tuple[tuple[str, float], ...]  # (fate, percent of pairs), bottom up


def violation_bars(result: CampaignResult) -> list[ViolationBar]:
    """Per size: the rate over all pairs (split by fate), then each category's."""
    categories = sorted({c for counts in result.sizes.values() for c in counts.categories})
    bars = []
    width = 1 + len(categories)
    for group, (size, counts) in enumerate(sorted(result.sizes.items())):
        base = group * (width + 1)
        rate = wilson(counts.violations, counts.pairs)
        order = [f for f in FATE_ORDER if f in counts.fates] + sorted(
            f for f in counts.fates if f not in FATE_ORDER
        )
        if counts.violations and not counts.fates:
            order, shares = ["other"], {"other": counts.violations}
        else:
            shares = counts.fates
        fates = tuple((fate, 100.0 * shares[fate] / counts.pairs) for fate in order if counts.pairs)
        bars.append(_bar(size, None, base, rate, fates))
        for offset, category in enumerate(categories, start=1):
            bars.append(_bar(size, category, base + offset, counts.category_rate(category), ()))
    return bars


def _bar(size: int, category: str | None, position: float, rate: Any, fates: Any) -> ViolationBar:
    if rate.value is None:
        return ViolationBar(size, category, position, 0.0, 0.0, 0.0, 0, 0, fates)
    return ViolationBar(
        size,
        category,
        position,
        100.0 * rate.value,
        100.0 * rate.low,
        100.0 * rate.high,
        rate.k,
        rate.n,
        fates,
    )


def _label(result: CampaignResult) -> str:
    return str(result.header.get("size_label", "n"))


def _group_label(axes: Any, text: str, positions: list[float], *, below: int) -> None:
    """A group of bars' name, centred under them, ``below`` points under the axis."""
    axes.annotate(
        text,
        (sum(positions) / len(positions), 0),
        xycoords=("data", "axes fraction"),
        xytext=(0, -below),
        textcoords="offset points",
        ha="center",
        va="top",
        fontsize=9,
    )


def _draw_violations(axes: Any, result: CampaignResult) -> None:
    bars = violation_bars(result)
    seen: dict[str, int] = {}
    for bar in bars:
        if bar.category is None:
            bottom = 0.0
            for fate, share in bar.fates:
                colour = FATE_COLORS.get(fate, FATE_COLORS["other"])
                axes.bar(bar.position, share, bottom=bottom, color=colour, width=0.8)
                bottom += share
            for fate, _ in bar.fates:
                seen[fate] = seen.get(fate, 0) + result.sizes[bar.size].fates.get(fate, 0)
            axes.annotate(
                f"{bar.k}/{bar.n}",
                (bar.position, bar.high),
                xytext=(0, 3),
                textcoords="offset points",
                ha="center",
                fontsize=7,
            )
        else:
            axes.bar(bar.position, bar.rate, color=_CATEGORY_COLOR, width=0.8, alpha=0.55)
        if bar.n:
            axes.errorbar(
                bar.position,
                bar.rate,
                yerr=[[max(0.0, bar.rate - bar.low)], [max(0.0, bar.high - bar.rate)]],
                color="black",
                capsize=3,
                linewidth=1,
            )
    axes.set_xticks(
        [bar.position for bar in bars],
        ["all" if bar.category is None else bar.category for bar in bars],
        rotation=60,
        fontsize=7,
    )
    groups: dict[int, list[float]] = {}
    for bar in bars:
        groups.setdefault(bar.size, []).append(bar.position)
    for size, positions in groups.items():
        _group_label(axes, f"{_label(result)}={size}", positions, below=44)
    top = max([bar.high for bar in bars] + [1.0])
    axes.set_ylim(0, min(100.0, max(5.0, top * 1.2)))
    axes.set_ylabel("% of pairs violating (Wilson 95%)")
    relation = textwrap.shorten(str(result.header.get("relation", "")), 60, placeholder="...")
    axes.set_title(f"violations of {relation}", fontsize=9)
    from matplotlib.patches import Patch

    order = [f for f in FATE_ORDER if f in seen] + sorted(f for f in seen if f not in FATE_ORDER)
    handles = [
        Patch(color=FATE_COLORS.get(fate, FATE_COLORS["other"]), label=f"{fate} ({seen[fate]})")
        for fate in reversed(order)  # top of the stack first, as drawn
    ]
    handles.append(Patch(color=_CATEGORY_COLOR, alpha=0.55, label="per category"))
    axes.legend(handles=handles, loc="upper left", fontsize=7, title="violating pairs by fate")


def _draw_counts(axes: Any, result: CampaignResult) -> None:
    columns = chart_columns(result)
    names = list(dict.fromkeys(column.category for column in columns))
    positions = [column.position for column in columns]
    bottoms = [0.0] * len(columns)
    for slot, name in enumerate(_OUTCOMES):
        heights = [column.percentages[slot] for column in columns]
        axes.bar(
            positions,
            heights,
            bottom=bottoms,
            color=_COUNT_COLORS[name],
            label=_COUNT_LABELS[name],
        )
        bottoms = [b + h for b, h in zip(bottoms, heights, strict=True)]
    axes.set_xticks(positions, [str(column.size) for column in columns], fontsize=7)
    for name in names:
        _group_label(axes, name, [c.position for c in columns if c.category == name], below=24)
    label = _label(result)
    axes.set_xlabel(
        "noise points n, per category" if label == "n" else f"{label}, per category",
        labelpad=22,
    )
    axes.set_ylabel("% of source/follow-up pairs")
    axes.set_ylim(0, 100)
    axes.set_title("objects per category, O vs O' (the paper's Fig. 3)", fontsize=9)
    axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)


def write_chart(result: CampaignResult, path: Path) -> None:
    """The campaign's chart as a PNG (needs matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    categories = len({c for counts in result.sizes.values() for c in counts.categories})
    width = max(11.0, 0.32 * len(result.sizes) * (categories + 2) * 2 + 5.0)
    figure, (left, right) = plt.subplots(
        1, 2, figsize=(width, 5.0), gridspec_kw={"width_ratios": [1.0, 1.2]}
    )
    _draw_violations(left, result)
    _draw_counts(right, result)
    title = f"{result.header['campaign']}: {len(result.sources_done)} sources"
    if not result.complete:
        title += " (PARTIAL)"
    figure.suptitle(title, fontsize=11)
    figure.tight_layout()
    write_atomically(
        path, lambda p: figure.savefig(p, dpi=110, format="png"), what="the campaign chart"
    )
    plt.close(figure)
