"""Apollo's MinBox builder: Apollo's own expected boxes, invariances, geometry, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from pytest_metamorphic import DataError, InvalidArgument
from pytest_metamorphic.lidar.io.apollo import read_apollo_clusters
from pytest_metamorphic.lidar.systems.perception import minbox
from pytest_metamorphic.lidar.systems.perception.minbox import hull, min_box, min_boxes

CLUSTERS = ("apollo", "min_box_object_builder", "QB9178_3_1461381834_1461382134_30651.pcd")

# Apollo's min_box_test.cc: (points, length, width, height, direction x, direction y).
APOLLO_EXPECTED = [
    (3, 0.1499978, 0.0560999, 0.7320720, 0.0, 1.0),
    (76, 3.740892, 0.387848, 1.855707, -0.9987907, -0.0491651),
    (4, 0.693386, 0.278326, 0.0199099, 0.743031, -0.669257),
    (7, 0.688922, 0.356031, 0.311353, 0.992437, 0.122754),
    (11, 1.147774, 0.326984, 0.977219, 0.979983, -0.199081),
]


@pytest.fixture(scope="module")
def apollo_clusters(request: pytest.FixtureRequest) -> list[np.ndarray]:
    from conftest import shared_data_path

    return [cloud.points for cloud in read_apollo_clusters(shared_data_path(*CLUSTERS))]


@pytest.mark.parametrize("index", range(5))
def test_matches_apollo_expected_boxes(apollo_clusters: list[np.ndarray], index: int) -> None:
    count, length, width, height, dx, dy = APOLLO_EXPECTED[index]
    points = apollo_clusters[index]
    assert len(points) == count
    box = min_box(points)
    # Apollo's test tolerance is 1e-6 on every value.
    assert box.length == pytest.approx(length, abs=1e-6)
    assert box.width == pytest.approx(width, abs=1e-6)
    assert box.height == pytest.approx(height, abs=1e-6)
    assert box.direction == pytest.approx((dx, dy, 0.0), abs=1e-6)
    assert box.points == count


def test_batch_builder_matches_single_builder(apollo_clusters: list[np.ndarray]) -> None:
    points = np.concatenate(apollo_clusters)
    labels = np.repeat(np.arange(5), [len(c) for c in apollo_clusters])
    shuffled = np.random.default_rng(0).permutation(len(points))
    batch = min_boxes(points[shuffled], labels[shuffled])
    for single, cluster in zip(batch, apollo_clusters, strict=True):
        _assert_same_box(single, min_box(cluster))


def test_nearest_start_gives_apollos_boxes_up_to_the_heading_sign(
    apollo_clusters: list[np.ndarray],
) -> None:
    for points in apollo_clusters:
        apollo, nearest = min_box(points), min_box(points, start="nearest")
        assert (nearest.length, nearest.width) == pytest.approx(
            (apollo.length, apollo.width), abs=1e-9
        )
        assert abs(math.remainder(nearest.yaw - apollo.yaw, math.pi)) < 1e-9


def test_edges_facing_away_from_the_sensor_are_not_tried(
    apollo_clusters: list[np.ndarray],
) -> None:
    # Cluster 2 (76 points) seen from the origin: the global minimum-area rectangle over
    # all hull edges is smaller than Apollo's box, which only tries the near edges.
    box = min_box(apollo_clusters[1])
    assert _global_min_area(apollo_clusters[1]) < box.length * box.width - 1e-4
    # Seen from the far side, other edges face the sensor and the box changes.
    far = min_box(apollo_clusters[1], ref_center=(40.0, -80.0, 0.0))
    assert (far.length, far.width) != pytest.approx((box.length, box.width), abs=1e-4)


def _global_min_area(points: np.ndarray) -> float:
    xy = points[:, :2].astype(np.float64)
    vertices = xy[ConvexHull(xy).vertices]
    best = math.inf
    for a, b in zip(vertices, np.roll(vertices, -1, axis=0), strict=True):
        u = (b - a) / np.linalg.norm(b - a)
        along, across = xy @ u, xy @ np.array([-u[1], u[0]])
        best = min(best, np.ptp(along) * np.ptp(across))
    return best


def _assert_same_box(a: minbox.MinBox, b: minbox.MinBox) -> None:
    assert a.center == pytest.approx(b.center, abs=1e-9)
    assert (a.length, a.width, a.height) == pytest.approx((b.length, b.width, b.height), abs=1e-9)
    assert a.direction == pytest.approx(b.direction, abs=1e-9)
    np.testing.assert_allclose(a.polygon, b.polygon, atol=1e-9)


@st.composite
def clusters(draw: st.DrawFn, max_points: int = 40) -> np.ndarray:
    """A small obstacle-like cluster somewhere around the sensor (float32 metres)."""
    n = draw(st.integers(1, max_points))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-40, 40, 2)
    extent = rng.uniform(0.05, 5.0, 2)
    angle = rng.uniform(0, math.pi)
    local = rng.uniform(-0.5, 0.5, (n, 2)) * extent
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    xy = local @ rotation.T + centre
    z = rng.uniform(-1.7, 0.3, n)
    if draw(st.booleans()):  # repeated points, as real clouds have
        xy[: n // 2] = xy[n - n // 2 :][: n // 2]
    return np.column_stack([xy, z]).astype(np.float32)


@settings(max_examples=60)
@given(clusters(), st.randoms(use_true_random=False))
def test_result_does_not_depend_on_point_order(points: np.ndarray, random) -> None:
    order = list(range(len(points)))
    random.shuffle(order)
    _assert_same_box(min_box(points), min_box(points[order]))


@settings(max_examples=60)
@given(clusters())
def test_box_encloses_every_point(points: np.ndarray) -> None:
    box = min_box(points)
    ux, uy, _ = box.direction
    assert math.hypot(ux, uy) == pytest.approx(1.0)
    assert box.length >= box.width >= 0
    offset = points[:, :2].astype(np.float64) - np.array(box.center[:2])
    along = np.abs(offset @ np.array([ux, uy]))
    across = np.abs(offset @ np.array([-uy, ux]))
    assert along.max() <= box.length / 2 + 1e-4
    assert across.max() <= box.width / 2 + 1e-4
    # Apollo's centre z is the lowest point (the mid-height for < 4 points without a
    # facing edge), all within SetDefaultValue's 1 mm widening.
    assert points[:, 2].min() - 1e-3 <= box.center[2] <= points[:, 2].max() + 1e-3


@settings(max_examples=60)
@given(clusters(max_points=120))
def test_hull_has_qhulls_vertices(points: np.ndarray) -> None:
    xy = points[:, :2].astype(np.float64)
    unique = np.unique(xy, axis=0)
    ours = hull.convex_hull([tuple(p) for p in xy.tolist()])
    if len(unique) < 3 or len(ours) < 3:
        return  # collinear: Apollo falls back to the bounding rectangle
    try:
        expected = {tuple(p) for p in xy[ConvexHull(xy).vertices].tolist()}
    except Exception:  # qhull refuses nearly flat input that is not exactly collinear
        return
    assert set(ours) == expected


@settings(max_examples=40)
@given(st.lists(clusters(max_points=80), min_size=1, max_size=6))
def test_interior_pruning_changes_nothing(
    monkeypatch_module: pytest.MonkeyPatch, parts: list[np.ndarray]
) -> None:
    points = np.concatenate(parts)
    labels = np.repeat(np.arange(len(parts)), [len(p) for p in parts])
    pruned = min_boxes(points, labels)
    with monkeypatch_module.context() as patch:
        # no pruning at all: neither the octagon nor qhull
        patch.setattr(hull, "_QHULL_FROM", 10**9)
        patch.setattr(hull, "_inside_octagon", lambda xy, *_: np.zeros(len(xy), dtype=bool))
        whole = min_boxes(points, labels)
    with monkeypatch_module.context() as patch:
        patch.setattr(hull, "_QHULL_FROM", 0)
        eager = min_boxes(points, labels)
    for a, b in zip(pruned, eager, strict=True):
        _assert_same_box(a, b)
    for a, b in zip(pruned, whole, strict=True):
        _assert_same_box(a, b)


@settings(max_examples=80)
@given(st.lists(clusters(max_points=80), min_size=1, max_size=6))
def test_the_octagon_never_prunes_a_hull_vertex(parts: list[np.ndarray]) -> None:
    xy = np.concatenate(parts)[:, :2].astype(np.float32).astype(np.float64)
    sizes = np.array([len(p) for p in parts])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    inside = hull._inside_octagon(xy, sizes, starts)
    for begin, size in zip(starts, sizes, strict=True):
        chunk = [tuple(p) for p in xy[begin : begin + size].tolist()]
        kept = {p for p, drop in zip(chunk, inside[begin : begin + size], strict=True) if not drop}
        assert set(hull.convex_hull(chunk)) <= kept


@settings(max_examples=80)
@given(st.lists(st.tuples(st.integers(-4, 4), st.integers(-4, 4)), min_size=1, max_size=40))
def test_the_octagon_keeps_hull_vertices_of_lattice_points(cells: list[tuple[int, int]]) -> None:
    # exact ties and collinear points everywhere: extremes shared by several points
    xy = np.array(cells, dtype=np.float64) * 0.25 + 30.0
    inside = hull._inside_octagon(xy, np.array([len(xy)]), np.array([0]))
    kept = {tuple(p) for p, drop in zip(xy.tolist(), inside, strict=True) if not drop}
    assert set(hull.convex_hull([tuple(p) for p in xy.tolist()])) <= kept


def test_the_octagon_keeps_degenerate_clusters() -> None:
    # one repeated point, a segment, a square with its centre
    xy = np.array(
        [[1, 1]] * 5 + [[0, 0], [1, 1], [2, 2], [3, 3]] + [[0, 0], [2, 0], [2, 2], [0, 2], [1, 1]],
        dtype=np.float64,
    )
    sizes, starts = np.array([5, 4, 5]), np.array([0, 5, 9])
    inside = hull._inside_octagon(xy, sizes, starts)
    assert inside.tolist() == [False] * 13 + [True]


@pytest.fixture(scope="module")
def monkeypatch_module() -> pytest.MonkeyPatch:
    patch = pytest.MonkeyPatch()
    yield patch
    patch.undo()


def test_fewer_than_four_points_keep_the_axis_aligned_defaults() -> None:
    box = min_box([[1.0, 2.0, 0.0], [1.0, 2.0, 0.0], [1.0, 2.0, 0.5]])
    # One distinct x-y position: every extent is widened to Apollo's 1 mm.
    assert (box.length, box.width) == pytest.approx((1e-3, 1e-3), abs=1e-7)
    assert box.height == pytest.approx(0.5)
    assert box.points == 3


def test_collinear_points_fall_back_to_the_bounding_rectangle() -> None:
    points = [[x, 2.0 * x + 1.0, 0.0] for x in (5.0, 6.0, 7.0, 8.0)]
    box = min_box(points)
    np.testing.assert_allclose(box.polygon[:, :2], [[5, 11], [5, 17], [8, 17], [8, 11]], atol=1e-6)
    # The box is fitted to that rectangle, not to the segment.
    assert (box.length, box.width) == pytest.approx((6.0, 3.0), abs=1e-5)


@pytest.mark.parametrize(
    ("points", "error", "match"),
    [
        (np.empty((0, 3)), InvalidArgument, "empty"),
        (np.zeros((4, 2)), InvalidArgument, r"shape \(n, 3\) or \(n, 4\)"),
        ([[0.0, 0.0, math.nan]] * 4, DataError, "NaN"),
        ("points", InvalidArgument, "float array"),
    ],
)
def test_bad_points_are_rejected_with_a_clear_error(points, error, match) -> None:
    with pytest.raises(error, match=match):
        min_box(points)


def test_bad_labels_and_ref_center_are_rejected() -> None:
    points = np.zeros((4, 3), dtype=np.float32)
    with pytest.raises(InvalidArgument, match="id 1 has no points"):
        min_boxes(points, [0, 0, 2, 2])
    with pytest.raises(InvalidArgument, match="one per point"):
        min_boxes(points, [0, 0, 0])
    with pytest.raises(InvalidArgument, match=">= 0"):
        min_boxes(points, [0, -1, 0, 0])
    with pytest.raises(InvalidArgument, match="ref_center"):
        min_box(points, ref_center=(0.0, 0.0))
    with pytest.raises(InvalidArgument, match="start"):
        min_box(points, start="first")  # type: ignore[arg-type]


@settings(max_examples=60)
@given(clusters(max_points=80), st.sampled_from([1, 2, 3]))
def test_nearest_start_boxes_turn_with_the_scene(points: np.ndarray, quarter_turns: int) -> None:
    turned = points.copy()
    for _ in range(quarter_turns):  # exact in float32: (x, y) -> (-y, x)
        turned[:, 0], turned[:, 1] = -turned[:, 1].copy(), turned[:, 0].copy()
    a = min_box(points, start="nearest")
    b = min_box(turned, start="nearest")
    theta = quarter_turns * math.pi / 2
    c, s = math.cos(theta), math.sin(theta)
    x, y, _ = a.center
    assert b.center[:2] == pytest.approx((c * x - s * y, s * x + c * y), abs=1e-6)
    assert (b.length, b.width) == pytest.approx((a.length, a.width), abs=1e-6)
    if a.length - a.width > 1e-3:
        assert abs(math.remainder(b.yaw - a.yaw - theta, math.pi)) < 1e-6


def _apollo_area_along_one_edge(polygon: list[tuple[float, float]], first: int) -> tuple:
    """min_box.cc's ComputeAreaAlongOneEdge, line by line (all pairs i < j for the length)."""
    index = (first + 1) % len(polygon)
    (bx, by), (ax, ay) = polygon[first], polygon[index]
    projected, wid, v, vn = [], 0.0, (0.0, 0.0), (0.0, 0.0)
    for i, (ox, oy) in enumerate(polygon):
        if i in (first, index):
            projected.append((ox, oy))
            continue
        k = (ax - ox) * (bx - ax) + (ay - oy) * (by - ay)
        k = -(k / ((bx - ax) ** 2 + (by - ay) ** 2))
        n = ((bx - ax) * k + ax, (by - ay) * k + ay)
        height = abs((ox - bx) * (ay - by) - (ax - bx) * (oy - by))
        height /= math.sqrt((ax - bx) ** 2 + (ay - by) ** 2)
        if height > wid:
            wid, v, vn = height, (ox, oy), n
        projected.append(n)
    length, p1, p2 = 0.0, 0, 0
    for i in range(len(projected) - 1):
        for j in range(i + 1, len(projected)):
            dist = math.dist(projected[i], projected[j])
            if dist > length:
                length, p1, p2 = dist, i, j
    n1, n2 = projected[p1], projected[p2]
    vp1 = (v[0] + n1[0] - vn[0], v[1] + n1[1] - vn[1])
    vp2 = (v[0] + n2[0] - vn[0], v[1] + n2[1] - vn[1])
    center = ((vp1[0] + vp2[0] + n1[0] + n2[0]) / 4, (vp1[1] + vp2[1] + n1[1] + n2[1]) / 4)
    along = n2 if length > wid else vp1
    direction = (along[0] - n1[0], along[1] - n1[1])
    long_side, short_side = max(length, wid), min(length, wid)
    return long_side * short_side, long_side, short_side, *center, *direction


def test_boxes_along_all_edges_at_once_are_apollos_one_edge_at_a_time() -> None:
    # The vectorised ComputeAreaAlongOneEdge (every candidate edge of a frame in one
    # pass, Apollo's O(h^2) pair search replaced by the extremes along the edge) against
    # a literal port, on every edge of random hulls: float points, and lattice points
    # whose projections tie exactly (where the pair Apollo keeps is the subtle part).
    from pytest_metamorphic.lidar.systems.perception.minbox import edges

    rng = np.random.default_rng(20261127)
    polygons = []
    for trial in range(300):
        xy = rng.normal(rng.normal(0, 20, 2), rng.choice([0.05, 1.0, 5.0]), (12, 2))
        if trial % 2:
            xy = np.round(xy * 2) / 2  # a 0.5 m lattice: ties in every direction
        vertices = hull.hull_polygon(
            [tuple(p) for p in xy.astype(np.float32).astype(np.float64).tolist()],
            xy.min(axis=0).tolist(), xy.max(axis=0).tolist(), "apollo", (0.0, 0.0, 0.0),
        )  # fmt: skip
        if len(set(vertices)) == len(vertices):  # no zero-length edge (tested below)
            polygons.append(vertices)
    every = np.array([vertex for polygon in polygons for vertex in polygon])
    candidates = [list(range(len(polygon))) for polygon in polygons]
    found = edges._boxes_along_edges(
        every[:, 0], every[:, 1], [len(polygon) for polygon in polygons], candidates
    )
    expected = [
        _apollo_area_along_one_edge(polygon, edge)
        for polygon, polygon_edges in zip(polygons, candidates, strict=True)
        for edge in polygon_edges
    ]
    assert len(found) == len(expected) > 1000
    for ours, apollos in zip(found, expected, strict=True):
        assert ours is not None
        assert ours == pytest.approx(apollos, rel=1e-9, abs=1e-9)
    # A zero-length edge (Apollo divides by zero there) gives no box.
    square = [(0.0, 0.0), (0.0, 1.0), (0.0, 1.0), (1.0, 0.0)]
    boxes = edges._boxes_along_edges(*np.array(square).T, [4], [[1, 2]])
    assert boxes[0] is None and boxes[1] is not None
