"""How good the CNN segmentation is: recall and precision per class at BEV IoU 0.5.

A detection is a true positive when it has its own ground-truth box of the same class
with bird's-eye IoU >= 0.5 (one-to-one,
:func:`~pytest_metamorphic.lidar.judging.evaluation.evaluate`).
Ground truth counts when it lies within ``max_range`` of the sensor (the grid's reach) and
holds at least ``min_points`` returns; detections count within ``max_range`` too.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np

from pytest_metamorphic.lidar.judging.evaluation import Evaluation, evaluate, visible_truth
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, IoUMatcher

__all__ = ["detection_quality"]


def _within(boxes: Iterable[Box], max_range: float) -> list[Box]:
    return [box for box in boxes if float(np.hypot(*box.center[:2])) <= max_range]


def detection_quality(
    detector: Callable[[Frame], Sequence[Box]],
    frames: Iterable[Frame],
    *,
    max_range: float = 40.0,
    min_points: int = 10,
    min_iou: float = 0.5,
    labels: Sequence[str] = ("car", "pedestrian", "cyclist"),
) -> Evaluation:
    """Recall and precision of ``detector`` over labelled ``frames`` (summed counts).

    Parameters
    ----------
    detector : callable(Frame) -> sequence of Box
    frames : iterable of Frame
        With ground-truth ``boxes`` and an ROI (truth is kept where its centre is in it).
    max_range : float
        Metres from the sensor; boxes farther away are not scored.
    min_points : int
        Ground truth with fewer returns inside is invisible and not scored.
    min_iou : float
        Bird's-eye IoU a detection needs with its ground truth.
    """
    total: Evaluation | None = None
    matcher = IoUMatcher(min_iou, same_label=False)
    for frame in frames:
        truth = visible_truth(
            _within(frame.boxes, max_range), frame.cloud, roi=frame.roi, min_points=min_points
        )
        found = _within(detector(frame), max_range)
        score = evaluate(found, truth, labels=labels, matcher=matcher)  # type: ignore[arg-type]
        total = score if total is None else total + score
    if total is None:
        raise ValueError("detection_quality needs at least one frame")
    return total
