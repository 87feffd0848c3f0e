"""Reducing violating follow-ups: the Reducible protocol, the ddmin driver, the engine hook.

Minimality is checked independently of the reducer: the reduced follow-up is rebuilt,
the system is run on it, and then on each one-element removal.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pytest_metamorphic import Followup, MetamorphicViolation, metamorphic, relations
from pytest_metamorphic.core import engine
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.perturbation import (
    Reducible,
    as_reducible,
    find_reducible,
    register_reducible,
)
from pytest_metamorphic.core.reduction import reduce_followup
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.core.stats import Recorder, recording


class Append:
    """Test transform: append ``items`` to a list input."""

    def __init__(self, items: Sequence[int]) -> None:
        self.items = list(items)

    def __len__(self) -> int:
        return len(self.items)

    def restrict(self, indices: Sequence[int]) -> Append:
        return Append([self.items[i] for i in indices])

    def apply(self, source: list[int]) -> list[int]:
        return [*source, *self.items]

    def params(self) -> dict[str, Any]:
        return {"n": len(self.items), "append": self}


def followup_of(source: list[int], items: Sequence[int]) -> Followup:
    transform = Append(items)
    return Followup(transform.apply(source), transform.params())


# The system under test: a "max" that ignores values in 100..199 unless 7 is present,
# and a relation "appending never lowers the max".
def buggy_max(values: list[int]) -> int:
    if 7 in values:
        return max((v for v in values if not 100 <= v < 200), default=0)
    return max(values, default=0)


MONOTONE = relations.predicate(lambda a, b, ctx: b >= a, name="max never drops")


def holds(source: list[int], items: Sequence[int]) -> bool:
    followup = followup_of(source, items)
    context = CheckContext(source, followup.input, followup.params, 0)
    return MONOTONE.check(buggy_max(source), buggy_max(followup.input), context).holds


def assert_one_minimal(source: list[int], kept: Sequence[int]) -> None:
    """Independent check: ``kept`` fails, and so does no one-element removal."""
    kept = list(kept)
    assert not holds(source, kept)
    for index in range(len(kept)):
        assert holds(source, kept[:index] + kept[index + 1 :]), (kept, index)


def reduce(source: list[int], items: Sequence[int], budget: int = 1000):
    followup = followup_of(source, items)
    return reduce_followup(
        followup.params,
        source=source,
        source_output=buggy_max(source),
        followup_output=buggy_max(followup.input),
        run=buggy_max,
        check=MONOTONE.check,
        budget=budget,
    )


@settings(max_examples=60)
@given(
    noise=st.lists(st.integers(0, 99), max_size=60),
    sevens=st.integers(1, 3),
    high=st.integers(100, 199),
)
def test_reduction_is_one_minimal_and_keeps_only_the_culprit(noise, sevens, high) -> None:
    source = [high]
    items = [*noise, *([7] * sevens)]
    result = reduce(source, items)
    assert result.proven_minimal
    kept = [items[i] for i in result.indices]
    assert kept == [7]  # one 7 is enough; the noise never matters
    assert_one_minimal(source, kept)
    assert result.size == 1 and result.original_size == len(items)
    assert result.followup_input == [high, 7]
    assert result.params["n"] == 1 and result.params["append"].items == [7]
    assert not result.verdict.holds and result.output == 7  # the high value was ignored


def test_reduction_of_a_conjunction_keeps_every_needed_element() -> None:
    # Fails only when 7 and two values >= 300 are appended (max stays, but 7 hides 150).
    def system(values: list[int]) -> int:
        big = [v for v in values if v >= 300]
        return -1 if 7 in values and len(big) >= 2 else max(values)

    source = [150]
    items = [1, 2, 300, 3, 4, 7, 5, 400, 6, 500]
    result = reduce_followup(
        Append(items).params(),
        source=source,
        source_output=system(source),
        followup_output=system([*source, *items]),
        run=system,
        check=MONOTONE.check,
    )
    kept = [items[i] for i in result.indices]
    assert result.proven_minimal and 7 in kept and len(kept) == 3
    for index in range(len(kept)):
        rest = kept[:index] + kept[index + 1 :]
        assert system([*source, *rest]) >= system(source)


def test_budget_exhaustion_is_reported() -> None:
    source = [150]
    items = [*range(8, 48), 7, *range(48, 88)]
    result = reduce(source, items, budget=3)
    assert not result.proven_minimal
    assert result.calls == 3
    assert "NOT proven minimal" in result.summary() and "budget of 3" in result.summary()
    assert not holds(source, [items[i] for i in result.indices])  # still a failing subset


def test_relation_failing_without_any_element_is_not_called_minimal() -> None:
    # An unsound relation: violated even with nothing appended.
    never = relations.predicate(lambda a, b, ctx: False, name="never")
    result = reduce_followup(
        Append([5]).params(),
        source=[1],
        source_output=1,
        followup_output=5,
        run=max,
        check=never.check,
    )
    assert not result.proven_minimal and result.fails_without_elements
    assert "fails even with none of them" in result.summary()


def test_crashing_subsets_count_as_passing_and_are_reported() -> None:
    def fragile(values: list[int]) -> int:
        if len(values) == 2:
            raise ZeroDivisionError("two")
        return buggy_max(values)

    source = [150]
    items = [1, 7, 2]
    result = reduce_followup(
        Append(items).params(),
        source=source,
        source_output=fragile(source),
        followup_output=fragile([*source, *items]),
        run=fragile,
        check=MONOTONE.check,
    )
    assert result.crashes >= 1 and "crashed" in result.summary()
    kept = [items[i] for i in result.indices]
    assert not MONOTONE.check(150, fragile([*source, *kept]), CheckContext()).holds


def test_inconsistent_restrict_is_an_error_not_a_wrong_answer() -> None:
    class Lossy(Append):
        def restrict(self, indices: Sequence[int]) -> Append:
            return Append([])  # forgets everything

    with pytest.raises(InvalidArgument, match="does not violate the relation"):
        reduce_followup(
            Lossy([7]).params() | {"append": Lossy([7])},
            source=[150],
            source_output=150,
            followup_output=0,
            run=buggy_max,
            check=MONOTONE.check,
        )


def test_ranking_must_be_a_permutation() -> None:
    class BadRank(Append):
        def ranking(self, source: Any, source_output: Any, followup_output: Any) -> list[int]:
            return [0, 0]

    with pytest.raises(InvalidArgument, match="permutation"):
        reduce_followup(
            {"append": BadRank([7, 1])},
            source=[150],
            source_output=150,
            followup_output=0,
            run=buggy_max,
            check=MONOTONE.check,
        )


def test_ranking_puts_culprits_first_and_saves_calls() -> None:
    items = [*range(8, 100), *range(8, 100), 7]

    class Ranked(Append):
        def restrict(self, indices: Sequence[int]) -> Ranked:
            return Ranked([self.items[i] for i in indices])

        def ranking(self, source: Any, source_output: Any, followup_output: Any) -> list[int]:
            order = sorted(range(len(self.items)), key=lambda i: self.items[i] != 7)
            return order

    common = {
        "source": [150],
        "source_output": 150,
        "followup_output": 0,
        "run": buggy_max,
        "check": MONOTONE.check,
    }
    plain = reduce_followup(Append(items).params(), **common)
    ranked = reduce_followup({"append": Ranked(items)}, **common)
    assert plain.indices == ranked.indices == (len(items) - 1,)
    assert ranked.calls < plain.calls


def test_fallback_orders_share_the_budget_and_continue_from_the_first_pass() -> None:
    # Fails when at least 20 values >= 50 are appended; the first order interleaves them
    # with small values, the second (fallback) order puts them first.
    def system(values: list[int]) -> int:
        return -1 if sum(v >= 50 for v in values) >= 20 else max(values)

    items = [v for pair in zip(range(50, 90), range(40), strict=True) for v in pair]
    tested: list[tuple[int, bool]] = []  # (subset size, fails)

    def run(values: list[int]) -> int:
        output = system(values)
        tested.append((len(values) - 1, output == -1))
        return output

    class TwoOrders(Append):
        def restrict(self, indices: Sequence[int]) -> TwoOrders:
            return TwoOrders([self.items[i] for i in indices])

        def rankings(self, source: Any, source_output: Any, followup_output: Any):
            plain = list(range(len(self.items)))
            return [plain, sorted(plain, key=lambda i: -self.items[i])]

    common = {"source": [10], "source_output": 10, "followup_output": -1, "check": MONOTONE.check}
    for budget in (40, 100, 300):
        tested.clear()
        result = reduce_followup({"append": TwoOrders(items)}, budget=budget, run=run, **common)
        assert result.calls == len(tested) <= budget
        kept = [items[i] for i in result.indices]
        assert system([10, *kept]) == -1  # always a failing set
    assert result.proven_minimal and result.size == 20  # 300 calls are enough
    # With room enough, the first order proves the set and the fallback is never used.
    single = reduce_followup({"append": Append(items)}, budget=1000, run=system, **common)
    double = reduce_followup({"append": TwoOrders(items)}, budget=1000, run=system, **common)
    assert single.proven_minimal and double.proven_minimal
    assert (double.calls, double.indices) == (single.calls, single.indices)
    assert all(items[i] >= 50 for i in double.indices) and double.size == 20


def test_a_fallback_order_only_tries_subsets_of_the_first_passs_set() -> None:
    # Fails when 7 and 300 are both appended; tiny budgets leave the first pass unproven.
    def system(values: list[int]) -> int:
        return -1 if 7 in values and 300 in values else max(values)

    items = [*range(8, 20), 300, *range(20, 40), 7, *range(40, 60)]
    tested: list[int] = []

    def run(values: list[int]) -> int:
        tested.append(len(values) - 1)
        return system(values)

    class TwoOrders(Append):
        def restrict(self, indices: Sequence[int]) -> TwoOrders:
            return TwoOrders([self.items[i] for i in indices])

        def rankings(self, source: Any, source_output: Any, followup_output: Any):
            plain = list(range(len(self.items)))
            return [plain, plain[::-1]]

    common = {"source": [10], "source_output": 10, "followup_output": -1, "check": MONOTONE.check}
    result = reduce_followup({"append": TwoOrders(items)}, budget=12, run=run, **common)
    assert result.calls == len(tested) <= 12
    assert system([10, *(items[i] for i in result.indices)]) == -1


def test_no_reducible_parameter_means_no_reduction() -> None:
    assert (
        reduce_followup(
            {"angle": 3, "label": "x"},
            source=[1],
            source_output=1,
            followup_output=0,
            run=max,
            check=MONOTONE.check,
        )
        is None
    )
    assert find_reducible({"empty": Append([])}) is None
    assert find_reducible({"a": 1, "b": Append([3])})[0] == "b"


def test_adapters_are_found_through_the_class_hierarchy() -> None:
    class Legacy:
        def __init__(self, values: list[int]) -> None:
            self.values = values

    class Newer(Legacy):
        pass

    register_reducible(Legacy, lambda value: Append(value.values))
    adapted = as_reducible(Newer([1, 2]))
    assert isinstance(adapted, Reducible) and adapted.items == [1, 2]
    assert as_reducible("text") is None and as_reducible({"a": 1}) is None
    assert as_reducible([1, 2]) is None
    with pytest.raises(InvalidArgument, match="class"):
        register_reducible("Legacy", lambda value: value)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="callable"):
        register_reducible(Legacy, None)  # type: ignore[arg-type]


def test_bad_budget_is_named() -> None:
    with pytest.raises(InvalidArgument, match="budget"):
        reduce([150], [7], budget=0)


# -- through the engine ------------------------------------------------------------------------


def appended(source: list[int]) -> st.SearchStrategy[Followup]:
    return st.lists(st.integers(0, 99), min_size=1, max_size=50).map(
        lambda items: followup_of(source, items)
    )


def make_test(calls: list[int], **options: Any):
    @settings(database=None, derandomize=True, max_examples=300, **options)
    @metamorphic(
        source=st.lists(st.integers(100, 199), min_size=1, max_size=3),
        followup=appended,
        relation=MONOTONE,
        followups=1,
    )
    def test(values: list[int]) -> int:
        calls.append(len(values))
        return buggy_max(values)

    return test


def test_engine_reports_a_proven_minimal_follow_up_once(monkeypatch) -> None:
    runs: list[Any] = []
    original = engine.reduce_followup

    def counting(*args: Any, **kwargs: Any) -> Any:
        runs.append(kwargs["budget"])
        return original(*args, **kwargs)

    monkeypatch.setattr(engine, "reduce_followup", counting)
    calls: list[int] = []
    with pytest.raises(MetamorphicViolation) as caught:
        make_test(calls)()
    error = caught.value
    record = error.record
    # Reduced once, in Hypothesis' final replay only, with the default budget.
    assert runs == [500]
    assert record.reduction is not None and record.reduction.proven_minimal
    kept = record.reduction.perturbation.items
    assert 7 in kept
    assert_one_minimal(record.source, kept)
    assert error.followup.input == [*record.source, *kept]
    message = str(error)
    assert "minimal follow-up:" in message and "proven 1-minimal" in message
    assert f"of {record.reduction.original_size} element(s) of 'append'" in message


def test_recorder_budget_zero_switches_reduction_off() -> None:
    recorder = Recorder(minimize_budget=0)
    with recording(recorder), pytest.raises(MetamorphicViolation) as caught:
        make_test([])()
    assert caught.value.record.reduction is None
    assert "minimal follow-up" not in str(caught.value)
    assert recorder.relation("max never drops").minimize_calls == 0


def test_reduction_calls_are_counted_and_violations_handed_over() -> None:
    seen: list[tuple[bool, Any]] = []

    def sink(record: Any, final: bool) -> str:
        seen.append((final, record))
        return "saved somewhere"

    recorder = Recorder(on_violation=sink, nodeid="tests/x.py::test")
    with recording(recorder), pytest.raises(MetamorphicViolation) as caught:
        make_test([])()
    stats = recorder.relation("max never drops")
    final = [record for is_final, record in seen if is_final]
    assert len(final) == 1 and final[0].reduction is not None
    assert not any(record.reduction for is_final, record in seen if not is_final)
    assert stats.minimize_calls == final[0].reduction.calls > 0
    assert stats.sut_calls >= stats.followups + stats.minimize_calls
    assert recorder.violations[-1]["minimal_size"] == final[0].reduction.size
    assert final[0].nodeid == "tests/x.py::test"
    assert "artifacts: saved somewhere" in str(caught.value)


def test_a_failing_reduction_keeps_the_violation(monkeypatch) -> None:
    def broken(*args: Any, **kwargs: Any) -> Any:
        raise RuntimeError("reducer bug")

    monkeypatch.setattr(engine, "reduce_followup", broken)
    with pytest.raises(MetamorphicViolation) as caught:
        make_test([])()
    assert "could not reduce the follow-up: RuntimeError: reducer bug" in str(caught.value)


def _count_driven(threshold: int):
    """A system that loses the source's value once ``threshold`` values are appended (a
    point budget): which values arrive does not matter, only how many."""

    def system(values: list[int]) -> int:
        return 0 if len(values) - 1 >= threshold else max(values)

    return system


@pytest.mark.parametrize(("appended", "threshold"), [(1000, 476), (1000, 289), (300, 40)])
def test_count_driven_failures_end_proven_within_the_default_budget(
    appended: int, threshold: int
) -> None:
    """ddmin alone ran out at 476 of 1000 such elements after 500 calls; bisecting the
    prefix, then one sweep of single removals, proves the set in about threshold calls."""
    system = _count_driven(threshold)
    source, items = [150], list(range(appended))
    result = reduce_followup(
        Append(items).params(),
        source=source,
        source_output=system(source),
        followup_output=system([*source, *items]),
        run=system,
        check=MONOTONE.check,
    )
    assert result.proven_minimal, result.summary()
    assert result.size == threshold and result.count_bound == threshold
    assert result.calls <= threshold + 20
    kept = [items[i] for i in result.indices]
    assert system([*source, *kept]) == 0 and system([*source, *kept[1:]]) != 0


def test_a_count_too_large_to_prove_is_stated_with_its_bound() -> None:
    system = _count_driven(37_721)
    source, items = [150], list(range(81_926))
    result = reduce_followup(
        Append(items).params(),
        source=source,
        source_output=system(source),
        followup_output=system([*source, *items]),
        run=system,
        check=MONOTONE.check,
        budget=500,
    )
    assert not result.proven_minimal and result.calls <= 500
    assert result.count_bound == 37_721 and result.size == 37_721
    assert "the first 37721 ranked element(s) fail and the first 37720 do not" in result.summary()


def test_a_slow_system_gets_the_smallest_set_found_when_the_time_is_up() -> None:
    """A reduction is bounded in time as well as in calls: a system at 60 ms a call gets,
    after 0.3 s, the smallest failing set found so far (it still fails), marked as cut
    short by time, not an interrupted run."""
    import time

    source, items = [150], [*range(10, 50), 7, *range(50, 90)]

    def slow(values: list[int]) -> int:
        time.sleep(0.06)
        return buggy_max(values)

    followup = followup_of(source, items)
    started = time.monotonic()
    result = reduce_followup(
        followup.params,
        source=source,
        source_output=buggy_max(source),
        followup_output=buggy_max(followup.input),
        run=slow,
        check=MONOTONE.check,
        budget=1000,
        seconds=0.3,
    )
    assert time.monotonic() - started < 3.0  # stopped at the limit, not after 1000 calls
    assert result is not None and result.timed_out and not result.proven_minimal
    kept = [items[i] for i in result.indices]
    assert 7 in kept and not holds(source, kept)  # the set kept still fails
    assert result.size < len(items)
    assert "the time limit of 0.3 s ran out" in result.summary()
    # without the limit, the same reduction is proven 1-minimal
    unlimited = reduce(source, items)
    assert unlimited.proven_minimal and [items[i] for i in unlimited.indices] == [7]
