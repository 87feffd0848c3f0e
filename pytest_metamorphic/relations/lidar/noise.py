"""MR1 and its relatives: noise added outside the ROI, points removed outside it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.followups.perturb import (
    DropPoints,
    NoiseOutsideROI,
    PreparedNoise,
)
from pytest_metamorphic.lidar.judging.scope import (
    ScopeLike,
    as_scope,
    judged_count,
    judged_equal,
    obstacles_kept,
)
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.relations.lidar._common import _check_size, _frame, lidar_relation
from pytest_metamorphic.strategies import noise_outside_roi
from pytest_metamorphic.strategies._noise import chunked_seeds

__all__ = [
    "DEFAULT_CLEARANCE",
    "DEFAULT_NOISE",
    "NoiseSize",
    "mr1_cardinality",
    "mr1_subset",
    "outside_noise_invariance",
    "outside_removal",
]


DEFAULT_CLEARANCE = 5.0
"""Metres outside the ROI within which :func:`outside_removal` keeps points (ROI scope)."""

DEFAULT_NOISE = 1000
"""The paper's largest setting; shrinking then finds how few of them matter."""

NoiseSize = int | Sequence[int] | None


def _noise(n: NoiseSize, max_size: int) -> Any:
    """Follow-up strategy: noise outside the ROI, as many points as ``n`` says; not
    applicable, with the reason, where the ROI leaves no room outside it within the
    sensor's range (an ROI over the whole sweep: nothing to test, and said so)."""
    sizes = None if n is None else (n,) if isinstance(n, int) else tuple(n)

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        noise = NoiseOutsideROI.prepare(frame)  # no ROI, empty frame: fail now
        if len(noise.cells) == 0:
            return st.just(Followup.not_applicable(frame, _NO_ROOM.format(noise.max_range)))
        noise.from_seeds([0])
        if sizes is None:
            return noise_outside_roi(frame, min_size=1, max_size=max_size)
        return st.sampled_from(sizes).flatmap(lambda size: _chunked_noise(frame, noise, size))

    return followup


_NO_ROOM = (
    "noise outside the ROI: the ROI leaves no room outside it within {:g} m of the sensor "
    "(it covers the whole sweep), so there is nothing to add the noise to"
)


def _chunked_noise(
    frame: Frame, noise: PreparedNoise[NoiseOutsideROI], n: int
) -> st.SearchStrategy[Followup]:
    """Exactly ``n`` noise points from chunk seeds (``chunked_seeds``; these may repeat,
    as they always have here, so that the relations draw what they drew before)."""

    def make(drawn: tuple[list[int], list[int]]) -> Followup:
        seeds, chunks = drawn
        points = noise.from_seeds(seeds)
        return Followup(points.apply(frame), params={**points.params(), "chunks": chunks})

    return chunked_seeds(n, unique=False).map(make)


def _check_noise(n: NoiseSize, max_size: int) -> None:
    _check_size(max_size, "max_size")
    if n is None or isinstance(n, int):
        _check_size(n, "n", allow_none=True)
        return
    if isinstance(n, (str, bytes)) or not isinstance(n, Sequence) or not n:
        raise InvalidArgument(f"n={n!r} must be an int, a non-empty sequence of ints, or None")
    for size in n:
        _check_size(size, "n")


def mr1_subset(
    *,
    n: NoiseSize = DEFAULT_NOISE,
    max_size: int = 1000,
    matcher: Matcher | None = None,
    scope: ScopeLike = "roi",
    name: str = "MR1: noise outside ROI => O subset of O'",
) -> MetamorphicRelation:
    """The paper's MR1: points added outside the ROI must not remove any obstacle.

    Parameters
    ----------
    n : int, sequence of int, or None
        Noise points per follow-up: ``n`` (default 1000, the paper's largest setting);
        or one of several sizes (e.g. :data:`PAPER_NOISE_SIZES`, shrinking toward the
        first); the engine's reduction then finds the few points that matter. With
        None, between 1 and ``max_size`` points (Hypothesis then mostly draws a
        handful, which rarely land next to the ROI).
    max_size : int
        The largest count when ``n`` is None.
    matcher : Matcher, optional
        When a follow-up obstacle counts as the same as a source one. Default: same
        label and bird's-eye IoU >= 0.5 (KITTI's threshold for people), so an obstacle
        that moves a little is kept but one that vanishes or changes class is not.
    scope : "roi", "all" or ObstacleScope
        Which source obstacles must be kept: by default those whose footprint lies wholly
        inside the ROI (:mod:`pytest_metamorphic.lidar.judging.scope`), so a detector
        that reports the whole sweep is not blamed for noise changing obstacles off the
        road; those changes are counted as information. ``"all"`` judges every obstacle.
    """
    _check_noise(n, max_size)
    relation = obstacles_kept(matcher=matcher, scope=scope)
    return lidar_relation(name, _noise(n, max_size), relation)


def mr1_cardinality(
    *,
    n: NoiseSize = DEFAULT_NOISE,
    max_size: int = 1000,
    scope: ScopeLike = "roi",
    name: str = "MR1 (paper's check): noise outside ROI => |O| <= |O'|",
) -> MetamorphicRelation:
    """MR1 as Zhou & Sun checked it: the follow-up has at least as many obstacles.

    ``n``, ``max_size`` and ``scope`` as for :func:`mr1_subset`; the judged obstacles of
    each side are counted.
    """
    _check_noise(n, max_size)
    return lidar_relation(name, _noise(n, max_size), judged_count("<=", scope=scope))


def outside_noise_invariance(
    *,
    n: NoiseSize = DEFAULT_NOISE,
    max_size: int = 1000,
    scope: ScopeLike = "roi",
    matcher: Matcher | None = None,
    min_points: int = 0,
    name: str = "noise outside ROI => O == O'",
) -> MetamorphicRelation:
    """Points outside the ROI change nothing judged: the judged obstacles are equal.

    ``n``, ``max_size`` and ``scope`` as for :func:`mr1_subset`. Every judged obstacle of
    either output needs an identical one in the other (order aside); with
    ``scope="all"`` the two outputs must be equal exactly, order included. With a
    ``matcher``, "identical" is "matched", both ways (a detector whose outputs jitter),
    and obstacles supported by fewer than ``min_points`` returns (``Box.points``) are not
    judged (:func:`~pytest_metamorphic.lidar.judging.scope.judged_equal`).
    """
    _check_noise(n, max_size)
    relation = judged_equal(scope=scope, matcher=matcher, min_points=min_points)
    return lidar_relation(name, _noise(n, max_size), relation)


def outside_removal(
    *,
    method: Literal["raster", "exact"] = "raster",
    max_size: int = 1000,
    scope: ScopeLike = "roi",
    clearance: float | None = None,
    matcher: Matcher | None = None,
    min_points: int = 0,
    name: str = "outside-ROI points removed => O == O'",
) -> MetamorphicRelation:
    """Removing points outside the ROI changes nothing judged.

    The follow-up drops either every point outside the ROI or up to ``max_size`` of them
    (a drawn subset, shrinking toward one point). ``method`` decides "outside" the way
    the system under test does (Apollo: the rasterised bitmap). ``scope`` as for
    :func:`outside_noise_invariance`.

    ``clearance`` (metres): only points at least this far outside the ROI are dropped.
    A detector that sees the whole sweep legitimately uses the points next to the ROI:
    its ground estimate under an obstacle at the road's edge looks a few metres around
    it, and an object straddling the edge is one cluster. Removing that context changes
    judged obstacles without any fault, unlike adding sparse noise there. The default is
    5 m with the ROI scope (beyond the reference ground window's 3.5 m) and 0 with
    ``scope="all"``, for ROI-first stacks, where no outside point may matter.
    ``matcher`` and ``min_points`` as for :func:`outside_noise_invariance`.
    """
    chosen = as_scope(scope)
    relation = judged_equal(scope=chosen, matcher=matcher, min_points=min_points)
    if method not in ("raster", "exact"):
        raise InvalidArgument(f"method={method!r} must be 'raster' or 'exact'")
    _check_size(max_size, "max_size")
    if clearance is None:
        clearance = 0.0 if chosen.everything else DEFAULT_CLEARANCE
    if isinstance(clearance, bool) or not isinstance(clearance, (int, float)):
        raise InvalidArgument(f"clearance={clearance!r} must be a number of metres >= 0")
    if not (math.isfinite(clearance) and clearance >= 0):
        raise InvalidArgument(f"clearance={clearance!r} must be a number of metres >= 0")

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        if frame.roi is None:
            raise InvalidArgument(f"{frame!r} has no ROI; outside_removal needs frame.roi")
        outside = np.flatnonzero(~frame.roi.contains(frame.cloud.points, method=method))
        if clearance > 0 and len(outside):
            far = frame.roi.boundary_distance(frame.cloud.points[outside, :2]) >= clearance
            outside = outside[far]
        if len(outside) == 0:
            return st.just(Followup(frame, params={"dropped": 0}))

        def drop(choice: tuple[bool, list[int]]) -> Followup:
            everything, picks = choice
            rows = outside if everything else outside[np.asarray(picks, dtype=np.intp)]
            removal = DropPoints(rows)
            params = {
                **removal.params(),
                "all_outside": everything,
                "method": method,
                "clearance": clearance,
            }
            return Followup(removal.apply(frame), params=params)

        picks = st.lists(
            st.integers(0, len(outside) - 1),
            min_size=1,
            max_size=min(max_size, len(outside)),
            unique=True,
        )
        return st.tuples(st.booleans(), picks).map(drop)

    return lidar_relation(name, followup, relation)
