"""Relations under transforms that change nothing a detector may depend on: point order
and repeated points."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.followups.perturb import DuplicatePoints
from pytest_metamorphic.lidar.judging.scope import judged_equal
from pytest_metamorphic.relations.lidar._common import _check_size, _frame
from pytest_metamorphic.strategies import duplicated_points, permuted_points

__all__ = ["PACKET_POINTS", "duplication_invariance", "permutation_invariance"]


def permutation_invariance(
    *, matcher: Matcher | None = None, name: str = "points reordered => O == O'"
) -> MetamorphicRelation:
    """The order of the points in the cloud does not matter, for any obstacle.

    Not scoped: reordering touches every point alike, so a detector must give the same
    obstacles everywhere (this and :func:`duplication_invariance` hold for whole-scene
    detectors as they do for ROI-first ones): as multisets (the order a detector lists
    them in is not part of its answer) and to floating-point rounding (a centroid summed
    in another order differs in its last digits). ``matcher``: compare obstacles
    by it, both ways, instead of exactly
    (:data:`~pytest_metamorphic.lidar.judging.tolerance.LEARNED`).
    """
    return MetamorphicRelation(
        name,
        lambda frame: permuted_points(_frame(frame)),
        judged_equal(scope="all", matcher=matcher),
    )


PACKET_POINTS = 384
"""Points in one HDL-64E data packet (12 firings x 32 lasers)."""


def duplication_invariance(
    *,
    max_size: int = 100,
    matcher: Matcher | None = None,
    name: str = "points repeated => O == O'",
) -> MetamorphicRelation:
    """Repeating points does not matter.

    Follow-ups repeat, in order of shrinking preference: up to ``max_size`` scattered
    points; one packet's worth of consecutive points (:data:`PACKET_POINTS`, a driver
    that sends a packet twice); or the whole sweep (two drivers publishing one topic).
    ``matcher`` as for :func:`permutation_invariance`.
    """
    _check_size(max_size, "max_size")

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

    return MetamorphicRelation(name, followup, judged_equal(scope="all", matcher=matcher))
