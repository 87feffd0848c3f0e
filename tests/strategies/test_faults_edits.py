"""Strategies for sensor faults, weather and object edits: what they draw, what they
shrink to, and arguments named early (before any frame is read)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.edit import RemoveObject
from pytest_metamorphic.lidar.followups.faults import DropRings
from pytest_metamorphic.lidar.followups.insert import InsertObject
from tests.core.lidar_cases import street
from tests.deterministic import find

FIND = settings(
    database=None, derandomize=True, max_examples=200, phases=[Phase.generate, Phase.shrink],
    suppress_health_check=list(HealthCheck),
)  # fmt: skip


@settings(max_examples=5, database=None, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_each_strategy_draws_its_edit_of_the_source(data) -> None:  # type: ignore[no-untyped-def]
    source = street()
    n = len(source.cloud)
    beams = data.draw(mst.dead_beams(source, max_rings=2))
    rings = beams.params["drop_rings"].rings
    assert 1 <= len(rings) <= 2
    assert not np.isin(beams.input.cloud.fields["ring"], rings).any()
    packets = data.draw(mst.lost_packets(source, max_packets=3))
    assert 1 <= packets.params["packets"] <= 3 and len(packets.input.cloud) < n
    weather = data.draw(mst.weathered_frames(source, kinds=("rain",), visibilities=(80.0,)))
    assert weather.params["weather"] == "rain" and weather.params["visibility_m"] == 80.0
    removed = data.draw(mst.removed_objects(source))
    assert isinstance(removed.params["remove_object"], RemoveObject)
    assert len(removed.input.boxes) == len(source.boxes) - 1
    inserted = data.draw(mst.inserted_objects(source))
    insertion = inserted.params["insert_object"]
    assert isinstance(insertion, InsertObject) and len(insertion) >= 30
    assert inserted.input.boxes[-1] == insertion.box


def test_edits_shrink_to_the_simplest_case() -> None:
    source = street()
    beams = find(mst.dead_beams(source), lambda f: True, settings=FIND)
    assert beams.params["drop_rings"] == DropRings((0,))
    packet = find(mst.lost_packets(source), lambda f: True, settings=FIND)
    assert packet.params["packets"] == 1 and packet.params["lost_block_start_deg"] == 0.0
    coarse = find(mst.quantized_ranges(source), lambda f: True, settings=FIND)
    assert coarse.params["range_step_m"] == 0.05
    weather = find(mst.weathered_frames(source), lambda f: True, settings=FIND)
    assert weather.params["weather"] == "fog" and weather.params["visibility_m"] == 200.0
    assert weather.params["weather_seed"] == 0
    removed = find(mst.removed_objects(source), lambda f: True, settings=FIND)
    nearest = min(source.boxes, key=lambda box: np.hypot(*box.center[:2]))
    assert removed.params["remove_object"].box == nearest
    inserted = find(mst.inserted_objects(source), lambda f: True, settings=FIND)
    # The first object (the nearest), placed with the smallest move.
    assert inserted.params["insert_object"].template.label == nearest.label


def test_arguments_are_named_before_any_frame_is_read() -> None:
    source = street()
    with pytest.raises(InvalidArgument, match="max_rings"):
        mst.dead_beams(source, max_rings=0)
    with pytest.raises(InvalidArgument, match="max_packets"):
        mst.lost_packets(source, max_packets=True)
    with pytest.raises(InvalidArgument, match="step"):
        mst.quantized_ranges(source, steps=(0.1, 2.0))
    with pytest.raises(InvalidArgument, match="visibilities"):
        mst.weathered_frames(source, visibilities=())
    with pytest.raises(InvalidArgument, match="margin"):
        mst.removed_objects(source, margin=-1.0)
    with pytest.raises(InvalidArgument, match="min_returns"):
        mst.inserted_objects(source, min_returns=3)
    with pytest.raises(InvalidArgument, match="must be a Frame"):
        mst.inserted_objects(np.zeros((3, 4)))
