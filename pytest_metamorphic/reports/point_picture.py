"""The picture of a component's violation: the source's returns coloured by the label or
cluster the component gave them, the returns that changed marked, and what the follow-up
added (the minimal points as stars).

Two panels seen from above, like :mod:`.birdseye`'s: the whole sweep, and a close-up on the
changed returns. Ground / not-ground labels are drawn brown / blue; clusters in a cycle of
colours, noise in light grey; a changed return is a red cross.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["draw_point_violation"]

_SIZE = (13.0, 6.0)
_DPI = 100
_MAX_POINTS = 60_000  # drawn returns per panel (a sweep thinned evenly past this)
_CLUSTER_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf")
_LABEL_COLOURS = {0: "#4c72b0", 1: "#a0785a"}  # not ground, ground


def _colours(labels: NDArray[np.int64], kind: str) -> list[str]:
    if kind == "labels":
        cycle = list(_CLUSTER_COLOURS)
        return [_LABEL_COLOURS.get(int(v), cycle[int(v) % len(cycle)]) for v in labels]
    return [
        "#d0d0d0" if v < 0 else _CLUSTER_COLOURS[int(v) % len(_CLUSTER_COLOURS)] for v in labels
    ]


def draw_point_violation(
    path: str | os.PathLike[str],
    *,
    source: Any,
    labels: NDArray[np.int64],
    kind: str,
    changed: Sequence[int],
    added: Any = None,
    minimal: Any = None,
    title: str = "",
) -> None:
    """Draw a point-by-point violation and save it as a PNG.

    Parameters
    ----------
    path : path-like
    source : Frame
        The source sweep (its returns and ROI).
    labels : (n,) int
        The component's output on the source, one per return.
    kind : {"labels", "clusters"}
    changed : sequence of int
        Source returns whose label or cluster changed.
    added, minimal : (k, >=2) array_like, optional
        The follow-up's added returns, and the minimal ones among them (stars).
    title : str
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    xyz = np.asarray(source.cloud.xyz, dtype=np.float64)
    labels = np.asarray(labels, dtype=np.int64)
    changed_rows = np.asarray(
        sorted({int(i) for i in changed if 0 <= int(i) < len(xyz)}), dtype=np.intp
    )
    step = max(1, -(-len(xyz) // _MAX_POINTS))
    shown = np.arange(0, len(xyz), step)
    figure = Figure(figsize=_SIZE, dpi=_DPI)
    FigureCanvasAgg(figure)
    overview, zoom = figure.subplots(1, 2)
    extra = [
        np.asarray(p, dtype=np.float64)[:, :2] for p in (added, minimal) if p is not None and len(p)
    ]
    for ax, size in ((overview, 1.0), (zoom, 8.0)):
        for polygon in getattr(getattr(source, "roi", None), "polygons", ()):
            ring = np.asarray(polygon, dtype=np.float64)
            ax.fill(ring[:, 0], ring[:, 1], color="#e8f0d8", zorder=0)
        ax.scatter(
            xyz[shown, 0],
            xyz[shown, 1],
            s=0.3 * size,
            c=_colours(labels[shown], kind),
            linewidths=0,
        )
        if added is not None and len(added):
            points = np.asarray(added, dtype=np.float64)
            ax.scatter(points[:, 0], points[:, 1], s=0.6 * size, c="#777777", marker=".")
        if minimal is not None and len(minimal):
            points = np.asarray(minimal, dtype=np.float64)
            ax.scatter(
                points[:, 0],
                points[:, 1],
                s=60,
                c="#ffbf00",
                marker="*",
                edgecolors="black",
                zorder=5,
            )
        if len(changed_rows):
            ax.scatter(
                xyz[changed_rows, 0],
                xyz[changed_rows, 1],
                s=8 * size**0.5,
                c="red",
                marker="x",
                zorder=4,
            )
        ax.plot([0], [0], marker="^", color="black")
        ax.set_aspect("equal")
    overview.set_title(f"{len(changed_rows)} returns changed (red crosses)", fontsize=9)
    focus = (
        xyz[changed_rows, :2]
        if len(changed_rows)
        else (np.concatenate(extra) if extra else xyz[shown, :2])
    )
    if len(focus):
        low, high = focus.min(axis=0), focus.max(axis=0)
        pad = max(2.0, 0.15 * float(np.max(high - low)))
        zoom.set_xlim(low[0] - pad, high[0] + pad)
        zoom.set_ylim(low[1] - pad, high[1] + pad)
    zoom.set_title("close-up on the changed returns", fontsize=9)
    figure.suptitle(title[:160], fontsize=9)
    figure.savefig(os.fspath(path))
