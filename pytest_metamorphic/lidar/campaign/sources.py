"""What every LiDAR campaign shares: where its source frames come from, how its
system, severities and judged obstacles are checked."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from pytest_metamorphic.core.campaign import Campaign
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import Relation
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.fates import obstacle_fates
from pytest_metamorphic.lidar.judging.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors import ScanPattern, as_sensor
from pytest_metamorphic.lidar.synthetic import render
from pytest_metamorphic.lidar.synthetic.layout import random_scene

__all__ = [
    "DEFAULT_SYNTHETIC_SOURCES",
    "SourceFn",
    "box_label",
    "recorded_frames",
    "synthetic_frames",
]

SourceFn = Callable[[np.random.Generator, int], Frame]
DEFAULT_SYNTHETIC_SOURCES = 1000  # the paper's frame count


def synthetic_frames(*, beams: ScanPattern | str = HDL64E, **scene_options: Any) -> SourceFn:
    """Campaign sources: an independent random street scene per source, rendered with
    ``beams`` (a sensor model of :mod:`pytest_metamorphic.lidar.model.sensors` or its key).

    ``scene_options`` go to :func:`~pytest_metamorphic.lidar.synthetic.layout.random_scene` (road
    kinds, obstacle counts and classes, clutter). The render's range noise is seeded from
    the source's own generator, so source ``i`` is the same frame in every run.
    """
    sensor = as_sensor(beams, "beams")
    if sensor is None:
        raise InvalidArgument("beams=None: pass a sensor model or a catalogue key")
    # Validate the options now rather than in the first source.
    random_scene(np.random.default_rng(0), **scene_options)

    def source(rng: np.random.Generator, index: int) -> Frame:
        scene = random_scene(rng, name=f"random-{index}", **scene_options)
        return render(scene, beams=sensor, seed=int(rng.integers(2**31)))

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


def box_label(box: Box) -> str:
    """Per-class breakdown key: the obstacle's label."""
    if not isinstance(box, Box):
        raise InvalidArgument(
            f"the system under test returned {box!r} in its obstacle list; an MR1 "
            "campaign's system must return a list of Box (pytest_metamorphic.lidar.model.obstacles)"
        )
    return box.label


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


def _severities(
    severities: Sequence[int] | None, default: tuple[int, ...], limit: int
) -> tuple[int, ...]:
    levels = tuple(default if severities is None else severities)
    if not levels or not all(
        isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= limit for v in levels
    ):
        raise InvalidArgument(f"severities={severities!r} must be ints in [1, {limit}]")
    return levels


class _Judged:
    """``counted`` of a scoped MR1 campaign: the obstacles the scope judges (picklable)."""

    def __init__(self, scope: ObstacleScope) -> None:
        self.scope = scope

    def __call__(self, boxes: Sequence[Box], frame: Frame) -> list[Box]:
        for box in boxes:
            box_label(box)  # names a non-Box item the way the campaign's own check does
        return self.scope.select(boxes, frame)


def scoped_campaign(
    system: Callable[[Frame], Sequence[Box]],
    *,
    name: str,
    frames: SourceFn | FrameCatalog | str | os.PathLike[str] | None,
    sources: int | None,
    followup: Callable[[Frame, int, np.random.Generator], Any],
    relation: Callable[[ObstacleScope], Relation],
    sizes: Sequence[int],
    followups: int,
    seed: int,
    scope: ScopeLike,
    size_label: str = "n",
    fates: bool = True,
) -> Campaign:
    """A LiDAR campaign whose tables count what ``scope`` judges, broken down by label
    and, where follow-up obstacles lie in the source's frame (``fates``), by what became
    of each violated obstacle; ``relation`` is built from the resolved scope (arguments
    checked before any frame is read)."""
    chosen = as_scope(scope)
    _check_system(system)
    check = relation(chosen)
    source, sources = _frame_source(frames, sources)
    return Campaign(
        name=name,
        source=source,
        followup=followup,
        system=system,
        relation=check,
        sizes=tuple(sizes),
        sources=sources,
        followups=followups,
        seed=seed,
        category=box_label,
        counted=None if chosen.everything else _Judged(chosen),
        size_label=size_label,
        fate=obstacle_fates if fates else None,
    )
