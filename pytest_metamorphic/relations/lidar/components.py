"""Relations for the components of a stack: ground segmenters and clusterers, point by point.

A component's output says something about every return (a
:class:`~pytest_metamorphic.lidar.model.point_outputs.PointLabels` or a
:class:`~pytest_metamorphic.lidar.model.point_outputs.Partition`), so its relations say what
must happen to each return: the follow-ups are those of the obstacle relations (the same
strategies, shrinking alike), and the output relation is
:class:`~pytest_metamorphic.lidar.judging.points.PointsKeepLabels`.

==========================  ==================================  ===========================
relation                    follow-up                           every judged return ...
==========================  ==================================  ===========================
:func:`reordered_returns`   points reordered                    keeps its label / cluster
:func:`repeated_returns`    some points repeated                keeps it; a repeat takes
                                                                its original's
:func:`noise_locality`      noise outside the ROI (MR1's)       keeps it beyond ``radius``
                                                                of the noise
:func:`removal_locality`    one car, pedestrian or cyclist      keeps it beyond ``radius``
                            removed, its beams re-cast          of the change
:func:`turned_returns`      cloud and ROI turned 90/180/270°    keeps it (if symmetric)
:func:`mirrored_returns`    cloud and ROI mirrored              keeps it (if symmetric)
:func:`repeated_sweep`      the sweep again after other sweeps  keeps it (per-sweep)
==========================  ==================================  ===========================

**Locality is a claim with a radius.** A component whose decision for a return depends on
the returns around it (a local ground height, DBSCAN's ``eps``-neighbourhood) keeps its
labels beyond that neighbourhood; a component that fits regions (Patchwork++'s zones of up
to tens of metres) or chains neighbourhoods (DBSCAN clusters can be joined by a bridge of
added points) does not, and that is a property of the algorithm, not a defect: choose
``radius`` from the component's design, and read a violation's distance to the change
(every explanation states it) before calling it a defect. ``docs/findings/`` classifies
what these relations found on the components people compose.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal

from pytest_metamorphic.core.engine import MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.judging.points import PointsKeepLabels
from pytest_metamorphic.lidar.judging.relative import RelativeScore
from pytest_metamorphic.lidar.model.point_outputs import PointOutputKind
from pytest_metamorphic.relations.lidar._common import lidar_relation
from pytest_metamorphic.relations.lidar.geometry import mirror_symmetry, rotation_equivariance
from pytest_metamorphic.relations.lidar.history import history_independence
from pytest_metamorphic.relations.lidar.invariance import (
    duplication_invariance,
    permutation_invariance,
)
from pytest_metamorphic.relations.lidar.noise import (
    DEFAULT_NOISE,
    NoiseSize,
    _check_noise,
    mr1_subset,
)
from pytest_metamorphic.relations.lidar.objects import object_removal

__all__ = [
    "DEFAULT_RADIUS",
    "EDGE_MARGIN",
    "component_relations",
    "mirrored_returns",
    "noise_locality",
    "relative_relations",
    "removal_locality",
    "reordered_returns",
    "repeated_returns",
    "repeated_sweep",
    "turned_returns",
]

DEFAULT_RADIUS = 2.0
"""Metres from a change within which a return is not judged: twice the reference ground
stage's 1 m cell, four times a typical DBSCAN ``eps`` of 0.5 m."""

EDGE_MARGIN = 0.5
"""Metres from the ROI's edge within which turns and mirrors judge no return: the turned
ROI is rasterised afresh (0.25 m cells), so what an ROI-first component is fed differs
there (the margin of :func:`~pytest_metamorphic.relations.lidar.rotation_equivariance`)."""

Within = Literal["all", "roi"]


def _what(kind: PointOutputKind) -> str:
    if kind not in ("labels", "clusters"):
        raise InvalidArgument(
            f"kind={kind!r} must be 'labels' (a per-point labelling) or 'clusters'"
        )
    return "label" if kind == "labels" else "cluster"


def _keeping(
    kind: PointOutputKind, name: str | None, default: str, followup: Any, **judge: Any
) -> MetamorphicRelation:
    """A component relation: ``followup``'s follow-ups, judged by :class:`PointsKeepLabels`
    (``default`` names it, with ``{what}`` for "label" or "cluster")."""
    what = _what(kind)
    return lidar_relation(
        name or default.format(what=what), followup, PointsKeepLabels(kind, **judge)
    )


def reordered_returns(
    kind: PointOutputKind, *, border: float = 0.0, name: str | None = None
) -> MetamorphicRelation:
    """Points reordered: every return keeps its label or cluster.

    ``border`` (partitions): DBSCAN's ``eps``; a border point reachable from two clusters
    may change sides (see :mod:`pytest_metamorphic.lidar.judging.points`).
    """
    return _keeping(
        kind,
        name,
        "points reordered => every return keeps its {what}",
        permutation_invariance().followup,
        border=border,
    )


def repeated_returns(
    kind: PointOutputKind, *, border: float = 0.0, max_size: int = 100, name: str | None = None
) -> MetamorphicRelation:
    """Points repeated (scattered ones, a packet, the whole sweep): every return keeps its
    label or cluster, and a repeated return takes its original's."""
    return _keeping(
        kind,
        name,
        "points repeated => every return keeps its {what}",
        duplication_invariance(max_size=max_size).followup,
        border=border,
    )


def noise_locality(
    kind: PointOutputKind,
    *,
    radius: float = DEFAULT_RADIUS,
    within: Within = "all",
    border: float = 0.0,
    n: NoiseSize = DEFAULT_NOISE,
    name: str | None = None,
) -> MetamorphicRelation:
    """MR1's noise outside the ROI: returns farther than ``radius`` metres from every noise
    point keep their label or cluster (``within="roi"``: only those in the ROI judged)."""
    _check_noise(n, 1000)
    return _keeping(
        kind,
        name,
        f"noise outside ROI => returns beyond {radius:g} m keep their {{what}}",
        mr1_subset(n=n).followup,
        radius=radius,
        within=within,
        border=border,
    )


def removal_locality(
    kind: PointOutputKind,
    *,
    radius: float = DEFAULT_RADIUS,
    within: Within = "all",
    border: float = 0.0,
    name: str | None = None,
) -> MetamorphicRelation:
    """One car, pedestrian or cyclist removed (its beams re-cast to the ground behind it,
    :func:`~pytest_metamorphic.relations.lidar.object_removal`'s follow-up): returns
    farther than ``radius`` metres from its returns and from the re-cast ones keep their
    label or cluster."""
    return _keeping(
        kind,
        name,
        f"an object removed => returns beyond {radius:g} m keep their {{what}}",
        object_removal(scope="all").followup,
        radius=radius,
        within=within,
        border=border,
    )


def turned_returns(
    kind: PointOutputKind, *, border: float = 0.0, name: str | None = None
) -> MetamorphicRelation:
    """Cloud and ROI turned 90, 180 or 270 degrees about the sensor: every return keeps its
    label or cluster. Only for components that claim this symmetry (a grid anchored at the
    sensor, a neighbourhood search); zone models with sector counts that are no multiple
    of four do not."""
    return _keeping(
        kind,
        name,
        "cloud turned => every return keeps its {what}",
        rotation_equivariance().followup,
        border=border,
        boundary_margin=EDGE_MARGIN,
    )


def mirrored_returns(
    kind: PointOutputKind, *, border: float = 0.0, name: str | None = None
) -> MetamorphicRelation:
    """Cloud and ROI mirrored (y -> -y): every return keeps its label or cluster (a
    component with no preferred side)."""
    return _keeping(
        kind,
        name,
        "cloud mirrored => every return keeps its {what}",
        mirror_symmetry().followup,
        border=border,
        boundary_margin=EDGE_MARGIN,
    )


def repeated_sweep(
    kind: PointOutputKind, *, border: float = 0.0, name: str | None = None
) -> MetamorphicRelation:
    """The same sweep after 1-3 other sweeps: every return keeps its label or cluster (a
    per-sweep component). Like
    :func:`~pytest_metamorphic.relations.lidar.history_independence`, it compares with the
    source's second run, so a component that differs only on its very first call (a
    reused Patchwork++) passes."""
    what = _what(kind)
    sweeps = history_independence()
    return MetamorphicRelation(
        name or f"the same sweep after others => every return keeps its {what}",
        sweeps.followup,
        PointsKeepLabels(kind, border=border),
        same_input=sweeps.same_input,  # the follow-up *is* its source: it tests the history
    )


def component_relations(
    kind: PointOutputKind,
    *,
    radius: float = DEFAULT_RADIUS,
    within: Within = "all",
    border: float = 0.0,
    symmetric: bool = False,
    history: bool = True,
    n: NoiseSize = DEFAULT_NOISE,
) -> list[MetamorphicRelation]:
    """The component relations for a labelling (``kind="labels"``) or a partition
    (``kind="clusters"``).

    Reordering, repetition, noise locality and removal locality always; the turn and the
    mirror when the component claims that symmetry (``symmetric=True``); the repeated
    sweep unless ``history=False`` (a component meant to carry state from sweep to sweep).
    ``radius``, ``within`` and ``border`` as for :func:`noise_locality`.
    """
    relations = [
        reordered_returns(kind, border=border),
        repeated_returns(kind, border=border),
        noise_locality(kind, radius=radius, within=within, border=border, n=n),
        removal_locality(kind, radius=radius, within=within, border=border),
    ]
    if symmetric:
        relations += [turned_returns(kind, border=border), mirrored_returns(kind, border=border)]
    if history:
        relations.append(repeated_sweep(kind, border=border))
    return relations


def relative_relations(
    kind: PointOutputKind, *, tolerance: float = 0.05, symmetric: bool = False
) -> list[MetamorphicRelation]:
    """The follow-ups of :func:`component_relations` (no history), judged by semLidarFuzz's
    relative metric where the sweeps have labelled boxes: the component's score against
    the follow-up's labels may fall at most ``tolerance`` below its score against the
    source's (:class:`~pytest_metamorphic.lidar.judging.relative.RelativeScore`). For
    components that are not exact: an imperfect one passes as long as no change makes it
    worse."""
    judge = RelativeScore(kind, tolerance=tolerance)
    return [
        dataclasses.replace(
            relation,
            name=f"{relation.name.split(' => ')[0]} => score falls by at most {tolerance:g}",
            relation=judge,
        )
        for relation in component_relations(kind, symmetric=symmetric, history=False)
    ]
