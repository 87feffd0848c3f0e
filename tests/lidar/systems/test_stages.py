"""Stage blame: the first stage of a pipeline that answers differently where a violation is."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.followups.perturb import PermutePoints
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import PointLabels
from pytest_metamorphic.lidar.systems.components import ReferenceClusters, ReferenceGround
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.lidar.systems.perception.trace import reference_stages
from pytest_metamorphic.lidar.systems.stages import (
    BlamedRelation,
    Stage,
    StagedPipeline,
    blame,
)
from pytest_metamorphic.relations.lidar import mr1_subset
from pytest_metamorphic.relations.lidar.blame import with_stage_blame
from tests.core.lidar_cases import MR1, failing_noise, kitti, street


def test_the_reference_pipelines_trace_ends_in_its_output() -> None:
    frame = kitti(1)
    trace = reference_stages().trace(frame)
    assert [stage.name for stage in trace] == [
        "input", "roi filter", "ground removal", "segmentation", "objects", "output",
    ]  # fmt: skip
    assert trace[-1].value == ReferencePerception()(frame)
    passed = [int(np.count_nonzero(stage.value)) for stage in trace[:3]]
    assert passed[0] == len(frame.cloud) and passed[0] > passed[1] > passed[2] > 0


@pytest.mark.parametrize(
    ("name", "frame", "n", "stage"),
    [
        ("full_cloud_ground", "kitti", 1000, "ground removal"),
        ("count_scaled_radius", "kitti", 1000, "segmentation"),
        ("grid_anchored_at_sweep", "kitti", 1000, "segmentation"),
    ],
)
def test_mr1_violations_are_blamed_on_the_stage_each_mutant_changes(name, frame, n, stage) -> None:
    system = mutant(name)
    source = kitti(1)
    noise, _, _ = failing_noise(system, source, n)
    found = blame(reference_stages(system), source, noise.apply(source), noise.params())
    assert found.stage == stage, found.describe()
    assert found.describe().startswith(f"stage blame: {stage} (the first stage that differs: ")


def test_an_order_dependent_voxel_filter_is_blamed_on_the_input_stage() -> None:
    system = mutant("order_dependent_voxels")
    source = kitti(1)
    for seed in range(20):
        reorder = PermutePoints(seed)
        followup = reorder.apply(source)
        if system(followup) != system(source):
            break
    found = blame(reference_stages(system), source, followup, reorder.params())
    assert found.stage == "input" and found.agreed == []


def test_a_relation_with_stage_blame_names_the_stage_in_the_failure() -> None:
    system = mutant("count_scaled_radius")
    (relation,) = with_stage_blame([mr1_subset(n=1000)], reference_stages(system))
    assert isinstance(relation.relation, BlamedRelation)

    @settings(max_examples=4, deadline=None, database=None, derandomize=True,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))  # fmt: skip
    @metamorphic(source=st.just(1).map(kitti), relations=[relation], followups=2)
    def check(frame: Frame):
        return system(frame)

    with pytest.raises(MetamorphicViolation, match=r"stage blame: segmentation \(") as failure:
        check()
    assert failure.value.verdict.details["stage_blame"] == "segmentation"


def test_a_pipeline_of_your_own_components_in_a_few_lines() -> None:
    ground = ReferenceGround()
    clusters = ReferenceClusters(ground=ground, within_roi=True)
    detector = ReferencePerception()
    stack = StagedPipeline([("ground", ground), ("clusters", clusters), ("boxes", detector)])
    frame = street()
    trace = stack.trace(frame)
    assert [(s.name, s.kind) for s in trace] == [
        ("ground", "labels"), ("clusters", "clusters"), ("boxes", "boxes"),
    ]  # fmt: skip
    reorder = PermutePoints(0)
    found = blame(stack, frame, reorder.apply(frame), reorder.params())
    assert found.stage is None and found.agreed == ["ground", "clusters", "boxes"]
    # A relation that holds is left alone.
    verdict = BlamedRelation(MR1.relation, stack).check(
        detector(frame), detector(frame), CheckContext(frame, frame)
    )
    assert verdict.holds and "stage_blame" not in verdict.details


@pytest.mark.parametrize(
    ("stages", "message"),
    [
        ([], "at least one stage"),
        ([("a", len), ("a", len)], "stage names must differ"),
        ([Stage("a", 3)], "is not callable"),  # type: ignore[arg-type]
    ],
)
def test_bad_pipelines_are_refused(stages, message) -> None:
    with pytest.raises(InvalidArgument, match=message):
        StagedPipeline(stages)


def test_a_stage_that_returns_something_else_is_named() -> None:
    frame = street()
    with pytest.raises(InvalidArgument, match="stage 'odd' returned str"):
        StagedPipeline([("odd", lambda f: "x")]).trace(frame)
    with pytest.raises(InvalidArgument, match="stage 'short' returned 2 entries for a sweep of"):
        StagedPipeline([("short", lambda f: PointLabels([0, 1]))]).trace(frame)
    with pytest.raises(InvalidArgument, match="has no trace"):
        blame(object(), frame, frame)


def test_a_mirror_is_blamed_past_the_roi_filter_which_is_rasterised_afresh() -> None:
    # Boxes reported in a frame turned 2 degrees: the mirror shows it. The mirrored ROI's
    # bitmap passes other returns at its edge; those are not compared.
    from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX

    system = mutant("turned_output_frame")
    source = kitti(1)
    mirror = MirrorAcrossX()
    found = blame(reference_stages(system), source, mirror.apply(source), mirror.params())
    assert found.stage == "objects", found.describe()
    assert found.agreed == ["input", "roi filter", "ground removal", "segmentation"]
