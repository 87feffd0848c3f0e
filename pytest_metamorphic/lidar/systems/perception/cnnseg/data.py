"""The training data of the CNN segmentation network: rendered street scenes (no PyTorch).

Training scenes are :func:`~pytest_metamorphic.lidar.synthetic.layout.random_scene` streets over all
four road kinds with 2-12 cars, pedestrians and cyclists at every heading and up to 10
poles, trees and buildings off the road, rendered with the HDL-64E beam layout and its
2 cm range noise, then thinned by 0-10 % of the returns and dimmed or brightened by up to
40 % (real sweeps lose returns and differ from the renderer's reflectances). Held-out
scenes (:func:`held_out_frame`) come from the same distribution with seeds no training
scene uses, and are not thinned or re-lit.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.synthetic import render
from pytest_metamorphic.lidar.synthetic.layout import random_scene
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import GridSpec, bev_features
from pytest_metamorphic.lidar.systems.perception.cnnseg.targets import cell_targets

__all__ = [
    "HELD_OUT_SEED_OFFSET",
    "SCENE_OPTIONS",
    "dataset",
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
HELD_OUT_SEED_OFFSET = 10**9  # held-out scenes never share a seed with training ones


def training_frame(seed: int) -> Frame:
    """The rendered, thinned and re-lit frame of training scene ``seed``."""
    rng = np.random.default_rng(seed)
    scene = random_scene(rng, name=f"train-{seed}", **SCENE_OPTIONS)
    frame = render(scene, seed=int(rng.integers(2**31)))
    keep = rng.random(len(frame.cloud)) >= rng.uniform(0.0, 0.1)
    cloud = frame.cloud[keep]
    points = cloud.points.copy()
    points[:, 3] = np.clip(points[:, 3] * rng.uniform(0.6, 1.4), 0.0, 1.0)
    return frame.with_cloud(cloud.with_points(points))


def held_out_frame(index: int) -> Frame:
    """Held-out scene ``index``: the training distribution, a seed training never uses."""
    seed = HELD_OUT_SEED_OFFSET + index
    rng = np.random.default_rng(seed)
    scene = random_scene(rng, name=f"held-out-{index}", **SCENE_OPTIONS)
    return render(scene, seed=int(rng.integers(2**31)))


def example(seed: int, grid: GridSpec) -> dict[str, np.ndarray]:
    """Features (whole sweep and ROI only) and targets of training scene ``seed``."""
    frame = training_frame(seed)
    points = frame.cloud.points
    in_roi = frame.roi.contains(points[:, :2])
    targets = cell_targets(frame, grid)
    return {
        "full": bev_features(points, grid).astype(np.float16),
        "roi": bev_features(points[in_roi], grid).astype(np.float16),
        "objectness": targets.objectness.astype(np.uint8),
        "offset": targets.offset.astype(np.float16),
        "label": targets.label.astype(np.int8),
        "height": targets.height.astype(np.float16),
    }


def dataset(seeds: Sequence[int], grid: GridSpec, workers: int) -> dict[str, np.ndarray]:
    """Stacked examples of ``seeds`` (rendered in ``workers`` processes)."""
    with ProcessPoolExecutor(max_workers=workers) as pool:
        parts = list(pool.map(example, seeds, [grid] * len(seeds), chunksize=8))
    return {key: np.stack([p[key] for p in parts]) for key in parts[0]}
