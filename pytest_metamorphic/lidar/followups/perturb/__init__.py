"""Deterministic frame perturbations for follow-up inputs, usable with or without Hypothesis.

Each perturbation is a small value object with ``apply(frame) -> Frame``, ``params()``
(what a :class:`~pytest_metamorphic.core.engine.Followup` records) and a ``repr`` short
enough for failure messages:

* :class:`NoiseOutsideROI` - the paper's MR1 recipe (Zhou & Sun, CACM 2019): n points with
  (x, y) uniform over the sensor's range *outside* the ROI, z uniform in the frame's
  [min z, max z], intensity uniform in the frame's [min, max] intensity. "Outside" holds
  for the exact polygons and for Apollo's 0.25 m bitmap, with at least one free cell
  between every injected point and every set cell.
* :class:`NoiseInsideROI` - points inside the ROI (both methods) and away from obstacles.
* :class:`DropPoints`, :class:`DuplicatePoints`, :class:`PermutePoints`.
* :class:`RotateAboutSensor` - the cloud, the ROI and the boxes turned together about z.

Noise points are built from one integer seed per point through a counter-based hash
(SplitMix64, :mod:`.seeds`), so a list of small integers is a complete, replayable
description: Hypothesis shrinks noise by deleting seeds, campaign code draws seeds from a
numpy generator, and the same seeds always give the same points.

:mod:`.noise` holds the injected points, :mod:`.edits` the point edits and the rotation,
:mod:`.seeds` the hash; everything is importable from here.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from pytest_metamorphic.lidar.followups.perturb.edits import (
    DropPoints,
    DuplicatePoints,
    PermutePoints,
    RotateAboutSensor,
)
from pytest_metamorphic.lidar.followups.perturb.noise import (
    NOISE_INSTANCE,
    PAPER_NOISE_SIZES,
    NoiseInsideROI,
    NoiseOutsideROI,
    PreparedNoise,
    append_points,
)
from pytest_metamorphic.lidar.followups.perturb.seeds import SEED_BITS, seeded_uniforms
from pytest_metamorphic.lidar.model.frame import Frame

__all__ = [
    "NOISE_INSTANCE",
    "PAPER_NOISE_SIZES",
    "SEED_BITS",
    "DropPoints",
    "DuplicatePoints",
    "NoiseInsideROI",
    "NoiseOutsideROI",
    "PermutePoints",
    "Perturbation",
    "PreparedNoise",
    "RotateAboutSensor",
    "append_points",
    "seeded_uniforms",
]


@runtime_checkable
class Perturbation(Protocol):
    """A deterministic change to a frame (the "input transform" of a metamorphic relation)."""

    def apply(self, frame: Frame) -> Frame:
        """The perturbed frame; ``frame`` is not modified."""
        ...

    def params(self) -> dict[str, Any]:
        """Parameters to record with the follow-up (shown in failure reports)."""
        ...
