"""ROI containment: exact, Apollo-rasterised, against Apollo's labelled points and oracles."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path as MplPath

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.roi import ROI, validate_polygon
from pytest_metamorphic.lidar.roi.polygon import _points_in_polygon
from pytest_metamorphic.lidar.roi.raster import _BLOCK, _scan_intervals

SQUARE = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
# A concave "U" with a notch, exercising several intervals per scan line.
U_SHAPE = np.array(
    [[-20, -10], [20, -10], [20, 15], [8, 15], [8, 0], [-8, 0], [-8, 15], [-20, 15]], float
)


def _apollo_labels(shared_data):
    labels = np.loadtxt(
        shared_data / "apollo/hdmap_roi_filter/poly_mask_ut_pcd_first676.txt", skiprows=1
    )
    return labels[:, :2], labels[:, 2] > 0


def _apollo_roi(shared_data, **options):
    pytest.importorskip("pytest_metamorphic.lidar.io.apollo")
    return ROI.from_apollo_poly(
        shared_data / "apollo/hdmap_roi_filter/poly_mask_ut.poly", **options
    )


def test_apollo_unit_test_labels_agree_with_raster(shared_data):
    # Apollo's ROI-filter unit test runs with range 70 m and 0.25 m cells; its labelled
    # points are what that bitmap says. Our scan conversion reproduces all 676.
    roi = _apollo_roi(shared_data, raster_range=70.0)
    xy, inside = _apollo_labels(shared_data)
    raster = roi.contains(xy)
    assert np.array_equal(raster, inside), np.flatnonzero(raster != inside)
    # The exact test disagrees on the 7 points next to edges or beyond 70 m.
    exact = roi.contains(xy, method="exact")
    assert np.count_nonzero(exact == inside) == 669
    assert np.count_nonzero(inside) == 86


def test_apollo_polygons_exact_matches_matplotlib(shared_data):
    roi = _apollo_roi(shared_data)
    xy = np.random.default_rng(1).uniform(-140, 140, size=(50_000, 2))
    expected = np.zeros(len(xy), dtype=bool)
    for polygon in roi.polygons:
        expected |= MplPath(polygon).contains_points(xy)
    assert np.array_equal(roi.contains(xy, method="exact"), expected)


def test_apollo_bitmap_quirks():
    roi = ROI.from_polygons([SQUARE], raster_range=20.0)
    # x extent == y extent: Apollo picks x as major axis.
    assert roi.major_axis == "x"
    assert ROI.from_polygons([SQUARE * [2, 1]], raster_range=30.0).major_axis == "y"
    # Points beyond the bitmap are outside even when inside the polygon.
    far = ROI.from_polygons([SQUARE * 10], raster_range=50.0)
    assert far.contains([[60.0, 60.0]], method="exact")[0]
    assert not far.contains([[60.0, 60.0]])[0]
    # A polygon thinner than one cell column is not drawn at all.
    sliver = ROI.from_polygons([[[0.01, 0], [0.1, 0], [0.1, 5], [0.01, 5]]], raster_range=10.0)
    assert sliver.major_axis == "x"
    assert not sliver.bitmap.any()
    assert sliver.contains([[0.05, 2.0]], method="exact")[0]


def test_apollo_simple_case_diamond():
    # Apollo's SimpleCaseFilter polygon (with its repeated vertices), moved to the sensor.
    world = np.array([[5, 10], [5, 10], [10, 15], [10, 15], [15, 10], [10, 5]], float)
    roi = ROI.from_polygons([world - 10.0])
    assert len(roi.polygons[0]) == 4
    assert roi.contains([[0.0, 0.0], [0.0, -10.0]]).tolist() == [True, False]


def test_scan_intervals_match_apollo_scan_converter_counts():
    # Apollo's polygon-scan-converter unit test (y-major scans at y = 0..11); compared on
    # the scan lines that pass through no vertex, where the half-open rule and Apollo's
    # singular-vertex rule agree.
    polygon = np.array([[1, 3], [2, 8], [7, 6], [9, 10], [13, 5], [5, 1]], float)
    expected = {0: 0, 2: 1, 4: 1, 7: 2, 9: 1, 11: 0}
    column, low, high = _scan_intervals(polygon[:, 1], polygon[:, 0], 0, 12, 1.0, 0.5)
    counts = np.bincount(column, minlength=12)
    assert {y: int(counts[y]) for y in expected} == expected
    assert (low <= high).all()


def _reference_bitmap(roi: ROI) -> np.ndarray:
    """Slow per-column loop over Apollo's algorithm, as an oracle for the vectorised one."""
    cell, r = roi.cell_size, roi.raster_range
    size = int(2 * r / cell) + 1
    bitmap = np.zeros((size, size), dtype=bool)
    major = 0 if roi.major_axis == "x" else 1
    for polygon in roi.polygons:
        u, v = polygon[:, major], polygon[:, 1 - major]
        first, last = max(u.min(), -r), min(u.max(), r)
        start_centre = (int((first + r) / cell) + 0.5) * cell - r
        # Apollo: scans_size = (size_t)((last - first_centre) / cell), so a last column
        # whose centre lies less than one cell below the top is not scanned.
        for scan in range(int((last - start_centre) / cell)):
            centre = start_centre + scan * cell
            nodes = []
            for i in range(len(u)):
                j = (i + 1) % len(u)
                if min(u[i], u[j]) <= centre < max(u[i], u[j]):
                    nodes.append(v[i] + (centre - u[i]) * (v[j] - v[i]) / (u[j] - u[i]))
            nodes.sort()
            column = int((centre + r) / cell)
            for lo, hi in zip(nodes[0::2], nodes[1::2], strict=True):
                lo, hi = max(lo - roi.extend_dist, -r), min(hi + roi.extend_dist, r)
                if lo <= hi:
                    start, stop = int((lo + r) / cell), int((hi + r) / cell)
                    if major == 0:
                        bitmap[column, start : stop + 1] = True
                    else:
                        bitmap[start : stop + 1, column] = True
    return bitmap


@pytest.mark.parametrize("extend_dist", [0.0, 0.6])
@pytest.mark.parametrize("polygon", [U_SHAPE, U_SHAPE[:, ::-1] * [1.5, 0.7] + [3.3, -7.1]])
def test_bitmap_equals_reference_scan_conversion(polygon, extend_dist):
    roi = ROI.from_polygons([polygon], raster_range=30.0, extend_dist=extend_dist)
    assert np.array_equal(roi.bitmap, _reference_bitmap(roi))


def test_extend_dist_widens_along_minor_axis_only():
    # y extent 10 > x extent 4, so x is the major axis and intervals run along y.
    rect = np.array([[0, 0], [4, 0], [4, 10], [0, 10]], float)
    plain = ROI.from_polygons([rect], raster_range=20.0)
    wide = ROI.from_polygons([rect], raster_range=20.0, extend_dist=1.0)
    assert plain.major_axis == "x"
    probe = np.array([[2.0, -0.9], [2.0, 10.9], [-0.9, 5.0], [4.9, 5.0]])
    assert plain.contains(probe).tolist() == [False, False, False, False]
    assert wide.contains(probe).tolist() == [True, True, False, False]


def _random_simple_polygon(rng: np.random.Generator, k: int) -> np.ndarray:
    # Star-shaped around the origin: sorted angles with positive radii is always simple.
    angles = np.sort(rng.uniform(0, 2 * math.pi, k))
    radii = rng.uniform(3, 40, k)
    return np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)


@settings(max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 30))
def test_raster_agrees_with_exact_away_from_edges(seed, k):
    rng = np.random.default_rng(seed)
    polygon = _random_simple_polygon(rng, k)
    try:
        roi = ROI.from_polygons([polygon], raster_range=50.0)
    except InvalidArgument:
        return  # duplicate angles can make a degenerate polygon
    xy = rng.uniform(-50, 50, size=(4000, 2))
    far = roi.boundary_distance(xy) > 1.5 * roi.cell_size
    exact = roi.contains(xy, method="exact")
    assert np.array_equal(roi.contains(xy)[far], exact[far])
    assert np.array_equal(exact, MplPath(polygon).contains_points(xy))


def test_exact_union_of_overlapping_polygons_and_outside_bitmap():
    a = SQUARE
    b = SQUARE + np.array([5.0, 5.0])
    roi = ROI.from_polygons([a, b], raster_range=8.0)
    xy = np.array([[2, 2], [7, 7], [12, 12], [7, 2], [14.9, 14.9], [-1, -1]], float)
    assert roi.contains(xy, method="exact").tolist() == [True, True, True, True, True, False]
    # Beyond raster_range=8 the raster says no.
    assert roi.contains(xy).tolist() == [True, True, False, True, False, False]


def test_contains_accepts_point_clouds_and_ignores_nan():
    roi = ROI.from_polygons([SQUARE])
    cloud = PointCloud(np.array([[1, 1, 0, 0], [20, 20, 0, 0]], np.float32))
    assert roi.contains(cloud).tolist() == [True, False]
    nan = np.array([[np.nan, 1.0], [1.0, np.inf]])
    assert roi.contains(nan).tolist() == [False, False]
    assert roi.contains(nan, method="exact").tolist() == [False, False]
    assert roi.contains(np.empty((0, 2))).shape == (0,)


def test_contains_rejects_bad_arguments():
    roi = ROI.from_polygons([SQUARE])
    with pytest.raises(InvalidArgument, match="method="):
        roi.contains([[0, 0]], method="fuzzy")
    with pytest.raises(InvalidArgument, match="xy must have shape"):
        roi.contains(np.zeros((3, 1)))
    with pytest.raises(InvalidArgument, match="numeric"):
        roi.contains(np.array([["a", "b"]]))


@pytest.mark.parametrize(
    ("polygon", "message"),
    [
        ([[0, 0], [1, 1]], "at least 3 distinct vertices"),
        ([[0, 0], [0, 0], [0, 0], [1, 1]], "at least 3 distinct vertices"),
        ([[0, 0], [1, 0], [2, 0]], "zero area"),
        ([[0, 0], [1, 0], [np.nan, 1]], "vertex 2 is not finite"),
        ([[0, 0], [4, 4], [4, 0], [0, 4]], "self-intersecting"),  # bow tie
        ([[0, 0], [4, 0], [4, 4], [2, 0], [0, 4]], "self-intersecting"),  # vertex on an edge
        ([[0, 0], [4, 0], [4, 4], [4, 2], [0, 4]], "self-intersecting"),  # folds back
        (np.zeros((4, 4)), r"shape \(k, 2\) or \(k, 3\)"),
        ([["a", "b"], ["c", "d"], ["e", "f"]], "cannot be converted"),
    ],
)
def test_invalid_polygons_are_rejected_by_name(polygon, message):
    with pytest.raises(InvalidArgument, match=rf"polygons\[1\]: .*{message}"):
        ROI.from_polygons([SQUARE, polygon])


def test_invalid_polygon_from_a_file_names_the_file():
    with pytest.raises(DataError, match=r"map\.poly: polygons\[0\]: .*self-intersecting"):
        validate_polygon([[0, 0], [4, 4], [4, 0], [0, 4]], name="polygons[0]", path="map.poly")


def test_closing_vertex_and_z_are_dropped():
    closed = np.array([[0, 0, 1], [3, 0, 1], [3, 3, 1], [0, 3, 1], [0, 0, 1]], float)
    polygon = validate_polygon(closed)
    assert polygon.dtype == np.float64
    assert polygon.tolist() == [[0, 0], [3, 0], [3, 3], [0, 3]]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"cell_size": 0}, "cell_size"),
        ({"cell_size": float("nan")}, "cell_size"),
        ({"extend_dist": -1}, "extend_dist"),
        ({"raster_range": 0.1}, "raster_range"),
        ({"raster_range": "far"}, "raster_range"),
    ],
)
def test_bad_raster_parameters(options, message):
    with pytest.raises(InvalidArgument, match=message):
        ROI.from_polygons([SQUARE], **options)


def test_empty_and_non_list_polygons():
    with pytest.raises(InvalidArgument, match="empty"):
        ROI.from_polygons([])
    with pytest.raises(InvalidArgument, match="list of"):
        ROI.from_polygons("square")
    # A single (k, 2) array is one polygon.
    assert len(ROI.from_polygons(SQUARE).polygons) == 1


def test_rotation_moves_polygons_and_containment_together():
    roi = ROI.from_polygons([U_SHAPE + np.array([30, 5])])
    theta = 0.7
    rotated = roi.rotated(theta)
    xy = np.random.default_rng(3).uniform(-60, 60, size=(5000, 2))
    c, s = math.cos(theta), math.sin(theta)
    turned = xy @ np.array([[c, -s], [s, c]]).T
    assert np.array_equal(
        roi.contains(xy, method="exact"), rotated.contains(turned, method="exact")
    )
    assert rotated.rotated(-theta).polygons[0] == pytest.approx(roi.polygons[0])
    # The raster is recomputed in the sensor frame, so it only agrees away from edges.
    far = roi.boundary_distance(xy) > 0.5
    assert np.array_equal(roi.contains(xy)[far], rotated.contains(turned)[far])


def test_bounds_translation_equality_and_repr():
    roi = ROI.from_polygons([SQUARE, SQUARE + np.array([20, -5])])
    assert roi.bounds.tolist() == [[0, -5], [30, 10]]
    moved = roi.translated(1.0, 2.0)
    assert moved.bounds.tolist() == [[1, -3], [31, 12]]
    assert roi == ROI.from_polygons([SQUARE, SQUARE + np.array([20, -5])])
    assert roi != moved
    assert hash(roi) == hash(ROI.from_polygons([SQUARE, SQUARE + np.array([20, -5])]))
    assert roi != ROI.from_polygons([SQUARE, SQUARE + np.array([20, -5])], cell_size=0.5)
    assert "2 polygon(s)" in repr(roi)
    assert roi.area() == pytest.approx(200.0)


def test_free_and_interior_cells_are_outside_and_inside_by_both_methods():
    roi = ROI.from_polygons([U_SHAPE], raster_range=40.0, extend_dist=0.3)
    for margin in (1, 3):
        free = roi.free_cells(margin_cells=margin)
        interior = roi.interior_cells(margin_cells=margin)
        assert free.any() and interior.any()
        assert not (free & interior).any()
        rng = np.random.default_rng(margin)
        for cells, expected in ((free, False), (interior, True)):
            ix, iy = np.nonzero(cells)
            pick = rng.integers(0, len(ix), 20_000)
            xy = roi.cell_origin(ix[pick], iy[pick]) + rng.uniform(0, roi.cell_size, (20_000, 2))
            assert (roi.contains(xy) == expected).all()
            assert (roi.contains(xy, method="exact") == expected).all()
        # Free cells keep a gap of `margin` cells to every raster cell.
        ix, iy = np.nonzero(free)
        bitmap = np.pad(roi.bitmap, margin)
        for dx in range(-margin, margin + 1):
            for dy in range(-margin, margin + 1):
                assert not bitmap[ix + margin + dx, iy + margin + dy].any()
    with pytest.raises(InvalidArgument, match="margin_cells"):
        roi.free_cells(margin_cells=-1)


@pytest.mark.parametrize("which", ["free", "interior"])
@pytest.mark.parametrize("max_range", [None, 25.0])
def test_cell_sets_name_the_same_cells_as_the_masks(which: str, max_range: float | None) -> None:
    roi = ROI.from_polygons([U_SHAPE], raster_range=40.0, extend_dist=0.3)
    mask = roi.free_cells(margin_cells=2) if which == "free" else roi.interior_cells(margin_cells=2)
    cells = roi.cells(which, margin_cells=2, max_range=max_range)  # type: ignore[arg-type]
    assert cells is roi.cells(which, margin_cells=2, max_range=max_range)  # type: ignore[arg-type]
    ix, iy = np.divmod(cells.flat, roi.grid_size)
    assert mask[ix, iy].all()
    if max_range is None:
        assert len(cells) == mask.sum()
    else:  # every cell reaches within max_range; the nearest corner of each decides
        near = np.clip(0.0, roi.cell_origin(ix, iy), roi.cell_origin(ix, iy) + roi.cell_size)
        assert (np.hypot(near[:, 0], near[:, 1]) <= max_range).all()
    corners = roi.cell_origins(which, margin_cells=2, max_range=max_range)  # type: ignore[arg-type]
    assert np.array_equal(cells.origins(), corners)
    assert np.array_equal(cells.origins(np.array([0, len(cells) - 1])), corners[[0, -1]])
    keep = np.arange(len(cells)) % 3 == 0
    assert np.array_equal(cells.subset(keep).origins(), corners[keep])
    with pytest.raises(ValueError):
        cells.flat[0] = 0  # shared by every caller: read-only
    with pytest.raises(InvalidArgument, match="pick holds positions"):
        cells.origins(np.array([len(cells)]))
    with pytest.raises(InvalidArgument, match="pick must be a 1-D array of ints"):
        cells.origins(np.array([0.5]))
    with pytest.raises(InvalidArgument, match="keep must be"):
        cells.subset(keep[:-1])


def test_roads_are_buffered_centrelines():
    road = SimpleNamespace(centerline=np.array([[-30.0, 0.0], [0.0, 0.0], [0.0, 30.0]]), width=7.0)
    roi = ROI.from_roads([road])
    xy = np.array([[-20, 3.4], [-20, 3.6], [3.4, 20], [3.6, 20], [2.4, -2.4], [-2.6, 2.6]])
    # The round join covers the outer corner within the half-width; the inner corner is
    # covered by both rectangles.
    assert roi.contains(xy, method="exact").tolist() == [True, False, True, False, True, True]
    distance_to_centreline = np.minimum(
        np.hypot(np.maximum(np.abs(xy[:, 0] + 15) - 15, 0), xy[:, 1]),
        np.hypot(xy[:, 0], np.maximum(np.abs(xy[:, 1] - 15) - 15, 0)),
    )
    assert (distance_to_centreline[roi.contains(xy, method="exact")] <= 3.5).all()


@pytest.mark.parametrize(
    ("road", "message"),
    [
        (SimpleNamespace(centerline=[[0, 0]], width=3.0), r"roads\[0\]\.centerline"),
        (SimpleNamespace(centerline=[[0, 0], [0, 0]], width=3.0), "fewer than 2 distinct"),
        (SimpleNamespace(centerline=[[0, 0], [1, np.nan]], width=3.0), "non-finite"),
        (SimpleNamespace(centerline=[[0, 0], [5, 0]], width=0.0), r"roads\[0\]\.width"),
        (SimpleNamespace(width=3.0), "needs .centerline"),
    ],
)
def test_bad_roads(road, message):
    with pytest.raises(InvalidArgument, match=message):
        ROI.from_roads([road])


def _distance_to_polyline(xy: np.ndarray, line: np.ndarray) -> np.ndarray:
    a, b = line[:-1], line[1:]
    ab = b - a
    t = ((xy[:, None, :] - a) * ab).sum(axis=2) / np.maximum((ab**2).sum(axis=1), 1e-12)
    closest = a + np.clip(t, 0, 1)[..., None] * ab
    return np.sqrt(((xy[:, None, :] - closest) ** 2).sum(axis=2)).min(axis=1)


def test_roads_from_a_real_osm_extract(shared_data):
    osm = pytest.importorskip("pytest_metamorphic.driving.osm")
    path = shared_data / "osm_osmnx/planet_10.068,48.135_10.071,48.137.osm"
    roads = osm.load_roads(path, highway=osm.DRIVABLE_HIGHWAYS)
    assert len(roads) >= 5
    roi = ROI.from_roads(roads)
    # Inside exactly where some road's centreline is within half its width (round joins
    # are 16-gons, so allow 2 % of the half-width at the outer side of bends).
    rng = np.random.default_rng(11)
    low, high = roi.bounds
    xy = rng.uniform(low - 10, high + 10, size=(20_000, 2))
    slack = np.min([_distance_to_polyline(xy, r.centerline) - r.width / 2 for r in roads], axis=0)
    exact = roi.contains(xy, method="exact")
    assert exact[slack < -0.03 * 3.0].all()
    assert not exact[slack > 0].any()
    # Apollo's raster agrees with the exact union away from the edges.
    far = roi.boundary_distance(xy) > 1.5 * roi.cell_size
    interior_edges = slack < -0.5  # edges between overlapping pieces lie inside the union
    agree = roi.contains(xy) == exact
    assert agree[far | interior_edges].all()
    for road in roads:
        assert roi.contains(road.centerline, method="exact").all()


def test_pickles_without_the_cached_bitmaps():
    import pickle

    roi = ROI.from_polygons([U_SHAPE])
    roi.contains(np.zeros((1, 2)))
    roi.free_cells()
    data = pickle.dumps(roi)
    assert len(data) < 5000
    copy = pickle.loads(data)
    assert copy == roi
    xy = np.random.default_rng(0).uniform(-30, 30, (1000, 2))
    assert np.array_equal(copy.contains(xy), roi.contains(xy))


@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 60), integer=st.booleans())
def test_banded_point_in_polygon_equals_testing_every_edge(seed, k, integer):
    # The banded test must give exactly the all-edges crossing count, also for integer
    # coordinates where points sit on vertices and horizontal edges.
    rng = np.random.default_rng(seed)
    polygon = _random_simple_polygon(rng, k)
    xy = rng.uniform(-45, 45, size=(2000, 2))
    if integer:
        polygon, xy = np.round(polygon), np.round(xy)
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    px, py = xy[:, :1], xy[:, 1:]
    crossing = x0 + (py - y0) * (x1 - x0) / np.where(y1 != y0, y1 - y0, 1.0)
    hits = ((y0 <= py) != (y1 <= py)) & (px < crossing)
    expected = (np.count_nonzero(hits, axis=1) & 1).astype(bool)
    assert np.array_equal(_points_in_polygon(xy, polygon), expected)


@pytest.mark.parametrize("method", ["raster", "exact"])
def test_containment_is_the_same_in_blocks_as_point_by_point(method: str) -> None:
    # The lookup converts and indexes block by block (raster._BLOCK points): a point's
    # answer must not depend on the block it falls in, its dtype or the array's strides.
    roi = ROI.from_polygons([np.array([[-20, -8], [35, -3], [30, 28], [-12, 16]], float)])
    rng = np.random.default_rng(3)
    sweep = rng.uniform(-60, 60, size=(2 * _BLOCK + 3, 4)).astype(np.float32)
    sweep[::101, 0] = np.nan
    sweep[::103, 1] = -np.inf
    sweep[7] = (roi.raster_range, 0, 0, 0)  # on the grid's open upper edge: off it
    alone = np.array([roi.contains(point[:2], method=method)[0] for point in sweep[::37]])
    whole = roi.contains(sweep, method=method)  # (n, 4) float32, strided columns
    assert np.array_equal(whole[::37], alone)
    assert not whole[7] and not whole[::101].any() and not whole[::103].any()
    assert np.array_equal(roi.contains(sweep[:, :2].astype(np.float64), method=method), whole)
    lattice = rng.integers(-40, 40, size=(_BLOCK + 5, 2))
    assert np.array_equal(
        roi.contains(lattice, method=method), roi.contains(lattice.astype(float), method=method)
    )
