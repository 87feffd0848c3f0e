"""The phase of Hypothesis's search, which decides what the plugin counts as a new case."""

from __future__ import annotations

import pytest
from hypothesis import Phase, example, given, settings
from hypothesis import strategies as st

from pytest_metamorphic.core.search_phase import counts_as_new_case, search_phase


def test_outside_hypothesis_is_a_new_case() -> None:
    assert search_phase() == "outside"
    assert counts_as_new_case()


def test_a_failure_is_generated_then_shrunk_then_replayed_once() -> None:
    seen: list[tuple[str, bool]] = []

    # Fails on every list of 3 or more; derandomized, so the search is the same each run.
    @settings(database=None, derandomize=True, max_examples=100, report_multiple_bugs=False)
    @given(st.lists(st.integers()))
    def fails(xs: list[int]) -> None:
        seen.append((search_phase(), counts_as_new_case()))
        assert len(xs) < 3

    with pytest.raises(AssertionError):
        fails()
    phases = [phase for phase, _ in seen]
    assert phases[-1] == "final" and phases.count("final") == 1  # the minimal case's replay
    first_failure = phases.index("shrink") - 1
    assert set(phases[: first_failure + 1]) == {"generate"}
    assert set(phases[first_failure + 1 : -1]) <= {"shrink", "explain"}
    # Only the generated cases are new; shrinking steps and the replay are re-runs.
    assert [new for _, new in seen] == [phase == "generate" for phase in phases]


def test_explicit_examples_are_new_cases() -> None:
    seen: list[tuple[str, bool]] = []

    @settings(database=None, phases=[Phase.explicit])
    @example(1)
    @example(2)
    @given(st.integers())
    def explicit(x: int) -> None:
        seen.append((search_phase(), counts_as_new_case()))

    explicit()
    assert seen == [("explicit", True), ("explicit", True)]
