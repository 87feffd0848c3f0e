"""Detected or ground-truth obstacles as 3-D boxes in the sensor frame.

:mod:`.box`: the :class:`Box` type, exact bird's-eye IoU of rotated boxes, centre
distances and per-class size priors; :mod:`.points`: the points inside boxes and their
distance to them; :mod:`.matching`: the matchers the subset relation pairs source and
follow-up detections with. Everything is importable from here.
"""

from pytest_metamorphic.lidar.model.obstacles.box import (
    LABELS,
    SIZE_PRIORS,
    Box,
    Label,
    SizePrior,
    as_boxes,
    bev_intersection,
    bev_iou,
    center_distances,
)
from pytest_metamorphic.lidar.model.obstacles.matching import (
    ROUNDING,
    CenterDistanceMatcher,
    IoUMatcher,
    unmatched_twins,
)
from pytest_metamorphic.lidar.model.obstacles.points import (
    box_gap,
    box_support,
    footprint_distances,
    points_in_boxes,
    share_inside,
)

__all__ = [
    "LABELS",
    "ROUNDING",
    "SIZE_PRIORS",
    "Box",
    "CenterDistanceMatcher",
    "IoUMatcher",
    "Label",
    "SizePrior",
    "as_boxes",
    "bev_intersection",
    "bev_iou",
    "box_gap",
    "box_support",
    "center_distances",
    "footprint_distances",
    "points_in_boxes",
    "share_inside",
    "unmatched_twins",
]
