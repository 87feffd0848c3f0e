"""Faulty variants of the reference pipeline: what it reads. Point budgets, buffers, voxel
filters, gates and monitors on the raw returns (the ``prepare`` stage).

See :mod:`pytest_metamorphic.lidar.systems.perception.mutants` for the list.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.lidar.model.cloud import intensity_scale
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    ReferencePerception,
)

__all__ = [
    "BlindedSensorMonitor",
    "IntensityFloor",
    "OrderDependentVoxels",
    "RandomPointBudget",
    "RepeatedRangeFilter",
    "ShortRangeGate",
    "StalePackets",
    "TruncatingBuffer",
    "VoxelBudget",
]


class RandomPointBudget(ReferencePerception):
    """A random subsample to at most ``budget`` points, taken before the ROI filter.

    Learned detectors take a fixed number of points; sampling the whole sweep (instead
    of the ROI) with a fixed seed makes every kept point depend on every other one.
    """

    name = "random_point_budget"
    budget = 100_000

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        if len(points) <= self.budget:
            return points
        chosen = np.random.default_rng(0).choice(len(points), self.budget, replace=False)
        return points[np.sort(chosen)]


class TruncatingBuffer(ReferencePerception):
    """Only the first 120,000 points are processed (a fixed-size sweep buffer)."""

    name = "truncating_buffer"
    capacity = 120_000

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        return points[: self.capacity]


class VoxelBudget(ReferencePerception):
    """Voxel downsampling whose voxel size grows with the sweep's size, before the ROI.

    Keeping memory constant by scaling the voxel edge with the point count: any point
    anywhere moves every voxel border. Each voxel is replaced by its centroid.
    """

    name = "voxel_budget"
    base_size = 0.08  # metres at 100,000 points

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        size = self.base_size * math.sqrt(max(len(points), 1) / 100_000)
        keys = _voxel_keys(points[:, :3], size)
        _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
        sums = np.zeros((len(counts), 4))
        np.add.at(sums, inverse, points)
        return (sums / counts[:, None]).astype(np.float32)


class OrderDependentVoxels(ReferencePerception):
    """A 0.1 m voxel filter that keeps the first point it meets in each voxel."""

    name = "order_dependent_voxels"
    size = 0.1

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        _, first = np.unique(_voxel_keys(points[:, :3], self.size), return_index=True)
        return points[np.sort(first)]


class IntensityFloor(ReferencePerception):
    """Returns with intensity below ``floor`` are dropped before anything else.

    A speckle filter tuned on clear-weather sweeps, where dark returns at this level are
    mostly noise. Fog and rain scale every return's intensity down with range: a car
    20 m away whose returns all still arrive drops below the floor and is lost. Geometric
    relations never change intensities, so only weather shows it.
    """

    name = "intensity_floor"
    floor = 0.05

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        return points[points[:, 3] >= self.floor * intensity_scale(points[:, 3])]


class RepeatedRangeFilter(ReferencePerception):
    """Returns whose range equals (within 0.1 mm) that of the next firing of the same laser
    are dropped, both of them, as the two echoes of one pulse in dual-return mode.

    At the HDL-64E's 2 mm resolution neighbouring firings seldom report the same range:
    the filter drops 1.5 % of a KITTI sweep's returns and changes none of the reference's
    obstacles on the six sweeps. A sensor or driver with coarser range steps reports runs
    of equal ranges on every flat surface facing it, and the filter eats them. Repeated
    points are merged first, so duplication, reordering and rigid motions leave it alone.
    """

    name = "repeated_range_filter"
    tolerance = 1e-4

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        points = np.unique(points, axis=0)
        xyz = points[:, :3].astype(np.float64)
        ranges = np.linalg.norm(xyz, axis=1)
        beam = np.round(np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))) / 0.2)
        order = np.lexsort((np.arctan2(xyz[:, 1], xyz[:, 0]), beam))
        same = (np.abs(np.diff(ranges[order])) < self.tolerance) & (np.diff(beam[order]) == 0)
        repeated = np.zeros(len(points), dtype=bool)
        repeated[order[1:][same]] = True
        repeated[order[:-1][same]] = True
        return points[~repeated]


class ShortRangeGate(ReferencePerception):
    """Returns farther than ``max_range`` metres (bird's eye) are dropped first.

    A range gate carried over from a 16-beam sensor's configuration. Nothing beyond it is
    ever reported, in the source or in any follow-up, so relations that compare the two
    never see it; an object inserted at a range nobody saw one at before does.
    """

    name = "short_range_gate"
    max_range = 40.0

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        return points[np.hypot(points[:, 0], points[:, 1]) <= self.max_range]


class BlindedSensorMonitor(ReferencePerception):
    """Nothing is reported when the sensor looks blinded: returns closer than ``near``
    metres in at least ``min_sectors`` of the 36 azimuth sectors of 10 degrees (a sector
    counts with ``min_returns`` distinct returns).

    A blockage monitor (mud, snow or a bag on the window give returns at the cover all
    round) whose output is withheld while it fires. Clear KITTI sweeps light at most 12
    sectors (a wall or a kerb close by); droplet echoes in fog of 200 m visibility or rain
    of 100 m light nearly all 36, while cars 20 m away are still seen plainly. Nothing but
    weather puts returns next to the sensor all round.
    """

    name = "blinded_sensor_monitor"
    near = 2.5
    min_returns = 3
    min_sectors = 24

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        close = np.unique(points[np.linalg.norm(points[:, :3], axis=1) < self.near], axis=0)
        sector = np.floor(np.degrees(np.arctan2(close[:, 1], close[:, 0])) / 10.0) % 36
        lit = np.bincount(sector.astype(np.intp), minlength=36) >= self.min_returns
        return points[:0] if lit.sum() >= self.min_sectors else points


class StalePackets(ReferencePerception):
    """Azimuth columns of ``column_degrees`` that hold no return in this sweep keep the
    returns they last held: a scan buffer whose columns are not cleared when a packet is
    lost.

    Drivers assemble a sweep into a buffer of azimuth columns and swap it with the one
    being filled; ouster-sdk's ``ScanBatcher`` zeroed a lost column's data but not its
    headers, so a sweep whose first packets were dropped carried the timestamp of the
    sweep two before (ouster-sdk issue #300). Here the data stay too: a lost packet's
    columns are filled with what the buffer last held there. Right after the clean sweep
    the fill restores it, so packet loss (run on each follow-up after its own source)
    passes; after another sweep the gap holds that sweep's returns, and the obstacles of a
    sweep with lost packets depend on what ran before it. On a sweep cut to a camera's
    view the columns behind the car are always empty and always filled, outside the ROI.
    """

    name = "stale_packets"
    column_degrees = 1.0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._columns: dict[int, NDArray[np.float32]] = {}

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        bearing = np.degrees(np.arctan2(points[:, 1], points[:, 0])) % 360.0
        column = (bearing // self.column_degrees).astype(np.int64)
        order = np.argsort(column, kind="stable")
        present, starts = np.unique(column[order], return_index=True)
        pieces = np.split(points[order], starts[1:]) if len(points) else []
        received = dict(zip(present.tolist(), pieces, strict=True))
        stale = [rows for key, rows in self._columns.items() if key not in received]
        self._columns.update(received)
        return np.concatenate([points, *stale]) if stale else points


def _voxel_keys(coordinates: NDArray[np.float32], size: float) -> NDArray[np.int64]:
    """(n,) int64: one key per voxel of edge ``size`` (cells packed into one integer)."""
    cells = np.floor(coordinates / np.float32(size)).astype(np.int64)
    cells -= cells.min(axis=0)
    key = np.zeros(len(cells), dtype=np.int64)
    for column in range(cells.shape[1]):
        key = key * (int(cells[:, column].max()) + 1) + cells[:, column]
    return key
