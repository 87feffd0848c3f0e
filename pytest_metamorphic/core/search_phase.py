"""Which part of Hypothesis's search is calling the test now: a new case, or a re-run.

The plugin's counts are per *distinct case*: a source Hypothesis generated (or replayed
from its database, or an explicit ``@example``) is one source, and a violation found
there is one violation. When a case fails, Hypothesis runs many variants of it while it
shrinks (and explains) the failure, then replays the minimal one once more; counted as
sources and violations, those made one bug read as "52 sources, 18 violations". They are
counted apart, as re-runs (:attr:`~pytest_metamorphic.core.stats.Recorder.reruns`): their
system calls are real cost, their verdicts are the same failure again.

Hypothesis has no public API for its current phase. The engine's ``ConjectureRunner``
keeps it in ``_current_phase`` (present since 6.x, in every version this package
supports); it is found on the call stack, read defensively, and anything unknown counts
as a new case (over-counting a rare case is better than hiding real ones).
"""

from __future__ import annotations

import sys
from types import FrameType
from typing import Literal

from hypothesis.errors import HypothesisException

__all__ = ["Phase", "counts_as_new_case", "search_phase"]

Phase = Literal["outside", "explicit", "reuse", "generate", "target", "shrink", "explain", "final"]

# Phases whose cases are variants or replays of a case already counted.
_RERUN_PHASES = frozenset({"shrink", "explain", "final"})
_KNOWN: dict[str, Phase] = {
    name: name for name in ("reuse", "generate", "target", "shrink", "explain")
}  # the runner's own phases
# Deep enough for pytest + Hypothesis + the plugin between the runner and the test body.
_MAX_FRAMES = 200


def search_phase() -> Phase:
    """The phase of Hypothesis's search running the current test case.

    Returns
    -------
    phase : str
        ``"outside"`` (no Hypothesis test running: a direct call, an artifact replay),
        ``"explicit"`` (an ``@example``), ``"final"`` (the last replay of a failing case),
        or the runner's phase: ``"reuse"``, ``"generate"``, ``"target"``, ``"shrink"``,
        ``"explain"``.
    """
    from hypothesis.control import current_build_context

    try:
        context = current_build_context()
    except HypothesisException:
        return "outside"
    frame: FrameType | None = sys._getframe(1)
    for _ in range(_MAX_FRAMES):
        if frame is None:
            break
        code = frame.f_code
        if code.co_name == "execute_explicit_examples":
            return "explicit"
        runner = frame.f_locals.get("self") if code.co_name == "test_function" else None
        if type(runner).__name__ == "ConjectureRunner":
            phase = getattr(runner, "_current_phase", "generate")
            return _KNOWN.get(phase, "generate")
        frame = frame.f_back
    return "final" if context.is_final else "generate"


def counts_as_new_case() -> bool:
    """True when the current case is a new source to count, False for a re-run of one."""
    return search_phase() not in _RERUN_PHASES
