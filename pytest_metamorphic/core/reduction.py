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

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.minimize import ddmin
from pytest_metamorphic.core.perturbation import Reducible, find_reducible
from pytest_metamorphic.core.relations import CheckContext, Verdict

__all__ = ["DEFAULT_BUDGET", "Reduction", "reduce_followup"]

DEFAULT_BUDGET = 500
"""SUT calls one reduction may spend (``--mt-minimize-budget``)."""

_SHOWN_ELEMENTS = 10


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
        else:
            status = (
                f"NOT proven minimal: the budget of {self.budget} SUT calls ran out "
                "(raise it with --mt-minimize-budget)"
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
    proven = False
    sizes: list[int] = []
    for number, order in enumerate(orders):
        remaining = budget - calls
        if remaining <= 0:
            break
        # Later orders are fallbacks: each pass but the last gets 4/5 of what is left.
        share = remaining if number == len(orders) - 1 else max(remaining * 4 // 5, 1)
        kept = set(current)
        try:
            result = ddmin(
                [i for i in order if i in kept], fails, max_calls=share, check_input=number == 0
            )
        except InvalidArgument:
            raise InvalidArgument(
                f"rebuilding the follow-up from all {len(reducible)} elements of {key!r} "
                f"({type(reducible).__name__}.restrict + apply) does not violate the "
                "relation, so it cannot be reduced"
            ) from None
        current = sorted(result.elements)
        sizes.extend(result.history)
        if result.proven_minimal:
            proven = True
            break
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
    )
