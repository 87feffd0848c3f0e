"""semLidarFuzz's relative metric: a component scored against the labels on both sides.

Where a sweep has ground truth (labelled boxes), a component's output can be scored against
it; after a follow-up, against the follow-up's truth (the boxes the follow-up moved,
mirrored or removed along with the returns). semLidarFuzz (Cheng et al. 2023) calls a
follow-up a failure when the follow-up's score falls below the source's by more than a
tolerance: the component may be imperfect, but the change must not make it worse.

Scores, from the returns inside labelled car, pedestrian and cyclist boxes (the objects),
averaged over the objects both sides hold (a removed object is left out of both):

* a labelling (a ground segmenter): the share of object returns labelled ``NOT_GROUND``;
* a partition (a clusterer): per object, the share of its returns in its largest cluster
  (noise counts as in none), averaged over the objects.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import points_in_boxes
from pytest_metamorphic.lidar.model.point_outputs import (
    NOISE,
    NOT_GROUND,
    PointOutputKind,
    as_point_output,
)

__all__ = ["RelativeScore", "object_scores", "truth_score"]

_OBJECTS = ("car", "pedestrian", "cyclist")
_MIN_RETURNS = 5  # an object held by fewer returns is not scored


def object_scores(frame: Frame, output: Any, kind: PointOutputKind) -> list[float | None]:
    """Per labelled box of ``frame`` (in order), ``output``'s score on that object (the
    module docstring says which); None for a box that is no car, pedestrian or cyclist or
    holds fewer than 5 returns."""
    labels = as_point_output(output, kind, points=len(frame.cloud), name="the output").labels
    held_rows = points_in_boxes(frame.cloud.xyz, frame.boxes)
    scores: list[float | None] = []
    for box, rows in zip(frame.boxes, held_rows, strict=True):
        if box.label not in _OBJECTS or len(rows) < _MIN_RETURNS:
            scores.append(None)
            continue
        held = labels[rows]
        if kind == "labels":
            scores.append(float(np.mean(held == NOT_GROUND)))
        else:
            members = held[held != NOISE]
            largest = int(np.bincount(members - members.min()).max()) if len(members) else 0
            scores.append(largest / len(held))
    return scores


def truth_score(frame: Frame, output: Any, kind: PointOutputKind) -> tuple[float, int]:
    """(mean score, objects scored) of ``output`` against ``frame``'s labelled boxes;
    (nan, 0) when no object holds enough returns."""
    scores = [score for score in object_scores(frame, output, kind) if score is not None]
    return (float(np.mean(scores)) if scores else math.nan), len(scores)


def _paired(source: Frame, followup: Frame) -> list[tuple[int, int]]:
    """Labelled boxes that are the same object on both sides: by position when the
    follow-up kept every box (it turned or mirrored them along), else the boxes it left
    as they were (a removal takes one out)."""
    if len(source.boxes) == len(followup.boxes):
        return [(i, i) for i in range(len(source.boxes))]
    return [
        (i, j)
        for i, box in enumerate(source.boxes)
        for j, other in enumerate(followup.boxes)
        if box == other
    ]


class RelativeScore(Relation):
    """The follow-up's score against its truth is at most ``tolerance`` below the source's
    (:func:`truth_score`). Frames without labelled objects are not judged (counted)."""

    def __init__(self, kind: PointOutputKind, *, tolerance: float = 0.05) -> None:
        if kind not in ("labels", "clusters"):
            raise InvalidArgument(f"kind={kind!r} must be 'labels' or 'clusters'")
        if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)):
            raise InvalidArgument(f"tolerance={tolerance!r} must be a number in [0, 1)")
        if not 0 <= tolerance < 1:
            raise InvalidArgument(f"tolerance={tolerance!r} must be a number in [0, 1)")
        self.kind: PointOutputKind = kind
        self.tolerance = float(tolerance)
        self.name = f"score against the labels falls by at most {self.tolerance:g}"

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source, followup = context.source_input, context.followup_input
        if not isinstance(source, Frame) or not isinstance(followup, Frame):
            raise InvalidArgument("the relative score needs Frame inputs on both sides")
        was = object_scores(source, source_output, self.kind)
        now = object_scores(followup, followup_output, self.kind)
        pairs = [(was[i], now[j]) for i, j in _paired(source, followup)]
        pairs_scored = [(a, b) for a, b in pairs if a is not None and b is not None]
        objects = len(pairs_scored)
        before = float(np.mean([a for a, _ in pairs_scored])) if objects else math.nan
        after = float(np.mean([b for _, b in pairs_scored])) if objects else math.nan
        details = {"source_score": before, "followup_score": after, "judged": objects}
        if objects == 0:
            return Verdict(
                True, self.name, "no labelled object", details | {"judged_nothing": True}
            )
        if after >= before - self.tolerance:
            return Verdict(True, self.name, "", details)
        what = (
            "object returns called not ground"
            if self.kind == "labels"
            else "object returns in their largest cluster"
        )
        return Verdict(
            False,
            self.name,
            f"score {after:.3f} after the follow-up against {before:.3f} before "
            f"({what}, {objects} labelled objects): it fell by {before - after:.3f}, more "
            f"than {self.tolerance:g}",
            details,
        )
