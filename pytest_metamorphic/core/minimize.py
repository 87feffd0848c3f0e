"""Delta debugging to a proven 1-minimal failing subset.

Hypothesis's shrinker is capped (500 successful shrinks) and works on the choice sequence,
not on "which injected points matter". Once a failing perturbation is known, ddmin
(Zeller & Hildebrandt, 2002) removes elements directly, and its last round at granularity
``n = len(elements)`` is exactly the 1-minimality proof: removing any single remaining
element makes the failure disappear. The result says whether that proof completed within
the call budget.
"""

from __future__ import annotations

import array
import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["MinimizationResult", "ddmin", "one_minimal_sweep", "shortest_failing_prefix"]

T = TypeVar("T")


@dataclass(frozen=True)
class MinimizationResult(Generic[T]):
    """The smallest failing subset found.

    Attributes
    ----------
    elements : tuple
        The failing subset, in the original order.
    indices : tuple of int
        Their positions in the input sequence.
    proven_minimal : bool
        True when every one-element removal was tried and none still failed.
    calls : int
        Calls of the failure test spent (the initial confirmation included).
    """

    elements: tuple[T, ...]
    indices: tuple[int, ...]
    proven_minimal: bool
    calls: int
    history: tuple[int, ...] = field(default=(), repr=False)  # subset size after each step

    def __len__(self) -> int:
        return len(self.elements)


class _Budget(Exception):
    pass


def ddmin(
    elements: Sequence[T],
    fails: Callable[[Sequence[T]], bool],
    *,
    max_calls: int = 1000,
    check_input: bool = True,
) -> MinimizationResult[T]:
    """Reduce ``elements`` to a 1-minimal subset for which ``fails(subset)`` is true.

    Parameters
    ----------
    elements : sequence
        The failing perturbation (e.g. injected points).
    fails : callable(subset) -> bool
        Runs the system on the source plus ``subset`` and says whether the relation is
        still violated. Called with subsets in the original order.
    max_calls : int
        Budget of ``fails`` calls. When it runs out the best subset so far is returned
        with ``proven_minimal=False``.
    check_input : bool
        Confirm first that the full sequence fails (one call).
    """
    if isinstance(max_calls, bool) or not isinstance(max_calls, int) or max_calls < 1:
        raise InvalidArgument(f"max_calls={max_calls!r} must be an int >= 1")
    if not callable(fails):
        raise InvalidArgument(f"fails={fails!r} must be callable(subset) -> bool")
    current = list(range(len(elements)))
    calls = 0
    # Keyed by a digest of the subset, not the subset: 500 calls on 10^6 noise points kept
    # 500 tuples of up to a million ints (18 GB).
    cache: dict[bytes, bool] = {}
    history: list[int] = []

    def test(indices: list[int]) -> bool:
        nonlocal calls
        key = hashlib.blake2b(array.array("q", indices).tobytes(), digest_size=16).digest()
        if key in cache:
            return cache[key]
        if calls >= max_calls:
            raise _Budget
        calls += 1
        result = bool(fails([elements[i] for i in indices]))
        cache[key] = result
        return result

    def result(proven: bool) -> MinimizationResult[T]:
        return MinimizationResult(
            tuple(elements[i] for i in current), tuple(current), proven, calls, tuple(history)
        )

    try:
        if check_input and not test(current):
            raise InvalidArgument("fails(elements) is False: the full input does not fail")
        if not current:
            return result(True)
        if len(current) == 1:
            # The only smaller subset is the empty one.
            return result(not test([]))
        granularity = 2
        while len(current) >= 2:
            chunks = _split(current, granularity)
            reduced = False
            for chunk in chunks:
                if test(chunk):
                    current, granularity, reduced = chunk, 2, True
                    break
            if not reduced:
                for index in range(len(chunks)):
                    complement = [i for j, c in enumerate(chunks) if j != index for i in c]
                    if test(complement):
                        current, reduced = complement, True
                        granularity = max(granularity - 1, 2)
                        break
            if reduced:
                history.append(len(current))
                continue
            if granularity >= len(current):
                # Every one-element removal was tested and none fails: 1-minimal.
                return result(True)
            granularity = min(2 * granularity, len(current))
        # One element left: 1-minimal unless the empty perturbation fails too.
        return result(not test([]))
    except _Budget:
        return result(False)


def shortest_failing_prefix(
    order: Sequence[T], fails: Callable[[Sequence[T]], bool], *, max_calls: int
) -> tuple[int, bool]:
    """Bisect the length ``k`` of the shortest prefix ``order[:k]`` that fails.

    ``order`` must fail as a whole (not re-checked). For failures that depend on *how many*
    elements arrive (a point budget, a density, a percentile) ddmin's halves and
    complements all pass until its granularity reaches the count; bisection over a
    ranked prefix finds it in ``log2(len(order))`` calls. With a non-monotonic failure it
    still ends on a failing prefix.

    Returns
    -------
    (k, bounded)
        ``order[:k]`` fails; ``bounded`` is True when ``order[:k - 1]`` was seen to pass
        (or ``k == 1``), i.e. no shorter prefix fails at the boundary.
    """
    lo, hi, calls = 0, len(order), 0  # order[:hi] fails; order[:lo] passes (lo = 0 assumed)
    while hi - lo > 1 and calls < max_calls:
        mid = (lo + hi) // 2
        calls += 1
        if fails(order[:mid]):
            hi = mid
        else:
            lo = mid
    return hi, hi - lo == 1


def one_minimal_sweep(
    elements: Sequence[T], fails: Callable[[Sequence[T]], bool], *, max_calls: int
) -> tuple[list[int], bool, int]:
    """Try removing each element once, last first, keeping every removal that still fails.

    ``elements`` must fail as a whole. When no removal fails in a full sweep the set is
    proven 1-minimal in ``len(elements)`` calls (ddmin would spend about twice that on
    a set whose every half passes, as count-driven failures have).

    Returns
    -------
    (kept, proven, calls)
        Positions of the kept elements in ``elements``, whether the sweep proved them
        1-minimal (no removal succeeded and the sweep completed), and calls spent.
    """
    kept = list(range(len(elements)))
    calls, removed = 0, False
    for position in reversed(range(len(elements))):
        if calls >= max_calls:
            return kept, False, calls
        trial = [i for i in kept if i != position]
        calls += 1
        if fails([elements[i] for i in trial]):
            kept, removed = trial, True
    return kept, not removed, calls


def _split(items: list[int], parts: int) -> list[list[int]]:
    size, extra = divmod(len(items), parts)
    chunks, start = [], 0
    for index in range(parts):
        end = start + size + (1 if index < extra else 0)
        chunks.append(items[start:end])
        start = end
    return [chunk for chunk in chunks if chunk]
