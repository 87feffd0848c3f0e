"""Relations under sensor faults: dead beams, lost packets and a coarser range resolution
leave well-covered obstacles detected."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.faults import (
    PACKET_DEGREES,
    QUANTIZATION_RANGE,
    CoveredObstaclesKept,
)
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.lidar.model.hdl64 import BeamLayout
from pytest_metamorphic.relations.lidar._common import _PROBE, _check_size, _frame, lidar_relation
from pytest_metamorphic.strategies._faults import dead_beams, lost_packets, quantized_ranges

__all__ = [
    "PACKET_DEGREES",
    "CoveredObstaclesKept",
    "beam_loss",
    "packet_loss",
    "range_quantization",
]


def beam_loss(
    *,
    max_rings: int = 4,
    min_points: int = 30,
    min_share: float = 0.5,
    min_height_share: float = 0.8,
    min_detected: float = 0.5,
    layout: BeamLayout | None = None,
    scope: ScopeLike = "roi",
    name: str = "beams missing => well-covered obstacles kept",
) -> MetamorphicRelation:
    """Lasers that return nothing (dead channels) lose no obstacle they leave well covered.

    The follow-up drops every return of 1 to ``max_rings`` of the frame's lasers
    (:func:`~pytest_metamorphic.strategies.dead_beams`; the sensor is ``layout``, else the
    frame's: its laser field under any driver's name, a KITTI sweep's storage order, or a
    catalogue sensor fitted to the elevations; shrinking toward fewer and lower rings). A
    frame whose lasers cannot be known (an unidentified sensor without a laser field, a
    non-repetitive scanner) gets no follow-up, and the report says why. A violation
    reduces to the fewest dead beams that still lose the obstacle. The check is
    :class:`CoveredObstaclesKept`.

    Precondition (measured): the reference pipeline and the whole-scene detector keep every
    well-covered obstacle (>= 30 points and >= half of them left, over >= 80 % of their
    height), at least half of their remaining points in follow-up obstacles, on all six
    KITTI sweeps and rendered streets under 1-4
    dead rings (the tests; a Hypothesis search of 100 cases in ``bench/mutation_score.py``).
    Without the height condition the search found a car at 38 m that two dead rings
    legitimately turn into ground. A detector tuned to a dense sensor, e.g. one that needs
    40 points per object, breaks the relation.
    """
    _check_size(max_rings, "max_rings")
    if layout is not None and not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout or None (the frame's)")
    relation = CoveredObstaclesKept(
        min_points=min_points,
        min_share=min_share,
        min_height_share=min_height_share,
        min_detected=min_detected,
        scope=scope,
    )

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return dead_beams(_frame(frame), max_rings=max_rings, layout=layout)

    return lidar_relation(name, followup, relation)


def packet_loss(
    *,
    max_packets: int = 10,
    within_roi: bool = True,
    min_points: int = 30,
    min_share: float = 0.5,
    min_height_share: float = 0.8,
    min_detected: float = 0.5,
    scope: ScopeLike = "roi",
    name: str = "packets lost => well-covered obstacles kept",
) -> MetamorphicRelation:
    """Lost packets (an azimuth block of every laser) lose no obstacle they leave well
    covered. The follow-up removes 1 to ``max_packets`` consecutive packets (the frame's
    sensor's packet width each: 1.04 degrees for the HDL-64E, 4.8 for a VLP-16; not
    applicable, and reported so, when the sensor is unknown) centred on a drawn bearing,
    by default one at which the ROI holds returns (``within_roi``;
    :func:`~pytest_metamorphic.strategies.lost_packets`).
    The check is :class:`CoveredObstaclesKept`.
    """
    _check_size(max_packets, "max_packets")
    relation = CoveredObstaclesKept(
        min_points=min_points,
        min_share=min_share,
        min_height_share=min_height_share,
        min_detected=min_detected,
        scope=scope,
    )

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return lost_packets(_frame(frame), max_packets=max_packets, within_roi=within_roi)

    return lidar_relation(name, followup, relation)


def range_quantization(
    *,
    steps: Sequence[float] | None = None,
    min_step: float = QUANTIZATION_RANGE[0],
    max_step: float = QUANTIZATION_RANGE[1],
    min_points: int = 30,
    min_height_share: float = 0.8,
    min_detected: float = 0.5,
    scope: ScopeLike = "roi",
    name: str = "ranges quantized => obstacles kept",
) -> MetamorphicRelation:
    """A coarser range resolution loses no obstacle: every return stays, its range rounded
    along its beam to a step drawn in millimetres from ``min_step`` to ``max_step`` metres
    (or to one of ``steps``; :func:`~pytest_metamorphic.strategies.quantized_ranges`,
    shrinking toward the finest).
    The check is :class:`CoveredObstaclesKept` (nothing is dropped, so every judged
    obstacle of >= ``min_points`` points whose height span survives the rounding counts).

    Precondition (measured, tests): the reference pipeline and the whole-scene detector
    hold it with 5, 10 and 20 cm steps on all six KITTI sweeps and a rendered street.
    """
    quantized_ranges(_PROBE, steps=steps, min_step=min_step, max_step=max_step)  # validate now
    relation = CoveredObstaclesKept(
        min_points=min_points,
        min_share=0.5,
        min_height_share=min_height_share,
        min_detected=min_detected,
        scope=scope,
    )

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return quantized_ranges(_frame(frame), steps=steps, min_step=min_step, max_step=max_step)

    return lidar_relation(name, followup, relation)
