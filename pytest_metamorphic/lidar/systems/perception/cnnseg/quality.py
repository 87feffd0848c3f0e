"""How good the CNN segmentation is: recall and precision per class at BEV IoU 0.5.

A detection is a true positive when it has its own ground-truth box of the same class
with bird's-eye IoU >= 0.5 (one-to-one,
:func:`~pytest_metamorphic.lidar.judging.evaluation.evaluate`). What is scored follows
KITTI's evaluation, with the issue's range and return count in place of its pixel heights:

* ground truth counts when its centre lies in the frame's ROI (the region the labels
  cover), within ``max_range`` of the sensor, and it holds at least ``min_points``
  returns;
* a detection counts when its centre lies in the ROI and within ``max_range``; one that
  no counted truth takes is *ignored*, neither found nor false, when it matches a truth
  box that was not counted (too few returns: KITTI's "ignored" objects) or falls in a
  region the labels leave out (``ignore``: KITTI's DontCare,
  :class:`~pytest_metamorphic.lidar.io.kitti.KittiDontCare`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np

from pytest_metamorphic.lidar.judging.evaluation import Evaluation, evaluate, visible_truth
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, IoUMatcher, Label

__all__ = ["detection_quality"]


_LABELS: tuple[Label, ...] = ("car", "pedestrian", "cyclist", "unknown")


def _within(boxes: Iterable[Box], max_range: float, frame: Frame) -> list[Box]:
    near = [box for box in boxes if float(np.hypot(*box.center[:2])) <= max_range]
    if frame.roi is None or not near:
        return near
    inside = frame.roi.contains([box.center[:2] for box in near], method="exact")
    return [box for box, keep in zip(near, inside, strict=True) if keep]


def _scored(
    found: list[Box],
    truth: list[Box],
    ignored_truth: list[Box],
    frame: Frame,
    matcher: IoUMatcher,
    ignore: Callable[[Frame, Box], bool] | None,
) -> list[Box]:
    """The detections that count: those counted truth takes, and the unexplained rest."""
    taken = {i for _, i, _ in evaluate(found, truth, labels=_LABELS, matcher=matcher).matches}
    kept = []
    for i, box in enumerate(found):
        if i not in taken:
            if ignored_truth and np.any(matcher.pairwise([box], ignored_truth)[0]):
                continue  # an object too sparse to score: KITTI ignores it
            if ignore is not None and ignore(frame, box):
                continue  # where nothing was labelled (DontCare)
        kept.append(box)
    return kept


def detection_quality(
    detector: Callable[[Frame], Sequence[Box]],
    frames: Iterable[Frame],
    *,
    max_range: float = 40.0,
    min_points: int = 10,
    min_iou: float = 0.5,
    labels: Sequence[str] = ("car", "pedestrian", "cyclist"),
    ignore: Callable[[Frame, Box], bool] | None = None,
) -> Evaluation:
    """Recall and precision of ``detector`` over labelled ``frames`` (summed counts).

    Parameters
    ----------
    detector : callable(Frame) -> sequence of Box
    frames : iterable of Frame
        With ground-truth ``boxes`` and, where the labels cover only part of the sweep,
        an ROI saying which part (truth and detections are scored where their centre is
        in it).
    max_range : float
        Metres from the sensor; boxes farther away are not scored.
    min_points : int
        Ground truth with fewer returns inside is invisible and not scored; a detection
        of it is not counted either way.
    min_iou : float
        Bird's-eye IoU a detection needs with its ground truth.
    ignore : callable(Frame, Box) -> bool, optional
        True where a detection in that frame falls where the labels say nothing (KITTI:
        ``lambda frame, box: dont_care[frame.source].covers(box)``).
    """
    total: Evaluation | None = None
    matcher = IoUMatcher(min_iou, same_label=False)
    for frame in frames:
        candidates = _within(frame.boxes, max_range, frame)
        truth = visible_truth(candidates, frame.cloud, min_points=min_points)
        ignored_truth = [box for box in candidates if box not in truth]
        found = _scored(_within(detector(frame), max_range, frame), truth, ignored_truth,
                        frame, matcher, ignore)  # fmt: skip
        score = evaluate(found, truth, labels=labels, matcher=matcher)  # type: ignore[arg-type]
        total = score if total is None else total + score
    if total is None:
        raise ValueError("detection_quality needs at least one frame")
    return total
