"""The same obstacle when a sweep's points are only reordered or repeated: identified by
the points it holds.

Reordering or repeating points leaves the *set* of points a detector sees unchanged, so
the same physical objects are there, held by the same points. A detector that treats the
sweep as a set gives identical boxes; one with ties does not quite: DBSCAN gives a border
point within reach of two touching clusters to whichever the traversal reaches first, a
voxel filter keeps whichever point of a voxel comes first. Measured on the six KITTI
sweeps, three reorderings each (issue 26), a DBSCAN detector in the sweep's own order
(``tests/lidar/systems/ties_detector.py``) kept every obstacle and its class, while a
border point changing sides moved small clusters' boxes by up to 29 cm, their widths by
up to 41 cm and their headings by up to 39 degrees (a 7-point pedestrian taking an
eighth point): no geometric tolerance separates that from a fault, and both are the same
object.

So two boxes are the same obstacle when they hold mostly the same points: the points of
the source sweep inside each box (grown by :data:`HELD_GROW` for points on its faces),
intersection over union **above** :data:`HELD_IOU`, and the same class. That is the
matching rule of panoptic segmentation (Kirillov et al., "Panoptic Segmentation", CVPR
2019; SemanticKITTI's panoptic benchmark uses it on LiDAR points): with IoU above 0.5 no
object can match two, so the matching is unique. A violation is then what an engineer
acts on: an obstacle lost, split, merged with another, or reclassified because of the
order or the repetition of the points. Boxes that hold no point of the sweep (a detector
may report a predicted box beside its points) are compared by place instead
(:data:`~pytest_metamorphic.lidar.judging.equivariance.SAME_OBSTACLE`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict, equal
from pytest_metamorphic.lidar.judging.equivariance import SAME_OBSTACLE
from pytest_metamorphic.lidar.model.obstacles import (
    Box,
    as_boxes,
    points_in_boxes,
    unmatched_twins,
)

__all__ = ["HELD_GROW", "HELD_IOU", "SameHeldPoints", "held_points"]

#: Two boxes are the same obstacle when the points they hold have an IoU above this.
HELD_IOU = 0.5
#: Metres a box grows on every side when counting the points it holds (fitted boxes have
#: their outermost points on their faces).
HELD_GROW = 0.05

_SHOWN = 3  # violations spelled out in a message


def held_points(points: Any, boxes: Sequence[Box], *, grow: float = HELD_GROW) -> list[set[int]]:
    """The indices of ``points`` inside each box grown by ``grow`` metres.

    Parameters
    ----------
    points : (n, >=3) array_like or PointCloud
        x, y, z in the boxes' frame; extra columns are ignored.
    boxes : sequence of Box

    Returns
    -------
    list of set of int
        One set per box.
    """
    xyz = np.asarray(getattr(points, "points", points), dtype=np.float64)
    if xyz.ndim != 2 or xyz.shape[1] < 3:
        raise InvalidArgument(f"points must be (n, >=3), got shape {xyz.shape}")
    return [{int(i) for i in rows} for rows in points_in_boxes(xyz, boxes, grow=grow)]


class SameHeldPoints(Relation):
    """``O == O'`` up to the points each obstacle holds (see the module docstring).

    Every obstacle of either output needs its own partner on the other side: an identical
    box (to rounding), or one of the same class holding points of the source sweep with an
    IoU above ``min_iou``. Partners that are not identical (a border point changed sides,
    a score moved) are counted in the verdict's details, as information.

    Parameters
    ----------
    min_iou : float, default :data:`HELD_IOU`
        Strictly above; 0.5 or more keeps the matching unique.
    same_label : bool, default True
    """

    def __init__(self, *, min_iou: float = HELD_IOU, same_label: bool = True) -> None:
        if isinstance(min_iou, bool) or not isinstance(min_iou, (int, float)):
            raise InvalidArgument(f"min_iou={min_iou!r} must be a number in [0.5, 1)")
        if not 0.5 <= min_iou < 1:
            raise InvalidArgument(
                f"min_iou={min_iou!r} must be in [0.5, 1): below 0.5 one obstacle could match two"
            )
        if not isinstance(same_label, bool):
            raise InvalidArgument(f"same_label={same_label!r} must be True or False")
        self.min_iou = float(min_iou)
        self.same_label = same_label
        self.name = (
            f"same obstacles(points held IoU > {self.min_iou:g}"
            f"{', same label' if same_label else ''})"
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        if not (_is_box_list(source_output) and _is_box_list(followup_output)):
            # Not obstacles (a point count, a mask): compared exactly.
            return equal().check(source_output, followup_output, context)
        source = as_boxes(source_output, "source")
        followup = as_boxes(followup_output, "follow-up")
        gone, new = unmatched_twins(source, followup)
        moved: list[dict[str, Any]] = []
        if gone or new:
            cloud = getattr(context.source_input, "cloud", context.source_input)
            gone, new, moved = self._pair_by_points(cloud, source, followup, gone, new)
        details: dict[str, Any] = {
            # Every obstacle of either output is judged (the points are the same set).
            "judged": len(source) + len(followup),
            "changed_source": gone,
            "changed_followup": new,
            "same_not_identical": moved,
            "blamed": list(gone),
        }
        if not gone and not new:
            return Verdict(True, self.name, self._information(len(moved)), details)
        return Verdict(
            False, self.name, self._explain(source, followup, gone, new, context), details
        )

    def _pair_by_points(
        self, cloud: Any, source: list[Box], followup: list[Box], gone: list[int], new: list[int]
    ) -> tuple[list[int], list[int], list[dict[str, Any]]]:
        a = held_points(cloud, [source[i] for i in gone])
        b = held_points(cloud, [followup[j] for j in new])
        iou = np.zeros((len(gone), len(new)))
        for r, first in enumerate(a):
            for c, second in enumerate(b):
                if first and second and self._labels_agree(source[gone[r]], followup[new[c]]):
                    iou[r, c] = len(first & second) / len(first | second)
        # Boxes without a point of the sweep are compared by place (a predicted box).
        for r in range(len(gone)):
            for c in range(len(new)):
                if not a[r] and not b[c] and self._same_place(source[gone[r]], followup[new[c]]):
                    iou[r, c] = 1.0
        pairs = []
        taken_rows: set[int] = set()
        taken_cols: set[int] = set()
        for flat in np.argsort(-iou, axis=None):
            r, c = divmod(int(flat), len(new))
            if iou[r, c] <= self.min_iou:
                break
            if r in taken_rows or c in taken_cols:
                continue
            taken_rows.add(r)
            taken_cols.add(c)
            pairs.append((r, c))
        moved = [
            {
                "source": source[gone[r]].describe(),
                "followup": followup[new[c]].describe(),
                "held_iou": round(float(iou[r, c]), 3),
            }
            for r, c in pairs
        ]
        still_gone = [gone[r] for r in range(len(gone)) if r not in taken_rows]
        still_new = [new[c] for c in range(len(new)) if c not in taken_cols]
        return still_gone, still_new, moved

    def _labels_agree(self, first: Box, second: Box) -> bool:
        return not self.same_label or first.label == second.label

    def _same_place(self, first: Box, second: Box) -> bool:
        centre, size, _ = SAME_OBSTACLE
        return (
            self._labels_agree(first, second)
            and math.dist(first.center[:2], second.center[:2]) <= centre
            and all(
                abs(x - y) <= size for x, y in zip(first.size[:2], second.size[:2], strict=True)
            )
        )

    def _information(self, moved: int) -> str:
        if not moved:
            return ""
        return (
            f"{moved} obstacle(s) not identical but holding the same points "
            f"(IoU > {self.min_iou:g}): the same obstacles"
        )

    def _explain(
        self,
        source: list[Box],
        followup: list[Box],
        gone: list[int],
        new: list[int],
        context: CheckContext,
    ) -> str:
        cloud = getattr(context.source_input, "cloud", context.source_input)
        source_held = held_points(cloud, source)
        followup_held = held_points(cloud, followup)
        lines = [
            f"source {source[i].describe()} ({len(source_held[i])} points held) has no "
            f"obstacle of its class holding mostly the same points in follow-up "
            f"{context.index}" + _where(source_held[i], followup, followup_held, "follow-up")
            for i in gone[:_SHOWN]
        ]
        lines += [
            f"follow-up {context.index}'s {followup[j].describe()} ({len(followup_held[j])} "
            "points held) has no obstacle of its class holding mostly the same points in "
            "the source" + _where(followup_held[j], source, source_held, "source")
            for j in new[:_SHOWN]
        ]
        hidden = len(gone) + len(new) - min(len(gone), _SHOWN) - min(len(new), _SHOWN)
        if hidden:
            lines.append(f"... and {hidden} more")
        return "; ".join(lines)


def _where(held: set[int], boxes: list[Box], boxes_held: list[set[int]], side: str) -> str:
    """Where an obstacle's points are on the other side: per obstacle, and in none."""
    if not held:
        return ""
    shares = sorted(
        ((len(held & other), box) for box, other in zip(boxes, boxes_held, strict=True)),
        key=lambda item: -item[0],
    )
    shown = [f"{count} in the {side} {box.describe()}" for count, box in shares if count]
    alone = len(held - set().union(*boxes_held)) if boxes_held else len(held)
    parts = shown[:_SHOWN] + ([f"{alone} in no {side} obstacle"] if alone else [])
    return f" (its points: {', '.join(parts)})"


def _is_box_list(value: Any) -> bool:
    return isinstance(value, (list, tuple)) and all(isinstance(item, Box) for item in value)
