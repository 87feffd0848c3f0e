"""Fog and rain: returns attenuated with range, droplet echoes near the sensor, and the
relation built on them valid on real sweeps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX
from pytest_metamorphic.lidar.followups.weather import Weather, extinction
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception
from pytest_metamorphic.relations.lidar import adverse_weather, mirror_symmetry
from tests.core.lidar_cases import kitti, street


def _ranges(points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points[:, :3].astype(np.float64), axis=1)


def test_the_visibility_sets_the_extinction_koschmieder() -> None:
    assert extinction(1000.0) == pytest.approx(3.0e-3, rel=0.01)
    # Two-way transmission over the visibility is 0.05 squared.
    assert math.exp(-2 * extinction(50.0) * 50.0) == pytest.approx(0.05**2)


def test_clear_air_changes_nothing() -> None:
    frame = kitti(0)
    after = Weather(1e9, scatter=0.0).apply(frame)
    assert len(after.cloud) == len(frame.cloud)
    assert np.allclose(after.cloud.points, frame.cloud.points, atol=1e-6)


def test_thicker_fog_loses_more_far_returns_first_and_dims_the_rest() -> None:
    frame = kitti(0)
    kept, reach = [], []
    for visibility in (400.0, 100.0, 25.0):
        weather = Weather(visibility, scatter=0.0)
        lost, _, intensity = weather.effects(frame)
        kept.append(int((~lost).sum()))
        reach.append(float(np.percentile(_ranges(frame.cloud.points[~lost]), 99)))
        ranges = _ranges(frame.cloud.points)
        expected = frame.cloud.intensity * np.exp(-2 * weather.alpha * ranges)
        assert np.allclose(intensity, expected, rtol=1e-5, atol=1e-7)
    assert kept[0] > kept[1] > kept[2] > 0 and reach[0] > reach[1] > reach[2]
    # Within a few metres, fog of 25 m still lets every bright return through.
    near = (_ranges(frame.cloud.points) < 5.0) & (frame.cloud.intensity >= 0.1)
    lost, _, _ = Weather(25.0, scatter=0.0).effects(frame)
    assert near.sum() > 1000 and not lost[near].any()


def test_droplet_echoes_stay_on_their_beams_in_front_of_what_they_replace() -> None:
    frame = street()
    weather = Weather(50.0, "fog", seed=3)
    lost, echo, _ = weather.effects(frame)
    moved = ~np.isnan(echo)
    ranges = _ranges(frame.cloud.points)
    assert 0.01 < moved.mean() < 0.1
    assert (echo[moved] < ranges[moved]).all() and (echo[moved] <= 22.5).all()
    after = weather.apply(frame)
    assert len(after.cloud) == int((moved | ~lost).sum())
    # Fields stay with their beams; the echo points lie along the original directions.
    rows = np.flatnonzero(moved | ~lost)
    assert np.array_equal(after.cloud.fields["ring"], frame.cloud.fields["ring"][rows])
    echoes = np.isin(rows, np.flatnonzero(moved))
    before = frame.cloud.xyz[rows[echoes]].astype(np.float64)
    now = after.cloud.xyz[echoes].astype(np.float64)
    cosine = (before * now).sum(axis=1) / (_ranges(before) * _ranges(now))
    assert (cosine > 1 - 1e-6).all()
    # Rain has fewer echoes than fog of the same visibility; seeds are reproducible.
    rain = Weather(50.0, "rain", seed=3).effects(frame)[1]
    assert (~np.isnan(rain)).sum() < moved.sum() / 2
    again = Weather(50.0, "fog", seed=3).apply(frame)
    assert again.cloud.equals(after.cloud)
    assert not Weather(50.0, "fog", seed=4).apply(frame).cloud.equals(after.cloud)


@pytest.mark.parametrize("system", [ReferencePerception(), WholeScenePerception()], ids=repr)
def test_adverse_weather_holds_on_every_kitti_sweep_and_a_rendered_street(system) -> None:  # type: ignore[no-untyped-def]
    """Validity: fog and rain of 200, 100 and 50 m, two seeds each, on seven frames: 0
    violations in 84 follow-ups."""
    relation = adverse_weather().relation
    runs = covered = 0
    for frame in [street(), *(kitti(index) for index in range(6))]:
        source_output = system(frame)
        for kind in ("fog", "rain"):
            for visibility in (200.0, 100.0, 50.0):
                for seed in (0, 1):
                    weather = Weather(visibility, kind, seed)
                    followup = weather.apply(frame)
                    context = CheckContext(frame, followup, weather.params(), 0)
                    verdict = relation.check(source_output, system(followup), context)
                    assert verdict.holds, verdict.explanation
                    runs += 1
                    covered += verdict.details["covered"]
    assert runs == 84 and covered >= 80


def test_a_clear_weather_speckle_filter_loses_a_car_in_fog_and_only_there() -> None:
    faulty = mutant("intensity_floor")
    frame = street()
    weather = Weather(50.0, "fog", seed=0)
    followup = weather.apply(frame)
    verdict = adverse_weather().relation.check(
        faulty(frame), faulty(followup), CheckContext(frame, followup, weather.params(), 0)
    )
    assert not verdict.holds and "lost although" in verdict.explanation
    # A geometric relation does not see it: intensities do not change under a mirror.
    mirror = MirrorAcrossX()
    mirrored = mirror.apply(frame)
    holds = mirror_symmetry().relation.check(
        faulty(frame), faulty(mirrored), CheckContext(frame, mirrored, mirror.params(), 0)
    )
    assert holds


def test_a_blockage_monitor_blinds_the_detector_in_fog_and_only_there() -> None:
    """``blinded_sensor_monitor`` withholds everything when returns come from within 2.5 m
    all round. Clear sweeps (KITTI's walls and kerbs close by included) and their doubled
    points never trip it; droplet echoes of fog at 200 m visibility do, while a car 26 m
    away is still seen plainly, so the weather relation fails and the reference holds."""
    faulty = mutant("blinded_sensor_monitor")
    reference = ReferencePerception()
    for frame in [street(), *(kitti(index) for index in range(6))]:
        assert faulty(frame) == reference(frame)
    frame = kitti(0)  # its 1,005 returns within 2.5 m light 12 of the 36 sectors
    doubled = frame.with_cloud(PointCloud.concatenate([frame.cloud, frame.cloud]))
    assert faulty(doubled) == reference(frame)
    frame = street()
    weather = Weather(200.0, "fog", seed=0)
    followup = weather.apply(frame)
    context = CheckContext(frame, followup, weather.params(), 0)
    assert faulty(followup) == []
    verdict = adverse_weather().relation.check(faulty(frame), faulty(followup), context)
    assert not verdict.holds and "car at (25.9, 2.5) lost" in verdict.explanation
    assert adverse_weather().relation.check(reference(frame), reference(followup), context)


def test_obstacles_beyond_the_visibility_are_not_judged() -> None:
    frame = kitti(1)
    system = ReferencePerception()
    relation = adverse_weather().relation
    weather = Weather(25.0, "fog", seed=0)
    followup = weather.apply(frame)
    verdict = relation.check(
        system(frame), system(followup), CheckContext(frame, followup, weather.params(), 0)
    )
    near = relation.covered(system(frame), frame, followup, 25.0)
    assert verdict.details["covered"] == len(near)
    assert all(math.hypot(*system(frame)[i].center[:2]) <= 25.0 for i, *_ in near)


def test_bad_weather_arguments_are_named() -> None:
    with pytest.raises(InvalidArgument, match="visibility"):
        Weather(0.0)
    with pytest.raises(InvalidArgument, match="kind"):
        Weather(50.0, "snow")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="scatter"):
        Weather(50.0, scatter=1.5)
    with pytest.raises(InvalidArgument, match="seed"):
        Weather(50.0, seed=1.5)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="kinds"):
        adverse_weather(kinds=("hail",))  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match="visibilities"):
        adverse_weather(visibilities=(100.0, -1.0))
