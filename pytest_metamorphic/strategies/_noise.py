"""Follow-up strategies that perturb a LiDAR frame, for ``@metamorphic(followup=...)``.

Each strategy takes the source :class:`~pytest_metamorphic.lidar.model.frame.Frame` and draws
:class:`~pytest_metamorphic.core.engine.Followup` values: the perturbed frame plus the
perturbation itself in ``params`` (a small value object from
:mod:`pytest_metamorphic.lidar.followups.perturb` whose ``repr`` shows the injected points), so a
failure report says exactly what was done.

Noise points come from 32-bit integer seeds, which a deterministic hash maps to points.
With ``min_size``/``max_size`` (a range that can shrink) each point is one drawn seed
(``st.lists(st.integers(0, 2**32 - 1))``; a point drawn as four floats would exhaust
Hypothesis' choice budget after ~230), and shrinking deletes points one by one: a failure
caused by one stray point shrinks to that single point. With ``n=`` (an exact count, the
paper's 10, 100, 1000) nothing can be deleted, so at most 10 chunk seeds are drawn, each
giving n/10 consecutive point seeds: two follow-ups of 1000 points fit the budget, and the
engine reduces a violation to the points that matter.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.perturb import (
    SEED_BITS,
    DropPoints,
    DuplicatePoints,
    NoiseInsideROI,
    NoiseOutsideROI,
    PermutePoints,
    RotateAboutSensor,
)
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.roi import ROI

__all__ = [
    "dropped_points",
    "duplicated_points",
    "noise_inside_roi",
    "noise_outside_roi",
    "permuted_points",
    "rotated_frames",
]

_SEEDS = st.integers(0, 2**SEED_BITS - 1)


def _check_frame(frame: Any) -> Frame:
    if not isinstance(frame, Frame):
        raise InvalidArgument(
            f"frame must be a Frame (the source input), got {type(frame).__name__}; use "
            "followup=lambda frame: noise_outside_roi(frame, ...)"
        )
    return frame


def _sizes(n: Any, min_size: Any, max_size: Any, default_max: int = 1000) -> tuple[int, int]:
    """Resolve ``n`` (exact) or ``min_size``/``max_size`` (a range) to list bounds."""
    for name, value in (("n", n), ("min_size", min_size), ("max_size", max_size)):
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise InvalidArgument(f"{name}={value!r} must be a non-negative int")
    if n is not None:
        if min_size is not None or max_size is not None:
            raise InvalidArgument(
                f"pass n={n} for an exact count or min_size/max_size for a range, not both"
            )
        return n, n
    low = 1 if min_size is None else min_size
    high = max(default_max, low) if max_size is None else max_size
    if high < low:
        raise InvalidArgument(f"max_size={high} must be >= min_size={low}")
    return low, high


CHUNKS = 10
"""Exact-size noise is drawn as at most this many chunk seeds (``chunked_seeds``)."""


def chunked_seeds(n: int, *, unique: bool = True) -> st.SearchStrategy[tuple[list[int], list[int]]]:
    """Exactly ``n`` seeds, drawn as ``min(n, CHUNKS)`` chunk seeds of ``ceil(n / chunks)``
    consecutive seeds each: ``(seeds, chunk seeds)``.

    Hypothesis' choice budget holds about a thousand integers per test case, so one seed
    per point cannot give two follow-ups of 1000 points (the test fails its
    ``large_base_example`` health check), and each drawn integer costs ~30 us. Shrinking
    simplifies the chunk seeds; the engine's own reduction then finds the few points that
    matter. The ``n`` seeds are always distinct (so are the points): with ``unique`` the
    chunk seeds differ; without it a repeated chunk seed is moved to the next free one.
    """
    chunks = min(n, CHUNKS)
    if chunks == 0:
        return st.just(([], []))
    size = -(-n // chunks)
    top = 2**SEED_BITS // size - 1

    def expand(values: list[int]) -> tuple[list[int], list[int]]:
        # A chunk seed drawn twice (shrinking sends them all to 0) would give the same
        # points twice, and a "minimal set" of one point twice: a repeated chunk moves to
        # the next free base instead. Distinct chunks keep their seeds, so draws without
        # repeats are the same as before.
        bases: list[int] = []
        taken: set[int] = set()
        for value in values:
            base = value
            while base in taken:
                base = (base + 1) % (top + 1)
            taken.add(base)
            bases.append(base)
        return [b * size + j for b in bases for j in range(size)][:n], values

    chunk_seeds = st.lists(st.integers(0, top), min_size=chunks, max_size=chunks, unique=unique)
    return chunk_seeds.map(expand)


def _seed_lists(n: int | None, bounds: tuple[int, int]) -> st.SearchStrategy[list[int]]:
    if n is not None:
        return chunked_seeds(n).map(lambda drawn: drawn[0])
    # Distinct seeds, so n points are n distinct points (Hypothesis likes to repeat values);
    # one per point, so that shrinking deletes points one by one.
    return st.lists(_SEEDS, min_size=bounds[0], max_size=bounds[1], unique=True)


def _followups(
    frame: Frame,
    seeds: st.SearchStrategy[list[int]],
    build: Callable[[list[int]], Any],
    extra: dict[str, Any],
) -> st.SearchStrategy[Followup]:
    def make(values: list[int]) -> Followup:
        perturbation = build(values)
        return Followup(perturbation.apply(frame), params={**perturbation.params(), **extra})

    return seeds.map(make)


def noise_outside_roi(
    frame: Frame,
    n: int | None = None,
    *,
    min_size: int | None = None,
    max_size: int | None = None,
    roi: ROI | None = None,
    max_range: float = 120.0,
    margin_cells: int = 1,
) -> st.SearchStrategy[Followup]:
    """The paper's MR1 follow-up: the frame plus points scattered outside the ROI.

    Parameters
    ----------
    frame : Frame
      The source frame; its ROI is used unless ``roi`` is given.
    n : int, optional
      Exactly this many points (the paper used 10, 100 and 1000), drawn as at most 10
      chunk seeds of consecutive point seeds (one seed per point would not fit two
      follow-ups of 1000 points in Hypothesis' choice budget). A violation's points are
      then reduced by the engine, not by Hypothesis.
    min_size, max_size : int, optional
      Otherwise, a number of points in this range, one seed per point, shrinking toward
      ``min_size`` by deleting points (default 1 to 1000, the paper's largest n).
    roi : ROI, optional
    max_range : float
      Sensor range in metres: (x, y) are uniform over this disk minus the ROI.
    margin_cells : int
      Free bitmap cells kept between the points and the ROI (>= 1).

    Returns
    -------
    strategy of Followup
      ``Followup(frame_with_noise, params={"n": ..., "noise_outside_roi":
      NoiseOutsideROI(...), "max_range": ..., "margin_cells": ...})``; z and intensity
      are uniform over the frame's own ranges.
    """
    frame = _check_frame(frame)
    bounds = _sizes(n, min_size, max_size)
    # Fail now, not inside Hypothesis: no ROI, bad range or margin, empty frame, no room.
    # The recipe is the frame's, shared by every follow-up drawn from this strategy.
    noise = NoiseOutsideROI.prepare(frame, roi=roi, max_range=max_range, margin_cells=margin_cells)
    noise.from_seeds([0])
    extra = {"max_range": float(max_range), "margin_cells": int(margin_cells)}
    return _followups(frame, _seed_lists(n, bounds), noise.from_seeds, extra)


def noise_inside_roi(
    frame: Frame,
    n: int | None = None,
    *,
    min_size: int | None = None,
    max_size: int | None = None,
    roi: ROI | None = None,
    obstacles: Sequence[Box] | None = None,
    clearance: float = 1.0,
    max_range: float = 120.0,
    margin_cells: int = 1,
) -> st.SearchStrategy[Followup]:
    """The frame plus points inside the ROI, at least ``clearance`` metres from obstacles.

    ``obstacles`` defaults to the frame's ground-truth boxes; other arguments as in
    :func:`noise_outside_roi`.
    """
    frame = _check_frame(frame)
    bounds = _sizes(n, min_size, max_size)
    options: dict[str, Any] = {
        "roi": roi,
        "obstacles": obstacles,
        "clearance": clearance,
        "max_range": max_range,
        "margin_cells": margin_cells,
    }
    noise = NoiseInsideROI.prepare(frame, **options)
    noise.from_seeds([0])
    extra = {"clearance": float(clearance), "max_range": float(max_range)}
    return _followups(frame, _seed_lists(n, bounds), noise.from_seeds, extra)


def _index_lists(frame: Frame, min_size: Any, max_size: Any) -> st.SearchStrategy[list[int]]:
    low, high = _sizes(None, min_size, max_size, default_max=100)
    count = len(frame.cloud)
    if count == 0:
        raise InvalidArgument(f"{frame!r} has no points to pick")
    if low > count:
        raise InvalidArgument(f"min_size={low} exceeds the frame's {count} points")
    return st.lists(st.integers(0, count - 1), min_size=low, max_size=min(high, count), unique=True)


def dropped_points(
    frame: Frame, *, min_size: int | None = None, max_size: int | None = None
) -> st.SearchStrategy[Followup]:
    """The frame without a few of its points: 1 to 100 distinct indices by default,
    shrinking toward fewer (and toward the first points)."""
    frame = _check_frame(frame)
    indices = _index_lists(frame, min_size, max_size)
    return _followups(
        frame, indices, lambda values: DropPoints(np.array(values, dtype=np.intp)), {}
    )


def duplicated_points(
    frame: Frame, *, min_size: int | None = None, max_size: int | None = None
) -> st.SearchStrategy[Followup]:
    """The frame with copies of a few of its points appended (1 to 100 distinct indices
    by default), shrinking toward fewer."""
    frame = _check_frame(frame)
    indices = _index_lists(frame, min_size, max_size)
    return _followups(
        frame, indices, lambda values: DuplicatePoints(np.array(values, dtype=np.intp)), {}
    )


def permuted_points(frame: Frame) -> st.SearchStrategy[Followup]:
    """The frame with all points reordered by a seeded random permutation."""
    frame = _check_frame(frame)

    def make(seed: int) -> Followup:
        permutation = PermutePoints(seed)
        return Followup(permutation.apply(frame), params=permutation.params())

    return _SEEDS.map(make)


def rotated_frames(
    frame: Frame, *, min_degrees: float = -180.0, max_degrees: float = 180.0
) -> st.SearchStrategy[Followup]:
    """The frame, its ROI and its boxes turned together about the sensor's vertical axis.

    Angles are drawn in tenths of a degree within ``[min_degrees, max_degrees]`` and shrink
    toward 0 (when the range contains it).
    """
    frame = _check_frame(frame)
    for name, value in (("min_degrees", min_degrees), ("max_degrees", max_degrees)):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise InvalidArgument(f"{name}={value!r} must be a finite number of degrees")
    if max_degrees < min_degrees:
        raise InvalidArgument(f"max_degrees={max_degrees} must be >= min_degrees={min_degrees}")
    if frame.roi is not None and not callable(getattr(frame.roi, "rotated", None)):
        raise InvalidArgument(f"the frame's roi ({type(frame.roi).__name__}) has no rotated()")
    low, high = math.ceil(min_degrees * 10), math.floor(max_degrees * 10)
    if high < low:
        raise InvalidArgument(f"no tenth of a degree lies in [{min_degrees}, {max_degrees}]")

    def make(tenths: int) -> Followup:
        rotation = RotateAboutSensor(math.radians(tenths / 10.0))
        return Followup(rotation.apply(frame), params=rotation.params())

    return st.integers(low, high).map(make)
