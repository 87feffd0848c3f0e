"""The paper's MR1 protocol as a campaign (Zhou & Sun, CACM 2019, section "Results").

For every source frame, and every noise size n (the paper's 10, 100 and 1000 points),
``followups`` follow-ups add n points uniformly outside the ROI (z and intensity uniform
over the frame's ranges); the system under test runs once on the source and once per
follow-up. The campaign counts the paper's table (``|O| > |O'|``, ``=``, ``<``), strict MR1
violations (some source obstacle without its own match in the follow-up, the
:func:`~pytest_metamorphic.relations.lidar.mr1_subset` relation) and a per-class
breakdown (the paper's Fig. 3), each with a Wilson 95% interval.

Sources are either synthetic street scenes rendered with the HDL-64E beam layout (no data
needed; :func:`synthetic_frames`) or recorded frames (:func:`recorded_frames`, e.g. the
KITTI sweeps with the camera wedge as ROI).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np

from pytest_metamorphic.core.campaign import Campaign
from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.campaign.sources import (
    SourceFn,
    scoped_campaign,
)
from pytest_metamorphic.lidar.followups.perturb import PAPER_NOISE_SIZES, NoiseOutsideROI
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.scope import ScopeLike, obstacles_kept
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, IoUMatcher

__all__ = ["mr1_campaign", "noise_followup"]


def noise_followup(frame: Frame, size: int, rng: np.random.Generator) -> Followup:
    """MR1's follow-up: ``size`` points uniformly outside the frame's ROI.

    The params hold the :class:`NoiseOutsideROI` itself (as the Hypothesis follow-ups do),
    so a violation found here can be reduced like one found by a test.
    """
    noise = NoiseOutsideROI.sample(frame, size, rng=rng)
    return Followup(noise.apply(frame), params=noise.params())


def mr1_campaign(
    system: Callable[[Frame], Sequence[Box]],
    *,
    name: str,
    frames: SourceFn | FrameCatalog | str | os.PathLike[str] | None = None,
    sources: int | None = None,
    sizes: Sequence[int] = PAPER_NOISE_SIZES,
    followups: int = 1,
    seed: int = 0,
    matcher: Matcher | None = None,
    scope: ScopeLike = "roi",
) -> Campaign:
    """The paper's MR1 campaign against ``system``.

    Parameters
    ----------
    system : callable(Frame) -> sequence of Box
        The perception stack under test.
    name : str
        Names the logs and reports; give each system its own.
    frames : source function, FrameCatalog, path, or None
        Where sources come from: None for :func:`synthetic_frames` with its defaults; a
        catalog or a path (a folder, bag or glob, read with ``FrameCatalog``; it must
        attach an ROI, so pass a catalog for recordings without one) for recorded frames.
    sources : int, optional
        S; default 1000 for synthetic sources, every frame for recorded ones.
    sizes : sequence of int
        Noise points per follow-up; the paper's (10, 100, 1000) by default.
    followups : int
        Follow-ups per source and size.
    seed : int
    matcher : Matcher, optional
        When a follow-up obstacle is the same as a source one (default: same label and
        bird's-eye IoU >= 0.5, as :func:`~pytest_metamorphic.relations.lidar.mr1_subset`).
    scope : "roi", "all" or ObstacleScope
        Which obstacles are judged and counted (:mod:`pytest_metamorphic.lidar.judging.scope`):
        by default those whose footprint lies wholly inside the ROI, so a detector
        reporting the whole sweep is not blamed for changes off the road (the table's
        "out of scope" column counts those pairs). ``"all"``: every obstacle.
    """
    return scoped_campaign(
        system,
        name=name,
        frames=frames,
        sources=sources,
        followup=noise_followup,
        relation=lambda chosen: obstacles_kept(matcher=matcher or IoUMatcher(), scope=chosen),
        sizes=sizes,
        followups=followups,
        seed=seed,
        scope=scope,
    )
