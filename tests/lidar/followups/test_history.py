"""Earlier sweeps: a per-frame system must give a sweep the same obstacles whatever it
ran on before, and the engine runs a history in order."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from pytest_metamorphic import Followup, InvalidArgument, MetamorphicViolation, metamorphic
from pytest_metamorphic.core.cases import MetamorphicRelation
from pytest_metamorphic.core.relations import equal
from pytest_metamorphic.lidar.followups.history import HISTORY_STEPS, EarlierSweeps
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.relations.lidar import (
    history_independence,
    history_under_faults,
    lidar_relations,
    packet_loss,
)
from pytest_metamorphic.strategies import degraded_earlier_sweeps
from tests.core.lidar_cases import labelled_kitti, street

FAST = settings(
    max_examples=6,
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=list(HealthCheck),
)


def test_earlier_sweeps_are_made_from_the_sweep_itself() -> None:
    frame = street()
    history = EarlierSweeps(("turned 90", "mirrored", "first half"))
    turned, mirrored, half = history.inputs(frame)
    x, y = frame.cloud.xyz[:, 0], frame.cloud.xyz[:, 1]
    assert np.allclose(turned.cloud.xyz[:, 0], -y, atol=1e-4)
    assert np.allclose(turned.cloud.xyz[:, 1], x, atol=1e-4)
    assert np.allclose(mirrored.cloud.xyz[:, 1], -y)
    assert len(half.cloud) == len(frame.cloud) // 2
    assert EarlierSweeps.from_json(history.to_json()) == history
    assert history.params()["earlier_sweeps"] == "turned 90, then mirrored, then first half"
    for bad in ((), ("turned 45",), "mirrored"):
        with pytest.raises(InvalidArgument):
            EarlierSweeps(bad)  # type: ignore[arg-type]
    assert set(HISTORY_STEPS) >= {"turned 180", "turned 270"}


def test_the_engine_runs_a_history_in_order_before_its_follow_up() -> None:
    calls: list[Any] = []

    def after_two(value: int) -> st.SearchStrategy[Followup]:
        return st.just(Followup(value, params={"history": "two"}, before=(value + 1, value + 2)))

    relation = MetamorphicRelation("history", after_two, equal(), same_input=lambda a, b: False)

    @FAST
    @metamorphic(source=st.just(10), relations=[relation], followups=1)
    def system(value: int) -> int:
        calls.append(value)
        return value

    system()
    assert calls[:6] == [10, 10, 10, 11, 12, 10]


def test_a_system_with_state_fails_history_and_a_per_frame_one_passes() -> None:
    frames = st.sampled_from([labelled_kitti(1), street()])
    reference = ReferencePerception()

    @FAST
    @metamorphic(source=frames, relations=[history_independence()])
    def per_frame(frame):  # type: ignore[no-untyped-def]
        return reference(frame)

    per_frame()
    remembering = mutant("temporal_ground")

    @FAST
    @metamorphic(source=frames, relations=[history_independence()])
    def stateful(frame):  # type: ignore[no-untyped-def]
        return remembering(frame)

    with pytest.raises(MetamorphicViolation, match="after other sweeps") as failure:
        stateful()
    assert "earlier_sweeps" in str(failure.value)


def test_history_is_in_the_library_unless_the_system_is_not_per_frame() -> None:
    names = [relation.name for relation in lidar_relations()]
    assert names[-2].startswith("the same sweep after other sweeps")
    assert names[-1].startswith("a degraded sweep (lasers dead or packets lost) after other")
    assert not any("after other sweeps" in r.name for r in lidar_relations(history=False))
    with pytest.raises(InvalidArgument, match="history"):
        lidar_relations(history="yes")  # type: ignore[arg-type]
    assert math.isfinite(len(names))


def test_a_degraded_history_compares_the_degraded_sweep_with_itself() -> None:
    # The engine runs the follow-up's own input (the degraded sweep) twice, then the
    # earlier sweeps, then the degraded sweep: the order a replay must repeat.
    calls: list[Any] = []

    def degraded(value: int) -> st.SearchStrategy[Followup]:
        return st.just(Followup(value + 100, params={"history": "two"}, before=(value + 1,)))

    relation = MetamorphicRelation("degraded", degraded, equal())

    @FAST
    @metamorphic(source=st.just(10), relations=[relation], followups=1)
    def system(value: int) -> int:
        calls.append(value)
        return value % 100

    system()
    assert calls[:5] == [10, 110, 110, 11, 110]


def test_degraded_histories_draw_the_frame_own_faults_after_sweeps_made_from_it() -> None:
    frame = street()
    seen: list[Followup] = []

    @FAST
    @given(degraded_earlier_sweeps(frame, max_steps=2))
    def draw(item: Followup) -> None:
        seen.append(item)

    draw()
    assert seen
    for item in seen:
        assert item.skipped is None
        assert len(item.input.cloud) < len(frame.cloud)  # lasers or packets gone
        assert 1 <= len(item.before) <= 2
        assert "earlier_sweeps" in item.params
        assert {"missing_rings", "lost_block_start_deg"} & set(item.params), item.params
    for bad in ({"faults": ()}, {"faults": "beams"}, {"faults": ("rain",)}, {"max_steps": 0},
                {"max_rings": 0}):  # fmt: skip
        with pytest.raises(InvalidArgument):
            degraded_earlier_sweeps(frame, **bad)  # type: ignore[arg-type]


def test_degraded_history_is_not_applicable_where_the_sensor_is_unknown() -> None:
    unknown = Frame(PointCloud(np.random.default_rng(0).normal(size=(500, 3)) * 10))
    seen: list[Followup] = []

    @FAST
    @given(degraded_earlier_sweeps(unknown))
    def draw(item: Followup) -> None:
        seen.append(item)

    draw()
    assert all(item.skipped is not None for item in seen)
    assert any("sensor" in str(item.skipped) or "lasers" in str(item.skipped) for item in seen)


def test_a_scan_buffer_that_keeps_lost_columns_fails_only_the_degraded_history() -> None:
    # stale_packets fills a lost packet's columns with what they last held: right after
    # the clean sweep that is the clean sweep, so packet loss and the plain history pass;
    # a degraded sweep after other sweeps shows the fill.
    frames = st.just(street())
    reference = ReferencePerception()

    def run(system: Any, relations: list[Any]) -> None:
        # No shrinking: a kill is what is asserted, not the smallest one (minutes saved).
        @settings(FAST, phases=[Phase.explicit, Phase.generate])
        @metamorphic(source=frames, relations=relations)
        def test(frame):  # type: ignore[no-untyped-def]
            return system(frame)

        test()

    run(reference, [history_under_faults()])
    run(mutant("stale_packets"), [packet_loss(), history_independence()])
    with pytest.raises(MetamorphicViolation, match="degraded sweep") as failure:
        run(mutant("stale_packets"), [history_under_faults(faults=("packets",))])
    assert "lost_block_start_deg" in str(failure.value)
