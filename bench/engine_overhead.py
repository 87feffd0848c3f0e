"""Engine overhead: time per SUT call through ``@metamorphic`` vs calling the SUT directly.

The system under test takes 10 ms (a sleep, so the number does not depend on CPU load).
The engine runs N examples of a test with two relations; we count its SUT calls C and
then call the SUT C times directly. overhead = engine time / direct time - 1.

    python bench/engine_overhead.py [--examples N]
"""

from __future__ import annotations

import argparse
import time

from hypothesis import Phase, settings
from hypothesis import strategies as st

from pytest_metamorphic import MetamorphicRelation, metamorphic, relations

SUT_SECONDS = 0.010


def sut(xs: list[int]) -> list[int]:
    time.sleep(SUT_SECONDS)
    return sorted(xs)


def run_engine(examples: int) -> tuple[float, int]:
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

    start = time.perf_counter()
    test_sort()
    return time.perf_counter() - start, calls


def run_direct(calls: int) -> float:
    inputs = [list(range(50, 0, -1))] * calls
    start = time.perf_counter()
    for xs in inputs:
        sut(xs)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=60)
    args = parser.parse_args()

    run_engine(5)  # warm-up: imports, Hypothesis start-up
    engine_s, calls = run_engine(args.examples)
    direct_s = run_direct(calls)
    overhead = engine_s / direct_s - 1.0
    per_call_us = (engine_s - direct_s) / calls * 1e6

    print(f"{'mode':<10}{'SUT calls':>10}{'wall s':>10}{'ms/call':>10}")
    print(f"{'engine':<10}{calls:>10}{engine_s:>10.3f}{engine_s / calls * 1e3:>10.3f}")
    print(f"{'direct':<10}{calls:>10}{direct_s:>10.3f}{direct_s / calls * 1e3:>10.3f}")
    print(f"engine overhead: {overhead:.2%} ({per_call_us:.0f} us per SUT call; target <= 5%)")
    print(
        f"RESULT overhead={overhead:.4f} per_call_us={per_call_us:.1f} sut_calls={calls} "
        f"engine_s={engine_s:.3f} direct_s={direct_s:.3f}"
    )


if __name__ == "__main__":
    main()
