"""Bird's-eye pictures of LiDAR violations: what was hidden, and by which points.

:func:`draw_birdseye` writes one PNG with two panels, the whole sweep on the left and a
close-up of the hidden obstacle(s) on the right. Both show the ROI (green), the source
cloud (grey), the injected points (orange), the *minimal* points (large magenta stars),
the source obstacles O (blue outlines), the follow-up obstacles O' (dashed orange) and the
hidden obstacles (filled red). Drawn with matplotlib's object API on an Agg canvas (no
pyplot, no global state); matplotlib is an optional extra (``pytest-metamorphic[plot]``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["COLORS", "Picture", "draw_birdseye"]

COLORS = {
    "roi": "#d9f2d9",
    "roi_edge": "#4c9a4c",
    "cloud": "#8c8c8c",
    "injected": "#ff9900",
    "minimal": "#d400ff",
    "source_box": "#1f5fbf",
    "followup_box": "#e07b00",
    "hidden": "#e00000",
    "unjudged": "#9a9a9a",
    "hidden_points": "#6b0000",
}
_SIZE = (16.0, 8.5)  # inches
_DPI = 100
_MAX_CLOUD_POINTS = 80_000
_ZOOM_MIN_HALF_WIDTH = 6.0


@dataclass(frozen=True)
class Picture:
    """Where things were drawn, in PNG pixel coordinates ``(column, row)`` from the top left.

    Attributes
    ----------
    path : Path
    size : (int, int)
        Width and height in pixels.
    hidden : list of (float, float)
        Centre of each hidden obstacle in the close-up panel.
    minimal : list of (float, float)
        Each minimal point in the overview panel.
    sensor : (float, float)
        The sensor (origin) in the overview panel.
    unjudged : list of (float, float)
        Centre of each obstacle outside the relation's scope in the overview panel.
    """

    path: Path
    size: tuple[int, int]
    hidden: list[tuple[float, float]] = field(default_factory=list)
    minimal: list[tuple[float, float]] = field(default_factory=list)
    sensor: tuple[float, float] = (0.0, 0.0)
    unjudged: list[tuple[float, float]] = field(default_factory=list)


def _xy(points: Any, name: str) -> NDArray[np.float64]:
    if points is None:
        return np.empty((0, 2))
    array = np.asarray(points, dtype=np.float64)
    if array.size == 0:
        return np.empty((0, 2))
    if array.ndim != 2 or array.shape[1] < 2:
        raise InvalidArgument(f"{name} must have shape (n, >=2), got {array.shape}")
    return array[:, :2]


def _draw_boxes(ax: Any, boxes: Sequence[Any], **style: Any) -> None:
    from matplotlib.patches import Polygon

    for box in boxes:
        ax.add_patch(Polygon(box.corners_bev(), closed=True, **style))


def _layers(
    ax: Any,
    *,
    roi: Any,
    cloud: NDArray[np.float64],
    injected: NDArray[np.float64],
    minimal: NDArray[np.float64],
    source_boxes: Sequence[Any],
    followup_boxes: Sequence[Any],
    hidden: Sequence[Any],
    hidden_points: NDArray[np.float64],
    unjudged: Sequence[Any],
    scale: float,
) -> None:
    from matplotlib.patches import Polygon

    for polygon in getattr(roi, "polygons", ()):
        ax.add_patch(
            Polygon(
                polygon,
                closed=True,
                facecolor=COLORS["roi"],
                edgecolor=COLORS["roi_edge"],
                linewidth=0.8,
                zorder=1,
            )
        )
    ax.scatter(
        cloud[:, 0],
        cloud[:, 1],
        s=0.4 * scale,
        c=COLORS["cloud"],
        linewidths=0,
        rasterized=True,
        zorder=2,
    )
    if len(injected):
        ax.scatter(
            injected[:, 0],
            injected[:, 1],
            s=6 * scale,
            c=COLORS["injected"],
            linewidths=0,
            zorder=3,
            label=f"injected points ({len(injected)})",
        )
    _draw_boxes(
        ax, unjudged, facecolor=COLORS["unjudged"], alpha=0.35, hatch="///", edgecolor="none",
        zorder=4,
    )  # fmt: skip
    _draw_boxes(ax, hidden, facecolor=COLORS["hidden"], alpha=0.55, edgecolor="none", zorder=4)
    _draw_boxes(ax, hidden, facecolor="none", edgecolor=COLORS["hidden"], linewidth=3.0, zorder=6)
    _draw_boxes(
        ax,
        source_boxes,
        facecolor="none",
        edgecolor=COLORS["source_box"],
        linewidth=1.2,
        zorder=5,
    )
    _draw_boxes(
        ax,
        followup_boxes,
        facecolor="none",
        edgecolor=COLORS["followup_box"],
        linewidth=1.2,
        linestyle="--",
        zorder=5,
    )
    ax.scatter([0.0], [0.0], marker="^", s=80, c="black", zorder=7)
    if len(minimal):
        ax.scatter(
            minimal[:, 0],
            minimal[:, 1],
            marker="*",
            s=420,
            c=COLORS["minimal"],
            edgecolors="black",
            linewidths=0.8,
            zorder=10,
            label=f"minimal points ({len(minimal)})",
        )


def _overview_limits(
    cloud: NDArray[np.float64], extra: NDArray[np.float64], boxes: Sequence[Any]
) -> tuple[float, float, float, float]:
    parts = [extra, *(box.corners_bev() for box in boxes)]
    if len(cloud):
        # The sweep's far outliers would shrink everything else to a dot.
        low, high = np.percentile(cloud, [0.5, 99.5], axis=0)
        parts.append(np.stack([low, high]))
    stacked = np.concatenate([p for p in parts if len(p)] or [np.zeros((1, 2))])
    (x0, y0), (x1, y1) = stacked.min(axis=0), stacked.max(axis=0)
    x0, y0, x1, y1 = min(x0, 0.0), min(y0, 0.0), max(x1, 0.0), max(y1, 0.0)
    half = max(x1 - x0, y1 - y0) / 2 + 3.0
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    return cx - half, cx + half, cy - half, cy + half


def _zoom_limits(
    hidden: Sequence[Any], minimal: NDArray[np.float64], fallback: Sequence[Any]
) -> tuple[float, float, float, float]:
    # What the violation is about: the hidden obstacles, else the minimal points (an
    # inserted object 46 m away: the close-up showed the near obstacles instead), else
    # the source's obstacles.
    if hidden:
        corners = np.concatenate([box.corners_bev() for box in hidden])
    elif len(minimal):
        corners = minimal
    elif fallback:
        corners = np.concatenate([box.corners_bev() for box in fallback])
    else:
        corners = np.zeros((1, 2))
    (x0, y0), (x1, y1) = corners.min(axis=0), corners.max(axis=0)
    half = max(x1 - x0, y1 - y0) / 2 + 6.0
    # Bring minimal points into view when they are close to the obstacle.
    if len(minimal):
        centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
        reach = np.abs(minimal - centre).max()
        if reach <= 30.0:
            half = max(half, reach + 3.0)
    half = max(half, _ZOOM_MIN_HALF_WIDTH)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    return cx - half, cx + half, cy - half, cy + half


def _pixel(ax: Any, xy: Sequence[float], height: int) -> tuple[float, float]:
    column, row = ax.transData.transform((float(xy[0]), float(xy[1])))
    return float(column), float(height - row)


def draw_birdseye(
    path: str | os.PathLike[str],
    *,
    source: Any,
    source_boxes: Sequence[Any],
    followup_boxes: Sequence[Any],
    hidden: Sequence[Any] = (),
    unjudged: Sequence[Any] = (),
    scope: str = "",
    injected: Any = None,
    minimal: Any = None,
    title: str = "",
) -> Picture:
    """Draw a violation seen from above and save it as a PNG.

    Parameters
    ----------
    path : path-like
        The PNG to write.
    source : Frame
        The source frame: its cloud and ROI are drawn.
    source_boxes, followup_boxes : sequence of Box
        O and O'.
    hidden : sequence of Box
        Source obstacles the follow-up lost; filled red and framed by the close-up.
    unjudged : sequence of Box
        Source obstacles outside the relation's scope (e.g. mostly outside the ROI):
        hatched grey, so the judged region is visible.
    scope : str
        The relation's scope in words, for the legend (e.g. ``in ROI (>= 50% footprint)``).
    injected : (n, >=2) array_like, optional
        All injected points of the follow-up as drawn (before reduction).
    minimal : (k, >=2) array_like, optional
        The minimal points: large stars, listed in the close-up panel.
    title : str

    Returns
    -------
    Picture
        Pixel positions of the hidden obstacles, minimal points and sensor in the PNG.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    raw = getattr(getattr(source, "cloud", None), "points", None)
    cloud = _xy(raw, "source cloud")
    hidden = list(hidden)
    # The hidden obstacles' own points, from the full cloud (before thinning it out).
    inside = np.zeros(len(cloud), dtype=bool)
    for box in hidden if raw is not None else ():
        inside |= box.contains(raw)
    hidden_points = cloud[inside]
    if len(cloud) > _MAX_CLOUD_POINTS:
        step = math.ceil(len(cloud) / _MAX_CLOUD_POINTS)
        cloud = cloud[::step]
    injected_xy = _xy(injected, "injected")
    minimal_xy = _xy(minimal, "minimal")
    figure = Figure(figsize=_SIZE, dpi=_DPI)
    FigureCanvasAgg(figure)
    overview, zoom = figure.subplots(1, 2)
    layers: dict[str, Any] = {
        "roi": getattr(source, "roi", None),
        "cloud": cloud,
        "injected": injected_xy,
        "minimal": minimal_xy,
        "source_boxes": list(source_boxes),
        "followup_boxes": list(followup_boxes),
        "hidden": hidden,
        "hidden_points": hidden_points,
        "unjudged": list(unjudged),
    }
    _layers(overview, scale=1.0, **layers)
    _layers(zoom, scale=8.0, **layers)
    x0, x1, y0, y1 = _overview_limits(cloud, np.concatenate([injected_xy, minimal_xy]), hidden)
    overview.set_xlim(x0, x1)
    overview.set_ylim(y0, y1)
    zx0, zx1, zy0, zy1 = _zoom_limits(hidden, minimal_xy, source_boxes)
    zoom.set_xlim(zx0, zx1)
    zoom.set_ylim(zy0, zy1)
    close_up = (
        "close-up of the hidden obstacle"
        if hidden
        else ("close-up of the minimal points" if len(minimal_xy) else "close-up")
    )
    for ax, name in ((overview, "whole sweep"), (zoom, close_up)):
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x (m, forward)")
        ax.set_ylabel("y (m, left)")
        ax.set_title(name, fontsize=10)
        ax.grid(True, linewidth=0.3, alpha=0.5)
    _annotate(zoom, hidden, minimal_xy)
    handles = [
        Patch(
            facecolor=COLORS["roi"],
            edgecolor=COLORS["roi_edge"],
            label=f"ROI (judged: obstacles {scope})" if scope else "ROI",
        ),
        Line2D(
            [], [], color=COLORS["source_box"], label=f"O: source obstacles ({len(source_boxes)})"
        ),
        Line2D(
            [],
            [],
            color=COLORS["followup_box"],
            linestyle="--",
            label=f"O': follow-up obstacles ({len(followup_boxes)})",
        ),
        Patch(facecolor=COLORS["hidden"], alpha=0.55, label=f"hidden ({len(hidden)})"),
        Patch(
            facecolor=COLORS["unjudged"],
            alpha=0.35,
            hatch="///",
            label=f"not judged: outside the scope ({len(list(unjudged))})",
        ),
        Line2D(
            [],
            [],
            marker="o",
            linestyle="",
            color=COLORS["hidden_points"],
            label=f"points of the hidden obstacle(s) ({len(hidden_points)})",
        ),
        Line2D([], [], marker="o", linestyle="", color=COLORS["injected"], label="injected points"),
        Line2D(
            [],
            [],
            marker="*",
            linestyle="",
            markersize=14,
            color=COLORS["minimal"],
            markeredgecolor="black",
            label=f"minimal points ({len(minimal_xy)})",
        ),
    ]
    overview.legend(handles=handles, loc="upper left", fontsize=8, framealpha=0.9)
    if title:
        figure.suptitle(title, fontsize=10)
    figure.subplots_adjust(left=0.05, right=0.98, bottom=0.07, top=0.86, wspace=0.15)
    figure.canvas.draw()
    width, height = (int(v) for v in figure.canvas.get_width_height())
    picture = Picture(
        path=Path(path),
        size=(width, height),
        hidden=[_pixel(zoom, box.center[:2], height) for box in hidden],
        minimal=[_pixel(overview, xy, height) for xy in minimal_xy],
        sensor=_pixel(overview, (0.0, 0.0), height),
        unjudged=[_pixel(overview, box.center[:2], height) for box in layers["unjudged"]],
    )
    figure.savefig(path, dpi=_DPI, format="png")
    return picture


def _annotate(ax: Any, hidden: Sequence[Any], minimal: NDArray[np.float64]) -> None:
    """List the hidden obstacles and the minimal points in a corner of the close-up."""
    lines = [f"hidden: {box.describe()}" for box in hidden[:4]]
    if len(minimal):
        from pytest_metamorphic.lidar.model.obstacles import footprint_distances

        # Distance to the nearest hidden footprint, as in the violation message.
        distances = footprint_distances(minimal, hidden)
        lines.append(f"{len(minimal)} minimal point(s):")
        for (x, y), nearest in zip(minimal[:8], distances[:8], strict=False):
            away = f", {nearest:.1f} m from a hidden obstacle" if math.isfinite(nearest) else ""
            lines.append(f"  ({x:.1f}, {y:.1f}){away}")
        if len(minimal) > 8:
            lines.append(f"  ... {len(minimal) - 8} others")
    if lines:
        ax.text(
            0.02,
            0.98,
            "\n".join(lines),
            transform=ax.transAxes,
            va="top",
            ha="left",
            fontsize=8,
            family="monospace",
            zorder=20,
            bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "#999999"},
        )
