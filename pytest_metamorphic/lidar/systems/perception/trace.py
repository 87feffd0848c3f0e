"""The reference pipeline as stages, for stage blame
(:mod:`pytest_metamorphic.lidar.systems.stages`).

:func:`reference_stages` runs :class:`~.pipeline.ReferencePerception` (or a mutant of it)
stage by stage, as :meth:`~.pipeline.ReferencePerception.run` does, and keeps each
stage's output, indexed like the frame's returns:

==================  ===============================================  ======================
stage               output                                           methods (mutants)
==================  ===============================================  ======================
``input``           which returns the pipeline works on              ``prepare``
``roi filter``      which of them are in the ROI                     ``roi_mask``
``ground removal``  which of those are obstacle returns              ``ground_heights``,
                                                                     ``obstacle_mask``
``segmentation``    their objects (a partition)                      ``segment``
``objects``         the boxes built, kept and classified             ``build_boxes``,
                                                                     ``keep_objects``,
                                                                     ``fit_boxes``,
                                                                     ``classify``
``output``          the boxes reported                               ``review_boxes``
==================  ===============================================  ======================

A return the ``input`` stage replaced (a voxel filter's representative point) is matched to
the frame's returns by its coordinates; the frame's repeated returns share one value.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.judging.correspondence import row_keys
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.systems.perception.pipeline import ReferencePerception, sweep_and_roi
from pytest_metamorphic.lidar.systems.stages import StageOutput

__all__ = ["STAGE_METHODS", "ReferenceStages", "reference_stages"]

STAGE_METHODS: dict[str, tuple[str, ...]] = {
    "input": ("prepare",),
    "roi filter": ("roi_mask",),
    "ground removal": ("ground_heights", "obstacle_mask"),
    "segmentation": ("segment",),
    "objects": ("build_boxes", "keep_objects", "fit_boxes", "classify"),
    "output": ("review_boxes",),
}
"""Which methods of :class:`~.pipeline.ReferencePerception` each stage runs: a mutant that
overrides one changes that stage."""


def _on_returns(
    frame_keys: NDArray[np.uint64], rows: NDArray[np.float32], values: Any
) -> NDArray[np.int64]:
    """Per-return values: each frame return takes the value of a stage row with its
    coordinates (0 where none: the stage did not pass it on)."""
    out = np.zeros(len(frame_keys), dtype=np.int64)
    if len(rows) == 0:
        return out
    keys = row_keys(rows[:, :3])
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    at = np.minimum(np.searchsorted(sorted_keys, frame_keys), len(keys) - 1)
    found = sorted_keys[at] == frame_keys
    out[found] = np.asarray(values, dtype=np.int64)[order[at[found]]]
    return out


class ReferenceStages:
    """:class:`~.pipeline.ReferencePerception` (or a mutant) as stages: ``trace(frame)``."""

    def __init__(self, system: ReferencePerception) -> None:
        if not isinstance(system, ReferencePerception):
            raise InvalidArgument(
                f"system={system!r} must be the reference pipeline or a mutant of it"
            )
        self.system = system

    def __repr__(self) -> str:
        return f"reference_stages({self.system!r})"

    def trace(self, frame: Frame) -> list[StageOutput]:
        system = self.system
        points, roi = sweep_and_roi(frame, None)
        keys = row_keys(frame.cloud.xyz)
        sweep = system.prepare(points)
        inside = system.roi_mask(sweep, roi)
        in_roi = np.compress(inside, sweep, axis=0)
        ground_z = system.ground_heights(in_roi, sweep, roi)
        keep = system.obstacle_mask(in_roi, ground_z, sweep)
        obstacles = np.compress(keep, in_roi, axis=0)
        clusters = system.segment(obstacles, sweep)
        built = system.build_boxes(obstacles, ground_z[keep], clusters)
        reported = system.review_boxes(built, in_roi)
        ones = np.ones(len(sweep), dtype=np.int64)
        objects = _on_returns(keys, obstacles, np.asarray(clusters.labels) + 1) - 1
        return [
            StageOutput("input", "labels", _on_returns(keys, sweep, ones), passes=True),
            StageOutput(
                "roi filter",
                "labels",
                _on_returns(keys, in_roi, ones[: len(in_roi)]),
                within_roi=True,
                passes=True,
            ),
            StageOutput(
                "ground removal",
                "labels",
                _on_returns(keys, obstacles, ones[: len(obstacles)]),
                within_roi=True,
                passes=True,
            ),
            StageOutput("segmentation", "clusters", objects, passes=True),
            StageOutput("objects", "boxes", list(built), passes=True),
            StageOutput("output", "boxes", list(reported), passes=True),
        ]


def reference_stages(system: ReferencePerception | None = None) -> ReferenceStages:
    """The reference pipeline (default) or ``system``, a mutant of it, as stages."""
    return ReferenceStages(system if system is not None else ReferencePerception())
