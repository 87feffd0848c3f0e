"""One-to-one matching of output elements, used by the subset and superset relations.

Counting is not enough for "O ⊆ O'": two source cars must be matched by two distinct
follow-up cars, not both by the same one. A :class:`Matcher` says which pairs are
compatible (and how good each pair is); :func:`one_to_one` then finds a maximum-cardinality
assignment, preferring low total cost among those.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["EqualityMatcher", "Matcher", "PredicateMatcher", "matched_pairs", "one_to_one"]


@runtime_checkable
class Matcher(Protocol):
    """Decides which (source element, follow-up element) pairs may be matched."""

    @property
    def name(self) -> str:
        """What the matcher requires, for messages (an attribute or a property)."""
        ...

    def pairwise(
        self, source: Sequence[Any], followup: Sequence[Any]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """Return ``(compatible, cost)``, both of shape ``(len(source), len(followup))``.

        ``cost`` ranks compatible pairs (lower is better); it is ignored where
        ``compatible`` is False.
        """
        ...


@dataclass(frozen=True)
class PredicateMatcher:
    """Matches ``a`` with ``b`` when ``predicate(a, b)`` is true; all costs equal."""

    predicate: Callable[[Any, Any], bool]
    name: str = "predicate"

    def pairwise(
        self, source: Sequence[Any], followup: Sequence[Any]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        compatible = np.array(
            [[bool(self.predicate(a, b)) for b in followup] for a in source], dtype=bool
        ).reshape(len(source), len(followup))
        return compatible, np.zeros(compatible.shape)


def _equal(a: Any, b: Any) -> bool:
    from pytest_metamorphic.core.comparison import deep_equal

    return deep_equal(a, b)


class EqualityMatcher(PredicateMatcher):
    """Matches elements that are equal (numpy-aware deep equality)."""

    def __init__(self) -> None:
        super().__init__(_equal, "equality")


def one_to_one(
    compatible: NDArray[np.bool_], cost: NDArray[np.floating] | None = None
) -> list[tuple[int, int]]:
    """Maximum-cardinality one-to-one matching, of least total cost among those.

    Parameters
    ----------
    compatible : (n, m) bool
    cost : (n, m) float, optional
      Finite costs of compatible pairs; zeros when omitted.

    Returns
    -------
    list of (i, j)
      Matched pairs, sorted by ``i``; every pair is compatible.
    """
    compatible = np.asarray(compatible, dtype=bool)
    if compatible.ndim != 2:
        raise InvalidArgument(f"compatible must be 2-D, got shape {compatible.shape}")
    if compatible.size == 0 or not compatible.any():
        return []
    costs = np.zeros(compatible.shape) if cost is None else np.asarray(cost, dtype=float)
    if costs.shape != compatible.shape:
        raise InvalidArgument(f"cost has shape {costs.shape}, compatible has {compatible.shape}")
    valid = costs[compatible]
    if not np.isfinite(valid).all():
        raise InvalidArgument("cost must be finite wherever compatible is True")
    # Shift costs to be non-negative, then make every incompatible pair dearer than any
    # complete set of compatible pairs: minimising total cost then maximises cardinality.
    shifted = np.where(compatible, costs - valid.min(), 0.0)
    penalty = float(shifted.sum()) + 1.0
    matrix = np.where(compatible, shifted, penalty)
    rows, cols = linear_sum_assignment(matrix)
    return [(int(i), int(j)) for i, j in zip(rows, cols, strict=True) if compatible[i, j]]


def matched_pairs(
    matcher: Matcher, source: Sequence[Any], followup: Sequence[Any]
) -> list[tuple[int, int]]:
    """Pairs of ``source`` and ``followup`` elements that ``matcher`` matches.

    One to one (:func:`one_to_one`) unless the matcher says ``exclusive = False``: then
    every source element takes its best compatible follow-up element, which others may
    share (a detector whose output jitters may report one object as two pieces in one
    run and one box in the next; both pieces are still *there*).
    """
    if not source or not followup:
        return []
    compatible, cost = matcher.pairwise(source, followup)
    if getattr(matcher, "exclusive", True):
        return one_to_one(compatible, cost)
    ranked = np.where(compatible, np.asarray(cost, dtype=float), np.inf)
    best = np.argmin(ranked, axis=1)
    return [(int(i), int(j)) for i, j in enumerate(best) if compatible[i, j]]
