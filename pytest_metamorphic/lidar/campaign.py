"""The paper's MR1 protocol as a campaign (Zhou & Sun, CACM 2019, section "Results").

For every source frame, and every noise size n (the paper's 10, 100 and 1000 points),
``followups`` follow-ups add n points uniformly outside the ROI (z and intensity uniform
over the frame's ranges); the system under test runs once on the source and once per
follow-up. The campaign counts the paper's table (|O| > |O'|, =, <), strict MR1
violations (some source obstacle without its own match in the follow-up, the
:func:`~pytest_metamorphic.relations.lidar.mr1_subset` relation) and a per-class
breakdown (the paper's Fig. 3), each with a Wilson 95% interval.

Sources are either synthetic street scenes rendered with the HDL-64E beam layout (no data
needed; :func:`synthetic_frames`) or recorded frames (:func:`recorded_frames`, e.g. the
KITTI sweeps with the camera wedge as ROI).

Examples
--------
>>> from pytest_metamorphic.core.campaign import campaign_test
>>> from pytest_metamorphic.lidar.campaign import mr1_campaign
>>> test_mr1 = campaign_test(mr1_campaign(my_perception, name="MR1 my stack"))  # doctest: +SKIP

and run ``pytest --mt-campaign``.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Sequence
from typing import Any, Literal

import numpy as np

from pytest_metamorphic.core.campaign import Campaign
from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.core.relations import Relation
from pytest_metamorphic.lidar.edit import OthersKept, RemoveObject, removal_candidates
from pytest_metamorphic.lidar.faults import (
    PACKET_DEGREES,
    CoveredObstaclesKept,
    DropAzimuthBlock,
    DropRings,
    QuantizeRange,
)
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.insert import (
    InsertedDetected,
    InsertObject,
    ObjectTemplate,
    free_placements,
    object_templates,
)
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.layout import random_scene
from pytest_metamorphic.lidar.obstacles import Box, IoUMatcher
from pytest_metamorphic.lidar.perturb import PAPER_NOISE_SIZES, SEED_BITS, NoiseOutsideROI
from pytest_metamorphic.lidar.scene import render
from pytest_metamorphic.lidar.scope import ObstacleScope, ScopeLike, as_scope, obstacles_kept
from pytest_metamorphic.lidar.weather import Weather

__all__ = [
    "EDIT_SEVERITIES",
    "FAULT_SEVERITIES",
    "box_label",
    "dead_beams_followup",
    "edit_campaign",
    "fault_campaign",
    "fog_followup",
    "insertion_followup",
    "lost_packets_followup",
    "mr1_campaign",
    "noise_followup",
    "quantized_followup",
    "rain_followup",
    "recorded_frames",
    "removal_followup",
    "synthetic_frames",
]

SourceFn = Callable[[np.random.Generator, int], Frame]
DEFAULT_SYNTHETIC_SOURCES = 1000  # the paper's frame count


def synthetic_frames(*, beams: BeamLayout = HDL64E, **scene_options: Any) -> SourceFn:
    """Campaign sources: an independent random street scene per source, rendered.

    ``scene_options`` go to :func:`~pytest_metamorphic.lidar.layout.random_scene` (road
    kinds, obstacle counts and classes, clutter). The render's range noise is seeded from
    the source's own generator, so source ``i`` is the same frame in every run.
    """
    if not isinstance(beams, BeamLayout):
        raise InvalidArgument(f"beams must be a BeamLayout, got {type(beams).__name__}")
    # Validate the options now rather than in the first source.
    random_scene(np.random.default_rng(0), **scene_options)

    def source(rng: np.random.Generator, index: int) -> Frame:
        scene = random_scene(rng, name=f"random-{index}", **scene_options)
        return render(scene, beams=beams, seed=int(rng.integers(2**31)))

    return source


def recorded_frames(catalog: FrameCatalog) -> SourceFn:
    """Campaign sources: frame ``i`` of a :class:`FrameCatalog` for source ``i``.

    The frames need an ROI (``FrameCatalog(..., roi=...)``). A campaign over recorded
    frames has at most ``len(catalog)`` sources (the default).
    """
    if not isinstance(catalog, FrameCatalog):
        raise InvalidArgument(f"catalog must be a FrameCatalog, got {type(catalog).__name__}")
    if catalog.roi is None:
        raise InvalidArgument(
            f"{catalog!r} attaches no ROI; MR1 needs one (FrameCatalog(..., roi=...))"
        )

    return _Recorded(catalog)


class _Recorded:
    """Source ``i`` is frame ``i``; ``len()`` caps the campaign's source count."""

    def __init__(self, catalog: FrameCatalog) -> None:
        self.catalog = catalog

    def __call__(self, rng: np.random.Generator, index: int) -> Frame:
        return self.catalog.load(index)

    def __len__(self) -> int:
        return len(self.catalog)

    def __repr__(self) -> str:
        return f"recorded_frames({self.catalog!r})"


def noise_followup(frame: Frame, size: int, rng: np.random.Generator) -> Followup:
    """MR1's follow-up: ``size`` points uniformly outside the frame's ROI.

    The params hold the :class:`NoiseOutsideROI` itself (as the Hypothesis follow-ups do),
    so a violation found here can be reduced like one found by a test.
    """
    noise = NoiseOutsideROI.sample(frame, size, rng=rng)
    return Followup(noise.apply(frame), params=noise.params())


def box_label(box: Box) -> str:
    """Per-class breakdown key: the obstacle's label."""
    if not isinstance(box, Box):
        raise InvalidArgument(
            f"the system under test returned {box!r} in its obstacle list; an MR1 "
            "campaign's system must return a list of Box (pytest_metamorphic.lidar.obstacles)"
        )
    return box.label


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
        Which obstacles are judged and counted (:mod:`pytest_metamorphic.lidar.scope`):
        by default those with at least half their footprint inside the ROI, so a detector
        reporting the whole sweep is not blamed for changes off the road (the table's
        "out of scope" column counts those pairs). ``"all"``: every obstacle.
    """
    chosen = as_scope(scope)
    _check_system(system)
    source, sources = _frame_source(frames, sources)
    return Campaign(
        name=name,
        source=source,
        followup=noise_followup,
        system=system,
        relation=obstacles_kept(matcher=matcher or IoUMatcher(), scope=chosen),
        sizes=tuple(sizes),
        sources=sources,
        followups=followups,
        seed=seed,
        category=box_label,
        counted=None if chosen.everything else _Judged(chosen),
    )


def _check_system(system: Any) -> None:
    if not callable(system):
        raise InvalidArgument(f"system={system!r} must be callable (Frame -> list of Box)")


def _frame_source(frames: Any, sources: int | None) -> tuple[SourceFn, int]:
    """The campaign's source function and source count, from the ``frames`` argument."""
    if frames is None:
        source = synthetic_frames()
    elif isinstance(frames, FrameCatalog):
        source = recorded_frames(frames)
    elif isinstance(frames, (str, os.PathLike)):
        source = recorded_frames(FrameCatalog(frames))
    elif callable(frames):
        source = frames
    else:
        raise InvalidArgument(
            f"frames={frames!r} must be None, a source function, a FrameCatalog or a path"
        )
    available = len(source) if hasattr(source, "__len__") else None
    if sources is None:
        sources = DEFAULT_SYNTHETIC_SOURCES if available is None else available
    elif available is not None and isinstance(sources, int) and sources > available:
        raise InvalidArgument(f"sources={sources} but the recording holds {available} frames")
    return source, sources


# -- sensor faults: robustness curves per relation ---------------------------------------------

#: Default severities: dead lasers (of 64), lost packets (of 1.04 degrees each). The
#: relation holds for the reference pipeline up to 8 dead lasers on the KITTI sweeps; with
#: 16 it loses 1 well-covered obstacle in 24 follow-ups (beyond the relation's validity).
#: Fog and rain: the visibility in metres (smaller is worse); quantisation: the range step
#: in centimetres.
FAULT_SEVERITIES: dict[str, tuple[int, ...]] = {
    "beam_loss": (1, 2, 4, 8),
    "packet_loss": (1, 5, 10, 20, 40),
    "fog": (400, 200, 100, 50),
    "rain": (400, 200, 100, 50),
    "quantization": (5, 10, 20),
}
_SEVERITY_LIMITS = {
    "beam_loss": HDL64E.lasers,
    "packet_loss": int(360 / PACKET_DEGREES),
    "fog": 100_000,
    "rain": 100_000,
    "quantization": 100,
}


def _severities(
    severities: Sequence[int] | None, default: tuple[int, ...], limit: int
) -> tuple[int, ...]:
    levels = tuple(default if severities is None else severities)
    if not levels or not all(
        isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= limit for v in levels
    ):
        raise InvalidArgument(f"severities={severities!r} must be ints in [1, {limit}]")
    return levels


def dead_beams_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """``severity`` random lasers of the HDL-64E return nothing."""
    rings = rng.choice(HDL64E.lasers, size=severity, replace=False)
    fault = DropRings(tuple(int(r) for r in rings))
    return Followup(fault.apply(frame), params=fault.params())


def lost_packets_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """``severity`` consecutive packets lost, from a random azimuth."""
    start = float(rng.uniform(0.0, 2 * math.pi))
    fault = DropAzimuthBlock(start, math.radians(PACKET_DEGREES * severity))
    return Followup(fault.apply(frame), params={**fault.params(), "packets": severity})


def fog_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """Fog of ``severity`` metres visibility (see :mod:`pytest_metamorphic.lidar.weather`)."""
    weather = Weather(float(severity), "fog", int(rng.integers(2**SEED_BITS)))
    return Followup(weather.apply(frame), params=weather.params())


def rain_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """Rain of ``severity`` metres visibility."""
    weather = Weather(float(severity), "rain", int(rng.integers(2**SEED_BITS)))
    return Followup(weather.apply(frame), params=weather.params())


def quantized_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """Every range rounded to ``severity`` centimetres."""
    fault = QuantizeRange(severity / 100.0)
    return Followup(fault.apply(frame), params=fault.params())


_FAULT_FOLLOWUPS = {
    "beam_loss": dead_beams_followup,
    "packet_loss": lost_packets_followup,
    "fog": fog_followup,
    "rain": rain_followup,
    "quantization": quantized_followup,
}


def fault_campaign(
    system: Callable[[Frame], Sequence[Box]],
    *,
    fault: Literal["beam_loss", "packet_loss", "fog", "rain", "quantization"],
    name: str,
    frames: SourceFn | FrameCatalog | str | os.PathLike[str] | None = None,
    sources: int | None = None,
    severities: Sequence[int] | None = None,
    followups: int = 1,
    seed: int = 0,
    min_points: int = 30,
    min_share: float | None = None,
    min_height_share: float = 0.8,
    min_detected: float = 0.5,
    scope: ScopeLike = "roi",
) -> Campaign:
    """A sensor-fault relation as a campaign: violation rates per severity, with Wilson
    intervals, i.e. a robustness curve per relation (Robo3D reports mAP drops; this
    reports how often a well-covered obstacle is lost).

    Parameters
    ----------
    system : callable(Frame) -> sequence of Box
    fault : {"beam_loss", "packet_loss", "fog", "rain", "quantization"}
        Dead lasers (severity: how many of the 64), lost packets (severity: how many
        consecutive 1.04-degree blocks), fog and rain (severity: the visibility in
        metres; obstacles farther than it are not judged), or a coarser range resolution
        (severity: the step in centimetres).
    name, frames, sources, followups, seed, scope
        As for :func:`mr1_campaign`.
    severities : sequence of int, optional
        Default :data:`FAULT_SEVERITIES` for the fault.
    min_points, min_share, min_height_share, min_detected
        What counts as well covered and as kept
        (:class:`~pytest_metamorphic.lidar.faults.CoveredObstaclesKept`); ``min_share``
        defaults to 0.8 for fog and rain (as
        :func:`~pytest_metamorphic.relations.lidar.adverse_weather`) and 0.5 otherwise.
    """
    if fault not in _FAULT_FOLLOWUPS:
        raise InvalidArgument(f"fault={fault!r} must be one of {sorted(_FAULT_FOLLOWUPS)}")
    chosen = as_scope(scope)
    _check_system(system)
    levels = _severities(severities, FAULT_SEVERITIES[fault], _SEVERITY_LIMITS[fault])
    weather = fault in ("fog", "rain")
    if min_share is None:
        min_share = 0.8 if weather else 0.5
    source, sources = _frame_source(frames, sources)
    return Campaign(
        name=name,
        source=source,
        followup=_FAULT_FOLLOWUPS[fault],
        system=system,
        relation=CoveredObstaclesKept(
            min_points=min_points,
            min_share=min_share,
            min_height_share=min_height_share,
            min_detected=min_detected,
            scope=chosen,
            range_param="visibility_m" if weather else None,
        ),
        sizes=levels,
        sources=sources,
        followups=followups,
        seed=seed,
        category=box_label,
        counted=None if chosen.everything else _Judged(chosen),
    )


class _Judged:
    """``counted`` of a scoped MR1 campaign: the obstacles the scope judges (picklable)."""

    def __init__(self, scope: ObstacleScope) -> None:
        self.scope = scope

    def __call__(self, boxes: Sequence[Box], frame: Frame) -> list[Box]:
        for box in boxes:
            box_label(box)  # names a non-Box item the way the campaign's own check does
        return self.scope.select(boxes, frame)


# -- object edits: insertion and removal as campaigns ------------------------------------------

#: Default severities: insertion at this percentage of the range the object was seen at
#: (nearer, the same, farther); removal of the k-th nearest object.
EDIT_SEVERITIES: dict[str, tuple[int, ...]] = {
    "insertion": (80, 100, 125, 150),
    "removal": (1, 2, 3, 4),
}


@functools.lru_cache(maxsize=4)
def _templates(frame: Frame) -> tuple[ObjectTemplate, ...]:
    return tuple(object_templates(frame))


def insertion_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """One of the frame's own cars, pedestrians or cyclists inserted again, at
    ``severity`` percent of the range it was seen at, at a random free place (none
    edited when there is no such place)."""
    factor = severity / 100.0
    places = [
        (template, placement)
        for template in _templates(frame)
        for placement in free_placements(frame, template, limit=8, factors=(factor,))
    ]
    if not places:
        return Followup(frame, params={"insert_object": None})
    template, placement = places[int(rng.integers(len(places)))]
    insertion = InsertObject.onto(frame, template, placement)
    return Followup(insertion.apply(frame), params=insertion.params())


def removal_followup(frame: Frame, severity: int, rng: np.random.Generator) -> Followup:
    """The ``severity``-th nearest car, pedestrian or cyclist removed (none when the frame
    has fewer)."""
    candidates = removal_candidates(frame)
    if len(candidates) < severity:
        return Followup(frame, params={"remove_object": None})
    removal = RemoveObject(candidates[severity - 1])
    return Followup(removal.apply(frame), params=removal.params())


_EDIT_FOLLOWUPS = {"insertion": insertion_followup, "removal": removal_followup}


def edit_campaign(
    system: Callable[[Frame], Sequence[Box]],
    *,
    edit: Literal["insertion", "removal"],
    name: str,
    frames: SourceFn | FrameCatalog | str | os.PathLike[str] | None = None,
    sources: int | None = None,
    severities: Sequence[int] | None = None,
    followups: int = 1,
    seed: int = 0,
    clearance: float = 5.0,
    min_points: int = 30,
    min_detected: float = 0.5,
    matcher: Matcher | None = None,
    scope: ScopeLike = "roi",
) -> Campaign:
    """Object insertion or removal as a campaign: violation rates per severity, with
    Wilson intervals.

    Parameters
    ----------
    system : callable(Frame) -> sequence of Box
    edit : {"insertion", "removal"}
        Insertion (severity: the range, in percent of the range the object was seen at;
        checked with :class:`~pytest_metamorphic.lidar.insert.InsertedDetected` and
        :class:`~pytest_metamorphic.lidar.edit.OthersKept`) or removal (severity: which
        object, nearest first; checked with ``OthersKept``). A follow-up that finds no
        place or no object edits nothing and holds.
    name, frames, sources, followups, seed, scope
        As for :func:`mr1_campaign`.
    clearance, min_points, min_detected, matcher
        As for :func:`~pytest_metamorphic.relations.lidar.object_insertion`.
    """
    if edit not in _EDIT_FOLLOWUPS:
        raise InvalidArgument(f"edit={edit!r} must be one of {sorted(_EDIT_FOLLOWUPS)}")
    chosen = as_scope(scope)
    _check_system(system)
    levels = _severities(severities, EDIT_SEVERITIES[edit], 1000)
    kept = OthersKept(clearance=clearance, matcher=matcher, scope=chosen)
    relation: Relation = kept
    if edit == "insertion":
        found = InsertedDetected(min_points=min_points, min_detected=min_detected, scope=chosen)
        relation = found & kept
    source, sources = _frame_source(frames, sources)
    return Campaign(
        name=name,
        source=source,
        followup=_EDIT_FOLLOWUPS[edit],
        system=system,
        relation=relation,
        sizes=levels,
        sources=sources,
        followups=followups,
        seed=seed,
        category=box_label,
        counted=None if chosen.everything else _Judged(chosen),
    )
