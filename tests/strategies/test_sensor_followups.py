"""Faults and edits follow the frame's sensor on real recordings of other sensors than
KITTI's HDL-64E (nebula's VLP-16 and VLP-32C), and say so where they cannot apply."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import shared_data_path
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.sensors import LIVOX_MID40, VLP16, VLP32C, frame_sensor
from pytest_metamorphic.lidar.roi import corridor_roi
from tests.deterministic import find

RECORDINGS = {
    "vlp16": (("nebula_velodyne", "vlp16", "1673400472138016708.pcd"), VLP16),
    "vlp32c": (("nebula_velodyne", "vlp32", "1713492677464078412.pcd"), VLP32C),
}
SEARCH = settings(
    max_examples=15, derandomize=True, database=None, deadline=None,
    suppress_health_check=list(HealthCheck),
)  # fmt: skip


@pytest.mark.parametrize("key", sorted(RECORDINGS))
def test_dead_beams_and_lost_packets_are_the_recording_sensors(key: str) -> None:
    parts, sensor = RECORDINGS[key]
    frame = FrameCatalog(shared_data_path(*parts), roi=corridor_roi())[0]
    estimate = frame_sensor(frame)
    assert estimate.sensor is sensor
    lasers = set(estimate.lasers)

    @SEARCH
    @given(st.data())
    def check(data: st.DataObject) -> None:
        beams = data.draw(mst.dead_beams(frame))
        dropped = set(beams.params["missing_rings"])
        assert 1 <= len(dropped) <= 4 and dropped <= lasers
        left = set(frame_sensor(beams.input).lasers) if len(beams.input.cloud) else set()
        assert left == lasers - dropped  # exactly those lasers, every return of them
        packets = data.draw(mst.lost_packets(frame))
        width = packets.params["lost_block_width_deg"]
        assert width / sensor.packet_degrees == pytest.approx(packets.params["packets"], abs=1e-3)

    check()


def test_an_unlabelled_sweep_gets_the_built_in_road_users_or_says_why_not() -> None:
    """A recording without labels has no objects of its own to insert: the built-in
    rendered road users are offered (re-cast for its VLP-32C); without them, the strategy
    says there is nothing to insert."""
    parts, _ = RECORDINGS["vlp32c"]
    frame = FrameCatalog(shared_data_path(*parts), roi=corridor_roi())[0]
    bare = find(mst.inserted_objects(frame, road_users=False), lambda f: True, settings=SEARCH)
    assert bare.skipped is not None and "no object to insert" in bare.skipped
    offered = find(mst.inserted_objects(frame), lambda f: True, settings=SEARCH)
    # This yard's 7 m corridor takes only what was seen from close by; shrinking goes to
    # the nearest road user, the adult seen from 4.2 m.
    assert offered.skipped is None
    assert offered.params["insert_object"].template.source == "road users#0 [adult close by]"


def test_a_sensor_without_rings_gets_no_dead_beams() -> None:
    cloud = np.random.default_rng(0).normal(size=(500, 3)) * 10
    frame = Frame(PointCloud(cloud), roi=corridor_roi(), sensor=LIVOX_MID40)
    followup = find(mst.dead_beams(frame), lambda f: True, settings=SEARCH)
    assert followup.skipped == "beam loss: Livox Mid-40 has no lasers to lose"
    packets = find(mst.lost_packets(frame), lambda f: True, settings=SEARCH)
    assert packets.skipped is not None and "not azimuth blocks" in packets.skipped
