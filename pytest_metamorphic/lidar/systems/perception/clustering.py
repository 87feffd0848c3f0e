"""Segmentation into objects: connected components of a bird's-eye occupancy grid.

Obstacle points are binned into square ``cell_size`` cells; occupied cells that touch
(8-connectivity: sides or corners) form one object. This is what Apollo's CNN
segmentation approximates with learned weights, and what grid-based LiDAR pipelines use
instead of per-point neighbour searches: one ``scipy.ndimage.label`` over the grid
replaces tens of thousands of radius queries.

Two points end up in the same object when a chain of occupied cells joins them, so the
largest gap that is bridged lies between one cell (points in cells two apart) and the
diagonal of two cells (points in diagonal neighbours), depending on where the cell
borders fall. The grid is anchored at the sensor origin, so a point's cell never depends
on the other points, and labels are a function of the set of occupied cells: point order
and repeated points do not change them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import label

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.grid import grid_cells

__all__ = ["ClusterParams", "Clusters", "cluster_points"]

_EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class ClusterParams:
    """Parameters of :func:`cluster_points`.

    Attributes
    ----------
    cell_size : float
        Occupancy cell edge in metres (0.25 m, the cell of Apollo's ROI bitmap).
    """

    cell_size: float = 0.25

    def __post_init__(self) -> None:
        if not self.cell_size > 0:
            raise InvalidArgument(f"cell_size={self.cell_size!r} must be > 0")


@dataclass(frozen=True)
class Clusters:
    """The segmentation of ``n`` points into ``count`` objects.

    Attributes
    ----------
    labels : (n,) intp
        Object of each point, ``0 <= label < count``; objects are numbered in order of
        their first cell (row-major over the grid), so the numbering is deterministic.
    count : int
    cells : (count,) intp
        Distinct occupied cells per object (unlike point counts, not changed by repeats).
    cell_index : (n,) int64
        Flat index of each point's cell in the object grid (equal for points sharing a cell).
    """

    labels: NDArray[np.intp]
    count: int
    cells: NDArray[np.intp]
    cell_index: NDArray[np.int64]


def cluster_points(xy: NDArray[np.floating], params: ClusterParams = ClusterParams()) -> Clusters:
    """Group points into objects by 8-connected occupied grid cells.

    Parameters
    ----------
    xy : (n, >=2) float
        Bird's-eye coordinates in metres (only the first two columns are used).
    params : ClusterParams

    Returns
    -------
    Clusters
    """
    n = len(xy)
    if n == 0:
        empty = np.empty(0, dtype=np.intp)
        return Clusters(empty, 0, empty, np.empty(0, dtype=np.int64))
    flat, shape = grid_cells(xy, params.cell_size)
    occupied = np.zeros(shape[0] * shape[1], dtype=bool)
    occupied[flat] = True
    grid, count = label(occupied.reshape(shape), _EIGHT_CONNECTED)
    cell_labels = grid.reshape(-1)
    # ndimage numbers components from 1 in row-major order of their first cell.
    labels = cell_labels[flat].astype(np.intp) - 1
    per_object = np.bincount(cell_labels, minlength=count + 1)[1:].astype(np.intp)
    return Clusters(labels, int(count), per_object, flat)
