"""Relations under transforms that change nothing a detector may depend on: point order
and repeated points."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.core.relations import Relation
from pytest_metamorphic.lidar.followups.perturb import DuplicatePoints
from pytest_metamorphic.lidar.judging.identity import SameHeldPoints
from pytest_metamorphic.lidar.judging.scope import judged_equal
from pytest_metamorphic.relations.lidar._common import _check_size, _frame, lidar_relation
from pytest_metamorphic.strategies import duplicated_points, permuted_points

__all__ = ["PACKET_POINTS", "duplication_invariance", "permutation_invariance"]

Identity = Literal["points", "exact"]


def _same_obstacles(identity: Identity, matcher: Matcher | None, min_points: int) -> Relation:
    """The output relation of the order and repetition invariances."""
    if identity not in ("points", "exact"):
        raise InvalidArgument(f"identity={identity!r} must be 'points' or 'exact'")
    if matcher is not None or min_points:
        return judged_equal(scope="all", matcher=matcher, min_points=min_points)
    return SameHeldPoints() if identity == "points" else judged_equal(scope="all")


def permutation_invariance(
    *,
    identity: Identity = "points",
    matcher: Matcher | None = None,
    min_points: int = 0,
    name: str = "points reordered => O == O'",
) -> MetamorphicRelation:
    """The order of the points in the cloud does not matter, for any obstacle.

    Not scoped: reordering touches every point alike, so a detector must give the same
    obstacles everywhere (this and :func:`duplication_invariance` hold for whole-scene
    detectors as they do for ROI-first ones). The outputs are compared as multisets (the
    order a detector lists obstacles in is not part of its answer).

    Parameters
    ----------
    identity : {"points", "exact"}
        When two obstacles are the same. ``"points"`` (default): identical boxes, or boxes
        of one class holding mostly the same points of the sweep
        (:class:`~pytest_metamorphic.lidar.judging.identity.SameHeldPoints`: point IoU
        above 0.5), so a DBSCAN border point that changes sides is no violation while an
        obstacle lost, split, merged or reclassified is. ``"exact"``: identical boxes to
        floating-point rounding, scores included (a detector that treats the sweep as a
        set of points).
    matcher : Matcher, optional
        Compare obstacles by it, both ways, instead
        (:data:`~pytest_metamorphic.lidar.judging.tolerance.LEARNED`).
    min_points : int
        With a ``matcher``: obstacles supported by fewer returns (``Box.points``) are not
        judged (a network's detection of an object seen by 2 or 3 returns flips).
    """
    return lidar_relation(
        name,
        lambda frame: permuted_points(_frame(frame)),
        _same_obstacles(identity, matcher, min_points),
    )


PACKET_POINTS = 384
"""Points in one HDL-64E data packet (12 firings x 32 lasers)."""


def duplication_invariance(
    *,
    max_size: int = 100,
    identity: Identity = "points",
    matcher: Matcher | None = None,
    min_points: int = 0,
    name: str = "points repeated => O == O'",
) -> MetamorphicRelation:
    """Repeating points does not matter.

    Follow-ups repeat, in order of shrinking preference: up to ``max_size`` scattered
    points; one packet's worth of consecutive points (:data:`PACKET_POINTS`, a driver
    that sends a packet twice); or the whole sweep (two drivers publishing one topic).
    ``identity``, ``matcher`` and ``min_points`` as for :func:`permutation_invariance`: by default a
    repeated point that only moves a box's border or its score is no violation (the
    change is counted as information), an obstacle lost, split, merged or reclassified
    is.
    """
    _check_size(max_size, "max_size")
    same = _same_obstacles(identity, matcher, min_points)

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        count = len(frame.cloud)

        def repeat(rows: NDArray[np.intp], what: str) -> Followup:
            perturbation = DuplicatePoints(rows)
            return Followup(
                perturbation.apply(frame), params={**perturbation.params(), "what": what}
            )

        def packet(start: int) -> Followup:
            rows = np.arange(start, min(start + PACKET_POINTS, count), dtype=np.intp)
            return repeat(rows, f"points {start}..{start + len(rows) - 1} (one packet)")

        whole = st.just(None).map(lambda _: repeat(np.arange(count, dtype=np.intp), "every point"))
        return st.one_of(
            duplicated_points(frame, max_size=max_size),
            st.integers(0, max(count - 1, 0)).map(packet),
            whole,
        )

    return lidar_relation(name, followup, same)
