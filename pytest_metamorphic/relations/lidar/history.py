"""The relations for per-frame detectors: a sweep's obstacles do not depend on earlier
sweeps, whether the sweep is clean or degraded by a sensor fault."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.matching import Matcher
from pytest_metamorphic.lidar.judging.scope import judged_equal
from pytest_metamorphic.relations.lidar._common import _PROBE, _check_size, _frame, coverage_of
from pytest_metamorphic.strategies._history import (
    HISTORY_FAULTS,
    HistoryFault,
    degraded_earlier_sweeps,
    earlier_sweeps,
)

__all__ = ["history_independence", "history_under_faults"]


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
    return MetamorphicRelation(
        name, followup, relation, same_input=_never_same, coverage=coverage_of(relation)
    )


def _never_same(source: Any, followup: Any) -> bool:
    return False


def history_under_faults(
    *,
    max_steps: int = 3,
    faults: Sequence[HistoryFault] = HISTORY_FAULTS,
    max_rings: int = 4,
    max_packets: int = 10,
    matcher: Matcher | None = None,
    name: str = "a degraded sweep (lasers dead or packets lost) after other sweeps => O == O'",
) -> MetamorphicRelation:
    """A per-frame detector gives a *degraded* sweep the same obstacles whatever it ran on
    before.

    :func:`history_independence` replays the clean sweep; a system whose state fills what
    a sweep lacks passes it, and passes the fault relations too, because each fault
    follow-up runs right after its own clean source: a double-buffered scan that does not
    clear the columns of lost packets (ouster-sdk issue #300: a LidarScan kept an old
    frame's column headers where packets were dropped), a driver that fills a dead laser
    from the previous revolution, a ground or occupancy cache that remembers cells the
    sweep no longer sees, all restore the clean sweep there and hide the fault. Here the
    follow-up is the source with 1 to ``max_rings`` lasers dead or 1 to ``max_packets``
    packets lost (``faults``; the frame's own sensor, as :func:`beam_loss` and
    :func:`packet_loss` draw them), run after 1 to ``max_steps`` earlier sweeps made from
    the source (turned, mirrored, cut short), and its output must equal, exactly for every
    obstacle (``matcher``: compare by it instead), the degraded sweep's output right after
    itself (the engine runs it twice first). What the earlier sweeps leave in the gaps
    then shows.

    Precondition: as for :func:`history_independence`, a detector that is per-frame by
    contract (a stateless detector holds it trivially); not applicable, with the reason,
    where the frame's sensor and so its lasers and packets are unknown.
    """
    _check_size(max_steps, "max_steps")
    relation = judged_equal(scope="all", matcher=matcher)
    degraded_earlier_sweeps(  # validate now
        _PROBE, max_steps=max_steps, faults=faults, max_rings=max_rings, max_packets=max_packets
    )

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        return degraded_earlier_sweeps(
            _frame(frame),
            max_steps=max_steps,
            faults=faults,
            max_rings=max_rings,
            max_packets=max_packets,
        )

    return MetamorphicRelation(name, followup, relation, coverage=coverage_of(relation))
