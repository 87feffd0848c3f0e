"""A picture of what a run reached of the operating domain: relations by bands.

One row per relation that counted coverage, one column per band of each dimension of
:data:`~pytest_metamorphic.lidar.judging.coverage.BANDS` (what it judged, where it placed
objects) and of the pose it drew; each cell holds how many checked follow-ups reached the
band. An empty cell in a dimension the relation varies is drawn red: the run did not test
it there. Written beside the JSON report (``--mt-report run.json`` gives
``run.coverage.png``); needs matplotlib (the ``plot`` extra).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.files import write_atomically
from pytest_metamorphic.lidar.judging.coverage import BANDS

__all__ = ["coverage_matrix", "write_coverage_chart"]

_POSE = {
    "pose pitch": tuple(f"{s}{a:g} to {s}{a + 1:g}°" for s in "-+" for a in (0, 1, 2)),
    "pose roll": tuple(f"{s}{a:g} to {s}{a + 1:g}°" for s in "-+" for a in (0, 1, 2)),
}


def coverage_matrix(
    rows: Iterable[Mapping[str, Any]],
) -> tuple[list[str], list[tuple[str, str]], list[list[int | None]]]:
    """(relations, columns as (dimension, band), counts): the JSON report's rows summed
    per relation; a count is None where the relation never varies that dimension."""
    per: dict[str, dict[str, int]] = {}
    for row in rows:
        cells = row.get("coverage") or {}
        if not cells:
            continue
        into = per.setdefault(str(row["relation"]), {})
        for cell, count in cells.items():
            into[cell] = into.get(cell, 0) + int(count)
    columns = [(dimension, band) for dimension, bands in {**BANDS, **_POSE}.items()
               for band in bands]  # fmt: skip
    relations = sorted(per)
    counts: list[list[int | None]] = []
    for name in relations:
        cells = per[name]
        varied = {cell.split(": ", 1)[0] for cell in cells}
        counts.append([
            cells.get(f"{dimension}: {band}", 0) if dimension in varied else None
            for dimension, band in columns
        ])  # fmt: skip
    return relations, columns, counts


def write_coverage_chart(rows: Iterable[Mapping[str, Any]], path: Path) -> bool:
    """The coverage picture of ``rows`` (the JSON report's) as a PNG at ``path``; False
    (nothing written) when no relation counted coverage."""
    relations, columns, counts = coverage_matrix(rows)
    if not relations:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    width = 2.0 + 0.32 * len(columns) + 0.07 * max(len(name) for name in relations)
    figure, axes = plt.subplots(figsize=(width, 1.4 + 0.32 * len(relations)))
    # 0: not varied (white), 1: varied but not reached (red), 2: reached (green).
    state = [[0 if c is None else (1 if c == 0 else 2) for c in row] for row in counts]
    axes.imshow(state, cmap=ListedColormap(["#ffffff", "#e05050", "#7cc47c"]), vmin=0,
                vmax=2, aspect="auto")  # fmt: skip
    for i, row in enumerate(counts):
        for j, count in enumerate(row):
            if count:
                axes.text(j, i, str(count), ha="center", va="center", fontsize=6)
    axes.set_yticks(range(len(relations)), [name[:70] for name in relations], fontsize=7)
    axes.set_xticks(range(len(columns)), [band for _, band in columns], fontsize=6, rotation=90)
    start = 0
    for dimension in dict.fromkeys(d for d, _ in columns):
        span = sum(1 for d, _ in columns if d == dimension)
        axes.axvline(start - 0.5, color="black", linewidth=0.6)
        axes.text(start + span / 2 - 0.5, -0.9, dimension, ha="center", va="bottom",
                  fontsize=7, clip_on=False)  # fmt: skip
        start += span
    axes.set_title("operating domain reached (red: varied, never reached)", fontsize=9, pad=18)
    figure.tight_layout()
    write_atomically(
        path, lambda p: figure.savefig(p, dpi=110, format="png"), what="the coverage picture"
    )
    plt.close(figure)
    return True
