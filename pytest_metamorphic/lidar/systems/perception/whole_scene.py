"""A whole-scene variant of the reference pipeline: obstacles over the entire sweep.

Learned detectors (PointPillars, CenterPoint) and most clustering stacks do not drop the
points outside the HD-map ROI first, as Apollo and :class:`~.pipeline.ReferencePerception`
do: they report obstacles everywhere in range. :class:`WholeScenePerception` is the
reference pipeline without its ROI filter, so it behaves like them under the LiDAR
relations: points added or removed outside the ROI change obstacles *outside* it, which
the relations' ROI scope (:mod:`pytest_metamorphic.lidar.judging.scope`) must not call
violations.

Its ground model is split at the ROI's edge, as map-aware stacks model the road surface
apart from off-road terrain: the ground under ROI points comes from ROI points, the
ground elsewhere from the other points. With one ground model across the edge
(``split_ground=False``), one stray low return up to 3 m outside the ROI lifts the road
inside it into an "obstacle" that swallows real ones near the edge: Apollo's
``use_full_cloud`` fault (the ``full_cloud_ground`` mutant), and a real MR1 violation in a
whole-scene detector too (``tests/lidar/systems/perception/test_whole_scene.py`` shows it).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.ground import ground_heights
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    PerceptionParams,
    ReferencePerception,
)

__all__ = ["WholeScenePerception"]


class WholeScenePerception(ReferencePerception):
    """The reference pipeline on every point of the sweep: ``perception(cloud, roi)``.

    Parameters
    ----------
    params : PerceptionParams, optional
        The reference's parameters.
    split_ground : bool
        Model the ground separately inside and outside the ROI (default). False: one
        ground model over the whole sweep, which lets off-road points change on-road
        obstacles near the ROI's edge.

    Notes
    -----
    The ROI only splits the ground model; obstacles are reported everywhere. Without an
    ROI the whole sweep has one ground model.
    """

    name = "whole_scene"

    def __init__(self, params: PerceptionParams | None = None, *, split_ground: bool = True):
        super().__init__(params)
        if not isinstance(split_ground, bool):
            raise InvalidArgument(f"split_ground={split_ground!r} must be True or False")
        self.split_ground = split_ground

    def __repr__(self) -> str:
        return f"WholeScenePerception(split_ground={self.split_ground})"

    def roi_mask(self, points: NDArray[np.float32], roi: Any) -> NDArray[np.bool_]:
        return np.ones(len(points), dtype=bool)  # every point is seen: no ROI filter

    def ground_heights(
        self, points: NDArray[np.float32], sweep: NDArray[np.float32], roi: Any = None
    ) -> NDArray[np.float32]:
        if roi is None or not self.split_ground:
            return ground_heights(points, self.params.ground)
        # The exact polygons, as the scope judges obstacles: every point of a judged
        # obstacle is on the road side, whatever the bitmap does in edge cells.
        inside = np.asarray(roi.contains(points[:, :2], method="exact"), dtype=bool)
        ground = np.empty(len(points), dtype=np.float32)
        ground[inside] = ground_heights(points[inside], self.params.ground)
        ground[~inside] = ground_heights(points[~inside], self.params.ground)
        return ground
