from __future__ import annotations

from collections.abc import Sequence

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.core.minimize import ddmin


def is_one_minimal(subset: Sequence[int], fails) -> bool:
    """Independent check: the subset fails and no one-element removal does."""
    items = list(subset)
    return fails(items) and not any(fails(items[:i] + items[i + 1 :]) for i in range(len(items)))


@given(
    st.lists(st.integers(0, 40), min_size=1, max_size=60, unique=True),
    st.sets(st.integers(0, 40), min_size=1, max_size=4),
)
def test_ddmin_finds_the_hidden_culprits(elements: list[int], culprits: set[int]) -> None:
    culprits = culprits & set(elements) or {elements[0]}

    def fails(subset: Sequence[int]) -> bool:
        return culprits <= set(subset)

    result = ddmin(elements, fails, max_calls=10_000)
    assert result.proven_minimal
    assert set(result.elements) == culprits
    assert is_one_minimal(result.elements, fails)
    assert [elements[i] for i in result.indices] == list(result.elements)


@given(st.lists(st.integers(0, 9), min_size=1, max_size=50))
def test_ddmin_result_is_one_minimal_for_threshold_failures(elements: list[int]) -> None:
    # Fails when the subset sums to >= 10: many minimal subsets exist, any will do.
    def fails(subset: Sequence[int]) -> bool:
        return sum(subset) >= 10

    if not fails(elements):
        with pytest.raises(InvalidArgument, match="does not fail"):
            ddmin(elements, fails)
        return
    result = ddmin(elements, fails, max_calls=10_000)
    assert result.proven_minimal
    assert is_one_minimal(result.elements, fails)


def test_budget_exhaustion_is_reported_not_hidden() -> None:
    elements = list(range(200))
    result = ddmin(elements, lambda s: {17, 123, 150} <= set(s), max_calls=10)
    assert not result.proven_minimal
    assert result.calls == 10
    assert {17, 123, 150} <= set(result.elements)


def test_calls_scale_well_below_one_per_element_pair() -> None:
    elements = list(range(1000))
    result = ddmin(elements, lambda s: {3, 777} <= set(s), max_calls=10_000)
    assert result.proven_minimal and result.elements == (3, 777)
    assert result.calls < 120  # ~ 2 * k * log2(n) + k, far from n


def test_single_element_that_fails_alone_is_minimal_unless_empty_fails() -> None:
    assert ddmin([5], lambda s: True).proven_minimal is False  # the empty set fails too
    assert ddmin([5], lambda s: bool(s)).proven_minimal is True
