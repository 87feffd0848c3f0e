# Copyright 2026 The pytest-metamorphic Authors
# Derived from Apollo (https://github.com/ApolloAuto/apollo), Copyright 2017-2018 The Apollo
# Authors, licensed under the Apache License, Version 2.0.
# What it derives from: the CNN segmentation's FeatureGenerator.
# Changed: re-implemented in Python and NumPy, with the differences stated below. See NOTICE.
# SPDX-License-Identifier: Apache-2.0
"""Apollo's bird's-eye feature grid for CNN segmentation.

Apollo's ``FeatureGenerator`` (``modules/perception/lidar/lib/segmentation/cnnseg``) turns
a sweep into a stack of bird's-eye maps, one value per grid cell and channel; the network
sees nothing else. With its velodyne64 parameters minus the constant channels it has six
channels, in this order:

====  ==================  =============================================================
 ch   name                value of a cell (points with ``min_height <= z <= max_height``)
====  ==================  =============================================================
 0    ``max_height``      highest z (0 when empty)
 1    ``mean_height``     mean z (0 when empty)
 2    ``log_count``       ``log(1 + n)``
 3    ``top_intensity``   intensity of the highest point (the largest, when several tie)
 4    ``mean_intensity``  mean intensity
 5    ``nonempty``        1 when the cell holds a point, else 0
====  ==================  =============================================================

Intensities are reflectance in 0-1 (KITTI's and the renderer's scale; a cloud recorded
on a 0-255 scale is divided by 255, as Apollo does). Rows map to x and columns to y, as
in Apollo: ``row = floor((range - x) / cell)``, ``col = floor((range - y) / cell)``.
The grid is anchored at the sensor, so its borders fall on multiples of the cell size and
a quarter turn or a mirror of the sweep maps every cell onto a cell.

The features are a function of the *multiset* of points, never of their order: sums are
taken over heights and intensities rounded to 0.1 mm and 1e-6 (integers, added exactly),
and the top intensity breaks height ties by the larger intensity. Repeated points count
again (Apollo's ``log_count`` does too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["CHANNELS", "SHIPPED_GRID", "GridSpec", "bev_features", "point_cells"]

CHANNELS = (
    "max_height",
    "mean_height",
    "log_count",
    "top_intensity",
    "mean_intensity",
    "nonempty",
)
# Sums of quantised values are exact in float64 (far below 2**53), so they do not
# depend on the order the points come in.
_Z_QUANTUM = 1e-4
_I_QUANTUM = 1e-6


MAX_GRID_SIZE = 2048  # cells a side: 4.2 million cells, 100 MB of features a frame
MAX_GRID_RANGE = 500.0  # metres: beyond any automotive LiDAR's reach


@dataclass(frozen=True)
class GridSpec:
    """The bird's-eye grid: ``size`` x ``size`` cells over ``(-range, range]`` metres in x and y.

    Attributes
    ----------
    size : int
        Cells per side (Apollo velodyne64: 672; the shipped model: 280).
    range : float
        Half the side in metres (Apollo and the shipped model: 70).
    min_height, max_height : float
        Points outside this z band (sensor frame, metres) are not in any cell (Apollo: -5, 5).
    """

    size: int = 280
    range: float = 70.0
    min_height: float = -5.0
    max_height: float = 5.0

    def __post_init__(self) -> None:
        if (
            isinstance(self.size, bool)
            or not isinstance(self.size, int)
            or not 8 <= self.size <= MAX_GRID_SIZE
        ):
            raise InvalidArgument(
                f"GridSpec size={self.size!r} must be an int in [8, {MAX_GRID_SIZE}] (Apollo's "
                "largest grid is 864 cells a side)"
            )
        if self.size % 8:
            raise InvalidArgument(
                f"GridSpec size={self.size} must be a multiple of 8 (the network halves it "
                "three times)"
            )
        for name in ("range", "min_height", "max_height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidArgument(f"GridSpec {name}={value!r} must be a number")
        if not (math.isfinite(self.range) and 0 < self.range <= MAX_GRID_RANGE):
            raise InvalidArgument(
                f"GridSpec range={self.range!r} must be a number in (0, {MAX_GRID_RANGE:g}] m"
            )
        if not all(abs(h) <= MAX_GRID_RANGE for h in (self.min_height, self.max_height)):
            raise InvalidArgument(
                f"GridSpec min_height and max_height must be finite, within +-{MAX_GRID_RANGE:g} m"
            )
        if self.min_height >= self.max_height:
            raise InvalidArgument(
                f"GridSpec min_height={self.min_height} must be < max_height={self.max_height}"
            )

    @property
    def cell(self) -> float:
        """Cell edge in metres."""
        return 2.0 * self.range / self.size

    def cell_centers(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(x, y)``: (size, size) float64 arrays, the centre of every cell."""
        index = np.arange(self.size, dtype=np.float64)
        coordinate = self.range - (index + 0.5) * self.cell
        return np.meshgrid(coordinate, coordinate, indexing="ij")

    def to_json(self) -> dict[str, float | int]:
        return {
            "size": self.size,
            "range": self.range,
            "min_height": self.min_height,
            "max_height": self.max_height,
        }


SHIPPED_GRID = GridSpec()
"""The shipped model's grid: 280 x 280 cells of 0.5 m over Apollo's +-70 m (Apollo's
HDL-64E model: 672 x 672 cells of 0.21 m over the same square; see the model card for
what each costs on a CPU)."""


def point_cells(points: ArrayLike, grid: GridSpec) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """The cell of every point.

    Parameters
    ----------
    points : (n, >=3) array_like
        x, y, z in the sensor frame.
    grid : GridSpec

    Returns
    -------
    flat : (n,) intp
        ``row * size + col``; meaningless where ``inside`` is False.
    inside : (n,) bool
        The point lies in the grid and in its height band.
    """
    xyz = np.asarray(points)
    if xyz.ndim != 2 or xyz.shape[1] < 3:
        raise InvalidArgument(f"points must be an (n, >=3) array, got shape {xyz.shape}")
    scale = 1.0 / grid.cell
    # float64: float32 rounding could move a point across a cell border differently
    # from the cell-centre arithmetic of the post-processing.
    row = np.floor((grid.range - xyz[:, 0].astype(np.float64)) * scale)
    col = np.floor((grid.range - xyz[:, 1].astype(np.float64)) * scale)
    z = xyz[:, 2]
    inside = (
        (row >= 0)
        & (row < grid.size)
        & (col >= 0)
        & (col < grid.size)
        & (z >= grid.min_height)
        & (z <= grid.max_height)
    )
    flat = np.where(inside, row * grid.size + col, 0).astype(np.intp)
    return flat, inside


def bev_features(points: ArrayLike, grid: GridSpec = GridSpec()) -> NDArray[np.float32]:
    """The six feature maps of one sweep.

    Parameters
    ----------
    points : (n, 4) array_like
        x, y, z, intensity (sensor frame; intensity 0-1, or 0-255 when any value
        exceeds 1).
    grid : GridSpec

    Returns
    -------
    (6, size, size) float32
        Channels in :data:`CHANNELS` order.
    """
    cloud = np.asarray(points, dtype=np.float32)
    if cloud.ndim != 2 or cloud.shape[1] < 4:
        raise InvalidArgument(
            f"points must be an (n, 4) array of x, y, z, intensity, got shape {cloud.shape}"
        )
    flat, inside = point_cells(cloud, grid)
    flat = flat[inside]
    z = cloud[inside, 2]
    intensity = cloud[inside, 3]
    if intensity.size and float(intensity.max()) > 1.0:
        intensity = intensity / np.float32(255.0)
    cells = grid.size * grid.size
    count = np.bincount(flat, minlength=cells)
    occupied = count > 0
    z_sum = np.bincount(flat, weights=np.round(z / _Z_QUANTUM), minlength=cells)
    i_sum = np.bincount(flat, weights=np.round(intensity / _I_QUANTUM), minlength=cells)
    top = np.full(cells, -np.inf, dtype=np.float32)
    np.maximum.at(top, flat, z)
    highest = z == top[flat]
    top_intensity = np.full(cells, -np.inf, dtype=np.float32)
    np.maximum.at(top_intensity, flat[highest], intensity[highest])
    safe = np.maximum(count, 1)
    features = np.zeros((len(CHANNELS), cells), dtype=np.float32)
    features[0] = np.where(occupied, top, 0.0)
    features[1] = z_sum * _Z_QUANTUM / safe
    features[2] = np.log1p(count)
    features[3] = np.where(occupied, top_intensity, 0.0)
    features[4] = i_sum * _I_QUANTUM / safe
    features[5] = occupied
    return features.reshape(len(CHANNELS), grid.size, grid.size)
