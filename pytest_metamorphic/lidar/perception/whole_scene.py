"""A whole-scene variant of the reference pipeline: obstacles over the entire sweep.

Learned detectors (PointPillars, CenterPoint) and most clustering stacks do not drop the
points outside the HD-map ROI first, as Apollo and :class:`~.pipeline.ReferencePerception`
do: they report obstacles everywhere in range. :class:`WholeScenePerception` is the
reference pipeline without its ROI filter, so it behaves like them under the LiDAR
relations: points added or removed outside the ROI change obstacles *outside* it, which
the relations' ROI scope (:mod:`pytest_metamorphic.lidar.scope`) must not call
violations.

Its ground estimate takes each 1 m cell's second-lowest distinct height
(``GroundParams(rank=2)``): with the plain minimum, one stray low return up to 3 m
outside the ROI would lift the road inside it into an "obstacle" that swallows real ones
near the ROI's edge, which is Apollo's ``use_full_cloud`` fault (the ``full_cloud_ground``
mutant) and a real MR1 violation in a whole-scene detector too
(``WholeScenePerception(PerceptionParams(ground=GroundParams(rank=1)))`` shows it).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.lidar.perception.ground import GroundParams
from pytest_metamorphic.lidar.perception.pipeline import PerceptionParams, ReferencePerception

__all__ = ["WHOLE_SCENE_PARAMS", "WholeScenePerception"]

WHOLE_SCENE_PARAMS = PerceptionParams(ground=GroundParams(rank=2))
"""The defaults of :class:`WholeScenePerception`: the reference's, with a rank-2 ground."""


class WholeScenePerception(ReferencePerception):
    """The reference pipeline on every point of the sweep: ``perception(cloud, roi=None)``.

    The ``roi`` argument is accepted and ignored (the detector reports the whole scene),
    so it plugs into the same tests as the reference. Ground removal, segmentation,
    MinBox and classes are the reference's.
    """

    name = "whole_scene"

    def __init__(self, params: PerceptionParams | None = None) -> None:
        super().__init__(params or WHOLE_SCENE_PARAMS)

    def roi_mask(self, points: NDArray[np.float32], roi: Any) -> NDArray[np.bool_]:
        return np.ones(len(points), dtype=bool)

    def with_ground(self, **changes: Any) -> WholeScenePerception:
        """A copy with ground parameters changed, e.g. ``with_ground(rank=1)``."""
        ground = replace(self.params.ground, **changes)
        return WholeScenePerception(replace(self.params, ground=ground))
