"""Pairing two detectors' boxes: exact twins up to rounding, and the two matchers the subset
relation uses to pair source and follow-up detections one-to-one (:class:`IoUMatcher`,
:class:`CenterDistanceMatcher`, both implementing
:class:`~pytest_metamorphic.core.matching.Matcher`)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles.box import Box, bev_iou, center_distances

__all__ = ["ROUNDING", "CenterDistanceMatcher", "IoUMatcher", "unmatched_twins"]


#: How far two boxes may differ and still be *identical*: floating-point rounding (metres,
#: radians, score). A detector that averages its points in the order it receives them
#: gives centres that differ in the 16th digit when the points are reordered
#: (1.7068876216562718 vs ...716): the same box, which exact float equality called a
#: change; no real difference is this small.
ROUNDING = 1e-6


def unmatched_twins(a: Sequence[Box], b: Sequence[Box]) -> tuple[list[int], list[int]]:
    """Indices of ``a`` and of ``b`` without an identical partner on the other side.

    A multiset difference (repeated equal boxes pair up one by one, in order): boxes hash
    by value, so exact twins pair in linear time; the rest pair when they differ by no
    more than :data:`ROUNDING` in every number, with the same label. Equality ignores
    ``points``, as ``Box ==`` does.
    """
    available = Counter(b)
    gone = []
    for index, box in enumerate(a):
        if available[box]:
            available[box] -= 1
        else:
            gone.append(index)
    paired = Counter(b)
    paired.subtract(available)  # per box value: how many of b's copies were paired
    new = []
    for index, box in enumerate(b):
        if paired[box]:
            paired[box] -= 1
        else:
            new.append(index)
    return _pair_rounded(a, b, gone, new)


def _pair_rounded(
    a: Sequence[Box], b: Sequence[Box], gone: list[int], new: list[int]
) -> tuple[list[int], list[int]]:
    """``gone`` and ``new`` less the pairs that differ by rounding only (few: a quadratic
    pass over what the exact pass left)."""
    left = list(new)
    still_gone = []
    for i in gone:
        twin = next((j for j in left if _rounded_twins(a[i], b[j])), None)
        if twin is None:
            still_gone.append(i)
        else:
            left.remove(twin)
    return still_gone, left


def _rounded_twins(first: Box, second: Box) -> bool:
    if first.label != second.label or (first.score is None) != (second.score is None):
        return False
    numbers = [*first.center, *first.size, first.yaw, first.score or 0.0]
    others = [*second.center, *second.size, second.yaw, second.score or 0.0]
    return all(abs(x - y) <= ROUNDING for x, y in zip(numbers, others, strict=True))


# -- matchers ----------------------------------------------------------------------------------


def _labelled(
    compatible: NDArray[np.bool_], same_label: bool, source: Sequence[Box], followup: Sequence[Box]
) -> NDArray[np.bool_]:
    """``compatible``, and where ``same_label`` asks for it, only pairs of equal labels."""
    if same_label:
        a = np.array([box.label for box in source], dtype=object).reshape(-1, 1)
        b = np.array([box.label for box in followup], dtype=object).reshape(1, -1)
        compatible &= np.asarray(a == b, dtype=bool).reshape(len(source), len(followup))
    return compatible


def _check_flag(value: Any, name: str) -> None:
    if not isinstance(value, bool):
        raise InvalidArgument(f"{name}={value!r} must be True or False")


@dataclass(frozen=True)
class IoUMatcher:
    """Pairs boxes whose bird's-eye IoU is at least ``min_iou`` (cost: ``1 - IoU``).

    Parameters
    ----------
    min_iou : float
      In (0, 1]. 0.5 by default; KITTI evaluates cars at 0.7 and people at 0.5.
    same_label : bool
      Also require equal labels (default), so a car that turns into "unknown" in the
      follow-up counts as missing.
    """

    min_iou: float = 0.5
    same_label: bool = True

    def __post_init__(self) -> None:
        value = self.min_iou
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"min_iou={value!r} must be a number in (0, 1]")
        if not 0 < value <= 1:
            raise InvalidArgument(f"min_iou={value!r} must be in (0, 1]")
        _check_flag(self.same_label, "same_label")

    @property
    def name(self) -> str:
        label = ", same label" if self.same_label else ""
        return f"BEV IoU >= {self.min_iou:g}{label}"

    def pairwise(
        self, source: Sequence[Any], followup: Sequence[Any]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        iou = bev_iou(source, followup)
        return _labelled(iou >= self.min_iou, self.same_label, source, followup), 1.0 - iou


@dataclass(frozen=True)
class CenterDistanceMatcher:
    """Pairs boxes whose centres are at most ``max_distance`` metres apart in bird's-eye view.

    Cost is the distance. ``same_label`` as for :class:`IoUMatcher`. ``exclusive=False``
    lets several boxes share one match (:func:`~pytest_metamorphic.core.matching.matched_pairs`):
    pieces of one object reported in one output and one box in the other.
    """

    max_distance: float = 2.0
    same_label: bool = True
    exclusive: bool = True

    def __post_init__(self) -> None:
        value = self.max_distance
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidArgument(f"max_distance={value!r} must be a positive number of metres")
        if not (math.isfinite(value) and value > 0):
            raise InvalidArgument(f"max_distance={value!r} must be a positive number of metres")
        _check_flag(self.same_label, "same_label")
        _check_flag(self.exclusive, "exclusive")

    @property
    def name(self) -> str:
        label = ", same label" if self.same_label else ""
        shared = "" if self.exclusive else ", pieces share a match"
        return f"centre distance <= {self.max_distance:g} m{label}{shared}"

    def pairwise(
        self, source: Sequence[Any], followup: Sequence[Any]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        distance = center_distances(source, followup)
        near = distance <= self.max_distance
        return _labelled(near, self.same_label, source, followup), distance
