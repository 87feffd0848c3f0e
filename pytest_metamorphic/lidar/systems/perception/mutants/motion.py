"""Faulty variants of the reference pipeline that show only when objects move: headings
corrected by where an object stands or how many returns it has, and state kept from one
sweep to the next.

Every relation that keeps the objects where the recording has them (noise, reordering,
removal, whole-scene turns and mirrors, which move the objects *and* what a fault keys
on together) sees the same wrong answer twice and passes. See
:mod:`pytest_metamorphic.lidar.systems.perception.mutants` for the list.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.clustering import Clusters
from pytest_metamorphic.lidar.systems.perception.pipeline import ReferencePerception

__all__ = ["SparseHeadingFlip", "TemporalGround", "ViewYawCorrection"]


def _turned_quarter(box: Box, size: tuple[float, float] | None = None) -> Box:
    """``box`` turned 90 degrees about its centre (its sides swapped, or ``size``)."""
    length, width = size if size is not None else (box.size[1], box.size[0])
    yaw = math.remainder(box.yaw + math.pi / 2, 2 * math.pi)
    return dataclasses.replace(box, size=(length, width, box.size[2]), yaw=yaw)


class ViewYawCorrection(ReferencePerception):
    """Boxes that lie across the line of sight are turned to lie along it.

    Modelled on the yaw correction first proposed for Autoware's shape estimation
    (autoware_universe pull request #11309): a car seen end-on shows one short face, its
    L-shape fit lies across the line of sight, and the correction turns such boxes by 90
    degrees and swaps their sides. Applied to every box within ``window`` degrees of
    lying across the line of sight, it also turns a car that really crosses it (at a
    junction, pulling out). Whole-scene turns and mirrors keep every object's view, and an
    object that stays where it stands is corrected the same way every time; an object
    turned in place into or out of the window is not.
    """

    name = "view_yaw_correction"
    window = 30.0

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        return [self._corrected(box) for box in super().build_boxes(points, ground_z, clusters)]

    def _corrected(self, box: Box) -> Box:
        bearing = math.atan2(box.center[1], box.center[0])
        view = math.remainder(box.yaw - bearing, math.pi)  # 0: along the line of sight
        if abs(abs(view) - math.pi / 2) <= math.radians(self.window):
            return _turned_quarter(box)
        return box


class SparseHeadingFlip(ReferencePerception):
    """A car box of few returns is extended to a default car size from the wrong edge.

    Autoware's shape estimation corrects a vehicle's box to default dimensions when its
    cluster is small; with very few returns the farthest edge it extends from is often
    the wrong one, and the box turns by 90 degrees (the mechanism autoware_universe pull
    request #11634 fixes). Here: car boxes supported by fewer than ``min_points`` returns
    become 4.5 x 1.8 m boxes turned 90 degrees. The same car is wrong the same way in
    every run while it stays at its range; moved farther (fewer returns) or nearer, it
    turns.
    """

    name = "sparse_heading_flip"
    min_points = 80

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        return [
            _turned_quarter(box, (4.5, 1.8))
            if box.label == "car" and (box.points or 0) < self.min_points
            else box
            for box in super().build_boxes(points, ground_z, clusters)
        ]


class TemporalGround(ReferencePerception):
    """Ground heights averaged per 2 m cell over this sweep and the previous one.

    A filter over consecutive sweeps left on in a detector that is per-frame by contract
    (Autoware's obstacle segmentation has a ``use_time_series_filter`` beside its
    single-frame one, autoware_universe pull request #2824; Apollo's camera object filter
    kept per-object state it never updated, ApolloAuto/apollo issue #5246): each cell's
    ground is the mean of the current sweep's estimate and the previous sweep's. Within
    one recording the ground barely changes between sweeps; after another sweep (turned,
    from elsewhere) a cell's ground is off by half the difference, and low objects sink
    into it or clutter rises out of it.
    """

    name = "temporal_ground"
    cell = 2.0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._heights: dict[tuple[int, int], float] = {}

    def ground_heights(
        self, points: NDArray[np.float32], sweep: NDArray[np.float32], roi: object = None
    ) -> NDArray[np.float32]:
        current = super().ground_heights(points, sweep, roi)
        if len(points) == 0:
            return current
        cells = np.floor(points[:, :2] / self.cell).astype(np.int64)
        keys, inverse = np.unique(cells, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        now = np.zeros(len(keys))
        np.add.at(now, inverse, current.astype(np.float64))
        now /= np.bincount(inverse, minlength=len(keys))
        cells_now = [(int(i), int(j)) for i, j in keys.tolist()]
        before = np.array(
            [self._heights.get(key, h) for key, h in zip(cells_now, now, strict=True)]
        )
        self._heights = dict(
            zip(cells_now, now.tolist(), strict=True)
        )  # this sweep's, for the next
        blended = 0.5 * now + 0.5 * before
        return (current + (blended - now)[inverse]).astype(np.float32)
