"""The batch protocol: campaigns and @metamorphic tests run batch systems in batches, with
the same results as one call per input, and blame a crash on its own input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings
from hypothesis import strategies as st

from pytest_metamorphic import InvalidArgument, metamorphic, relations
from pytest_metamorphic.core.batching import batched, supports_batches
from pytest_metamorphic.core.campaign import run_campaign
from pytest_metamorphic.core.errors import MetamorphicViolation, SystemUnderTestCrash
from tests.core.campaign.test_campaign import Lossy, campaign, followup, source


class BatchLossy(Lossy):
    """``Lossy`` with a batch call; records the size of every batch it is given."""

    def __init__(self, batch_size: int = 4, crash_on: int | None = None) -> None:
        super().__init__()
        self.batch_size = batch_size
        self.batches: list[int] = []
        self.crash_on = crash_on

    def __call__(self, scene):  # type: ignore[no-untyped-def]
        if self.crash_on is not None and scene[2] == self.crash_on:
            raise RuntimeError(f"bad noise {scene[2]}")
        return super().__call__(scene)

    def run_batch(self, scenes):  # type: ignore[no-untyped-def]
        self.batches.append(len(scenes))
        return [self(scene) for scene in scenes]


def test_a_campaign_runs_a_batch_system_in_batches_with_the_same_log(tmp_path: Path) -> None:
    plain = run_campaign(campaign(Lossy(), sources=12), log=tmp_path / "plain.jsonl")
    system = BatchLossy(batch_size=3)
    assert supports_batches(system)
    batched_result = run_campaign(campaign(system, sources=12), log=tmp_path / "batched.jsonl")
    # 1 source + 2 sizes x 2 follow-ups per source: batches of 3 and 2 (the source first).
    assert system.batches == [3, 2] * 12
    assert batched_result.sut_calls == plain.sut_calls == 12 * 5
    assert batched_result.outcome_json() == plain.outcome_json()
    plain_log, batched_log = (
        (tmp_path / name).read_text().splitlines() for name in ("plain.jsonl", "batched.jsonl")
    )

    # The same records (each sealed with a check over its log's header, which names the
    # system, so only the checks differ); the headers differ only in the system.
    def unsealed(log: list[str]) -> list[dict]:
        return [{k: v for k, v in json.loads(line).items() if k != "check"} for line in log[1:]]

    assert unsealed(plain_log) == unsealed(batched_log)
    headers = [json.loads(log[0]) for log in (plain_log, batched_log)]
    assert [h.pop("system")["type"].rsplit(".", 1)[1] for h in headers] == ["Lossy", "BatchLossy"]
    assert headers[0] == headers[1]


def test_a_crashing_batch_is_rerun_one_input_at_a_time(tmp_path: Path) -> None:
    # Find a follow-up noise value the campaign draws, and make exactly that input crash.
    first = followup(
        source(np.random.default_rng([7, 0]), 0), 10, np.random.default_rng([7, 0, 1, 0])
    )
    scenes = [first]
    system = BatchLossy(batch_size=4, crash_on=first[2])
    result = run_campaign(campaign(system, sources=1), log=tmp_path / "log.jsonl")
    record = json.loads((tmp_path / "log.jsonl").read_text().splitlines()[1])
    crashes = [pair for pair in record["pairs"] if "crash" in pair]
    assert [(p["size"], p["followup"]) for p in crashes] == [(10, 0)]
    assert crashes[0]["crash"] == f"RuntimeError: bad noise {scenes[0][2]}"
    assert sum("holds" in pair for pair in record["pairs"]) == 3
    assert result.sizes[10].crashes == 1


def test_batched_builds_a_batch_system_and_checks_its_outputs() -> None:
    system = batched(lambda xs: [x * 2 for x in xs], batch_size=3)
    assert system(4) == 8 and system.run_batch([1, 2]) == [2, 4]
    assert system.batch_size == 3
    short = batched(lambda xs: xs[:-1])
    with pytest.raises(InvalidArgument, match="returned 1 outputs for 2 inputs"):
        short.run_batch([1, 2])
    with pytest.raises(InvalidArgument, match="batch_size=0 must be an int >= 1"):
        batched(lambda xs: xs, batch_size=0)
    with pytest.raises(InvalidArgument, match="must be callable"):
        batched(3)  # type: ignore[arg-type]


def test_metamorphic_batch_calls_the_function_with_lists() -> None:
    seen: list[int] = []

    @settings(max_examples=10, database=None)
    @metamorphic(
        source=st.lists(st.integers(), max_size=5),
        followup=lambda xs: st.permutations(xs),
        relation=relations.equal(),
        followups=5,
        batch=4,
    )
    def test_sorted(batch):  # type: ignore[no-untyped-def]
        seen.append(len(batch))
        return [sorted(xs) for xs in batch]

    test_sorted()
    # 1 source + 5 follow-ups: a batch of 4, then of 2.
    assert seen and set(seen) == {4, 2}
    assert seen.count(4) == seen.count(2)


def test_metamorphic_batch_reports_violations_and_crashes_like_single_calls() -> None:
    @settings(max_examples=50, database=None, derandomize=True)
    @metamorphic(
        source=st.lists(st.integers(0, 9), min_size=2, max_size=5),
        followup=lambda xs: st.permutations(xs),
        relation=relations.equal(),
        followups=3,
        batch=True,
    )
    def test_first_element(batch):  # type: ignore[no-untyped-def]
        return [xs[0] for xs in batch]

    with pytest.raises(MetamorphicViolation, match="violated on follow-up"):
        test_first_element()

    @settings(max_examples=20, database=None, derandomize=True)
    @metamorphic(
        source=st.lists(st.integers(0, 9), min_size=1, max_size=4),
        followup=lambda xs: st.just([*xs, 99]),
        relation=relations.equal(),
        followups=1,
        batch=True,
    )
    def test_crash_on_99(batch):  # type: ignore[no-untyped-def]
        if any(99 in xs for xs in batch):
            raise ValueError("99 is not allowed")
        return [sorted(xs) for xs in batch]

    with pytest.raises(SystemUnderTestCrash, match="crashed on follow-up 0 of relation"):
        test_crash_on_99()


def test_metamorphic_batch_argument_is_checked() -> None:
    with pytest.raises(InvalidArgument, match="batch=0 must be True, False or a batch size"):
        metamorphic(
            source=st.just(1), followup=lambda x: st.just(x), relation=relations.equal(), batch=0
        )
