from __future__ import annotations

from collections.abc import Sequence

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.core.minimize import ddmin, one_minimal_sweep, shortest_failing_prefix


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


@given(st.integers(1, 2000), st.data())
def test_prefix_bisection_finds_the_shortest_failing_prefix(size: int, data) -> None:
    need = data.draw(st.integers(1, size))
    calls: list[int] = []

    def fails(subset: Sequence[int]) -> bool:
        calls.append(len(subset))
        return len(subset) >= need

    k, bounded = shortest_failing_prefix(list(range(size)), fails, max_calls=64)
    assert k == need and bounded
    assert len(calls) <= max(size - 1, 1).bit_length()


def test_prefix_bisection_ends_on_a_failing_prefix_when_not_monotone() -> None:
    def fails(subset: Sequence[int]) -> bool:  # fails at 10 and 40 and above, not between
        return len(subset) == 10 or len(subset) >= 40

    k, _ = shortest_failing_prefix(list(range(100)), fails, max_calls=64)
    assert fails(list(range(k)))
    k, bounded = shortest_failing_prefix(list(range(100)), fails, max_calls=1)
    assert k == 50 and not bounded and fails(list(range(k)))  # one call: stopped at 50


def test_one_sweep_proves_a_count_driven_set_or_keeps_reducing() -> None:
    def count(subset: Sequence[int]) -> bool:
        return len(subset) >= 5

    kept, proven, calls = one_minimal_sweep(list(range(5)), count, max_calls=100)
    assert kept == [0, 1, 2, 3, 4] and proven and calls == 5

    def needs_three(subset: Sequence[int]) -> bool:
        return 3 in subset

    kept, proven, calls = one_minimal_sweep(list(range(6)), needs_three, max_calls=100)
    assert kept == [3] and not proven  # removals happened: ddmin must confirm
    assert is_one_minimal(kept, needs_three)
    kept, proven, calls = one_minimal_sweep(list(range(6)), count, max_calls=2)
    assert not proven and calls == 2
