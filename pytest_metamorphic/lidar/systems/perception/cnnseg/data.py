"""The training data of the CNN segmentation network: rendered streets a real sweep
resembles (no PyTorch).

Four in five training scenes are
:func:`~pytest_metamorphic.lidar.synthetic.streetscape.street_scene` streets: kerbs and
pavements, parked rows of cars and vans, façades, fences, hedges, trees and poles, road
users on the road and pedestrians on the pavements. The fifth is a
:func:`~pytest_metamorphic.lidar.synthetic.layout.random_scene` street (road users in an
ROI, clutter kept off it), the scenes the relation library's strategies draw. Each is
rendered with the HDL-64E (four in five) or another sensor of
:mod:`pytest_metamorphic.lidar.model.sensors`, then degraded as real sweeps are
(:func:`degrade`): range noise, returns dropped, dead lasers, lost packets, reflectances
drawn per object and scaled per sweep with per-return noise, the sensor tilted by up to
a few degrees against the road, and one sweep in four cut to a camera's 90-degree view
as KITTI's published crops are.

Held-out scenes (:func:`held_out_frame`) come from the same distribution with seeds no
training scene uses. Real sweeps never enter training: the labelled KITTI sweeps measure
the model (``bench/learned.py``), and nothing was tuned on them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors import (
    HDL32E,
    HDL64E,
    OS1_64,
    OS1_128,
    PANDAR40P,
    VLP32C,
)
from pytest_metamorphic.lidar.synthetic import render
from pytest_metamorphic.lidar.synthetic.layout import random_scene
from pytest_metamorphic.lidar.synthetic.streetscape import street_scene
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import GridSpec, bev_features
from pytest_metamorphic.lidar.systems.perception.cnnseg.targets import cell_targets

__all__ = [
    "CROP",
    "HELD_OUT_SEED_OFFSET",
    "SCENE_OPTIONS",
    "dataset",
    "degrade",
    "example",
    "held_out_frame",
    "training_frame",
]

SCENE_OPTIONS: dict[str, Any] = {
    "kinds": ("corridor", "curved", "junction", "polygon"),
    "min_obstacles": 2,
    "max_obstacles": 12,
    "max_background": 10,
    "max_distance": 45.0,
}
STREET_SHARE = 0.8  # of scenes that are cluttered streets; the rest random_scene's
OTHER_SENSORS = (HDL32E, VLP32C, OS1_64, OS1_128, PANDAR40P)
OTHER_SENSOR_SHARE = 0.2
CROP = 160  # cells a side of the window one training example covers
MIN_TARGET_RETURNS = 4  # obstacles with fewer returns are background to the network
HELD_OUT_SEED_OFFSET = 10**9  # held-out scenes never share a seed with training ones


def _scene_and_sensor(rng: np.random.Generator, name: str) -> tuple[Any, Any]:
    if rng.random() < STREET_SHARE:
        scene = street_scene(rng, name=name)
    else:
        scene = random_scene(rng, name=name, **SCENE_OPTIONS)
    sensor = HDL64E
    if rng.random() < OTHER_SENSOR_SHARE:
        sensor = OTHER_SENSORS[int(rng.integers(len(OTHER_SENSORS)))]
    return scene, sensor


def degrade(frame: Frame, rng: np.random.Generator) -> Frame:
    """What a real sensor does to a rendered sweep (see the module docstring).

    Boxes move with the tilt, and their ``points`` count what is left of each obstacle.
    """
    cloud = frame.cloud
    points = cloud.points.astype(np.float64)
    keep = rng.random(len(points)) >= rng.uniform(0.0, 0.12)
    rings = cloud.fields.get("ring")
    if rings is not None and rng.random() < 0.25:  # dead lasers
        dead = rng.choice(int(np.max(rings)) + 1, size=int(rng.integers(1, 4)), replace=False)
        keep &= ~np.isin(rings, dead)
    azimuth = np.arctan2(points[:, 1], points[:, 0])
    for _ in range(int(rng.integers(0, 4)) if rng.random() < 0.25 else 0):  # lost packets
        start, width = rng.uniform(-math.pi, math.pi), math.radians(rng.uniform(0.5, 8.0))
        keep &= ((azimuth - start) % (2 * math.pi)) >= width
    if rng.random() < 0.25:  # a camera's view, as KITTI's published crops
        keep &= (points[:, 0] > 0) & (np.abs(azimuth) < math.radians(45.0))
    # Range noise beyond the renderer's 2 cm, along the ray.
    distance = np.linalg.norm(points[:, :3], axis=1, keepdims=True)
    stretch = 1.0 + rng.normal(0.0, rng.uniform(0.0, 0.03), (len(points), 1)) / np.maximum(
        distance, 0.5
    )
    points[:, :3] *= stretch
    # Reflectance: scaled per sweep, noisy per return (renderer: reflectivity x cos).
    intensity = points[:, 3] * rng.uniform(0.4, 1.6) * rng.lognormal(0.0, 0.35, len(points))
    points[:, 3] = np.clip(intensity, 0.0, 1.0)
    # The sensor tilted against the road (mounting, pitch under braking, cambered roads).
    pitch, roll = np.radians(rng.normal(0.0, 1.0, 2))
    rotation = _rotation(pitch, roll)
    points[:, :3] = points[:, :3] @ rotation.T
    kept = cloud[keep].with_points(points[keep].astype(np.float32))
    instance = np.asarray(kept.fields["instance"])
    counts = np.bincount(instance[instance >= 0], minlength=len(frame.boxes))
    boxes = [
        Box(tuple(rotation @ np.asarray(b.center)), b.size, b.yaw, b.label, points=int(n))
        for b, n in zip(frame.boxes, counts, strict=True)
    ]
    return Frame(kept, roi=frame.roi, boxes=tuple(boxes), source=frame.source, sensor=frame.sensor)


def _rotation(pitch: float, roll: float) -> np.ndarray:
    cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
    about_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    about_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return about_y @ about_x


def training_frame(seed: int) -> Frame:
    """The rendered and degraded frame of training scene ``seed``."""
    rng = np.random.default_rng(seed)
    scene, sensor = _scene_and_sensor(rng, f"train-{seed}")
    frame = render(scene, beams=sensor, seed=int(rng.integers(2**31)))
    return degrade(frame, rng)


def held_out_frame(index: int) -> Frame:
    """Held-out scene ``index``: the training distribution, a seed training never uses."""
    return training_frame(HELD_OUT_SEED_OFFSET + index)


def _window(frame: Frame, grid: GridSpec, rng: np.random.Generator) -> tuple[int, int]:
    """The top-left cell of the example's window: around a road user seven times in ten
    (so that most windows hold one), anywhere otherwise; multiples of 8 cells, so the
    network's stride-2 stages meet the grid as they do on a whole sweep."""
    room = (grid.size - CROP) // 8
    seen = [b for b in frame.boxes if (b.points or 0) >= 10 and b.label != "unknown"]
    if seen and rng.random() < 0.7:
        box = seen[int(rng.integers(len(seen)))]
        row = (grid.range - box.center[0]) / grid.cell - rng.uniform(16, CROP - 16)
        col = (grid.range - box.center[1]) / grid.cell - rng.uniform(16, CROP - 16)
        return (
            int(np.clip(round(row / 8), 0, room)) * 8,
            int(np.clip(round(col / 8), 0, room)) * 8,
        )
    return int(rng.integers(room + 1)) * 8, int(rng.integers(room + 1)) * 8


def example(seed: int, grid: GridSpec) -> dict[str, np.ndarray]:
    """Features (whole sweep and ROI only) and targets of training scene ``seed``, cut to
    a :data:`CROP`-cell window of ``grid`` (the network is fully convolutional)."""
    frame = training_frame(seed)
    points = frame.cloud.points
    in_roi = (
        frame.roi.contains(points[:, :2]) if frame.roi is not None else np.ones(len(points), bool)
    )
    row, col = _window(frame, grid, np.random.default_rng([seed, 1]))
    window = (slice(None), slice(row, row + CROP), slice(col, col + CROP))
    out: dict[str, np.ndarray] = {}
    for view, mask in (("full", np.ones(len(points), bool)), ("roi", in_roi)):
        part = frame.with_cloud(frame.cloud[mask])
        targets = cell_targets(part, grid, min_points=MIN_TARGET_RETURNS)
        out[view] = bev_features(points[mask], grid)[window].astype(np.float16)
        out[f"{view}_objectness"] = targets.objectness[window[1:]].astype(np.uint8)
        out[f"{view}_offset"] = targets.offset[window].astype(np.float16)
        out[f"{view}_label"] = targets.label[window[1:]].astype(np.int8)
        out[f"{view}_height"] = targets.height[window[1:]].astype(np.float16)
    return out


def dataset(seeds: Sequence[int], grid: GridSpec, workers: int) -> dict[str, np.ndarray]:
    """Stacked examples of ``seeds`` (rendered in ``workers`` processes)."""
    with ProcessPoolExecutor(max_workers=workers) as pool:
        parts = list(pool.map(example, seeds, [grid] * len(seeds), chunksize=8))
    return {key: np.stack([p[key] for p in parts]) for key in parts[0]}
