"""Relations under sensor faults: dead beams and lost packets leave well-covered obstacles
detected."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.faults import DropAzimuthBlock, DropRings, derive_rings
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.hdl64 import HDL64E, BeamLayout
from pytest_metamorphic.lidar.obstacles import Box, bev_iou
from pytest_metamorphic.lidar.scope import ObstacleScope, ScopeLike, as_scope
from pytest_metamorphic.relations.lidar._common import _as_box, _check_size, _frame

__all__ = ["CoveredObstaclesKept", "beam_loss", "packet_loss"]

PACKET_DEGREES = 1.04
"""Azimuth covered by one HDL-64E data packet at 10 Hz (6 firings of 0.1728 degrees)."""


def _fraction(value: Any, name: str, *, upper: float = 1.0) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name}={value!r} must be a number in [0, {upper:g}]")
    if not (math.isfinite(value) and 0.0 <= value <= upper):
        raise InvalidArgument(f"{name}={value!r} must be a number in [0, {upper:g}]")
    return float(value)


class CoveredObstaclesKept(Relation):
    """Every judged source obstacle that the fault leaves *well covered* is still detected.

    Well covered: at least ``min_points`` of the follow-up cloud's points, and at least
    ``min_share`` of the points it had, lie in the source obstacle's box. Detected: some
    follow-up obstacle overlaps its bird's-eye footprint with IoU >= ``min_iou`` (any
    label: fewer points may turn a car into an unknown object, and the box may shrink).
    Obstacles labelled ``unknown`` and those the ``scope`` does not judge are skipped.
    """

    def __init__(
        self,
        *,
        min_points: int = 30,
        min_share: float = 0.5,
        min_iou: float = 0.1,
        scope: ScopeLike = "roi",
    ) -> None:
        _check_size(min_points, "min_points")
        self.min_points = min_points
        self.min_share = _fraction(min_share, "min_share")
        self.min_iou = _fraction(min_iou, "min_iou")
        self.scope: ObstacleScope = as_scope(scope)
        self.name = (
            f"well-covered obstacles kept (>= {min_points} points and >= {min_share:.0%} "
            f"left, footprint IoU >= {min_iou:g}; {self.scope.describe()})"
        )

    def covered(
        self, boxes: Sequence[Box], source: Frame, followup: Frame
    ) -> list[tuple[int, int, int]]:
        """``(index, points before, points after)`` of the judged boxes left well covered."""
        judged = self.scope.judged(list(boxes), source)
        chosen = []
        for index, box in enumerate(boxes):
            if not judged[index] or box.label == "unknown":
                continue
            before = int(box.contains(source.cloud.xyz).sum())
            after = int(box.contains(followup.cloud.xyz).sum())
            if after >= self.min_points and after >= self.min_share * before:
                chosen.append((index, before, after))
        return chosen

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source, followup = _frame(context.source_input), _frame(context.followup_input)
        boxes = [_as_box(box, "source") for box in source_output]
        found = [_as_box(box, "follow-up") for box in followup_output]
        covered = self.covered(boxes, source, followup)
        overlap = bev_iou([boxes[i] for i, _, _ in covered], found) if covered and found else None
        missing = [
            (index, before, after)
            for row, (index, before, after) in enumerate(covered)
            if overlap is None or overlap[row].max() < self.min_iou
        ]
        details = {
            "covered": len(covered),
            "missing": [boxes[i].describe() for i, _, _ in missing],
            "scope": self.scope.describe(),
        }
        if not missing:
            return Verdict(True, self.name, details=details)
        lines = [
            f"{boxes[i].describe()} lost although {after} of its {before} points are left"
            for i, before, after in missing
        ]
        return Verdict(False, self.name, "; ".join(lines[:10]), details)


def beam_loss(
    *,
    max_rings: int = 4,
    min_points: int = 30,
    min_share: float = 0.5,
    min_iou: float = 0.1,
    layout: BeamLayout = HDL64E,
    scope: ScopeLike = "roi",
    name: str = "beams missing => well-covered obstacles kept",
) -> MetamorphicRelation:
    """Lasers that return nothing (dead channels) lose no obstacle they leave well covered.

    The follow-up drops every return of 1 to ``max_rings`` lasers
    (:class:`~pytest_metamorphic.lidar.faults.DropRings`; rings from the cloud's ``ring``
    field, a KITTI sweep's storage order, or ``layout``'s elevations; shrinking toward
    fewer and lower rings). A violation reduces to the fewest dead beams that still lose
    the obstacle. The check is :class:`CoveredObstaclesKept`.

    Precondition (measured): the reference pipeline and the whole-scene detector keep every
    well-covered obstacle (>= 30 points and >= half of them left) with footprint IoU >= 0.1
    on all six KITTI sweeps under 1-4 random dead rings (0 of 192 lost). A detector tuned to
    a dense sensor, e.g. one that needs 40 points per object, does not.
    """
    _check_size(max_rings, "max_rings")
    if not isinstance(layout, BeamLayout):
        raise InvalidArgument(f"layout={layout!r} must be a BeamLayout")
    relation = CoveredObstaclesKept(
        min_points=min_points, min_share=min_share, min_iou=min_iou, scope=scope
    )
    rings = st.lists(
        st.integers(0, layout.lasers - 1), min_size=1, max_size=min(max_rings, layout.lasers),
        unique=True,
    )  # fmt: skip

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        derive_rings(frame.cloud, layout=layout)  # a cloud whose rings cannot be found: now

        def drop(chosen: list[int]) -> Followup:
            fault = DropRings(tuple(chosen), layout)
            return Followup(fault.apply(frame), params=fault.params())

        return rings.map(drop)

    return MetamorphicRelation(name, followup, relation)


def packet_loss(
    *,
    max_packets: int = 10,
    min_points: int = 30,
    min_share: float = 0.5,
    min_iou: float = 0.1,
    scope: ScopeLike = "roi",
    name: str = "packets lost => well-covered obstacles kept",
) -> MetamorphicRelation:
    """Lost packets (an azimuth block of every laser) lose no obstacle they leave well
    covered. The follow-up removes 1 to ``max_packets`` consecutive packets
    (:data:`PACKET_DEGREES` each) starting at a drawn azimuth (tenths of a degree,
    shrinking toward straight ahead). The check is :class:`CoveredObstaclesKept`.
    """
    _check_size(max_packets, "max_packets")
    relation = CoveredObstaclesKept(
        min_points=min_points, min_share=min_share, min_iou=min_iou, scope=scope
    )
    blocks = st.tuples(st.integers(0, 3599), st.integers(1, max_packets))

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)

        def lose(block: tuple[int, int]) -> Followup:
            start, packets = block
            fault = DropAzimuthBlock(
                math.radians(start / 10), math.radians(PACKET_DEGREES * packets)
            )
            return Followup(fault.apply(frame), params={**fault.params(), "packets": packets})

        return blocks.map(lose)

    return MetamorphicRelation(name, followup, relation)
