"""Per-call time limits: a system that hangs is a crash of that call, never a violation."""

from __future__ import annotations

import time

import pytest
from hypothesis import Phase, settings
from hypothesis import strategies as st

from pytest_metamorphic import metamorphic, relations
from pytest_metamorphic.core.campaign import Campaign, run_campaign
from pytest_metamorphic.core.errors import InvalidArgument, SystemTimeout, SystemUnderTestCrash
from pytest_metamorphic.core.stats import Recorder, recording
from pytest_metamorphic.core.timeout import call_with_timeout

PINNED = settings(max_examples=5, database=None, derandomize=True, phases=[Phase.generate])


def sleepy(x: int) -> int:
    """Hangs (for 3 s) on negative inputs, answers at once otherwise."""
    if x < 0:
        time.sleep(3.0)
    return abs(x)


def test_call_with_timeout_returns_raises_and_stops_waiting() -> None:
    assert call_with_timeout(sleepy, 4, seconds=1.0) == 4
    with pytest.raises(ZeroDivisionError):
        call_with_timeout(lambda: 1 / 0, seconds=1.0)
    began = time.perf_counter()
    with pytest.raises(SystemTimeout, match=r"sleepy call did not return within 0.2 s") as info:
        call_with_timeout(sleepy, -1, seconds=0.2, what="sleepy call")
    assert time.perf_counter() - began < 1.5
    assert info.value.seconds == 0.2 and isinstance(info.value, TimeoutError)
    assert call_with_timeout(sleepy, -1, seconds=None) == 1 if False else True


def test_a_hanging_follow_up_is_a_crash_of_that_call() -> None:
    @PINNED
    @metamorphic(
        source=st.integers(1, 100),
        followup=lambda x: st.just(-x),
        relation=relations.equal(),
        followups=1,
        timeout=0.3,
    )
    def test_abs(x: int) -> int:
        return sleepy(x)

    recorder = Recorder()
    began = time.perf_counter()
    with recording(recorder), pytest.raises(SystemUnderTestCrash) as info:
        test_abs()
    assert time.perf_counter() - began < 10
    assert "timed out on follow-up 0 of relation 'equal'" in str(info.value)
    assert isinstance(info.value.__cause__, SystemTimeout)
    assert info.value.stage == "followup"
    stats = recorder.relation("equal")
    assert stats.crashes >= 1 and stats.violations == 0


def test_the_recorder_limit_applies_when_the_decorator_sets_none() -> None:
    @PINNED
    @metamorphic(source=st.just(-5), followup=lambda x: st.just(x), relation=relations.equal())
    def test_abs(x: int) -> int:
        return sleepy(x)

    with (
        recording(Recorder(timeout=0.2)),
        pytest.raises(SystemUnderTestCrash, match="timed out on the source"),
    ):
        test_abs()


def test_campaigns_record_a_timeout_and_go_on() -> None:
    campaign = Campaign(
        name="sleepy",
        source=lambda rng, index: index,
        followup=lambda value, size, rng: -value if value == 2 else value + size,
        system=lambda value: [sleepy(value)],
        relation=relations.predicate(lambda a, b, context: True, name="anything"),
        sizes=(1,),
        sources=4,
    )
    result = run_campaign(campaign, timeout=0.3)
    assert result.complete and result.sizes[1].crashes == 1 and result.sizes[1].pairs == 4
    with pytest.raises(InvalidArgument, match="timeout="):
        run_campaign(campaign, timeout=0)


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), "5", True])
def test_bad_timeouts_are_named(bad: object) -> None:
    with pytest.raises(InvalidArgument, match="timeout="):
        metamorphic(source=st.just(1), followup=st.just, relation=relations.equal(), timeout=bad)  # type: ignore[arg-type]


def test_a_hanging_input_is_saved_for_replay_like_any_failure(request) -> None:
    from hypothesis.database import InMemoryExampleDatabase

    if request.config.getoption("hypothesis_seed", None) is not None:
        pytest.skip("Hypothesis saves no examples when --hypothesis-seed fixes the seed")

    database = InMemoryExampleDatabase()
    calls: list[int] = []

    # Random search (derandomize excludes a database); every negative input hangs, and
    # 20 examples of integers(-3, 3) always include one.
    @settings(
        max_examples=20, database=database, phases=[Phase.reuse, Phase.generate, Phase.shrink]
    )
    @metamorphic(source=st.integers(-3, 3), followup=lambda x: st.just(x),
                 relation=relations.equal(), followups=1, timeout=0.2)  # fmt: skip
    def test_abs(x: int) -> int:
        calls.append(x)
        return sleepy(x)

    with pytest.raises(SystemUnderTestCrash, match="timed out"):
        test_abs()
    saved = [value for values in database.data.values() for value in values]
    assert saved, "Hypothesis did not save the hanging case"
    calls.clear()
    with pytest.raises(SystemUnderTestCrash, match="timed out"):
        test_abs()  # the saved case is replayed first
    assert calls[0] < 0


def test_a_system_that_always_hangs_is_reported_at_once_not_retried_while_shrinking() -> None:
    # Before: Hypothesis retried every case during shrinking, 2 s each: 218 s and ~100
    # threads for a --mt-timeout 2 test of a system that always hangs.
    import threading

    release = threading.Event()
    calls: list[int] = []

    def hangs(x: int) -> int:
        calls.append(x)
        release.wait(60)
        return x

    @settings(database=None, max_examples=50)
    @metamorphic(
        source=st.integers(0, 1000),
        followup=lambda x: st.just(x + 1),
        relation=relations.equal(),
        timeout=0.3,
        followups=1,
    )
    def test_hanging(x: int) -> int:
        return hangs(x)

    threads = threading.active_count()
    began = time.monotonic()
    try:
        with recording(Recorder()), pytest.raises(SystemUnderTestCrash, match="timed out"):
            test_hanging()
        assert time.monotonic() - began < 10
        assert len(calls) <= 3  # the first time-out and the final replay, not every shrink
        assert threading.active_count() - threads <= 3
    finally:
        release.set()


def test_abandoned_calls_are_bounded() -> None:
    import threading

    from pytest_metamorphic.core import timeout as limits

    release = threading.Event()
    try:
        refused = None
        for _ in range(limits.MAX_ABANDONED + 2):
            try:
                call_with_timeout(release.wait, 60, seconds=0.01)
            except SystemTimeout as error:
                if "still running" in str(error):
                    refused = error
                    break
        assert refused is not None and "isolate=True" in str(refused)
    finally:
        release.set()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and call_with_timeout_refuses():
        time.sleep(0.05)
    assert call_with_timeout(abs, -3, seconds=1.0) == 3  # the released threads ended


def call_with_timeout_refuses() -> bool:
    try:
        call_with_timeout(abs, 1, seconds=1.0)
    except SystemTimeout:
        return True
    return False


def catastrophic(text: str) -> bool:
    """Holds the GIL for minutes: a backtracking regular expression runs in C."""
    import re

    return re.match(r"(a+)+$", text) is not None


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="isolation forks")
def test_isolation_stops_a_call_that_holds_the_gil() -> None:
    from pytest_metamorphic.core.timeout import call_isolated

    assert call_isolated(catastrophic, "aaa", seconds=10) is True
    with pytest.raises(ZeroDivisionError):
        call_isolated(lambda: 1 / 0, seconds=10)
    began = time.monotonic()
    with pytest.raises(SystemTimeout, match="process was killed"):
        call_isolated(catastrophic, "a" * 40 + "b", seconds=1, what="the regex")
    assert time.monotonic() - began < 10


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="isolation forks")
def test_metamorphic_isolate_reports_a_gil_holding_hang_as_a_crash() -> None:
    @settings(database=None, max_examples=3, phases=[Phase.generate])
    @metamorphic(
        source=st.just("a" * 40 + "b"),
        followup=lambda text: st.just(text),
        relation=relations.equal(),
        timeout=1,
        isolate=True,
        followups=1,
    )
    def test_regex(text: str) -> bool:
        return catastrophic(text)

    began = time.monotonic()
    with recording(Recorder()), pytest.raises(SystemUnderTestCrash, match="timed out"):
        test_regex()
    assert time.monotonic() - began < 15


def test_isolate_is_checked() -> None:
    with pytest.raises(InvalidArgument, match="isolate"):
        metamorphic(source=st.just(1), followup=st.just, relation=relations.equal(), isolate=1)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="not with batch"):
        metamorphic(
            source=st.just(1), followup=st.just, relation=relations.equal(), isolate=True, batch=2
        )
