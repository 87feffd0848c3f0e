"""A bird's-eye picture of AEB runs: road and lanes, the car's path coloured by braking
stage, the pedestrian's path, where it became relevant and where they collided.

One panel per run (e.g. the source and the violating follow-up), drawn in road-aligned
world coordinates and cropped to the stretch from the car's start to past the collision
point. Needs matplotlib (the ``plot`` extra).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pytest_metamorphic.driving.kinematics import SimulationResult
from pytest_metamorphic.driving.kinematics.geometry import _corners

__all__ = ["Run", "draw_aeb_runs"]

_STAGE_COLOURS = {"off": "#888888", "FCW": "#e0b000", "PB1": "#f08000", "PB2": "#e04000",
                  "FB": "#c00000"}  # fmt: skip
_BEYOND = 15.0  # metres of road drawn past the collision point


@dataclass(frozen=True)
class Run:
    """One panel: a label, the run, and when the pedestrian became relevant (if known)."""

    label: str
    result: SimulationResult
    relevant_time: float | None = None


def _polygon(ax: Any, corners: Any, **style: Any) -> None:
    points = np.asarray([*list(corners), corners[0]])
    ax.plot(points[:, 0], points[:, 1], **style)


def _draw(ax: Any, run: Run) -> None:
    result = run.result
    scenario = result.scenario
    road = scenario.road
    start = scenario.ego_start_s - scenario.vehicle.length - 2.0
    stop = min(scenario.conflict_s + _BEYOND, road.length)
    s = np.linspace(max(start, 0.0), stop, 200)
    # Kerbs solid black, lane lines (and the edges of cycle/parking lanes) dashed grey.
    bounds = [road.lane_bounds(lane)[0] for lane in range(road.lanes)]
    bounds += [road.lane_bounds(road.lanes - 1)[1], -road.width / 2, road.width / 2]
    for d in sorted({round(d, 6) for d in bounds}):
        edge = road.to_world(s, np.full_like(s, d))
        outer = abs(abs(d) - road.width / 2) < 1e-9
        ax.plot(edge[:, 0], edge[:, 1], color="black" if outer else "#aaaaaa",
                lw=1.5 if outer else 0.8, ls="-" if outer else "--")  # fmt: skip
    offset = scenario.ego_offset
    # The car's bumper path, one line per braking stage (the steps each stage was active).
    if len(result.positions) > 1:
        path = road.to_world(result.positions, np.full_like(result.positions, offset))
        starts = [(0, "off")] + [
            (int(np.searchsorted(result.times, t)), name) for t, name in result.stages
        ]
        ends = [start for start, _ in starts[1:]] + [len(path) - 1]
        for (first, name), last in zip(starts, ends, strict=True):
            if last > first:
                ax.plot(path[first : last + 1, 0], path[first : last + 1, 1],
                        color=_STAGE_COLOURS.get(name, "#888888"), lw=3)  # fmt: skip
    for stage_start, name in result.stages:
        k = int(np.searchsorted(result.times, stage_start))
        if k < len(result.positions):
            x, y, _ = road.point(float(result.positions[k]), offset)
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(0, 8), fontsize=7,
                        color=_STAGE_COLOURS.get(name, "black"), ha="center")  # fmt: skip
    _car(ax, scenario, scenario.ego_start_s, color="#4060c0", ls=":", lw=1)
    _car(ax, scenario, result.ego_s, color="#4060c0", lw=2)
    for parked in scenario.obstructions():
        x, y, heading = road.point(parked.s, parked.d)
        corners = _corners(x, y, heading, parked.footprint.length, parked.footprint.width)
        _polygon(ax, corners, color="#606060", lw=1)
    motion = scenario.pedestrian()
    times = np.linspace(0.0, result.end_time, 60)
    ps, pd = motion.road_position(times)
    walk = road.to_world(np.asarray(ps), np.asarray(pd))
    ax.plot(walk[:, 0], walk[:, 1], color="#20a020", lw=1.5, label="pedestrian path")
    ax.plot(*walk[-1], "o", color="#20a020", ms=6)
    if run.relevant_time is not None:
        rs, rd = motion.road_position(run.relevant_time)
        x, y, _ = road.point(float(rs), float(rd))
        ax.plot(x, y, "^", color="#20a020", ms=8)
        ax.annotate(f"relevant t={run.relevant_time:.2f} s", (x, y), textcoords="offset points",
                    xytext=(4, -12), fontsize=7, color="#207020")  # fmt: skip
    if result.collision is not None:
        cs, cd = motion.road_position(result.collision.time)
        x, y, _ = road.point(float(cs), float(cd))
        ax.plot(x, y, "X", color="red", ms=12)
        where: str = result.collision.location
        if result.collision.side:
            where = f"{result.collision.side} {where}"
        ax.annotate(f"{where} impact {result.collision.impact_speed_kmh:.0f} km/h", (x, y),
                    textcoords="offset points", xytext=(6, 6), fontsize=8, color="red")  # fmt: skip
    ax.set_aspect("equal")
    ax.set_title(f"{run.label}: {result.describe()}", fontsize=9)


def _car(ax: Any, scenario: Any, front_s: float, **style: Any) -> None:
    road, vehicle = scenario.road, scenario.vehicle
    centre = front_s - vehicle.length / 2
    x, y, heading = road.point(centre, scenario.ego_offset)
    _polygon(ax, _corners(x, y, heading, vehicle.length, vehicle.width), **style)


def draw_aeb_runs(path: str | os.PathLike[str], runs: Sequence[Run], *, title: str = "") -> Path:
    """Write a PNG with one panel per run; returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    figure, axes = plt.subplots(len(runs), 1, figsize=(12, 3.2 * len(runs)), squeeze=False)
    try:
        for ax, run in zip(axes[:, 0], runs, strict=True):
            _draw(ax, run)
        handles = [
            Line2D([], [], color=colour, lw=3, label=f"car: {stage}")
            for stage, colour in _STAGE_COLOURS.items()
        ]
        figure.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8)
        if title:
            figure.suptitle(title, fontsize=10)
        figure.tight_layout(rect=(0, 0.05, 1, 0.97))
        target = Path(path)
        target.parent.mkdir(parents=True, exist_ok=True)
        figure.savefig(target, dpi=110)
    finally:
        plt.close(figure)
    return target
