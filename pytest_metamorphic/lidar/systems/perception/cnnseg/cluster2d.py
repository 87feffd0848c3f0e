# Copyright 2026 The pytest-metamorphic Authors
# Derived from Apollo (https://github.com/ApolloAuto/apollo), Copyright 2017-2018 The Apollo
# Authors, licensed under the Apache License, Version 2.0.
# What it derives from: the CNN segmentation's Cluster2D.
# Changed: re-implemented in Python and NumPy, with the differences stated below. See NOTICE.
# SPDX-License-Identifier: Apache-2.0
"""Apollo's ``Cluster2D``: object cells grouped by the centres the network points them to.

The network predicts, for every cell of the bird's-eye grid, the probability that it
belongs to an object (``objectness``) and the offset from the cell to that object's
centre. Apollo clusters *cells*, not points:

1. a cell is an **object cell** when its objectness is at least ``objectness_thresh``
   and it holds at least one valid point (Apollo: the points of the ROI);
2. each object cell points at the cell holding its predicted centre; cells that are
   pointed at are **centre cells**;
3. an object cell joins the cell it points at, and 4-neighbouring centre cells join each
   other (Apollo's disjoint-set union over ``center_node`` and the cross of neighbours):
   the connected groups are the objects.

The grouping depends only on the grid's values, never on the order of points. Cell
order decides only the numbering of the groups, and :func:`cluster_cells` numbers them
by their first cell in row-major order.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import GridSpec

__all__ = ["cluster_cells", "predicted_centers"]


def predicted_centers(
    offset: NDArray[np.floating], grid: GridSpec
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The object centre every cell predicts.

    Parameters
    ----------
    offset : (2, size, size) float
        Predicted centre minus cell centre, x and y in metres.
    grid : GridSpec

    Returns
    -------
    x, y : (size, size) float64
    """
    cx, cy = grid.cell_centers()
    return cx + offset[0], cy + offset[1]


def cluster_cells(
    objectness: NDArray[np.floating],
    offset: NDArray[np.floating],
    has_points: NDArray[np.bool_],
    grid: GridSpec,
    *,
    objectness_thresh: float = 0.5,
) -> tuple[NDArray[np.intp], int]:
    """Group object cells into objects.

    Parameters
    ----------
    objectness : (size, size) float
        Probability that a cell belongs to an object.
    offset : (2, size, size) float
        Offset from each cell's centre to its object's centre, metres.
    has_points : (size, size) bool
        Cells holding at least one point that may be clustered (Apollo's valid indices).
    grid : GridSpec
    objectness_thresh : float
        Apollo's ``objectness_thresh`` (0.5).

    Returns
    -------
    labels : (size * size,) intp
        Object of every cell (row-major), -1 for cells that are not object cells.
    count : int
        Number of objects; labels are ``0 .. count - 1`` in order of each object's first
        cell.
    """
    n = grid.size
    if objectness.shape != (n, n) or offset.shape != (2, n, n) or has_points.shape != (n, n):
        raise InvalidArgument(
            f"network outputs must be ({n}, {n}) and (2, {n}, {n}) for a {n}-cell grid; got "
            f"objectness {objectness.shape}, offset {offset.shape}, cells {has_points.shape}"
        )
    is_object = (objectness >= objectness_thresh) & has_points
    cells = np.flatnonzero(is_object.ravel())
    labels = np.full(n * n, -1, dtype=np.intp)
    if len(cells) == 0:
        return labels, 0
    x, y = predicted_centers(offset, grid)
    # The centre's cell, by the features' own mapping; a centre off the grid points at the
    # nearest border cell, as Apollo clamps it.
    row = np.clip(np.floor((grid.range - x.ravel()[cells]) / grid.cell), 0, n - 1)
    col = np.clip(np.floor((grid.range - y.ravel()[cells]) / grid.cell), 0, n - 1)
    target = (row * n + col).astype(np.intp)
    centre = np.zeros(n * n, dtype=bool)
    centre[target] = True
    grid_centre = centre.reshape(n, n)
    # 4-neighbouring centre cells join: right and down neighbours suffice.
    right = np.flatnonzero((grid_centre[:, :-1] & grid_centre[:, 1:]).ravel())
    right = (right // (n - 1)) * n + right % (n - 1)
    down = np.flatnonzero((grid_centre[:-1, :] & grid_centre[1:, :]).ravel())
    sources = np.concatenate([cells, right, down])
    targets = np.concatenate([target, right + 1, down + n])
    # Components over the cells involved only (object cells and centre cells).
    nodes, inverse = np.unique(np.concatenate([sources, targets]), return_inverse=True)
    edges = len(sources)
    graph = coo_matrix(
        (np.ones(edges, dtype=np.int8), (inverse[:edges], inverse[edges:])),
        shape=(len(nodes), len(nodes)),
    )
    _, component = connected_components(graph, directed=False)
    of_cell = component[np.searchsorted(nodes, cells)]
    # Number objects by their first object cell in row-major order.
    _, first, renumbered = np.unique(of_cell, return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first, kind="stable"), kind="stable")
    labels[cells] = order[renumbered]
    return labels, len(first)
