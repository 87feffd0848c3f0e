"""The component relations: what each follows up with, and what it judges."""

from __future__ import annotations

import functools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

import conftest
from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.judging.points import PointsKeepLabels
from pytest_metamorphic.lidar.judging.relative import RelativeScore, truth_score
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import Partition, PointLabels
from pytest_metamorphic.lidar.systems.components import ReferenceClusters, ReferenceGround
from pytest_metamorphic.relations.lidar.components import (
    component_relations,
    noise_locality,
    relative_relations,
    reordered_returns,
)
from tests.core.lidar_cases import labelled_kitti
from tests.core.lidar_cases import street as render_street

ROOT = Path(__file__).resolve().parent.parent.parent
street = functools.cache(render_street)
FAST = settings(
    max_examples=3, deadline=None, database=None, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)  # fmt: skip


def test_the_set_depends_on_what_the_component_claims() -> None:
    names = [r.name for r in component_relations("labels")]
    assert names == [
        "points reordered => every return keeps its label",
        "points repeated => every return keeps its label",
        "noise outside ROI => returns beyond 2 m keep their label",
        "an object removed => returns beyond 2 m keep their label",
        "the same sweep after others => every return keeps its label",
    ]
    symmetric = component_relations("clusters", symmetric=True, history=False, radius=6.0)
    assert [r.name for r in symmetric][-2:] == [
        "cloud turned => every return keeps its cluster",
        "cloud mirrored => every return keeps its cluster",
    ]
    assert all(isinstance(r.relation, PointsKeepLabels) for r in symmetric)
    assert symmetric[2].relation.radius == 6.0 and symmetric[-1].relation.boundary_margin == 0.5


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: reordered_returns("boxes"), "kind='boxes' must be 'labels'"),
        (lambda: noise_locality("labels", n=0), "n=0 must be a positive int"),
        (lambda: noise_locality("labels", radius=-1.0), "radius=-1.0 must be a finite number"),
        (lambda: component_relations("labels", border=0.5), "border= applies to partitions"),
    ],
)
def test_bad_arguments_fail_when_the_relation_is_made(make, message) -> None:
    with pytest.raises(InvalidArgument, match=message):
        make()


@FAST
@metamorphic(source=st.builds(street), relations=component_relations("clusters", symmetric=True))
def test_the_reference_segmentation_keeps_every_return_on_a_rendered_street(
    frame: Frame,
) -> Partition:
    # Grid cells anchored at the sensor, ground found among the ROI's returns only: the
    # rendered street has no return on a cell border, so even turns keep every cluster.
    return ReferenceClusters(ground=ReferenceGround(), within_roi=True)(frame)


def test_a_component_that_labels_by_position_fails_reordering() -> None:
    @settings(FAST, phases=[Phase.generate])
    @metamorphic(source=st.builds(street), relations=[reordered_returns("labels")])
    def check(frame: Frame) -> PointLabels:
        return PointLabels(np.arange(len(frame.cloud)) % 2)

    with pytest.raises(MetamorphicViolation, match=r"judged returns changed: \d+ "):
        check()


def test_a_component_that_returns_boxes_is_told_what_is_wrong() -> None:
    @FAST
    @metamorphic(source=st.builds(street), relations=[reordered_returns("labels")])
    def check(frame: Frame) -> list[int]:
        return []

    with pytest.raises(InvalidArgument, match="has 0 entries but its input cloud has"):
        check()


@pytest.mark.parametrize(
    ("script", "args", "error"),
    [
        ("sklearn_hdbscan_row_order.py", (), "AssertionError"),
        (
            "sklearn_hdbscan_epsilon_crash.py",
            ("velodyne/000001.bin",),
            "TypeError: only 0-dimensional",
        ),
    ],
)
def test_the_findings_reproducers_still_reproduce(
    script: str, args: tuple[str, ...], error: str
) -> None:
    # Each runs with scikit-learn and numpy alone; once upstream fixes a defect, its script
    # exits 0 and this test says so: then update docs/findings.
    pytest.importorskip("sklearn")
    paths = [
        str(conftest.shared_data_path("kitti_openpcdet", "training", *arg.split("/")))
        for arg in args
    ]
    result = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "findings" / script), *paths],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode != 0, (
        f"{script} no longer reproduces: update docs/findings\n{result.stdout}"
    )
    assert error in result.stderr, result.stderr


def test_the_relative_score_judges_a_component_against_the_labels_on_both_sides() -> None:
    # semLidarFuzz's metric on a labelled KITTI sweep: the reference ground stage calls
    # three quarters of the labelled objects' returns not ground (their lowest are ground).
    frame = labelled_kitti(1)
    score, objects = truth_score(frame, ReferenceGround()(frame), "labels")
    assert objects >= 2 and 0.7 < score <= 1.0
    names = [r.name for r in relative_relations("labels", symmetric=True)]
    assert names[0] == "points reordered => score falls by at most 0.05" and len(names) == 6
    with pytest.raises(InvalidArgument, match=r"tolerance=1\.5 must be a number in"):
        RelativeScore("labels", tolerance=1.5)
    empty = frame.with_cloud(frame.cloud[:0])
    verdict = RelativeScore("labels").check(
        PointLabels([]), PointLabels([]), CheckContext(empty, empty)
    )
    assert verdict.holds and verdict.details["judged_nothing"]
    # Every object called ground after the follow-up: the score falls from ~1 to 0.
    everything_ground = PointLabels(np.ones(len(frame.cloud), dtype=int))
    verdict = RelativeScore("labels").check(
        ReferenceGround()(frame), everything_ground, CheckContext(frame, frame)
    )
    assert not verdict.holds and "score 0.000 after the follow-up" in verdict.explanation


@FAST
@metamorphic(
    source=st.just(1).map(labelled_kitti),
    relations=relative_relations("labels", symmetric=True),
)
def test_the_reference_ground_stage_keeps_its_score_on_a_labelled_sweep(
    frame: Frame,
) -> PointLabels:
    return ReferenceGround()(frame)
