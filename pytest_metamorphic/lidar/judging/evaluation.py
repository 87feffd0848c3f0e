"""Detection quality against ground truth: recall and precision per class.

Detections and ground-truth boxes of one class are paired one-to-one
(:func:`~pytest_metamorphic.core.matching.one_to_one` with a
:class:`~pytest_metamorphic.core.matching.Matcher`, by default a
:class:`~pytest_metamorphic.lidar.model.obstacles.CenterDistanceMatcher`), so one detection can
never count for two objects. Matched pairs are true positives, unmatched detections
false positives, unmatched ground truth false negatives.

The default matching radius is per class: 2 m for cars, 1 m for pedestrians and cyclists.
A centre distance rather than IoU, because a LiDAR box covers the *visible* part of an
object: a car seen from behind is a 1.7 x 0.5 m box about 2 m from the labelled centre.

Ground truth should be restricted to what the sensor can see and what the detector is
asked about: :func:`visible_truth` keeps boxes inside the evaluation region that hold at
least ``min_points`` LiDAR points. KITTI frames have no HD map; :func:`kitti_label_region`
is the region KITTI labels cover (the camera's field of view), used as the ROI when
scoring on KITTI.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher, one_to_one
from pytest_metamorphic.lidar.model.obstacles import (
    LABELS,
    Box,
    CenterDistanceMatcher,
    Label,
    as_boxes,
)
from pytest_metamorphic.lidar.roi import ROI

__all__ = [
    "DEFAULT_MATCH_RADIUS",
    "ClassScore",
    "Evaluation",
    "evaluate",
    "kitti_label_region",
    "visible_truth",
]

DEFAULT_MATCH_RADIUS: Mapping[Label, float] = {
    "car": 2.0,
    "pedestrian": 1.0,
    "cyclist": 1.0,
    "unknown": 1.0,
}


@dataclass(frozen=True)
class ClassScore:
    """Counts for one class; rates are None when undefined (nothing to divide by)."""

    label: Label
    true_positives: int = 0
    false_positives: int = 0
    false_negatives: int = 0

    @property
    def recall(self) -> float | None:
        """TP / (TP + FN): the share of ground-truth objects found."""
        total = self.true_positives + self.false_negatives
        return self.true_positives / total if total else None

    @property
    def precision(self) -> float | None:
        """TP / (TP + FP): the share of detections that are real objects."""
        total = self.true_positives + self.false_positives
        return self.true_positives / total if total else None

    def __add__(self, other: ClassScore) -> ClassScore:
        if not isinstance(other, ClassScore) or other.label != self.label:
            return NotImplemented
        return ClassScore(
            self.label,
            self.true_positives + other.true_positives,
            self.false_positives + other.false_positives,
            self.false_negatives + other.false_negatives,
        )

    def describe(self) -> str:
        """E.g. ``car: recall 3/5 = 0.60, precision 3/9 = 0.33``."""
        tp, fp, fn = self.true_positives, self.false_positives, self.false_negatives
        return (
            f"{self.label}: recall {tp}/{tp + fn} = {_rate(self.recall)}, "
            f"precision {tp}/{tp + fp} = {_rate(self.precision)}"
        )


def _rate(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"


@dataclass(frozen=True)
class Evaluation:
    """Per-class scores of one or more frames (add evaluations to pool frames).

    Attributes
    ----------
    scores : mapping of label to ClassScore
    matches : list of (label, detection index, truth index)
        The matched pairs (indices into the lists given to :func:`evaluate`; empty for
        pooled evaluations).
    """

    scores: Mapping[Label, ClassScore]
    matches: list[tuple[Label, int, int]] = field(default_factory=list)

    def __getitem__(self, label: Label) -> ClassScore:
        return self.scores[label]

    def __add__(self, other: Evaluation) -> Evaluation:
        if not isinstance(other, Evaluation):
            return NotImplemented
        labels = list(dict.fromkeys([*self.scores, *other.scores]))
        return Evaluation(
            {
                label: self.scores.get(label, ClassScore(label))
                + other.scores.get(label, ClassScore(label))
                for label in labels
            }
        )

    def describe(self) -> str:
        """One line per class."""
        return "\n".join(score.describe() for score in self.scores.values())


def evaluate(
    detections: Sequence[Box],
    truth: Sequence[Box],
    *,
    labels: Iterable[Label] = ("car", "pedestrian"),
    matcher: Matcher | Mapping[Label, Matcher] | None = None,
) -> Evaluation:
    """Score detections against ground truth, class by class.

    Parameters
    ----------
    detections, truth : sequence of Box
        Boxes in the same frame; only boxes whose label is in ``labels`` count.
    labels : iterable of label
        Classes to score.
    matcher : Matcher, or mapping of label to Matcher, optional
        Which (detection, truth) pairs may match, with costs. Default: centre distance
        within :data:`DEFAULT_MATCH_RADIUS` of the class.

    Returns
    -------
    Evaluation
    """
    wanted = _as_labels(labels)
    if matcher is not None and not isinstance(matcher, (Mapping, Matcher)):
        raise InvalidArgument(
            f"matcher={matcher!r} must be a Matcher (with .pairwise) or a mapping of them"
        )
    detections = as_boxes(detections, "detections")
    truth = as_boxes(truth, "truth")
    scores: dict[Label, ClassScore] = {}
    matches: list[tuple[Label, int, int]] = []
    for label in wanted:
        found = [i for i, box in enumerate(detections) if box.label == label]
        real = [i for i, box in enumerate(truth) if box.label == label]
        pairs: list[tuple[int, int]] = []
        if found and real:
            compatible, cost = _matcher_for(matcher, label).pairwise(
                [detections[i] for i in found], [truth[i] for i in real]
            )
            pairs = one_to_one(compatible, cost)
        matches.extend((label, found[i], real[j]) for i, j in pairs)
        scores[label] = ClassScore(
            label, len(pairs), len(found) - len(pairs), len(real) - len(pairs)
        )
    return Evaluation(scores, matches)


def visible_truth(
    truth: Iterable[Box], points: Any, *, roi: ROI | None = None, min_points: int = 10
) -> list[Box]:
    """Ground-truth boxes worth scoring: centre in the ROI, enough LiDAR points inside.

    Parameters
    ----------
    truth : iterable of Box
    points : PointCloud or (n, >=3) array_like
        The frame's points (sensor frame).
    roi : ROI, optional
        Keep boxes whose centre is in it (exact polygons); None keeps all.
    min_points : int
        Boxes holding fewer points are invisible to any LiDAR detector.
    """
    if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 0:
        raise InvalidArgument(f"min_points={min_points!r} must be an int >= 0")
    xyz = np.asarray(getattr(points, "points", points))[:, :3]
    kept = []
    for box in as_boxes(list(truth), "truth"):
        if roi is not None and not roi.contains([box.center[:2]], method="exact")[0]:
            continue
        if int(np.count_nonzero(box.contains(xyz))) >= min_points:
            kept.append(box)
    return kept


def kitti_label_region(
    *, max_range: float = 70.0, half_angle: float = 40.0, min_range: float = 3.0
) -> ROI:
    """The region KITTI object labels cover, as an ROI (KITTI has no HD map).

    KITTI labels only objects visible in the left colour camera (about 81 degrees wide,
    looking along +x). The region is the wedge within ``half_angle`` degrees of +x,
    between ``min_range`` and ``max_range`` metres ahead. It is not a road: pavements,
    parked cars and buildings inside the wedge are all in it.
    """
    for name, value in (("max_range", max_range), ("half_angle", half_angle)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InvalidArgument(f"{name}={value!r} must be a positive number")
    if not 0 <= min_range < max_range:
        raise InvalidArgument(f"min_range={min_range!r} must be in [0, max_range)")
    if half_angle >= 90:
        raise InvalidArgument(f"half_angle={half_angle!r} must be < 90 degrees")
    slope = math.tan(math.radians(half_angle))
    near, far = float(min_range), float(max_range)
    corners = [(near, -near * slope), (far, -far * slope), (far, far * slope), (near, near * slope)]
    return ROI.from_polygons([corners])


def _matcher_for(matcher: Matcher | Mapping[Label, Matcher] | None, label: Label) -> Matcher:
    if matcher is None:
        return CenterDistanceMatcher(DEFAULT_MATCH_RADIUS[label], same_label=False)
    if isinstance(matcher, Mapping):
        if label not in matcher:
            raise InvalidArgument(f"matcher has no entry for label {label!r}")
        return matcher[label]
    return matcher


def _as_labels(labels: Iterable[Label]) -> list[Label]:
    if isinstance(labels, str):
        raise InvalidArgument(f"labels={labels!r} must be a collection of labels, not a string")
    result = list(labels)
    for label in result:
        if label not in LABELS:
            raise InvalidArgument(f"labels contains {label!r}; known labels are {LABELS}")
    return result
