"""Minimal hiding sets: LiDAR perturbations as reducible element sets, and lost obstacles.

The engine reduces a violating follow-up to a 1-minimal one
(:mod:`pytest_metamorphic.core.reduction`) when its transform is
:class:`~pytest_metamorphic.core.perturbation.Reducible`. This module makes the point
perturbations of :mod:`pytest_metamorphic.lidar.followups.perturb` reducible (importing it registers
the adapters; the engine does so on first sight of such a perturbation):

* injected points (:class:`~.perturb.NoiseOutsideROI`, :class:`~.perturb.NoiseInsideROI`):
  one element per point;
* :class:`~.perturb.DropPoints` and :class:`~.perturb.DuplicatePoints`: one element per index.

Elements are ranked by their bird's-eye distance to the obstacles the follow-up lost
(:func:`lost_obstacles`), nearest first. A ground or clustering fault hides an obstacle
through points near it, so the culprits end up in the same ddmin chunk and are found in
a few calls; a fault with far-reaching culprits (a bounding box of the whole sweep) only
loses the advantage, never the proof. When that pass runs out of its half of the budget,
a second pass orders the remaining points by height: faults driven by a height statistic
of the whole sweep (a percentile cut) need many high points, which the distance order
scatters over every ddmin chunk.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher, one_to_one
from pytest_metamorphic.core.perturbation import register_reducible
from pytest_metamorphic.lidar.followups.perturb import (
    DropPoints,
    DuplicatePoints,
    NoiseInsideROI,
    NoiseOutsideROI,
)
from pytest_metamorphic.lidar.judging.scope import DEFAULT_SCOPE
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import (
    Box,
    IoUMatcher,
    footprint_distances,
    unmatched_twins,
)

__all__ = [
    "IndexEditReduction",
    "InjectedPointsReduction",
    "PointsReduction",
    "changed_obstacles",
    "lost_obstacles",
]

_P = TypeVar("_P", bound=NoiseOutsideROI | NoiseInsideROI | DropPoints | DuplicatePoints)
_R = TypeVar("_R", bound="PointsReduction[Any]")


def _boxes(value: Any, which: str) -> list[Box]:
    if value is None:
        return []
    try:
        boxes = list(value)
    except TypeError:
        raise InvalidArgument(f"the {which} output must be a list of Box, got {value!r}") from None
    if not all(isinstance(box, Box) for box in boxes):
        raise InvalidArgument(f"the {which} output must be a list of Box")
    return boxes


def lost_obstacles(
    source_output: Sequence[Box], followup_output: Sequence[Box], *, matcher: Matcher | None = None
) -> list[int]:
    """Indices of source obstacles without their own match in the follow-up (MR1's ``O ⊄ O'``).

    Parameters
    ----------
    source_output, followup_output : sequence of Box
    matcher : Matcher, optional
        Default: same label and bird's-eye IoU >= 0.5, as :func:`~.relations.mr1_subset`.
    """
    source = _boxes(source_output, "source")
    followup = _boxes(followup_output, "follow-up")
    if not source:
        return []
    compatible, cost = (matcher or IoUMatcher(0.5, same_label=True)).pairwise(source, followup)
    matched = {row for row, _ in one_to_one(compatible, cost)}
    return [index for index in range(len(source)) if index not in matched]


def changed_obstacles(
    source_output: Sequence[Box], followup_output: Sequence[Box]
) -> tuple[list[int], list[int]]:
    """``(source indices, follow-up indices)`` of boxes without an identical partner."""
    source = _boxes(source_output, "source")
    followup = _boxes(followup_output, "follow-up")
    return unmatched_twins(source, followup)


def _in_scope(boxes: list[Box], frame: Any) -> list[Box]:
    """The boxes the default ROI scope judges; all of them when the frame has no ROI.

    A scoped relation's violation is about judged obstacles, so the culprits are near
    them, not near obstacles off the road that changed too.
    """
    if not boxes or getattr(frame, "roi", None) is None:
        return boxes
    judged = DEFAULT_SCOPE.select(boxes, frame)
    return judged or boxes


def _targets(source_output: Any, followup_output: Any, frame: Any = None) -> list[Box]:
    """The obstacles a violation is about: lost ones (judged first), else any that changed."""
    source = _boxes(source_output, "source")
    followup = _boxes(followup_output, "follow-up")
    lost = lost_obstacles(source, followup)
    if lost:
        return _in_scope([source[i] for i in lost], frame)
    gone, new = changed_obstacles(source, followup)
    return _in_scope([source[i] for i in gone] + [followup[j] for j in new], frame)


def _rank_by_distance(
    xy: NDArray[np.floating], source_output: Any, followup_output: Any, frame: Any = None
) -> list[int]:
    try:
        targets = _targets(source_output, followup_output, frame)
    except InvalidArgument:
        targets = []  # not a box detector: keep the original order
    if not targets or len(xy) == 0:
        return list(range(len(xy)))
    distance = footprint_distances(xy, targets)
    return np.argsort(distance, kind="stable").tolist()


def _effect_lines(
    xy: NDArray[np.floating], source_output: Any, followup_output: Any, frame: Any = None
) -> list[str]:
    """ "hidden: <obstacle>, <distance> from these points" for each lost judged obstacle."""
    try:
        source = _boxes(source_output, "source")
        lost = [source[i] for i in lost_obstacles(source, _boxes(followup_output, "follow-up"))]
    except InvalidArgument:
        return []
    judged = _in_scope(lost, frame)
    lines = []
    for box in judged:
        distance = footprint_distances(xy, [box]) if len(xy) else np.empty(0)
        if len(distance) == 0:
            where = ""
        elif len(distance) == 1:
            where = f", {distance[0]:.1f} m from this point"
        else:
            where = f", {distance.min():.1f} to {distance.max():.1f} m from these points"
        edge = DEFAULT_SCOPE.where(box, frame) if frame is not None else ""
        lines.append(f"hidden: {box.describe()}{f' ({edge})' if edge else ''}{where}")
    others = len(lost) - len(judged)
    if judged is not lost and others:
        lines.append(f"also changed, outside the ROI scope (not judged): {others} obstacle(s)")
    return lines


def _by_height(z: NDArray[np.floating]) -> list[int]:
    return np.argsort(-np.asarray(z, dtype=np.float64), kind="stable").tolist()


def _point_line(x: float, y: float, z: float, intensity: float) -> str:
    return (
        f"({x:.2f}, {y:.2f}, {z:.2f}) intensity {intensity:.3g}, "
        f"{math.hypot(x, y):.1f} m from the sensor"
    )


class PointsReduction(Generic[_P]):
    """A point perturbation as a :class:`~pytest_metamorphic.core.perturbation.Reducible`
    set of elements, the rows of one of its arrays (what both adapters below share).

    Subclasses name the array (``_elements``). The source frame last given to
    :meth:`apply` or ``ranking`` is kept for the messages (where the elements are).
    """

    def __init__(self, perturbation: _P) -> None:
        self.perturbation = perturbation
        self._source: Frame | None = None

    def _elements(self) -> NDArray[Any]:
        raise NotImplementedError

    def __len__(self) -> int:
        return len(self._elements())

    def __repr__(self) -> str:
        return repr(self.perturbation)

    def restrict(self: _R, indices: Sequence[int]) -> _R:
        """The same kind of reduction with only the elements at ``indices``, in order."""
        chosen = np.asarray(list(indices), dtype=np.intp)
        reduced = type(self)(type(self.perturbation)(self._elements()[chosen]))
        reduced._source = self._source
        return reduced

    def apply(self, source: Frame) -> Frame:
        """The follow-up frame: the perturbation applied to ``source``."""
        self._source = source
        return self.perturbation.apply(source)

    def params(self) -> dict[str, Any]:
        """The perturbation's parameters, as recorded with the follow-up."""
        return self.perturbation.params()

    def _more(self, lines: list[str], limit: int) -> list[str]:
        """``lines`` (the first ``limit`` elements) and a count of the rest."""
        if len(self) > limit:
            lines.append(f"... {len(self) - limit} other points")
        return lines


class InjectedPointsReduction(PointsReduction[NoiseOutsideROI | NoiseInsideROI]):
    """Points appended to a frame (MR1 noise), one element per point.

    Parameters
    ----------
    perturbation : NoiseOutsideROI or NoiseInsideROI
        Its ``points`` are (n, 4) float32 x, y, z, intensity.
    """

    @property
    def points(self) -> NDArray[np.float32]:
        """(n, 4) float32: the injected points."""
        return self.perturbation.points

    def _elements(self) -> NDArray[np.float32]:
        return self.points

    def ranking(self, source: Any, source_output: Any, followup_output: Any) -> list[int]:
        """Nearest to a lost (or changed) obstacle first, judged ones preferred."""
        if isinstance(source, Frame):
            self._source = source
        return _rank_by_distance(self.points, source_output, followup_output, source)

    def rankings(self, source: Any, source_output: Any, followup_output: Any) -> list[list[int]]:
        """By distance to the lost obstacle, then (fallback pass) highest first."""
        return [
            self.ranking(source, source_output, followup_output),
            _by_height(self.points[:, 2]),
        ]

    def describe_effect(self, source_output: Any, followup_output: Any) -> list[str]:
        """One line per obstacle the follow-up lost, with its distance to the points."""
        return _effect_lines(self.points, source_output, followup_output, self._source)

    def describe_elements(self, limit: int = 10) -> list[str]:
        return self._more([_point_line(*map(float, row)) for row in self.points[:limit]], limit)

    def to_json(self) -> dict[str, Any]:
        return {
            "type": type(self.perturbation).__name__,
            "points": self.points.astype(np.float64).tolist(),
        }


class IndexEditReduction(PointsReduction[DropPoints | DuplicatePoints]):
    """Points dropped or repeated by index (:class:`DropPoints`, :class:`DuplicatePoints`)."""

    @property
    def indices(self) -> NDArray[np.intp]:
        """(n,) intp: the edited points' positions in the source cloud."""
        return self.perturbation.indices

    def _elements(self) -> NDArray[np.intp]:
        return self.indices

    def ranking(self, source: Any, source_output: Any, followup_output: Any) -> list[int]:
        if not isinstance(source, Frame) or len(self) == 0:
            return list(range(len(self)))
        self._source = source
        xy = source.cloud.points[np.minimum(self.indices, len(source.cloud) - 1), :2]
        return _rank_by_distance(xy, source_output, followup_output, source)

    def rankings(self, source: Any, source_output: Any, followup_output: Any) -> list[list[int]]:
        """By distance to the lost obstacle, then (fallback pass) highest first."""
        first = self.ranking(source, source_output, followup_output)
        if not isinstance(source, Frame) or len(self) == 0:
            return [first]
        rows = np.minimum(self.indices, len(source.cloud) - 1)
        return [first, _by_height(source.cloud.points[rows, 2])]

    def describe_effect(self, source_output: Any, followup_output: Any) -> list[str]:
        """One line per obstacle the follow-up lost, with its distance to the edited points."""
        if self._source is None:
            return _effect_lines(np.empty((0, 2)), source_output, followup_output)
        rows = self.indices[self.indices < len(self._source.cloud)]
        xy = self._source.cloud.points[rows, :2]
        return _effect_lines(xy, source_output, followup_output, self._source)

    def describe_elements(self, limit: int = 10) -> list[str]:
        verb = "dropped" if isinstance(self.perturbation, DropPoints) else "repeated"
        lines = []
        for index in self.indices[:limit].tolist():
            if self._source is not None and index < len(self._source.cloud):
                row = self._source.cloud.points[index]
                lines.append(f"point #{index} {verb}: {_point_line(*map(float, row))}")
            else:
                lines.append(f"point #{index} {verb}")
        return self._more(lines, limit)

    def to_json(self) -> dict[str, Any]:
        return {"type": type(self.perturbation).__name__, "indices": self.indices.tolist()}


register_reducible(NoiseOutsideROI, InjectedPointsReduction)
register_reducible(NoiseInsideROI, InjectedPointsReduction)
register_reducible(DropPoints, IndexEditReduction)
register_reducible(DuplicatePoints, IndexEditReduction)
