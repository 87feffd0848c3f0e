"""Shared LiDAR fixtures for the hiding-set, artifact and picture tests (not a test module).

Frames are built once per process (``functools.cache``). The independent minimality check
lives here too: it never calls the reducer, only the system and the relation.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

import conftest
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.perturb import NoiseOutsideROI
from pytest_metamorphic.lidar.io import read_bin
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic import BackgroundObject, Obstacle, Scene, render
from pytest_metamorphic.relations.lidar import mr1_subset

GROUND_Z = -1.73
MR1 = mr1_subset(max_size=1000)
ROAD = ROI.from_polygons([[(-30.0, -6.0), (60.0, -6.0), (60.0, 6.0), (-30.0, 6.0)]])


def standing(x: float, y: float, size: tuple[float, float, float], yaw: float, label: str) -> Box:
    return Box((x, y, GROUND_Z + size[2] / 2), size, yaw, label)  # type: ignore[arg-type]


@functools.cache
def street() -> Frame:
    """A rendered HDL-64E sweep: two cars, a pedestrian and a cyclist on a straight road."""
    scene = Scene(
        roi=ROAD,
        obstacles=(
            Obstacle(standing(12.0, -2.5, (4.3, 1.8, 1.5), 0.35, "car")),
            Obstacle(standing(26.0, 2.5, (4.0, 1.7, 1.5), -0.2, "car")),
            Obstacle(standing(8.0, 3.0, (0.6, 0.5, 1.75), 0.0, "pedestrian")),
            Obstacle(standing(18.0, -1.0, (1.8, 0.6, 1.7), 1.2, "cyclist")),
        ),
        background=(
            BackgroundObject("building", (15.0, 16.0), (12.0, 6.0, 8.0)),
            BackgroundObject("tree", (8.0, -9.0), (3.0, 3.0, 6.0)),
        ),
        name="street",
    )
    return render(scene)


@functools.cache
def kitti(index: int) -> Frame:
    """A KITTI sweep with the camera-wedge ROI (its labels not attached); skips when the
    data is absent."""
    path = conftest.shared_data_path("kitti_openpcdet", "training", "velodyne", f"{index:06d}.bin")
    return Frame(read_bin(path), roi=kitti_label_region())


def labelled_kitti(index: int) -> Frame:
    """The same sweep with its KITTI labels as boxes (ground truth, e.g. for insertion
    templates)."""
    from pytest_metamorphic.lidar.io.catalog import FrameCatalog

    folder = conftest.shared_data_path("kitti_openpcdet", "training")
    return FrameCatalog(folder, roi=kitti_label_region()).load(index)


def mr1_holds(
    system: Callable[[Frame], Any], frame: Frame, points: Any, source_output: Any
) -> bool:
    """Does MR1 hold when exactly ``points`` (k, 4) are added to ``frame``?"""
    noise = NoiseOutsideROI(np.asarray(points, dtype=np.float32).reshape(-1, 4))
    followup = noise.apply(frame)
    context = CheckContext(frame, followup, noise.params(), 0)
    return MR1.relation.check(source_output, system(followup), context).holds


def assert_minimal_hiding_set(
    system: Callable[[Frame], Any], frame: Frame, points: Sequence[Any]
) -> None:
    """Independently: ``points`` hide an obstacle, and without any one of them none is hidden."""
    points = np.asarray(points, dtype=np.float32).reshape(-1, 4)
    source_output = system(frame)
    assert len(points) >= 1
    assert not mr1_holds(system, frame, points, source_output), "the set hides nothing"
    for index in range(len(points)):
        rest = np.delete(points, index, axis=0)
        assert mr1_holds(system, frame, rest, source_output), (
            f"removing point {index} of {len(points)} still hides an obstacle: not 1-minimal"
        )


def failing_noise(
    system: Callable[[Frame], Any], frame: Frame, n: int, seeds: Sequence[int] = range(40)
) -> tuple[NoiseOutsideROI, Any, Any]:
    """The first MR1 noise (from numpy seeds ``seeds``) that makes ``system`` lose an obstacle."""
    source_output = system(frame)
    for seed in seeds:
        noise = NoiseOutsideROI.sample(frame, n, rng=np.random.default_rng(seed))
        followup = noise.apply(frame)
        output = system(followup)
        if not MR1.relation.check(source_output, output, CheckContext(frame, followup)).holds:
            return noise, source_output, output
    raise AssertionError(f"no seed in {seeds} makes {system!r} violate MR1 with n={n}")
