"""The whole-scene variant: no false alarms under the ROI scope, real faults still shown.

A detector that reports obstacles over the whole sweep (as learned detectors and most
clustering stacks do) sees noise added outside the ROI change obstacles *outside* it.
With the relations' default ROI scope those changes are information, never violations;
with ``scope="all"`` MR1 fails, as it did before scopes existed.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

import conftest
from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.campaign import run_campaign
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.followups.perturb import NoiseOutsideROI
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.judging.scope import DEFAULT_SCOPE, footprint_overlap
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, unmatched_twins
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.ground import GroundParams, ground_heights
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception
from pytest_metamorphic.relations.lidar import (
    lidar_relations,
    mr1_subset,
    outside_noise_invariance,
)
from pytest_metamorphic.strategies import frames

KITTI = conftest.SHARED_DATA / "kitti_openpcdet" / "training"
needs_kitti = pytest.mark.skipif(not KITTI.is_dir(), reason=f"shared test data not found: {KITTI}")
WHOLE = WholeScenePerception()
LIDAR = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example]
# Derandomized: a whole-scene detector has rare *real* edge cases (see
# test_the_only_changes_in_the_roi_are_at_its_edge); a fixed search, 8 sources x 2
# follow-ups x 11 relations, where only such an edge case may fail (_only_at_the_roi_edge).
SEARCH = settings(
    max_examples=8, database=None, deadline=None, derandomize=True, suppress_health_check=LIDAR
)


@functools.cache
def catalog() -> FrameCatalog:
    return FrameCatalog(conftest.shared_data_path(str(KITTI)), roi=kitti_label_region())


def test_it_reports_obstacles_outside_the_roi_and_the_reference_does_not() -> None:
    frame = catalog().load(1)
    whole = WHOLE(frame)
    overlap = footprint_overlap(whole, frame.roi)
    assert (overlap == 0).sum() > 10  # most of a KITTI sweep lies outside the camera wedge
    reference = ReferencePerception()(frame)
    assert (footprint_overlap(reference, frame.roi) > 0).all()


def _only_at_the_roi_edge(search: Callable[[], None]) -> None:
    """Run ``search``; a violation passes only as the documented edge case: a noise
    relation, every changed judged obstacle within one raster cell of the ROI's edge (see
    test_the_only_changes_in_the_roi_are_at_its_edge). The search is derandomized, but
    which cases Hypothesis explores still varied between runs (a pytest-xdist run found
    the 7 cm case that a run alone did not)."""
    try:
        search()
    except BaseException as error:  # a violation, or a group of them
        errors = list(getattr(error, "exceptions", [error]))  # an exception group's parts
        for violation in errors:
            if not isinstance(violation, MetamorphicViolation) or not violation.relation.startswith(
                ("MR1", "noise outside ROI")
            ):
                raise
            frame = violation.record.source
            lost, new = unmatched_twins(violation.source_output, violation.followup_output)
            changed = [violation.source_output[i] for i in lost]
            changed += [violation.followup_output[j] for j in new]
            judged = DEFAULT_SCOPE.select(changed, frame)
            edges = [float(frame.roi.boundary_distance(b.corners_bev()).min()) for b in judged]
            assert edges and max(edges) < frame.roi.cell_size, str(violation)


@needs_kitti
def test_whole_scene_satisfies_every_relation_on_kitti_sweeps() -> None:
    @SEARCH
    @metamorphic(
        source=st.deferred(lambda: frames(str(KITTI), roi=kitti_label_region(), labels=False)),
        relations=lidar_relations(),
        followups=2,
    )
    def search(frame: Frame) -> list[Box]:
        return WHOLE(frame)

    _only_at_the_roi_edge(search)


@pytest.mark.slow  # 46 s; the KITTI search above is the default suite's
def test_whole_scene_satisfies_every_relation_on_rendered_streets() -> None:
    @SEARCH
    @metamorphic(source=mst.scene_frames(), relations=lidar_relations(), followups=2)
    def search(frame: Frame) -> list[Box]:
        return WHOLE(frame)

    _only_at_the_roi_edge(search)


@needs_kitti
def test_mr1_campaign_on_kitti_has_no_false_alarms_and_counts_changes_outside() -> None:
    # 6 sweeps x 3 sizes x 10 follow-ups = 180 pairs, numpy-seeded: the same on every run.
    scoped = run_campaign(mr1_campaign(WHOLE, name="w", frames=catalog(), followups=10))
    assert sum(c.pairs for c in scoped.sizes.values()) == 180
    assert all(c.crashes == 0 for c in scoped.sizes.values())
    # No false alarm; at most a rare real edge case (see the edge test below): an on-road
    # obstacle whose footprint touches the ROI's edge.
    assert sum(c.violations for c in scoped.sizes.values()) <= 2
    for example in scoped.examples:
        footprints = re.findall(r"footprint ([0-9.]+) m from it", example["explanation"])
        assert footprints and all(float(v) < 0.25 for v in footprints), example
    # The noise did change obstacles outside the ROI: counted, not judged.
    assert scoped.sizes[1000].unjudged_changes > 20
    unscoped = run_campaign(
        mr1_campaign(WHOLE, name="w", frames=catalog(), followups=3, sizes=(1000,), scope="all")
    )
    assert unscoped.sizes[1000].violations > 6  # of 18 pairs: the paper did not mean these


@needs_kitti
def test_the_only_changes_in_the_roi_are_at_its_edge(capsys) -> None:
    # 6 sweeps x 20 numpy-seeded noise follow-ups of 1000 points, checked with the strict
    # equality relation. A judged obstacle may still change when its footprint touches the
    # ROI's edge: the off-road points beside it, whose ground the noise moved, join or leave
    # its cluster. Off-road noise changing an on-road obstacle is what MR1 exists to catch
    # (not a false alarm); every such case must be at the edge, within one raster cell.
    relation = outside_noise_invariance().relation
    seen = []
    for index in range(6):
        frame = catalog().load(index)
        source_output = WHOLE(frame)
        for seed in range(20):
            noise = NoiseOutsideROI.sample(frame, 1000, rng=np.random.default_rng([index, seed]))
            followup = noise.apply(frame)
            output = WHOLE(followup)
            verdict = relation.check(source_output, output, CheckContext(frame, followup))
            if verdict.holds:
                continue
            changed = [source_output[i] for i in verdict.details["changed_source"]]
            changed += [output[j] for j in verdict.details["changed_followup"]]
            for box in changed:
                edge = float(frame.roi.boundary_distance(box.corners_bev()).min())
                seen.append((index, seed, box.describe(), round(edge, 3)))
    with capsys.disabled():
        print(f"\nedge cases in 120 follow-ups: {seen}")
    assert len({(index, seed) for index, seed, _, _ in seen}) <= 3
    assert all(edge < frame.roi.cell_size for *_, edge in seen), seen


def test_mr1_campaign_on_rendered_streets_has_no_false_alarms() -> None:
    result = run_campaign(mr1_campaign(WHOLE, name="w", sources=12, sizes=(100, 1000)))
    assert all(c.violations == 0 and c.pairs == 12 for c in result.sizes.values())


@needs_kitti
def test_mr1_with_scope_all_reports_the_outside_obstacle_the_paper_did_not_mean() -> None:
    frame = catalog().load(4)
    source_output = WHOLE(frame)
    scoped, unscoped = mr1_subset(), mr1_subset(scope="all")
    for seed in range(20):
        noise = NoiseOutsideROI.sample(frame, 1000, rng=np.random.default_rng(seed))
        followup = noise.apply(frame)
        output = WHOLE(followup)
        context = CheckContext(frame, followup, noise.params(), 0)
        verdict = unscoped.relation.check(source_output, output, context)
        if not verdict.holds:
            break
    else:
        pytest.fail("noise never changed an obstacle of the whole-scene detector")
    lost = [source_output[i] for i in verdict.details["unmatched"]]
    assert (footprint_overlap(lost, frame.roi) < DEFAULT_SCOPE.min_overlap).all()
    judged = scoped.relation.check(source_output, output, context)
    assert judged.holds
    assert judged.details["unjudged_changes"] >= len(lost)
    assert "outside the judged region" in judged.explanation


@needs_kitti
def test_a_fragile_ground_estimate_is_a_real_violation_at_the_roi_edge() -> None:
    # With one ground model across the ROI's edge, a stray low noise point up to 3 m
    # outside the ROI lifts the road inside it into an obstacle: off-road noise changes
    # on-road obstacles, which MR1 exists to catch, whatever the scope. Every such
    # violation is near the ROI's edge, within the ground window's reach.
    fragile = WholeScenePerception(split_ground=False)
    result = run_campaign(
        mr1_campaign(fragile, name="f", frames=catalog(), followups=10, sizes=(1000,))
    )
    assert result.sizes[1000].violations > 0
    for example in result.examples:
        for where in example.get("explanation", "").split("(")[1:]:
            if "the ROI's edge" in where:
                distance = float(where.split(" m ")[0])
                assert distance < 5.0, example["explanation"]


def test_rank_two_ground_ignores_one_stray_return_per_cell() -> None:
    road = np.array([[x + 0.5, y + 0.5, -1.7, 0] for x in range(5) for y in range(5)] * 3)
    road[:, 2] += np.arange(len(road)) * 1e-3  # distinct heights
    stray = np.array([[2.5, 2.5, -3.0, 0.0]])
    params = GroundParams(rank=2, window=3)
    before = ground_heights(road.astype(np.float32), params)
    after = ground_heights(np.concatenate([road, stray]).astype(np.float32), params)
    plain = ground_heights(np.concatenate([road, stray]).astype(np.float32), GroundParams(window=3))
    assert plain.min() == pytest.approx(-3.0)  # rank 1 follows the stray point
    # Rank 2 moves by at most the gap between the cell's two lowest real returns (25 mm).
    assert after.min() > -1.75 and np.abs(after[: len(road)] - before).max() <= 0.026
    # Repeats are one height: a point sent twice cannot become its cell's second lowest.
    twice = np.concatenate([road, stray, stray]).astype(np.float32)
    assert np.array_equal(ground_heights(twice, params), [*after.tolist(), after[-1]])


def test_rank_must_be_a_positive_int() -> None:
    from pytest_metamorphic import InvalidArgument

    for bad in (0, 1.5, True):
        with pytest.raises(InvalidArgument, match="rank="):
            GroundParams(rank=bad)  # type: ignore[arg-type]
