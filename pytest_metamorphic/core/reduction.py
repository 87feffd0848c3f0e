"""Reducing a violating follow-up to a 1-minimal one: the fewest elements that still fail.

After Hypothesis has shrunk a failing case, its follow-up may still carry hundreds of
injected points (the shrinker stops after 500 successful steps, and it spends most calls
on the values of the elements, not on which elements matter). :func:`reduce_followup`
takes the :class:`~pytest_metamorphic.core.perturbation.Reducible` transform recorded in
the follow-up's ``params`` and runs :func:`~pytest_metamorphic.core.minimize.ddmin` on its
elements, with ``fails(subset)`` = "the relation is violated when the system runs on the
source plus only ``subset``". The result is *proven* 1-minimal when ddmin's last round
(every single-element removal) completed within the budget of SUT calls: removing any one
remaining element makes the relation hold again.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.minimize import ddmin, one_minimal_sweep, shortest_failing_prefix
from pytest_metamorphic.core.perturbation import Reducible, find_reducible
from pytest_metamorphic.core.relations import CheckContext, Verdict
from pytest_metamorphic.core.timeout import check_timeout

__all__ = ["DEFAULT_BUDGET", "Reduction", "reduce_followup"]

DEFAULT_BUDGET = 500
"""SUT calls one reduction may spend (``--mt-minimize-budget``)."""

_SHOWN_ELEMENTS = 10
# Below this many elements ddmin alone is cheap; above it a ranked prefix is bisected first.
_PREFIX_MIN = 16
# A shortest failing prefix longer than this is swept one element at a time (a count-driven
# failure: every half passes, so ddmin would spend about twice the prefix's length).
_SWEEP_MIN = 32


@dataclass(frozen=True)
class Reduction:
    """The smallest failing version of a follow-up that was found.

    Attributes
    ----------
    key : str
        The ``params`` key of the reduced transform (e.g. ``"noise_outside_roi"``).
    original_size : int
        Elements of the transform before reduction.
    indices : tuple of int
        Positions of the kept elements in the original transform, ascending.
    perturbation : Reducible
        The transform restricted to those elements.
    followup_input, params
        The reduced follow-up input and its transform parameters.
    output, verdict
        The system's output on the reduced follow-up and the (failing) relation verdict.
    proven_minimal : bool
        True when every single-element removal was tried and none still fails.
    calls : int
        SUT calls the reduction spent (the confirming call included; subsets seen in an
        earlier pass are not run again).
    budget : int
        The call budget it ran under.
    crashes : int
        Subsets on which the system raised (counted as "does not fail").
    fails_without_elements : bool
        The transform with *no* elements violates the relation too (the relation fails
        on the untouched source: a nondeterministic system or an unsound relation).
    count_bound : int or None
        k when the first k ranked elements fail and the first k - 1 pass: a failure that
        needs about k elements to arrive (a point budget, a density), stated even when
        the set is too large to prove 1-minimal within the budget.
    """

    key: str
    original_size: int
    indices: tuple[int, ...]
    perturbation: Reducible
    followup_input: Any
    params: Mapping[str, Any]
    output: Any
    verdict: Verdict
    proven_minimal: bool
    calls: int
    budget: int
    crashes: int = 0
    fails_without_elements: bool = False
    sizes: tuple[int, ...] = field(default=(), repr=False)  # subset size after each reduction
    count_bound: int | None = None
    seconds: float | None = None  # the time it was allowed; None: no limit
    timed_out: bool = False  # it stopped at that limit, keeping the smallest set found

    @property
    def size(self) -> int:
        return len(self.indices)

    def summary(self) -> str:
        """One line: what was kept, and whether it is proven minimal."""
        kept = f"{self.size} of {self.original_size} element(s) of {self.key!r}"
        if self.proven_minimal:
            status = "proven 1-minimal (with any one of them removed the relation holds)"
        elif self.fails_without_elements:
            status = (
                "NOT minimal: the relation fails even with none of them (is the system "
                "deterministic, and does the relation hold for an unchanged input?)"
            )
        elif self.timed_out:
            status = (
                f"NOT proven minimal: the time limit of {self.seconds:g} s ran out, the "
                "smallest failing set found so far is kept (raise it with "
                "--mt-minimize-seconds)"
            )
        else:
            status = (
                f"NOT proven minimal: the budget of {self.budget} SUT calls ran out "
                "(raise it with --mt-minimize-budget)"
            )
            # Said only when the set is that long prefix's order of size: otherwise a
            # smaller set was found and "how many" is not what the failure depends on.
            if self.count_bound is not None and 2 * self.size >= self.count_bound:
                status += (
                    f"; the first {self.count_bound} ranked element(s) fail and the first "
                    f"{self.count_bound - 1} do not: the failure depends on how many arrive"
                )
        crashed = f"; the system crashed on {self.crashes} subset(s)" if self.crashes else ""
        return f"{kept}, {status}, {self.calls} SUT calls{crashed}"

    def effect_lines(self, source_output: Any) -> list[str]:
        """What the kept elements do (e.g. which obstacle they hide), when the transform says."""
        describe = getattr(self.perturbation, "describe_effect", None)
        if not callable(describe):
            return []
        try:
            return [str(line) for line in describe(source_output, self.output)]
        except Exception as error:  # decoration only: never replace the violation itself
            return [f"(describe_effect failed: {type(error).__name__}: {error})"]

    def element_lines(self, limit: int = _SHOWN_ELEMENTS) -> list[str]:
        """One line per kept element (at most ``limit``), for failure messages."""
        describe = getattr(self.perturbation, "describe_elements", None)
        if callable(describe):
            return [str(line) for line in describe(limit)]
        return [describe_value(self.perturbation)]


def _orders(
    reducible: Reducible, source: Any, source_output: Any, followup_output: Any
) -> list[list[int]]:
    """The element orders to try, one ddmin pass each (``rankings``, ``ranking`` or as is)."""
    size = len(reducible)
    rankings = getattr(reducible, "rankings", None)
    if callable(rankings):
        orders = [list(order) for order in rankings(source, source_output, followup_output)]
        method = "rankings"
    else:
        rank = getattr(reducible, "ranking", None)
        orders = [list(rank(source, source_output, followup_output))] if callable(rank) else []
        method = "ranking"
    for order in orders:
        if sorted(int(i) for i in order) != list(range(size)):
            raise InvalidArgument(
                f"{type(reducible).__name__}.{method}() must give permutations of "
                f"range({size}), got {describe_value(order)}"
            )
    return [[int(i) for i in order] for order in orders] or [list(range(size))]


def _smallest_first(kept: tuple[int, ...]) -> tuple[int, tuple[int, ...]]:
    return len(kept), kept


class _OutOfTime(Exception):
    """The reduction's time limit passed (raised between two system calls)."""


def reduce_followup(
    params: Mapping[str, Any],
    *,
    source: Any,
    source_output: Any,
    followup_output: Any,
    run: Callable[[Any], Any],
    check: Callable[[Any, Any, CheckContext], Verdict],
    index: int = 0,
    budget: int = DEFAULT_BUDGET,
    seconds: float | None = None,
) -> Reduction | None:
    """Reduce the reducible transform in ``params`` to a 1-minimal failing subset.

    Parameters
    ----------
    params : mapping
        The violating follow-up's transform parameters; the first
        :class:`~pytest_metamorphic.core.perturbation.Reducible` value is reduced.
    source, source_output
        The source input and the system's output on it (reused, never recomputed).
    followup_output
        The system's output on the full follow-up (used to rank the elements).
    run : callable(input) -> output
        Runs the system under test once.
    check : callable(source_output, followup_output, context) -> Verdict
        The relation.
    index : int
        The follow-up's index, passed on in :class:`CheckContext`.
    budget : int
        At most this many ``run`` calls (>= 1).
    seconds : float, optional
        At most this much time: a slow system gets the smallest failing set found when
        the time is up (``timed_out``), never an interrupted reduction.

    Returns
    -------
    Reduction or None
        None when no parameter is reducible.

    Raises
    ------
    InvalidArgument
        When rebuilding the follow-up from *all* its elements does not violate the
        relation (the transform's ``restrict``/``apply`` do not reproduce the follow-up),
        or the ranking is not a permutation.
    """
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 1:
        raise InvalidArgument(f"budget={budget!r} must be an int >= 1")
    seconds = check_timeout(seconds, "seconds")
    deadline = None if seconds is None else time.monotonic() + seconds
    found = find_reducible(params)
    if found is None:
        return None
    key, reducible = found
    orders = _orders(reducible, source, source_output, followup_output)
    verdicts: dict[tuple[int, ...], bool] = {}
    failing: dict[tuple[int, ...], tuple[Mapping[str, Any], Any, Verdict]] = {}
    crashes = calls = 0

    def build(indices: tuple[int, ...]) -> tuple[Reducible, Any, dict[str, Any]]:
        reduced = reducible.restrict(list(indices))
        return reduced, reduced.apply(source), {**params, **reduced.params()}

    def fails(chosen: Sequence[int]) -> bool:
        nonlocal crashes, calls
        indices = tuple(sorted(chosen))
        if indices in verdicts:  # passes after the first revisit subsets
            return verdicts[indices]
        if deadline is not None and failing and time.monotonic() > deadline:
            raise _OutOfTime
        _, value, subset_params = build(indices)
        calls += 1
        try:
            output = run(value)
        except Exception:
            # A crash is another bug; the subset must reproduce *this* violation.
            crashes += 1
            verdicts[indices] = False
            return False
        verdict = check(source_output, output, CheckContext(source, value, subset_params, index))
        if not verdict.holds:
            failing[indices] = (subset_params, output, verdict)
        verdicts[indices] = not verdict.holds
        return verdicts[indices]

    current = list(range(len(reducible)))
    if not fails(current):
        raise InvalidArgument(
            f"rebuilding the follow-up from all {len(reducible)} elements of {key!r} "
            f"({type(reducible).__name__}.restrict + apply) does not violate the "
            "relation, so it cannot be reduced"
        )
    sizes: list[int] = []
    count_bound, proven, timed_out = None, False, False
    try:
        count_bound, current, proven = _count_pass(orders[0], fails, lambda: budget - calls, sizes)
        for number, order in enumerate(orders):
            remaining = budget - calls
            if proven or remaining <= 0:
                break
            # Later orders are fallbacks: each pass but the last gets 4/5 of what is left.
            share = remaining if number == len(orders) - 1 else max(remaining * 4 // 5, 1)
            kept = set(current)
            result = ddmin(
                [i for i in order if i in kept], fails, max_calls=share, check_input=False
            )
            current = sorted(result.elements)
            sizes.extend(result.history)
            proven = result.proven_minimal
    except _OutOfTime:
        # The smallest failing set seen so far stands (the whole set failed first).
        timed_out, proven = True, False
        best: tuple[int, ...] = min(failing, key=_smallest_first)
        current = list(best)
    indices = tuple(current)
    reduced, value, _ = build(indices)
    subset_params, output, verdict = failing[indices]
    return Reduction(
        key=key,
        original_size=len(reducible),
        indices=indices,
        perturbation=reduced,
        followup_input=value,
        params=subset_params,
        output=output,
        verdict=verdict,
        proven_minimal=proven,
        calls=calls,
        budget=budget,
        crashes=crashes,
        fails_without_elements=() in failing,
        sizes=tuple(sizes),
        count_bound=count_bound,
        seconds=seconds,
        timed_out=timed_out,
    )


def _count_pass(
    order: list[int],
    fails: Callable[[Sequence[int]], bool],
    remaining: Callable[[], int],
    sizes: list[int],
) -> tuple[int | None, list[int], bool]:
    """The cheap first pass before ddmin.

    1. Bisect the shortest failing prefix ``order[:k]`` of the ranked elements.
    2. Its last element is needed by that prefix: keep it and bisect the shortest prefix of
       the others that still fails with it. A few culprits among many leave a short
       candidate (ddmin finishes it); a failure that needs almost all of them (it depends
       on how many arrive) leaves a long one.
    3. A long candidate is swept once, one removal at a time: for a count-driven failure
       every removal passes, which proves it 1-minimal in about k calls (ddmin would
       spend about twice that, since every half passes too).

    Returns ``(count_bound, kept indices, proven)``; ``count_bound`` is k when the first
    k - 1 ranked elements were seen to pass.
    """
    if len(order) <= _PREFIX_MIN:
        return None, sorted(order), False

    def limited(chosen: Sequence[int]) -> bool:
        if remaining() <= 0:
            raise _OutOfBudget
        return fails(chosen)

    best: list[int] = order
    count: int | None = None
    try:
        k, bounded = shortest_failing_prefix(order, limited, max_calls=max(remaining() // 8, 1))
        count = k if bounded else None
        best = order[:k]
        sizes.append(k)
        if k <= _SWEEP_MIN:
            return count, sorted(best), False
        last, rest = best[-1], best[:-1]
        if limited([last]):
            best = [last]
        else:
            j, _ = shortest_failing_prefix(
                rest, lambda chosen: limited([*chosen, last]), max_calls=max(remaining() // 8, 1)
            )
            best = [*rest[:j], last]
        sizes.append(len(best))
        if len(best) <= _SWEEP_MIN or 2 * len(best) < k:
            return count, sorted(best), False
        kept, proven, _ = one_minimal_sweep(best, limited, max_calls=remaining())
    except _OutOfBudget:
        return count, sorted(best), False
    sizes.append(len(kept))
    return count, sorted(best[i] for i in kept), proven


class _OutOfBudget(Exception):
    pass
