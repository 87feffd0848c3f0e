"""Rigid changes of the scene as campaigns: rotation per angle, the mirror, translation per
shift."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from pytest_metamorphic.core.campaign import Campaign
from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.campaign.sources import (
    SourceFn,
    _severities,
    scoped_campaign,
)
from pytest_metamorphic.lidar.followups.perturb import RotateAboutSensor
from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX, ShiftAlongX
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.equivariance import moved_obstacles
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box

__all__ = [
    "SYMMETRY_SEVERITIES",
    "mirrored_followup",
    "shifted_followup",
    "symmetry_campaign",
    "turned_followup",
]

#: Default severities: the turn in degrees; the mirror has one level (1); the shift along
#: x in metres (either way).
SYMMETRY_SEVERITIES: dict[str, tuple[int, ...]] = {
    "rotation": (90, 180, 270),
    "mirror": (1,),
    "translation": (1, 2, 5, 10),
}
_SEVERITY_LIMITS = {"rotation": 359, "mirror": 1, "translation": 100}
_SEVERITY_LABELS = {"rotation": "degrees", "mirror": "mirror", "translation": "shift m"}


def turned_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """The cloud and the ROI turned by ``severity`` degrees about the sensor."""
    rotation = RotateAboutSensor(math.radians(severity))
    return Followup(rotation.apply(frame), params=rotation.params())


def mirrored_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """The cloud and the ROI reflected in the sensor's x axis (``severity`` is always 1)."""
    mirror = MirrorAcrossX()
    return Followup(mirror.apply(frame), params=mirror.params())


def shifted_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """The cloud, the ROI and the boxes shifted ``severity`` metres along x, forward or
    back at random."""
    move = ShiftAlongX(float(severity) * float(rng.choice((-1.0, 1.0))))
    return Followup(move.apply(frame), params=move.params())


_FOLLOWUPS = {
    "rotation": turned_followup,
    "mirror": mirrored_followup,
    "translation": shifted_followup,
}


def symmetry_campaign(
    system: Callable[[Frame], Sequence[Box]],
    *,
    symmetry: Literal["rotation", "mirror", "translation"],
    name: str,
    frames: SourceFn | FrameCatalog | str | os.PathLike[str] | None = None,
    sources: int | None = None,
    severities: Sequence[int] | None = None,
    followups: int = 1,
    seed: int = 0,
    center_tolerance: float | None = None,
    size_tolerance: float | None = None,
    yaw_tolerance: float | None = None,
    min_points: int | None = None,
    boundary_margin: float | None = None,
    scope: ScopeLike = "roi",
) -> Campaign:
    """Rotation, the mirror or translation as a campaign: how often the obstacles do not
    move with the scene, per angle or shift, with Wilson intervals.

    Parameters
    ----------
    system : callable(Frame) -> sequence of Box
    symmetry : {"rotation", "mirror", "translation"}
        Turn the cloud and the ROI about the sensor (severity: degrees, default 90, 180,
        270), reflect them in the x axis (one level), or shift them and the boxes along x
        (severity: metres, forward or back at random; default 1, 2, 5, 10). Checked as
        :func:`~pytest_metamorphic.relations.lidar.rotation_equivariance`,
        ``mirror_symmetry`` and ``translation_equivariance`` check (see
        :class:`~pytest_metamorphic.lidar.judging.equivariance.MovedObstacles`).
    name, frames, sources, followups, seed, scope
        As for :func:`~pytest_metamorphic.lidar.campaign.mr1_campaign`.
    severities : sequence of int, optional
        Default :data:`SYMMETRY_SEVERITIES` for the symmetry.
    center_tolerance, size_tolerance, yaw_tolerance, min_points, boundary_margin
        Default: a quarter turn's (10 cm, 15 cm, 5 degrees, any size, 0.5 m from the ROI's
        edge, labels compared) for the mirror, translation and rotations by multiples of
        90 degrees; for other angles those of ``rotation_equivariance(angles="any")``
        (0.8 m, 0.8 m, 20 degrees, >= 30 points, 1 m, labels not compared).
    """
    if symmetry not in _FOLLOWUPS:
        raise InvalidArgument(f"symmetry={symmetry!r} must be one of {sorted(_FOLLOWUPS)}")
    levels = _severities(severities, SYMMETRY_SEVERITIES[symmetry], _SEVERITY_LIMITS[symmetry])
    quarter = symmetry != "rotation" or all(level % 90 == 0 for level in levels)
    return scoped_campaign(
        system,
        name=name,
        frames=frames,
        sources=sources,
        followup=_FOLLOWUPS[symmetry],
        relation=lambda chosen: moved_obstacles(
            symmetry,
            quarter_turns=quarter,
            center_tolerance=center_tolerance,
            size_tolerance=size_tolerance,
            yaw_tolerance=yaw_tolerance,
            min_points=min_points,
            boundary_margin=boundary_margin,
            scope=chosen,
        ),
        sizes=levels,
        followups=followups,
        seed=seed,
        scope=scope,
        size_label=_SEVERITY_LABELS[symmetry],
        fates=False,  # follow-up obstacles lie in a turned, mirrored or shifted frame
    )
