"""The training data of the CNN segmentation network: rendered streets a real sweep
resembles (no PyTorch).

Four in five training scenes are
:func:`~pytest_metamorphic.lidar.synthetic.streetscape.street_scene` streets: kerbs and
pavements, parked rows of cars and vans, façades, fences, hedges, trees and poles,
free-standing wall pieces a car's length or so (:data:`TRAINING_STREETS`), road users on
the road and pedestrians on the pavements. The fifth is a
:func:`~pytest_metamorphic.lidar.synthetic.layout.random_scene` street (road users in an
ROI, clutter kept off it), the scenes the relation library's strategies draw. Each is
rendered with the HDL-64E (four in five) or another sensor of
:mod:`pytest_metamorphic.lidar.model.sensors`, then degraded as real sweeps are
(:func:`degrade`): range noise, returns dropped, dead lasers, lost packets, far road
returns lost as a real sensor loses them (four sweeps in five), intensities as KITTI's
HDL-64E reports them in four sweeps of five (a bright road, dark objects, many returns
at 0) and scaled per sweep with per-return noise, the sensor tilted by up to a few
degrees against the road, and one sweep in four cut to what a camera sees, as KITTI's
published crops are (80 degrees wide, nothing below 14 degrees under its horizon). The
far road, the intensities and the camera's edges were measured on the two unlabelled
KITTI sweeps of the shared data.

Held-out scenes (:func:`held_out_frame`) come from the same distribution, without the
loose wall pieces (so that every model is measured on the same streets), with seeds no
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
from pytest_metamorphic.lidar.synthetic.description import BACKGROUND_INSTANCE, GROUND_INSTANCE
from pytest_metamorphic.lidar.synthetic.layout import random_scene
from pytest_metamorphic.lidar.synthetic.streetscape import StreetOptions, street_scene
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import GridSpec, bev_features
from pytest_metamorphic.lidar.systems.perception.cnnseg.targets import cell_targets, instance_field

__all__ = [
    "CROP",
    "HELD_OUT_SEED_OFFSET",
    "HELD_OUT_STREETS",
    "SCENE_OPTIONS",
    "TRAINING_STREETS",
    "dataset",
    "degrade",
    "example",
    "held_out_frame",
    "training_frame",
    "training_render",
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
CALIBRATED_SHARE = 0.8  # of sweeps whose intensities are KITTI's (see _reflectance)
FAR_GROUND_SHARE = 0.8  # of sweeps that lose far road returns (see _far_ground_kept)
FAR_GROUND_RANGE = (12.0, 25.0)  # metres within which a sweep keeps all of its road
# Training streets have free-standing wall pieces a car's length or so beside them
# (garden walls, hoardings): on the unlabelled KITTI crops the model trained without
# them called such pieces of fence lines "cars". Held-out and validation streets are
# drawn as for every model before, so that models stay comparable on them.
TRAINING_STREETS = StreetOptions(loose_walls=3.0)
HELD_OUT_STREETS = StreetOptions()
CAMERA_HALF_WIDTH = 40.0  # degrees: KITTI's crops, measured
CAMERA_LOWEST = -14.0  # degrees below the camera's horizon: KITTI's crops, measured
CAMERA_BELOW = 0.08  # metres the camera sits below the LiDAR (KITTI's calibration)


def _scene_and_sensor(
    rng: np.random.Generator, name: str, streets: StreetOptions
) -> tuple[Any, Any]:
    if rng.random() < STREET_SHARE:
        scene = street_scene(rng, name=name, options=streets)
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
    instance = instance_field(frame, "degrade")
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
    keep &= _far_ground_kept(points, instance, rng)
    if rng.random() < 0.25:  # a camera's view, as KITTI's published crops
        keep &= _in_camera_view(points, azimuth)
    # Range noise beyond the renderer's 2 cm, along the ray.
    distance = np.linalg.norm(points[:, :3], axis=1, keepdims=True)
    stretch = 1.0 + rng.normal(0.0, rng.uniform(0.0, 0.03), (len(points), 1)) / np.maximum(
        distance, 0.5
    )
    points[:, :3] *= stretch
    points[:, 3] = _reflectance(points, instance, rng)
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


def _far_ground_kept(
    points: np.ndarray, instance: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Which returns survive the real sensor's loss of far, grazing road returns (in
    :data:`FAR_GROUND_SHARE` of sweeps; all survive otherwise).

    Measured on the two unlabelled KITTI sweeps (camera wedge, returns under -1.4 m):
    0.2-0.4 ground returns per m² at 30-45 m and 1.6-2.9 at 20-30 m, where the rendered
    HDL-64E gives 0.6-1.5 and 3.6-5.3. Dark asphalt seen at a grazing angle sends back
    too little light, and the loss grows with range: a ground return at ``d`` metres is
    kept with probability ``min(1, (r / d) ** 2)``, ``r`` drawn per sweep.
    """
    keep = np.ones(len(points), bool)
    if rng.random() >= FAR_GROUND_SHARE:
        return keep
    ground = np.flatnonzero(instance == GROUND_INSTANCE)
    distance = np.maximum(np.hypot(points[ground, 0], points[ground, 1]), 0.5)
    chance = np.minimum(1.0, (rng.uniform(*FAR_GROUND_RANGE) / distance) ** 2)
    keep[ground] = rng.random(len(ground)) < chance
    return keep


def _in_camera_view(points: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
    """The returns KITTI's published crops keep: those its left colour camera sees.

    Measured on the two unlabelled crops: azimuth within +-40 degrees and elevation at
    least -14 degrees from the camera (8 cm below the LiDAR), so that the road nearer
    than some 6 m is cut away as well as everything beside and behind the car.
    """
    elevation = np.arctan2(points[:, 2] + CAMERA_BELOW, np.hypot(points[:, 0], points[:, 1]))
    return (
        (points[:, 0] > 0)
        & (np.abs(azimuth) < math.radians(CAMERA_HALF_WIDTH))
        & (elevation >= math.radians(CAMERA_LOWEST))
    )


def _reflectance(points: np.ndarray, instance: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Intensities (0-1) as a real sensor reports them, from the renderer's
    reflectivity x cos(incidence): scaled per sweep and noisy per return; then, in
    :data:`CALIBRATED_SHARE` of sweeps, as KITTI's HDL-64E reports them.

    Measured on the two unlabelled KITTI sweeps of the shared data (PointPillars' testing
    000002 and mmdetection3d's 000008; no labelled or reported sweep), camera wedge, 5-40 m:
    the road reads 0.23 and 0.30 (median), whatever the incidence, and fades to 0 beyond
    some 30 m; 31 % and 23 % of the returns above it read exactly 0 (dark paint, glass,
    foliage). The cos model gives the road 0.02-0.07 and no zero above it, so a network
    trained on it alone learns "dark is road": on a real sweep, a dark car.
    """
    count = len(points)
    intensity = points[:, 3] * rng.uniform(0.4, 1.6) * rng.lognormal(0.0, 0.35, count)
    if rng.random() < CALIBRATED_SHARE:
        distance = np.maximum(np.hypot(points[:, 0], points[:, 1]), 0.5)
        ground = instance == GROUND_INSTANCE
        road = rng.uniform(0.15, 0.35) * rng.lognormal(0.0, 0.3, count)
        road *= np.minimum(1.0, (rng.uniform(20.0, 45.0) / distance) ** 3)
        intensity[ground] = road[ground]
        # Each object its own surface: a factor on its brightness and a share of
        # returns that read 0; background surfaces share one share per sweep.
        objects, which = np.unique(np.maximum(instance, -1), return_inverse=True)
        factor = np.exp(rng.normal(0.0, 0.7, len(objects)))
        dark = rng.uniform(0.0, 0.5, len(objects))
        factor[objects < 0], dark[objects < 0] = 1.0, 0.0  # ground: set above
        background = instance == BACKGROUND_INSTANCE
        intensity *= factor[which]
        zero = rng.random(count) < np.where(background, rng.uniform(0.0, 0.4), dark[which])
        intensity[zero & ~ground] = 0.0
        intensity[intensity < rng.uniform(0.0, 0.02)] = 0.0  # the receiver's floor
    return np.clip(intensity, 0.0, 1.0)


def _rotation(pitch: float, roll: float) -> np.ndarray:
    cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
    about_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    about_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return about_y @ about_x


def training_render(seed: int, *, streets: StreetOptions = TRAINING_STREETS) -> tuple[Frame, Frame]:
    """Training scene ``seed`` as the renderer gives it and as training sees it (after
    :func:`degrade`): ``bench/learned_gap.py`` measures both against real sweeps.
    ``streets``: how its street (four scenes in five) is drawn."""
    rng = np.random.default_rng(seed)
    scene, sensor = _scene_and_sensor(rng, f"train-{seed}", streets)
    frame = render(scene, beams=sensor, seed=int(rng.integers(2**31)))
    return frame, degrade(frame, rng)


def training_frame(seed: int, *, streets: StreetOptions = TRAINING_STREETS) -> Frame:
    """The rendered and degraded frame of training scene ``seed``."""
    return training_render(seed, streets=streets)[1]


def held_out_frame(index: int) -> Frame:
    """Held-out scene ``index``: the training distribution without the loose wall
    pieces (:data:`HELD_OUT_STREETS`), a seed training never uses."""
    return training_frame(HELD_OUT_SEED_OFFSET + index, streets=HELD_OUT_STREETS)


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
        out[f"{view}_heading"] = targets.heading[window].astype(np.float16)
    return out


def dataset(seeds: Sequence[int], grid: GridSpec, workers: int) -> dict[str, np.ndarray]:
    """Stacked examples of ``seeds`` (rendered in ``workers`` processes)."""
    with ProcessPoolExecutor(max_workers=workers) as pool:
        parts = list(pool.map(example, seeds, [grid] * len(seeds), chunksize=8))
    return {key: np.stack([p[key] for p in parts]) for key in parts[0]}
