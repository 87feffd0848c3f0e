"""How far a detector's output may move when nothing it should depend on has changed.

A hand-written geometric pipeline that treats the sweep as a set of points gives the
*same* boxes for equivalent inputs, so the relation library compares them exactly
(:data:`EXACT`). A neural network does not: its maps are sums over a receptive field, so
a point repeated, a sweep turned by 90 degrees or mirrored changes them a little, and a
box built from them moves by centimetres, a border cell flips, a borderline class
changes. :data:`LEARNED` is the profile for such detectors, measured on the project's
CNN segmentation (:mod:`pytest_metamorphic.lidar.systems.perception.cnnseg`) over 30 rendered
streets, 92 judged obstacles per transform: matched centres moved by a median of 5 cm
and at most 24 cm under quarter turns, the mirror and a duplicated sweep; sizes by at
most 45 cm; small objects (pedestrians, 0.3-1 m boxes) often lose IoU 0.5 by such a
shift; 1-2 in 92 borderline objects changed class.

Under :data:`LEARNED` a violation means an obstacle is **gone or displaced**: no
obstacle of the other output has its centre within 0.5 m (cars are 1.5-2 m wide, so
that is a merge, a loss or a real move, not jitter). Matches may be shared: a network
may report one pedestrian as two pieces in one run and as one box in the next (seen when
a pedestrian 7 m away was removed), and both pieces are still there; two distinct
objects merged into one box leave at least one centre more than 0.5 m from it. What the
profile does to each relation:

* the invariances (noise or points removed outside the ROI, reordered or repeated points)
  compare judged obstacles by that matcher both ways instead of exactly, over obstacles
  of >= 10 points, as the turns do: an occluded pedestrian 34 m away, seen by 2 returns
  and not reported, came out as a 3-return "cyclist" when one of those returns was
  repeated (a detection threshold, not a weakness the relation is about);
* turns and the mirror compare *places*: each moved obstacle of >= 10 points needs one
  within 0.5 m; sizes, headings and classes are information, not compared (a cyclist
  came out of a mirrored sweep as two pieces of 28 and 35 returns, 15 cm apart, whose
  MinBoxes pointed 28 degrees apart; a network's class for a borderline object is not a
  symmetry of the scene); pieces share a partner;
* MR1 and the edits (removal, insertion: the others kept) match by centre within 0.5 m
  *and* class: the paper counts lost cars and pedestrians by class, and a car that turns
  into a pedestrian because of points off the road is lost as a car.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.model.obstacles import CenterDistanceMatcher

__all__ = ["EXACT", "LEARNED", "Tolerance", "ToleranceLike", "as_tolerance"]


@dataclass(frozen=True)
class Tolerance:
    """A tolerance profile for the LiDAR relations.

    Attributes
    ----------
    name : str
    same : Matcher or None
        When two obstacles of equivalent inputs are the same (invariances); None: identical.
    kept : Matcher or None
        When a source obstacle is kept in a follow-up (MR1, object edits); None: the
        relations' default (same label, bird's-eye IoU >= 0.5).
    moved : (centre m, size m, yaw degrees, min points) or None
        Rigid-motion tolerances; None: the relations' defaults (10 cm, 15 cm, 5 degrees:
        the same obstacle).
    moved_same_label : bool or None
        Whether moved obstacles must keep their class; None: the relations' default.
    moved_shared : bool
        Whether pieces of one moved object may share one partner.
    same_min_points : int
        The invariances judge only obstacles supported by at least this many returns
        (``Box.points``; 0: all; needs ``same``).
    """

    name: str
    same: Matcher | None = None
    kept: Matcher | None = None
    moved: tuple[float, float, float, int] | None = None
    moved_same_label: bool | None = None
    moved_shared: bool = False
    same_min_points: int = 0


EXACT = Tolerance("exact")
"""The default profile: the relations' own matchers (for deterministic detectors)."""
LEARNED = Tolerance(
    "learned",
    same=CenterDistanceMatcher(0.5, same_label=False, exclusive=False),
    kept=CenterDistanceMatcher(0.5, same_label=True, exclusive=False),
    # Sizes and headings are not compared (100 m and 90 degrees, modulo 180, never fail).
    moved=(0.5, 100.0, 90.0, 10),
    moved_same_label=False,
    moved_shared=True,
    same_min_points=10,
)
"""The profile for learned and jittery detectors: an obstacle is the same when a centre
lies within 0.5 m (see the module docstring)."""

ToleranceLike = Literal["exact", "learned"] | Tolerance


def as_tolerance(tolerance: ToleranceLike) -> Tolerance:
    """``"exact"``, ``"learned"`` or a :class:`Tolerance`, as a Tolerance."""
    if isinstance(tolerance, Tolerance):
        return tolerance
    if tolerance == "exact":
        return EXACT
    if tolerance == "learned":
        return LEARNED
    raise InvalidArgument(f"tolerance={tolerance!r} must be 'exact', 'learned' or a Tolerance")
