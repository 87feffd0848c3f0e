"""Apollo's feature grid and Cluster2D, checked against cells computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.cnnseg import (
    CHANNELS,
    GridSpec,
    bev_features,
    cluster_cells,
    point_cells,
)

GRID = GridSpec(size=160, range=40.0)  # 160 x 160 cells of 0.5 m over +-40 m


def test_the_grid_maps_rows_to_x_and_columns_to_y_as_apollo_does() -> None:
    points = np.array(
        [[39.9, 39.9, 0.0], [0.2, -0.3, 0.0], [-39.99, -39.99, 0.0], [-40.0, 0.0, 0.0], [0, 0, 5.5]]
    )
    flat, inside = point_cells(points, GRID)
    assert inside.tolist() == [
        True,
        True,
        True,
        False,
        False,
    ]  # x = -40 is off the grid (x = 40 is on it); z > 5
    rows, cols = np.divmod(flat[inside], GRID.size)
    # row = floor((40 - x) / 0.5), col = floor((40 - y) / 0.5)
    assert rows.tolist() == [0, 79, 159] and cols.tolist() == [0, 80, 159]
    cx, cy = GRID.cell_centers()
    assert (cx[79, 80], cy[79, 80]) == (0.25, -0.25)


def test_features_of_hand_computed_cells() -> None:
    points = np.array(
        [
            [0.2, -0.3, 1.0, 0.2],  # cell (79, 80): three points
            [0.4, -0.1, -0.5, 0.9],
            [0.1, -0.4, 0.25, 0.4],
            [10.1, 5.2, -1.7, 0.3],  # cell (59, 69): one point
            [10.1, 5.2, -6.0, 1.0],  # below min_height: in no cell
        ],
        dtype=np.float32,
    )
    features = bev_features(points, GRID)
    assert features.shape == (len(CHANNELS), 160, 160) and features.dtype == np.float32
    cell = features[:, 79, 80]
    expected = [1.0, 0.25, math.log(4.0), 0.2, 0.5, 1.0]
    assert cell == pytest.approx(expected, abs=1e-6)
    assert features[:, 59, 69] == pytest.approx(
        [-1.7, -1.7, math.log(2.0), 0.3, 0.3, 1.0], abs=1e-6
    )
    # Empty cells are all zero (Apollo resets an empty cell's max height to 0).
    assert np.count_nonzero(features[5]) == 2
    assert np.count_nonzero(features[:, features[5] == 0]) == 0


def test_highest_point_ties_take_the_largest_intensity_and_order_never_matters() -> None:
    rng = np.random.default_rng(3)
    points = np.column_stack(
        [rng.uniform(-30, 30, (5000, 2)), rng.uniform(-2, 3, 5000), rng.uniform(0, 1, 5000)]
    ).astype(np.float32)
    tie = np.array([[5.1, 5.1, 2.0, 0.1], [5.2, 5.2, 2.0, 0.7]], dtype=np.float32)
    points = np.concatenate([points, tie])
    features = bev_features(points, GRID)
    shuffled = bev_features(points[rng.permutation(len(points))], GRID)
    np.testing.assert_array_equal(features, shuffled)  # bit for bit
    flat, _ = point_cells(tie, GRID)
    row, col = divmod(int(flat[0]), GRID.size)
    assert features[0, row, col] == 2.0 and features[3, row, col] == pytest.approx(0.7)


def test_intensities_on_a_0_255_scale_are_read_as_reflectance() -> None:
    points = np.array([[1.1, 1.1, 0.0, 51.0], [1.2, 1.2, 0.1, 204.0]], dtype=np.float32)
    features = bev_features(points, GRID)
    flat, _ = point_cells(points, GRID)
    row, col = divmod(int(flat[0]), GRID.size)
    assert features[3, row, col] == pytest.approx(0.8) and features[4, row, col] == pytest.approx(
        0.5
    )


def test_bad_points_and_grids_are_named() -> None:
    with pytest.raises(InvalidArgument, match=r"points must be an \(n, 4\) array"):
        bev_features(np.zeros((3, 3)), GRID)
    with pytest.raises(InvalidArgument, match="multiple of 8"):
        GridSpec(size=100)
    with pytest.raises(InvalidArgument, match="min_height=2 must be < max_height=1"):
        GridSpec(min_height=2, max_height=1)


def _blob(
    offset: np.ndarray,
    objectness: np.ndarray,
    cells: list[tuple[int, int]],
    centre: tuple[float, float],
) -> None:
    cx, cy = GRID.cell_centers()
    for r, c in cells:
        objectness[r, c] = 0.9
        offset[:, r, c] = (centre[0] - cx[r, c], centre[1] - cy[r, c])


def test_cluster2d_groups_cells_by_the_centres_they_point_to() -> None:
    n = GRID.size
    objectness = np.zeros((n, n), dtype=np.float32)
    offset = np.zeros((2, n, n), dtype=np.float32)
    has_points = np.zeros((n, n), dtype=bool)
    cx, cy = GRID.cell_centers()
    # A car: a 3 x 7 block of cells pointing at the middle cell; a pedestrian far away.
    car = [(r, c) for r in range(40, 47) for c in range(70, 73)]
    _blob(offset, objectness, car, (cx[43, 71], cy[43, 71]))
    pedestrian = [(100, 20), (100, 21)]
    _blob(offset, objectness, pedestrian, (cx[100, 20], cy[100, 20]))
    for r, c in car + pedestrian:
        has_points[r, c] = True
    # Object-like cells without points, and points in cells below the threshold, are no objects.
    objectness[10, 10] = 0.99
    has_points[11, 11] = True
    objectness[11, 11] = 0.49
    labels, count = cluster_cells(objectness, offset, has_points, GRID)
    assert count == 2
    grid_labels = labels.reshape(n, n)
    assert {int(grid_labels[r, c]) for r, c in car} == {0}  # first in row-major order
    assert {int(grid_labels[r, c]) for r, c in pedestrian} == {1}
    assert grid_labels[10, 10] == grid_labels[11, 11] == -1
    assert np.count_nonzero(labels >= 0) == len(car) + len(pedestrian)


def test_cluster2d_joins_neighbouring_centres_and_splits_what_points_apart() -> None:
    n = GRID.size
    objectness = np.zeros((n, n), dtype=np.float32)
    offset = np.zeros((2, n, n), dtype=np.float32)
    cx, cy = GRID.cell_centers()
    # One row of cells: the left half points at (50, 50), the right half at (50, 51):
    # neighbouring centre cells, so one object.
    _blob(offset, objectness, [(50, c) for c in range(46, 50)], (cx[50, 50], cy[50, 50]))
    _blob(offset, objectness, [(50, c) for c in range(50, 54)], (cx[50, 51], cy[50, 51]))
    # Two touching blocks that point 3 cells apart: two objects although they touch.
    _blob(offset, objectness, [(80, c) for c in range(40, 43)], (cx[80, 40], cy[80, 40]))
    _blob(offset, objectness, [(80, c) for c in range(43, 46)], (cx[80, 45], cy[80, 45]))
    labels, count = cluster_cells(objectness, offset, objectness > 0, GRID)
    grid_labels = labels.reshape(n, n)
    assert count == 3
    assert len({int(v) for v in grid_labels[50, 46:54]}) == 1
    assert grid_labels[80, 40] != grid_labels[80, 45]
    with pytest.raises(InvalidArgument, match="network outputs must be"):
        cluster_cells(objectness[:10], offset, objectness > 0, GRID)
