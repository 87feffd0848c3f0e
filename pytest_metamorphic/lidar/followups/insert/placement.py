"""Where an object may be inserted: free, seen ground in the ROI, in clear view."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.insert.template import (
    ObjectTemplate,
    Placement,
    _bearing_window,
)
from pytest_metamorphic.lidar.judging.scope import ScopeLike, as_scope
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.model.obstacles import Box, footprint_distances

__all__ = ["RANGE_FACTORS", "free_ground", "free_placements"]

RANGE_FACTORS = (1.0, 0.9, 1.1, 0.8, 1.25, 1.5)
"""Ranges a template may be placed at, as multiples of the range it was seen from."""

_FREE_MARGIN = 0.5  # metres around a placed footprint that must hold no solid return
_SOLID = 0.3  # metres above the local ground that a return counts as solid
_GROUND_CELL = 1.0  # metres: cells of the local ground estimate of a target frame
_CELL_KEY = 1_000_003  # cell (i, j) -> i * _CELL_KEY + j
_BEARING_STEP = 2.0  # degrees between candidate bearings
_GHOST_DEPTH = 1.0  # metres below a block's median cell height that a cell is a mirror ghost


class _TargetGround:
    """A target frame's local ground and its solid returns.

    The ground under a return is the lowest 5th-percentile height of the 1 m cells around
    it (3 x 3): a cell on a car's flank holds no ground return of its own. Cells more than
    :data:`_GHOST_DEPTH` below the median of the nine are left out: returns below the road
    are mirror images (KITTI sweep 3 holds a row of them 2.6 m under the road beside a car),
    and as ground they made the whole road around them "solid".
    """

    def __init__(self, frame: Frame) -> None:
        xyz = frame.cloud.xyz.astype(np.float64)
        cells = np.floor(xyz[:, :2] / _GROUND_CELL).astype(np.int64)
        keys = cells[:, 0] * _CELL_KEY + cells[:, 1]
        order = np.lexsort((xyz[:, 2], keys))
        sorted_keys = keys[order]
        starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
        counts = np.diff(np.r_[starts, len(keys)])
        low = dict(
            zip(
                sorted_keys[starts].tolist(),
                xyz[order[starts + (counts * 0.05).astype(np.int64)], 2].tolist(),
                strict=True,
            )
        )
        around = [dx * _CELL_KEY + dy for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
        lowest = np.array(
            [
                _lowest([low.get(key + step, math.inf) for step in around])
                for key in sorted_keys[starts]
            ]
        )
        self.height = np.empty(len(xyz))
        self.height[order] = np.repeat(lowest, counts)
        self.solid = xyz[:, 2] > self.height + _SOLID
        self.xyz = xyz
        self.tree = cKDTree(xyz[:, :2])
        solid = xyz[self.solid]
        azimuth = np.arctan2(solid[:, 1], solid[:, 0])
        by_azimuth = np.argsort(azimuth)
        self.solid_azimuth = azimuth[by_azimuth]
        self.solid_range = np.hypot(solid[by_azimuth, 0], solid[by_azimuth, 1])

    def ground_under(self, box: Box, *, vacated: Box | None = None) -> float | None:
        """Median height of the non-solid returns in the grown footprint, or None when
        there are fewer than 5 (no ground seen there) or a solid return lies in it
        (``vacated``: where an object moved away stood; stray returns of it there, a
        mirror or an antenna outside its box, do not count)."""
        reach = math.hypot(box.size[0], box.size[1]) / 2 + _FREE_MARGIN
        near = np.asarray(self.tree.query_ball_point(box.center[:2], reach), dtype=np.intp)
        if len(near) == 0:
            return None
        footprint = box.grown(_FREE_MARGIN)
        inside = near[footprint_distances(self.xyz[near], [footprint]) == 0]
        solid = self.solid[inside]
        if vacated is not None and solid.any():
            solid &= ~vacated.grown(_FREE_MARGIN).contains(self.xyz[inside])
        if solid.any() or len(inside) < 5:
            return None
        return float(np.median(self.xyz[inside, 2]))

    @functools.cached_property
    def nearest_ground(self) -> float | None:
        """The height of the nearest ground the sensor sees: the median height of the
        non-solid returns within 3 m beyond the nearest of them (None: none within 15 m).
        Within the first metres a sensor sees no ground at all (the car and the lowest
        beam's angle hide it: an HDL-64E 1.73 m up meets the road 3.7 m out at the
        earliest), so a near-field placement stands on this, on the premise that the road
        under the car is as high as the road just beyond it."""
        planar = np.hypot(self.xyz[:, 0], self.xyz[:, 1])
        ground = ~self.solid & (planar < 15.0)
        if not ground.any():
            return None
        first = float(planar[ground].min())
        return float(np.median(self.xyz[ground & (planar < first + 3.0), 2]))

    def blind_ground_under(self, box: Box) -> float | None:
        """The ground height under ``box`` in the near field, where the sensor sees no
        ground: :attr:`nearest_ground`, when no solid return lies in the footprint grown
        by 0.5 m and the footprint holds fewer ground returns than :meth:`ground_under`
        needs (where it holds enough, that is the height); None otherwise."""
        seen = self.ground_under(box)
        if seen is not None:
            return seen
        reach = math.hypot(box.size[0], box.size[1]) / 2 + _FREE_MARGIN
        near = np.asarray(self.tree.query_ball_point(box.center[:2], reach), dtype=np.intp)
        if len(near):
            inside = near[footprint_distances(self.xyz[near], [box.grown(_FREE_MARGIN)]) == 0]
            if self.solid[inside].any() or len(inside) >= 5:
                return None
        return self.nearest_ground

    def in_clear_view(self, box: Box) -> bool:
        """Whether at most 2 solid returns lie between the sensor and ``box`` (within the
        bearings its footprint covers): it is not placed behind something."""
        corners = box.corners_bev()
        bearing = math.atan2(box.center[1], box.center[0])
        low, high = _bearing_window(np.column_stack([corners, np.zeros(4)]), bearing)
        nearest = float(np.hypot(corners[:, 0], corners[:, 1]).min())
        count = 0
        for start, stop in _azimuth_spans(bearing + low, bearing + high):
            a, b = np.searchsorted(self.solid_azimuth, [start, stop])
            count += int((self.solid_range[a:b] < nearest).sum())
        return count <= 2


def _lowest(lows: list[float]) -> float:
    """The lowest of a 3 x 3 block's cell heights that is not a ghost below the road."""
    seen = [value for value in lows if value != math.inf]
    if not seen:
        return math.inf
    floor = float(np.median(seen)) - _GHOST_DEPTH
    return min(value for value in seen if value >= floor)


def _azimuth_spans(start: float, stop: float) -> list[tuple[float, float]]:
    """``[start, stop]`` (radians, stop - start < 2π) as spans within [-π, π]."""
    width = stop - start
    start = math.remainder(start, 2 * math.pi)
    stop = start + width
    if stop <= math.pi:
        return [(start, stop)]
    return [(start, math.pi), (-math.pi, stop - 2 * math.pi)]


def _factors(factors: Sequence[float]) -> tuple[float, ...]:
    chosen = tuple(factors)
    if not chosen or not all(
        isinstance(f, (int, float)) and not isinstance(f, bool) and math.isfinite(f) and f > 0
        for f in chosen
    ):
        raise InvalidArgument(f"factors={factors!r} must be positive numbers")
    return tuple(float(f) for f in chosen)


def free_placements(
    frame: Frame,
    template: ObjectTemplate,
    *,
    scope: ScopeLike = "roi",
    layout: BeamLayout = HDL64E,
    limit: int = 32,
    factors: Sequence[float] = RANGE_FACTORS,
) -> list[Placement]:
    """Up to ``limit`` places where ``template`` can stand in ``frame``, smallest move first.

    A place is free when no return of ``frame`` rises more than 0.3 m above the local
    ground in the template's footprint grown by 0.5 m, and that footprint holds at least
    5 ground returns (the ground is seen there). The box must be judged by ``scope`` (by
    default: wholly inside the ROI) and within the sensor's range. Candidates keep the
    template's view and lie at ``factors`` times its range, at bearings 2
    degrees apart; they are ordered by how far they move it (bearing change in degrees
    plus 20 times the log of the range factor), so Hypothesis shrinks toward the place
    the object was seen from.
    """
    if not isinstance(frame, Frame):
        raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
    if not isinstance(template, ObjectTemplate):
        raise InvalidArgument(f"template={template!r} must be an ObjectTemplate")
    chosen = as_scope(scope)
    ground = _ground_of(frame)
    candidates = []
    for factor in _factors(factors):
        distance = template.range * factor
        if not layout.min_range + 2.0 < distance < 0.9 * layout.max_range:
            continue
        for step in range(-int(180 / _BEARING_STEP), int(180 / _BEARING_STEP)):
            turn = step * _BEARING_STEP
            candidates.append((abs(turn) + 20 * abs(math.log(factor)), turn, distance))
    candidates.sort()
    found: list[Placement] = []
    for _, turn, distance in candidates:
        bearing = math.remainder(template.bearing + math.radians(turn), 2 * math.pi)
        box = template.box_at(Placement(bearing, distance, 0.0))
        z = ground.ground_under(box)
        if z is None or not ground.in_clear_view(box):
            continue
        placement = Placement(bearing, distance, z)
        if not chosen.judged([template.box_at(placement)], frame)[0]:
            continue
        found.append(placement)
        if len(found) == limit:
            break
    return found


def free_ground(frame: Frame, box: Box, *, scope: ScopeLike = "roi") -> float | None:
    """The ground height under ``box`` when it may stand in ``frame`` as
    :func:`free_placements` requires (free, seen ground, in clear view, judged by
    ``scope``), else None."""
    ground = _ground_of(frame)
    z = ground.ground_under(box)
    if z is None or not ground.in_clear_view(box) or not as_scope(scope).judged([box], frame)[0]:
        return None
    return z


def ground_of(frame: Frame) -> _TargetGround:
    """``frame``'s local ground and solid returns (cached for the last 8 frames)."""
    return _ground_of(frame)


@functools.lru_cache(maxsize=8)
def _ground_of(frame: Frame) -> _TargetGround:
    return _TargetGround(frame)
