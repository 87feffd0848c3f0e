"""What became of an obstacle a relation says is missing: lost, merged, split, relabelled
or changed.

A violation of MR1 says that a source obstacle has no match in the follow-up; for an
engineer the next question is *how* it went missing, because each points at a different
stage of a perception stack:

``lost``
    nothing in the follow-up covers its footprint (segmentation or a filter dropped it);
``merged``
    one follow-up obstacle covers most of it and most of another source obstacle
    (clustering joined them: the paper's Fig. 4 case, two pedestrians become one);
``split``
    two or more follow-up obstacles each lie mostly inside its footprint (clustering
    broke it up);
``relabelled``
    a follow-up obstacle in its place (bird's-eye IoU >= ``match_iou``) has another label
    (the classifier changed its mind);
``changed``
    something overlaps it, but moved, grown, shrunk or turned beyond the matcher's
    tolerance (box fitting).

The words are judged on footprints alone (bird's-eye areas shared by boxes, exact for
rotated boxes), in the order above from the second on: a follow-up obstacle that both
merges and relabels counts as a merge. They explain a violation; they never decide one
(the relation does).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import Box, as_boxes, bev_intersection

__all__ = ["FATES", "obstacle_fates"]

FATES = ("lost", "merged", "split", "relabelled", "changed")

_MOSTLY = 0.5  # share of a footprint that counts as "most of it"
_TOUCHED = 0.1  # share of the source footprint below which an overlap is not there at all


def obstacle_fates(
    source: Sequence[Box],
    followup: Sequence[Box],
    indices: Sequence[int],
    *,
    match_iou: float = 0.5,
) -> list[str]:
    """The fate of each source obstacle ``source[i]`` for ``i`` in ``indices``.

    Parameters
    ----------
    source, followup : sequence of Box
        The system's obstacles on the source and on the follow-up, in one frame (for a
        turned or mirrored follow-up, move its boxes back first).
    indices : sequence of int
        The source obstacles to explain (those the relation blames).
    match_iou : float
        Bird's-eye IoU from which a follow-up obstacle stands in the source one's place
        (the matcher's threshold; only ``relabelled`` uses it).

    Returns
    -------
    list of str
        One of :data:`FATES` per index.
    """
    source_boxes = as_boxes(source, "source")
    followup_boxes = as_boxes(followup, "followup")
    for i in indices:
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise InvalidArgument(f"indices must be ints, got {i!r}")
        if not 0 <= i < len(source_boxes):
            raise InvalidArgument(f"index {i} is not one of the {len(source_boxes)} source boxes")
    if not followup_boxes:
        return ["lost"] * len(indices)
    shared = bev_intersection(source_boxes, followup_boxes)
    source_area = np.array([box.footprint_area() for box in source_boxes])
    followup_area = np.array([box.footprint_area() for box in followup_boxes])
    # covers[s, f]: follow-up f covers most of source s; inside[s, f]: f lies mostly in s
    covers = shared >= _MOSTLY * source_area[:, None]
    inside = shared >= _MOSTLY * followup_area[None, :]
    iou = shared / (source_area[:, None] + followup_area[None, :] - shared)
    return [
        _fate(int(i), source_boxes, followup_boxes, shared, covers, inside, iou, match_iou)
        for i in indices
    ]


def _fate(
    i: int,
    source: list[Box],
    followup: list[Box],
    shared: np.ndarray,
    covers: np.ndarray,
    inside: np.ndarray,
    iou: np.ndarray,
    match_iou: float,
) -> str:
    if shared[i].max() < _TOUCHED * source[i].footprint_area():
        return "lost"
    others = np.arange(len(source)) != i
    if np.any(covers[i] & covers[others].any(axis=0)):
        return "merged"
    if int(inside[i].sum()) >= 2:
        return "split"
    same_place = iou[i] >= match_iou
    if any(followup[f].label != source[i].label for f in np.flatnonzero(same_place)):
        return "relabelled"
    return "changed"
