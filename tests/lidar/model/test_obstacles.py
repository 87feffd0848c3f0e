"""Boxes: containment, rotation, exact bird's-eye IoU, matchers used by the subset relation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from pytest_metamorphic import relations
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher, one_to_one
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.obstacles import (
    LABELS,
    SIZE_PRIORS,
    Box,
    CenterDistanceMatcher,
    IoUMatcher,
    SizePrior,
    bev_iou,
    center_distances,
    points_in_boxes,
)


def _clip_area(subject: np.ndarray, clip: np.ndarray) -> float:
    """Sutherland-Hodgman clipping of convex polygons, one vertex at a time (oracle)."""
    output = [tuple(p) for p in subject]
    for i in range(len(clip)):
        a, b = clip[i], clip[(i + 1) % len(clip)]

        def side(p, a=a, b=b):
            return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])

        polygon, output = output, []
        for j in range(len(polygon)):
            p, q = np.array(polygon[j]), np.array(polygon[(j + 1) % len(polygon)])
            sp, sq = side(p), side(q)
            if sp >= 0:
                output.append(tuple(p))
            if (sp >= 0) != (sq >= 0):
                t = sp / (sp - sq)
                output.append(tuple(p + t * (q - p)))
        if not output:
            return 0.0
    x, y = np.array(output).T
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _oracle_iou(a: Box, b: Box) -> float:
    inter = _clip_area(a.corners_bev(), b.corners_bev())
    return inter / (a.footprint_area() + b.footprint_area() - inter)


boxes = st.builds(
    Box,
    center=st.tuples(st.floats(-6, 6), st.floats(-6, 6), st.just(0.0)),
    size=st.tuples(st.floats(0.3, 6), st.floats(0.3, 4), st.just(1.5)),
    yaw=st.floats(-math.pi, math.pi),
)


@settings(max_examples=150)
@given(a=boxes, b=boxes)
@example(  # found on a user's run (CI unset): the tolerance's own bound, not 1e-7
    a=Box((0.0, 3.0, 0.0), (0.5, 0.5, 1.5), 0.0),
    b=Box((0.0, 3.0, 0.0), (0.5, 0.5, 1.5), 1.192092896e-07),
)
def test_bev_iou_matches_polygon_clipping(a, b):
    # bev_iou counts a corner as inside the other box within 1e-9 * scale^2 of its edges
    # (cross-product units, m^2; scale: the largest coordinate + 1 m), so each of the 8
    # corners may add at most half that to the intersection: two boxes 1.2e-7 rad apart
    # came out as IoU 1.0 against the oracle's 0.99999988. Touching boxes overlap by a
    # sliver the two clipping orders round differently, well within the same bound.
    scale = max(np.abs(a.corners_bev()).max(), np.abs(b.corners_bev()).max()) + 1.0
    oracle = _oracle_iou(a, b)
    inter = _clip_area(a.corners_bev(), b.corners_bev())
    union = a.footprint_area() + b.footprint_area() - inter
    tolerance = 8 * 0.5e-9 * scale**2 / union + 1e-9
    assert bev_iou([a], [b])[0, 0] == pytest.approx(oracle, abs=tolerance)


def test_bev_iou_known_values():
    unit = Box((0, 0, 0), (2, 2, 1))
    assert unit.iou_bev(unit) == pytest.approx(1.0)
    assert unit.iou_bev(Box((1, 0, 0), (2, 2, 1))) == pytest.approx(1 / 3)
    assert unit.iou_bev(Box((2, 0, 0), (2, 2, 1))) == 0.0  # touching edges
    assert unit.iou_bev(Box((9, 9, 0), (2, 2, 1))) == 0.0
    # Same square turned 45 degrees: intersection is a regular octagon.
    octagon = 8 * (math.sqrt(2) - 1)
    expected = octagon / (8 - octagon)
    assert unit.iou_bev(Box((0, 0, 0), (2, 2, 1), yaw=math.pi / 4)) == pytest.approx(expected)
    # A box inside a larger one: IoU is the area ratio; heights are ignored.
    assert unit.iou_bev(Box((0.2, 0.1, 5), (1, 0.5, 9), yaw=0.3)) == pytest.approx(0.5 / 4)


def test_bev_iou_matrix_shape_symmetry_and_rotation_invariance():
    rng = np.random.default_rng(5)
    source = [
        Box((*rng.uniform(-5, 5, 2), 0), (*rng.uniform(0.5, 4, 2), 1), rng.uniform(-3, 3))
        for _ in range(7)
    ]
    followup = [Box((*rng.uniform(-5, 5, 2), 0), (*rng.uniform(0.5, 4, 2), 1)) for _ in range(4)]
    iou = bev_iou(source, followup)
    assert iou.shape == (7, 4)
    assert np.allclose(iou, bev_iou(followup, source).T)
    turned = bev_iou([b.rotated(1.1) for b in source], [b.rotated(1.1) for b in followup])
    assert np.allclose(iou, turned)
    assert bev_iou([], followup).shape == (0, 4)
    assert bev_iou(source, []).shape == (7, 0)


def test_rotated_and_translated_boxes():
    box = Box((10, 0, -1), (4, 2, 1.5), yaw=0.2, label="car", score=0.9, points=40)
    turned = box.rotated(math.pi / 2)
    assert turned.center == pytest.approx((0, 10, -1))
    assert turned.yaw == pytest.approx(0.2 + math.pi / 2)
    assert (turned.label, turned.score, turned.points, turned.size) == ("car", 0.9, 40, box.size)
    assert box.rotated(2 * math.pi).yaw == pytest.approx(0.2)
    # Corners rotate with the box.
    c, s = math.cos(0.4), math.sin(0.4)
    expected = box.corners_bev() @ np.array([[c, -s], [s, c]]).T
    assert np.allclose(box.rotated(0.4).corners_bev(), expected)
    assert box.translated(1, 2, 3).center == (11, 2, 2)
    with pytest.raises(InvalidArgument, match="theta"):
        box.rotated(float("nan"))


def test_contains_points_of_a_rotated_box():
    box = Box((5, 5, 0), (4, 2, 2), yaw=math.pi / 2)  # long side along y now
    points = np.array(
        [[5, 6.9, 0], [5, 7.1, 0], [5.9, 5, 0], [6.1, 5, 0], [5, 5, 0.99], [5, 5, 1.01]]
    )
    assert box.contains(points).tolist() == [True, False, True, False, True, False]
    cloud = PointCloud(np.c_[points, np.zeros(len(points))].astype(np.float32))
    assert box.contains(cloud).tolist() == box.contains(points).tolist()
    with pytest.raises(InvalidArgument, match="shape"):
        box.contains(np.zeros((3, 2)))


def test_center_distances_and_footprint():
    a = [Box((0, 0, 0), (1, 1, 1)), Box((3, 4, 9), (2, 3, 1))]
    b = [Box((0, 0, 5), (1, 1, 1))]
    assert center_distances(a, b).tolist() == [[0.0], [5.0]]
    assert a[1].center_distance(b[0]) == 5.0
    assert a[1].footprint_area() == 6.0
    assert a[1].bottom_z == 8.5


def test_matchers_follow_the_protocol_and_validate():
    for matcher in (IoUMatcher(), CenterDistanceMatcher()):
        assert isinstance(matcher, Matcher)
        assert "same label" in matcher.name
    for bad in (0, 1.5, "0.5", True):
        with pytest.raises(InvalidArgument, match="min_iou"):
            IoUMatcher(min_iou=bad)
    for bad in (0, -1, float("inf"), None):
        with pytest.raises(InvalidArgument, match="max_distance"):
            CenterDistanceMatcher(max_distance=bad)
    with pytest.raises(InvalidArgument, match="same_label"):
        IoUMatcher(same_label="yes")
    with pytest.raises(InvalidArgument, match=r"source\[0\] is 'car'"):
        IoUMatcher().pairwise(["car"], [])


def test_iou_matcher_pairs_one_to_one():
    car = Box((10, 0, 0), (4, 2, 1.5), label="car")
    car2 = Box((10, 3, 0), (4, 2, 1.5), label="car")
    moved = car.translated(0.3, 0)
    as_unknown = Box(car.center, car.size, label="unknown")
    compatible, cost = IoUMatcher().pairwise([car, car2], [moved, as_unknown])
    assert compatible.tolist() == [[True, False], [False, False]]
    assert cost[0, 0] == pytest.approx(1 - car.iou_bev(moved))
    loose = IoUMatcher(same_label=False).pairwise([car], [moved, as_unknown])[0]
    assert loose.tolist() == [[True, True]]
    # Two source cars cannot both be matched by one follow-up car.
    compatible, cost = CenterDistanceMatcher(max_distance=5).pairwise([car, car2], [moved])
    assert compatible.tolist() == [[True], [True]]
    assert one_to_one(compatible, cost) == [(0, 0)]


def test_subset_relation_with_obstacle_matchers():
    source = [Box((10, 0, 0), (4, 2, 1.5), label="car"), Box((5, 5, 0), (0.8, 0.6, 1.7))]
    followup = [source[1].translated(0.1, 0), Box((30, 3, 0), (4, 2, 1.5)), source[0]]
    context = CheckContext()
    for matcher in (IoUMatcher(), CenterDistanceMatcher(max_distance=1.0)):
        relation = relations.subset(matcher=matcher)
        assert relation.check(source, followup, context).holds
        verdict = relation.check(source, followup[:2], context)
        assert not verdict.holds
        assert verdict.details["unmatched"] == [0]
        assert "car at (10.0, 0.0)" in verdict.explanation


def test_size_priors_cover_every_label_and_reference_sizes():
    assert set(SIZE_PRIORS) == set(LABELS)
    for prior in SIZE_PRIORS.values():
        assert prior.contains(prior.mean)
    # Euro NCAP test car and dummies (REFERENCE.md section 7).
    assert SIZE_PRIORS["car"].contains((4.358, 1.815, 1.5))
    assert SIZE_PRIORS["pedestrian"].contains((0.6, 0.5, 1.8))
    assert SIZE_PRIORS["pedestrian"].contains((0.711, 0.298, 1.154))
    with pytest.raises(InvalidArgument, match="low <= mean <= high"):
        SizePrior(mean=(1, 1, 1), low=(2, 1, 1), high=(3, 1, 1))


def test_twins_are_equal_up_to_rounding_and_pair_one_to_one() -> None:
    from pytest_metamorphic.lidar.model.obstacles import ROUNDING, unmatched_twins

    car = Box((10.0, 2.0, -1.0), (4.2, 1.8, 1.5), 0.3, "car")
    # Averaged in another order: the last digits differ (a reordered sweep's centroid).
    summed_otherwise = Box((10.0 + 2e-15, 2.0, -1.0), (4.2, 1.8 - 4e-16, 1.5), 0.3, "car")
    assert unmatched_twins([car], [summed_otherwise]) == ([], [])
    # Anything larger than rounding is a difference, and each box has one twin only.
    moved = Box((10.0 + 10 * ROUNDING, 2.0, -1.0), (4.2, 1.8, 1.5), 0.3, "car")
    assert unmatched_twins([car], [moved]) == ([0], [0])
    assert unmatched_twins([car, car], [summed_otherwise]) == ([1], [])
    relabelled = Box(summed_otherwise.center, summed_otherwise.size, 0.3, "unknown")
    assert unmatched_twins([car], [relabelled]) == ([0], [0])


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(-20, 20),
            st.floats(-20, 20),
            st.floats(0.1, 6),
            st.floats(0.1, 3),
            st.floats(-math.pi, math.pi),
        ),
        max_size=6,
    ),
    st.integers(0, 2**32 - 1),
    st.sampled_from([0.0, 0.05, 0.1]),
)
def test_points_in_boxes_is_each_boxs_own_test(boxes, seed, grow) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    xyz = rng.uniform(-25, 25, size=(3000, 3)).astype(np.float32)
    xyz[:, 2] = rng.uniform(-2, 2, size=3000)
    chosen = [Box((x, y, 0.0), (length, width, 1.5), yaw) for x, y, length, width, yaw in boxes]
    # Points exactly on corners and faces, where a bounding-circle prefilter could cut.
    corners = [c for box in chosen for c in box.grown(grow).corners_bev()]
    if corners:
        xyz[: len(corners), :2] = np.array(corners, dtype=np.float32)
        xyz[: len(corners), 2] = 0.0
    found = points_in_boxes(xyz, chosen, grow=grow)
    for box, rows in zip(chosen, found, strict=True):
        assert np.array_equal(rows, np.flatnonzero(box.grown(grow).contains(xyz)))
    assert points_in_boxes(xyz, []) == []
    assert [len(r) for r in points_in_boxes(np.empty((0, 3)), chosen)] == [0] * len(chosen)
