"""Sensor faults: rings recovered from real KITTI sweeps and rendered scans, dead beams and
lost packets as follow-up transforms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.core.perturbation import find_reducible
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.faults import (
    PACKET_DEGREES,
    DropAzimuthBlock,
    DropRings,
    QuantizeRange,
    derive_rings,
)
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.hdl64 import HDL64E
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception
from pytest_metamorphic.relations.lidar import packet_loss, range_quantization
from tests.core.lidar_cases import kitti, street


def _elevation_deg(frame) -> np.ndarray:  # type: ignore[no-untyped-def]
    xyz = frame.cloud.xyz.astype(np.float64)
    return np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))


@pytest.mark.parametrize("index", range(6))
def test_kitti_sweeps_give_up_their_64_rings_from_storage_order(index: int) -> None:
    frame = kitti(index)
    assert "ring" not in frame.cloud.fields  # KITTI's .bin has x, y, z, intensity only
    rings = derive_rings(frame.cloud, method="scan_order")
    assert np.array_equal(rings, derive_rings(frame.cloud))  # what "auto" picks here
    counts = np.bincount(rings, minlength=64)
    assert len(counts) == 64 and counts.min() > 700  # every laser, a revolution each
    elevation = _elevation_deg(frame)
    medians = np.array([np.median(elevation[rings == ring]) for ring in range(64)])
    assert (np.diff(medians) > 0).all()  # ring 0 is the lowest beam, as ROS numbers them
    assert medians[0] < -22 and medians[-1] > 1.5  # the HDL-64E's ~26.9 degree span


def test_rendered_scans_carry_rings_and_elevation_recovers_them_exactly() -> None:
    frame = street()
    truth = frame.cloud.fields["ring"]
    assert np.array_equal(derive_rings(frame.cloud), truth)
    assert np.array_equal(derive_rings(frame.cloud, method="elevation"), truth)
    # Rendered in firing order (azimuth by azimuth), not laser by laser.
    with pytest.raises(InvalidArgument, match="not stored laser by laser"):
        derive_rings(frame.cloud, method="scan_order")


def test_an_unordered_real_sweep_is_not_guessed_unless_the_sensor_is_given() -> None:
    """KITTI's own unit differs from the nominal calibration: without a laser field or the
    storage order, nothing in the catalogue fits well enough, so the lasers are unknown
    (no silent HDL-64E guess); given the sensor, nearest elevation is off by about two
    rings, which the docs say (measured: median 2, at most 10)."""
    frame = kitti(0)
    truth = derive_rings(frame.cloud)
    order = np.random.default_rng(0).permutation(len(frame.cloud))
    with pytest.raises(InvalidArgument, match="cannot be known: unknown sensor"):
        derive_rings(frame.cloud[order])  # auto: no field, no scan order, no fit
    guessed = derive_rings(frame.cloud[order], layout=HDL64E)
    off = np.abs(guessed.astype(int) - truth[order].astype(int))
    assert np.median(off) <= 2 and off.max() <= 10
    with pytest.raises(InvalidArgument, match="no laser field"):
        derive_rings(frame.cloud, method="field")


def test_dropping_rings_removes_exactly_those_lasers() -> None:
    frame = kitti(1)
    rings = derive_rings(frame.cloud)
    fault = DropRings([40, 3, 3])
    assert fault.rings == (3, 40) and len(fault) == 2
    after = fault.apply(frame)
    assert len(after.cloud) == len(frame.cloud) - np.isin(rings, (3, 40)).sum()
    assert after.roi is frame.roi
    kept = derive_rings(frame.cloud)[fault.kept(frame)]
    assert not np.isin(kept, (3, 40)).any()
    assert fault.params()["missing_rings"] == [3, 40]
    # Reducible over the missing rings: a violation reduces to the fewest dead beams.
    key, reducible = find_reducible(fault.params())  # type: ignore[misc]
    assert key == "drop_rings" and reducible.restrict([1]).rings == (40,)
    assert fault.describe_elements(5) == ["ring 3", "ring 40"]


@pytest.mark.parametrize(
    ("rings", "message"),
    [([64], r"\[0, 63\]"), ([-1], r"\[0, 63\]"), ([True], "ring numbers"), (5, "sequence")],
)
def test_bad_rings_are_named(rings: object, message: str) -> None:
    with pytest.raises(InvalidArgument, match=message):
        DropRings(rings, HDL64E)  # type: ignore[arg-type]
    # Without a layout the rings are a laser field's values (uint16 at most).
    with pytest.raises(InvalidArgument):
        DropRings([65536] if rings == [64] else rings)  # type: ignore[arg-type]


def test_a_lost_packet_removes_one_azimuth_block_of_every_laser() -> None:
    frame = kitti(2)
    packet = math.radians(1.04)
    fault = DropAzimuthBlock(math.radians(359.5), packet)  # wraps past 0 (straight ahead)
    after = fault.apply(frame)
    azimuth = np.degrees(
        np.mod(np.arctan2(frame.cloud.xyz[:, 1], frame.cloud.xyz[:, 0]), 2 * np.pi)
    )
    lost = (azimuth >= 359.5) | (azimuth < 0.54)
    assert len(after.cloud) == len(frame.cloud) - lost.sum() and lost.sum() > 100
    rings = derive_rings(frame.cloud)
    assert len(np.unique(rings[lost])) > 50  # every laser loses its firings there
    assert fault.params() == {"lost_block_start_deg": 359.5, "lost_block_width_deg": 1.04}
    with pytest.raises(InvalidArgument, match="width"):
        DropAzimuthBlock(0.0, 7.0)
    with pytest.raises(InvalidArgument, match="start"):
        DropAzimuthBlock(float("nan"), 0.1)
    assert HDL64E.lasers == 64


def test_range_quantization_rounds_each_range_along_its_beam() -> None:
    frame = street()
    after = QuantizeRange(0.1).apply(frame)
    before_xyz = frame.cloud.xyz.astype(np.float64)
    after_xyz = after.cloud.xyz.astype(np.float64)
    ranges = np.linalg.norm(after_xyz, axis=1)
    assert np.allclose(ranges / 0.1, np.round(ranges / 0.1), atol=1e-3)
    assert np.abs(ranges - np.linalg.norm(before_xyz, axis=1)).max() <= 0.05 + 1e-4
    cosine = (before_xyz * after_xyz).sum(axis=1) / (np.linalg.norm(before_xyz, axis=1) * ranges)
    assert (cosine > 1 - 1e-6).all()
    assert np.array_equal(after.cloud.fields["ring"], frame.cloud.fields["ring"])
    with pytest.raises(InvalidArgument, match="step"):
        QuantizeRange(0.0)


@pytest.mark.parametrize("system", [ReferencePerception(), WholeScenePerception()], ids=repr)
def test_range_quantization_holds_on_every_kitti_sweep_and_a_rendered_street(system) -> None:  # type: ignore[no-untyped-def]
    """Validity: 5, 10 and 20 cm steps on seven frames: 0 violations in 21 follow-ups."""
    relation = range_quantization().relation
    covered = 0
    for frame in [street(), *(kitti(index) for index in range(6))]:
        source_output = system(frame)
        for step in (0.05, 0.1, 0.2):
            fault = QuantizeRange(step)
            followup = fault.apply(frame)
            context = CheckContext(frame, followup, fault.params(), 0)
            verdict = relation.check(source_output, system(followup), context)
            assert verdict.holds, verdict.explanation
            covered += verdict.details["covered"]
    assert covered >= 40


def test_a_repeated_range_filter_eats_a_car_once_ranges_come_in_10_cm_steps() -> None:
    """``repeated_range_filter`` drops returns whose range repeats a neighbouring firing's:
    harmless on the sweep as recorded, it loses a rendered car at 26 m once ranges are
    rounded to 10 cm; reordering and repeating the points do not move it."""
    faulty = mutant("repeated_range_filter")
    frame = street()
    assert faulty(frame) == ReferencePerception()(frame)
    fault = QuantizeRange(0.1)
    followup = fault.apply(frame)
    verdict = range_quantization().relation.check(
        faulty(frame), faulty(followup), CheckContext(frame, followup, fault.params(), 0)
    )
    assert not verdict.holds and "car at (25.9, 2.5) lost" in verdict.explanation
    doubled = frame.with_cloud(PointCloud.concatenate([frame.cloud, frame.cloud[::-1]]))
    assert faulty(doubled) == faulty(frame)


def test_a_sweep_seam_filter_drops_the_car_a_lost_packet_cuts_and_only_then() -> None:
    """``sweep_seam_filter`` takes a gap in the ROI's bearings for the sweep's boundary.
    A complete sweep has none (nor with three dead lasers); one lost packet through the
    street's first car drops it although nearly all of its points are left, so the
    packet-loss relation fails, and the reference holds."""
    faulty, reference = mutant("sweep_seam_filter"), ReferencePerception()
    frame = street()
    assert faulty(frame) == reference(frame)
    dead = DropRings((10, 20, 30)).apply(frame)
    assert faulty(dead) == reference(dead)
    bearing = math.atan2(-2.5, 12.0)  # the car at (12.0, -2.5)
    fault = DropAzimuthBlock(bearing, math.radians(PACKET_DEGREES))
    followup = fault.apply(frame)
    context = CheckContext(frame, followup, fault.params(), 0)
    verdict = packet_loss().relation.check(faulty(frame), faulty(followup), context)
    assert not verdict.holds and "car at (12.0, -2.5) lost" in verdict.explanation
    assert packet_loss().relation.check(reference(frame), reference(followup), context)
