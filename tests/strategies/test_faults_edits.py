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
from pytest_metamorphic.lidar.followups.faults import PACKET_DEGREES, DropRings
from pytest_metamorphic.lidar.followups.insert import InsertObject
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E
from pytest_metamorphic.lidar.roi import ROI
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
    # One packet centred straight ahead.
    assert packet.params["packets"] == 1
    assert packet.params["lost_block_start_deg"] == pytest.approx(
        360 - HDL64E.packet_degrees / 2, abs=1e-3
    )
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


def _bearings(frame: Frame) -> tuple[float, float]:
    xy = frame.cloud.xyz[:, :2]
    inside = np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))[frame.roi.contains(xy)]
    return float(inside.min()), float(inside.max())


@settings(max_examples=30, database=None, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_lost_packets_fall_where_the_roi_is(data) -> None:  # type: ignore[no-untyped-def]
    # A wedge ROI ahead and to the left (bearings 10-50 degrees), as KITTI's camera wedge
    # covers 80 of 360: every drawn block is centred on a bearing the ROI holds returns at.
    source = street()
    wedge = ROI.from_polygons([[(0.0, 0.0), (60.0, 10.6), (60.0, 71.5)]])
    frame = Frame(source.cloud, roi=wedge)
    low, high = _bearings(frame)
    assert low >= 5 and high <= 55  # the rasterised ROI widens the wedge near the sensor
    packets = data.draw(mst.lost_packets(frame))
    start = packets.params["lost_block_start_deg"]
    centre = (start + packets.params["lost_block_width_deg"] / 2 + 180) % 360 - 180
    assert low - 0.11 <= centre <= high + 0.11
    anywhere = data.draw(mst.lost_packets(frame, within_roi=False))
    assert 1 <= anywhere.params["packets"] <= 10


def test_a_lost_packet_shrinks_to_the_roi_bearing_nearest_ahead() -> None:
    wedge = ROI.from_polygons([[(0.0, 0.0), (60.0, 10.6), (60.0, 71.5)]])
    frame = Frame(street().cloud, roi=wedge)
    packet = find(mst.lost_packets(frame), lambda f: True, settings=FIND)
    centre = packet.params["lost_block_start_deg"] + PACKET_DEGREES / 2
    assert packet.params["packets"] == 1 and centre == pytest.approx(_bearings(frame)[0], abs=0.11)


@settings(max_examples=30, database=None, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_range_steps_are_drawn_in_millimetres_from_a_range(data) -> None:  # type: ignore[no-untyped-def]
    source = street()
    step = data.draw(mst.quantized_ranges(source)).params["range_step_m"]
    assert 0.05 <= step <= 0.2 and round(step * 1000) == pytest.approx(step * 1000)
    narrow = data.draw(mst.quantized_ranges(source, min_step=0.1, max_step=0.12))
    assert 0.1 <= narrow.params["range_step_m"] <= 0.12
    levels = data.draw(mst.quantized_ranges(source, steps=(0.3, 0.4)))
    assert levels.params["range_step_m"] in (0.3, 0.4)


def test_arguments_are_named_before_any_frame_is_read() -> None:
    source = street()
    with pytest.raises(InvalidArgument, match="max_rings"):
        mst.dead_beams(source, max_rings=0)
    with pytest.raises(InvalidArgument, match="max_packets"):
        mst.lost_packets(source, max_packets=True)
    with pytest.raises(InvalidArgument, match="step"):
        mst.quantized_ranges(source, steps=(0.1, 2.0))
    with pytest.raises(InvalidArgument, match="min_step=0 must be a number of metres"):
        mst.quantized_ranges(source, min_step=0)
    with pytest.raises(InvalidArgument, match=r"min_step=0\.2 must not exceed max_step=0\.1"):
        mst.quantized_ranges(source, min_step=0.2, max_step=0.1)
    with pytest.raises(InvalidArgument, match="within_roi"):
        mst.lost_packets(source, within_roi=1)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="visibilities"):
        mst.weathered_frames(source, visibilities=())
    with pytest.raises(InvalidArgument, match="margin"):
        mst.removed_objects(source, margin=-1.0)
    with pytest.raises(InvalidArgument, match="min_returns"):
        mst.inserted_objects(source, min_returns=3)
    with pytest.raises(InvalidArgument, match="must be a Frame"):
        mst.inserted_objects(np.zeros((3, 4)))
