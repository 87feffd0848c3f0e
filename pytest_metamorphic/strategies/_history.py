"""Strategies for histories: the source sweep again, or a degraded copy of it, after other
sweeps."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.history import HISTORY_STEPS, EarlierSweeps
from pytest_metamorphic.strategies._faults import dead_beams, lost_packets
from pytest_metamorphic.strategies._noise import _check_frame

__all__ = ["degraded_earlier_sweeps", "earlier_sweeps"]

HistoryFault = Literal["beams", "packets"]
#: The faults a degraded history draws from: dead lasers, lost packets.
HISTORY_FAULTS: tuple[HistoryFault, ...] = ("beams", "packets")


def _steps(max_steps: Any) -> st.SearchStrategy[list[Any]]:
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise InvalidArgument(f"max_steps={max_steps!r} must be a positive int")
    return st.lists(st.sampled_from(HISTORY_STEPS), min_size=1, max_size=max_steps)


def earlier_sweeps(frame: Any, *, max_steps: int = 3) -> st.SearchStrategy[Followup]:
    """The source sweep itself, to be run after 1 to ``max_steps`` earlier sweeps made from
    it (:class:`~pytest_metamorphic.lidar.followups.history.EarlierSweeps`: turned,
    mirrored, cut to its first half): ``Followup(frame, before=...)``. Shrinks toward one
    earlier sweep, turned by 90 degrees."""
    frame = _check_frame(frame)
    steps = _steps(max_steps)

    def after(chosen: list[Any]) -> Followup:
        history = EarlierSweeps(tuple(chosen))
        return Followup(frame, params=history.params(), before=tuple(history.inputs(frame)))

    return steps.map(after)


def degraded_earlier_sweeps(
    frame: Any,
    *,
    max_steps: int = 3,
    faults: Sequence[HistoryFault] = HISTORY_FAULTS,
    max_rings: int = 4,
    max_packets: int = 10,
) -> st.SearchStrategy[Followup]:
    """A degraded copy of the source sweep (1 to ``max_rings`` of its lasers dead, or 1 to
    ``max_packets`` of its packets lost: :func:`~pytest_metamorphic.strategies.dead_beams`,
    :func:`~pytest_metamorphic.strategies.lost_packets`), to be run after 1 to
    ``max_steps`` earlier sweeps made from the source, as :func:`earlier_sweeps` makes
    them: ``Followup(degraded, before=...)``.

    A system whose state fills what a sweep lacks (a double-buffered scan that keeps the
    columns of lost packets, dead lasers filled from the previous revolution) hides it when
    the degraded sweep comes right after the clean one, which is how the fault relations
    run it: the fill restores the clean sweep. After other sweeps the fill shows. The
    engine compares the degraded sweep's output after them with its output right after
    itself (:class:`~pytest_metamorphic.core.cases.Followup`'s ``before``). Not applicable,
    with the reason, where the fault is (an unknown sensor). Shrinks toward the first of
    ``faults``, the fewest lasers or packets, and one earlier sweep turned by 90 degrees.
    """
    frame = _check_frame(frame)
    steps = _steps(max_steps)
    if isinstance(faults, str) or not isinstance(faults, Sequence) or not faults:
        raise InvalidArgument(f"faults={faults!r} must be a non-empty sequence of {HISTORY_FAULTS}")
    for fault in faults:
        if fault not in HISTORY_FAULTS:
            raise InvalidArgument(f"fault {fault!r} in faults= must be one of {HISTORY_FAULTS}")
    makers = {
        "beams": lambda: dead_beams(frame, max_rings=max_rings),
        "packets": lambda: lost_packets(frame, max_packets=max_packets),
    }
    degraded = st.one_of([makers[fault]() for fault in dict.fromkeys(faults)])

    def after(pair: tuple[Followup, list[Any]]) -> Followup:
        fault, chosen = pair
        if fault.skipped is not None:
            return fault
        history = EarlierSweeps(tuple(chosen))
        return Followup(
            fault.input,
            params={**fault.params, **history.params()},
            before=tuple(history.inputs(frame)),
        )

    return st.tuples(degraded, steps).map(after)
