"""Engine overhead: time per SUT call through ``@metamorphic`` vs calling the SUT directly.

The system under test takes 10 ms (a sleep, so the number does not depend on CPU load).
The engine runs N examples of a test with two relations; we count its SUT calls C and
then call the SUT C times directly. overhead = engine time / direct time - 1.

The same property written by hand with ``@given`` and ``st.data()`` (the same source,
the same follow-up draws, the same SUT calls and checks) is timed too: the difference
between it and the engine is what ``@metamorphic`` itself costs per call (``engine_us``);
the rest of the overhead is Hypothesis generating the inputs (``hypothesis_us``), which
any property test pays. Each mode runs ``--rounds`` times, interleaved; the medians count.
The split is measured in CPU time (the SUT sleeps, so every CPU microsecond is overhead,
and a loaded machine's scheduling jitter of the 10 ms sleeps does not enter it); the
wall-clock ratio is shown beside it.

Profile (cProfile, SUT sleep 0, 200 examples, 2-core machine): of ~450 us per SUT call,
~85 % is Hypothesis (its engine's mutation and data-tree bookkeeping, drawing the 50
integers of a list and of each permutation); ``@metamorphic``'s own work (drawing the
follow-ups through one composite, the per-relation counters, building each check's
context, checking the relation) is ~15 us per call. Nothing in it copies or validates
inputs; the follow-ups are the values the relations' strategies return.

    python bench/engine_overhead.py [--examples N] [--rounds R]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from pytest_metamorphic import MetamorphicRelation, metamorphic, relations

SUT_SECONDS = 0.010


def sut(xs: list[int]) -> list[int]:
    time.sleep(SUT_SECONDS)
    return sorted(xs)


def timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall, CPU) seconds of ``fn()``."""
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def run_engine(examples: int) -> tuple[tuple[float, float], int]:
    calls = 0

    @settings(max_examples=examples, database=None, phases=[Phase.generate])
    @metamorphic(
        source=st.lists(st.integers(), max_size=50),
        relations=[
            MetamorphicRelation("permute", lambda xs: st.permutations(xs), relations.equal()),
            MetamorphicRelation(
                "append",
                lambda xs: st.integers().map(lambda x: [*xs, x]),
                relations.cardinality("<"),
            ),
        ],
        followups=2,
    )
    def test_sort(xs: list[int]) -> list[int]:
        nonlocal calls
        calls += 1
        return sut(xs)

    return timed(test_sort), calls


def run_by_hand(examples: int) -> tuple[tuple[float, float], int]:
    """The same property as ``run_engine`` written with plain Hypothesis."""
    calls = 0

    @settings(max_examples=examples, database=None, phases=[Phase.generate])
    @given(xs=st.lists(st.integers(), max_size=50), data=st.data())
    def test_sort(xs: list[int], data: st.DataObject) -> None:
        nonlocal calls
        calls += 1
        output = sut(xs)
        for _ in range(2):
            permuted = data.draw(st.permutations(xs))
            calls += 1
            assert sut(permuted) == output
        for _ in range(2):
            extra = data.draw(st.integers())
            calls += 1
            assert len(sut([*xs, extra])) > len(output)

    return timed(test_sort), calls


def run_direct(calls: int) -> tuple[float, float]:
    inputs = [list(range(50, 0, -1))] * calls
    return timed(lambda: [sut(xs) for xs in inputs])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=60)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()

    run_engine(5)  # warm-up: imports, Hypothesis start-up
    run_by_hand(5)
    wall: dict[str, list[float]] = {"engine": [], "by hand": [], "direct": []}
    cpu: dict[str, list[float]] = {"engine": [], "by hand": [], "direct": []}
    for _ in range(max(1, args.rounds)):
        (engine_wall, engine_cpu), calls = run_engine(args.examples)
        (hand_wall, hand_cpu), hand_calls = run_by_hand(args.examples)
        direct_wall, direct_cpu = run_direct(calls)
        for name, (w, c), n in (
            ("engine", (engine_wall, engine_cpu), calls),
            ("by hand", (hand_wall, hand_cpu), hand_calls),
            ("direct", (direct_wall, direct_cpu), calls),
        ):
            wall[name].append(w / n)
            cpu[name].append(c / n)
    w = {name: statistics.median(values) for name, values in wall.items()}
    c = {name: statistics.median(values) for name, values in cpu.items()}
    total_us = (c["engine"] - c["direct"]) * 1e6
    engine_us = (c["engine"] - c["by hand"]) * 1e6
    hypothesis_us = (c["by hand"] - c["direct"]) * 1e6
    overhead = total_us * 1e-6 / SUT_SECONDS
    engine_overhead = engine_us * 1e-6 / SUT_SECONDS
    wall_overhead = w["engine"] / w["direct"] - 1.0

    labels = {
        "engine": "@metamorphic",
        "by hand": "@given + st.data() by hand",
        "direct": "SUT called directly",
    }
    print(f"{'mode':<30}{'wall ms/call':>14}{'CPU us/call':>14}")
    for name, label in labels.items():
        print(f"{label:<30}{w[name] * 1e3:>14.3f}{c[name] * 1e6:>14.1f}")
    print(
        f"\noverhead on a 10 ms system: {overhead:.2%} ({total_us:.0f} us CPU per SUT call; "
        f"wall clock {wall_overhead:.2%})\n"
        f"  Hypothesis generating the inputs (the hand-written test's own cost): "
        f"{hypothesis_us:.0f} us\n"
        f"  @metamorphic itself: {engine_us:.0f} us = {engine_overhead:.2%} "
        f"(target <= 1 %, <= 100 us)"
    )
    print(
        f"RESULT overhead={overhead:.4f} per_call_us={total_us:.1f} engine_us={engine_us:.1f} "
        f"engine_overhead={engine_overhead:.4f} hypothesis_us={hypothesis_us:.1f} "
        f"wall_overhead={wall_overhead:.4f} sut_calls={calls} rounds={len(wall['engine'])}"
    )


if __name__ == "__main__":
    main()
