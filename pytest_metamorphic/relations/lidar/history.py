"""The relation for per-frame detectors: a sweep's obstacles do not depend on earlier sweeps."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.judging.scope import judged_equal
from pytest_metamorphic.relations.lidar._common import _PROBE, _check_size, _frame
from pytest_metamorphic.strategies._history import earlier_sweeps

__all__ = ["history_independence"]


def history_independence(
    *,
    max_steps: int = 3,
    matcher: Matcher | None = None,
    name: str = "the same sweep after other sweeps => O == O'",
) -> MetamorphicRelation:
    """A per-frame detector gives a sweep the same obstacles whatever it ran on before.

    The follow-up is the source sweep itself, run after 1 to ``max_steps`` earlier sweeps
    made from it (:func:`~pytest_metamorphic.strategies.earlier_sweeps`: turned about the
    sensor, mirrored, cut to its first half), and its output must equal, exactly and for
    every obstacle (``matcher``: compare by it instead), the output of the source run right
    after itself (the engine runs it twice first, so that a failing case replays alike
    whatever ran before it: see :class:`~pytest_metamorphic.core.cases.Followup`). It finds
    state carried from one call to the next: a ground height or clusters cached per grid
    cell, a smoothing filter left on, a cache keyed by what two sweeps share (the point
    count, the header, the leading points). The engine's determinism re-run catches some of
    this by chance, after a violation of another relation; this relation looks for it by
    design, and its violation is not re-run for determinism (it *is* a re-run).

    Precondition: a detector that is per-frame by contract. A tracker, or a detector that
    accumulates sweeps on purpose, is not; do not apply it to them.
    """
    _check_size(max_steps, "max_steps")
    relation = judged_equal(scope="all", matcher=matcher)
    earlier_sweeps(_PROBE, max_steps=max_steps)  # validate now

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return earlier_sweeps(_frame(frame), max_steps=max_steps)

    # The follow-up *is* its source: it tests the history, not the input.
    return MetamorphicRelation(name, followup, relation, same_input=_never_same)


def _never_same(source: Any, followup: Any) -> bool:
    return False
