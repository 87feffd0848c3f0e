"""Strategies for histories: the source sweep again, after other sweeps."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.history import HISTORY_STEPS, EarlierSweeps
from pytest_metamorphic.strategies._noise import _check_frame

__all__ = ["earlier_sweeps"]


def earlier_sweeps(frame: Any, *, max_steps: int = 3) -> st.SearchStrategy[Followup]:
    """The source sweep itself, to be run after 1 to ``max_steps`` earlier sweeps made from
    it (:class:`~pytest_metamorphic.lidar.followups.history.EarlierSweeps`: turned,
    mirrored, cut to its first half): ``Followup(frame, before=...)``. Shrinks toward one
    earlier sweep, turned by 90 degrees."""
    frame = _check_frame(frame)
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise InvalidArgument(f"max_steps={max_steps!r} must be a positive int")

    def after(steps: list[Any]) -> Followup:
        history = EarlierSweeps(tuple(steps))
        return Followup(frame, params=history.params(), before=tuple(history.inputs(frame)))

    return st.lists(st.sampled_from(HISTORY_STEPS), min_size=1, max_size=max_steps).map(after)
