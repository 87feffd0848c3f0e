"""The public API as a user's test module uses it, checked by mypy (``tests/test_typing.py``).

Never run or collected (its name does not start with ``test_``): it exists to be type
checked. Each ``assert_type`` pins what a user's checker infers; each ``# type: ignore[...]``
marks a misuse the annotations must reject (``warn_unused_ignores`` turns an ignore that is
no longer needed, i.e. a misuse that now type-checks, into an error).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray
from typing_extensions import assert_type

from pytest_metamorphic import (
    MetamorphicRelation,
    MetamorphicViolation,
    Relation,
    Verdict,
    __version__,
    metamorphic,
    relations,
)
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.campaign import (
    Campaign,
    CampaignResult,
    campaign_test,
    run_campaign,
)
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.followups.faults import DropRings
from pytest_metamorphic.lidar.io import read_cloud
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.judging.tolerance import LEARNED, Tolerance
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation
from pytest_metamorphic.lidar.systems.process import ProcessDetector
from pytest_metamorphic.relations.lidar import lidar_relations, mr1_subset

assert_type(__version__, str)


# -- @metamorphic on a plain function --------------------------------------------------
@metamorphic(
    source=st.lists(st.integers()),
    followup=lambda xs: st.permutations(xs),
    relation=relations.equal(),
    followups=3,
)
def test_sort_is_order_invariant(xs: list[int]) -> list[int]:
    return sorted(xs)


assert_type(test_sort_is_order_invariant, Callable[..., None])


def my_stack(points: NDArray[np.float32], roi: ROI | None) -> list[Box]:
    return [Box((10.0, 0.0, -1.0), (4.0, 1.8, 1.5), 0.0, "car")]


# -- LiDAR relations on rendered scenes and on real sweeps -------------------------------
@metamorphic(source=mst.scene_frames(), relations=[mr1_subset(n=1000)])
def test_my_stack_on_synthetic_streets(frame: Frame) -> list[Box]:
    return my_stack(frame.cloud.points, frame.roi)


@metamorphic(
    source=mst.frames("data/kitti/training", roi=kitti_label_region()),
    relations=lidar_relations(tolerance="learned"),
)
def test_my_stack_on_kitti(frame: Frame) -> list[Box]:
    return my_stack(frame.cloud.points, frame.roi)


@metamorphic(source=mst.scene_frames(), relations=lidar_relations(), batch=8)
def test_batched(frames: list[Frame]) -> list[list[Box]]:
    return [my_stack(frame.cloud.points, frame.roi) for frame in frames]


library: list[MetamorphicRelation] = lidar_relations(tolerance=LEARNED)
assert isinstance(LEARNED, Tolerance)


# -- A user relation ------------------------------------------------------------------------
def same_length(source: Sequence[Any], followup: Sequence[Any], context: Any) -> Verdict:
    return Verdict(len(source) == len(followup), "lengths differ")


user_relation: Relation = relations.predicate(same_length)
combined: Relation = relations.equal() & user_relation

# -- Boxes ------------------------------------------------------------------------------
box = Box((10.0, 2.0, -0.9), (4.2, 1.8, 1.5), 0.3, "car")
assert_type(box.center, tuple[float, float, float])
assert_type(box.size, tuple[float, float, float])
assert_type(box.yaw, float)
assert_type(box.points, int | None)
moved: Box = box.rotated(0.5)
Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.0, "truck")  # type: ignore[arg-type]

# -- Clouds and files -------------------------------------------------------------------
cloud = read_cloud(Path("sweep.pcd"))
assert_type(cloud, PointCloud)
assert_type(cloud.xyz, NDArray[np.float32])
read_cloud(Path("sweep.pcd"), nonfinite="ignore")  # type: ignore[arg-type]

# -- Systems from outside ----------------------------------------------------------------
detector = ProcessDetector(["./my_detector", "{input}", "{output}"], timeout=30)
boxes_from_process: Sequence[Box] = detector(Frame(cloud))
ProcessDetector(["./d"], input_format="ply")  # type: ignore[arg-type]
learned = CNNSegmentation(full_cloud=True)
reference = ReferencePerception()

# -- Campaigns ----------------------------------------------------------------------------
catalog = FrameCatalog("data/kitti/training", roi=kitti_label_region())
campaign = mr1_campaign(reference, name="MR1 reference", frames=catalog, sources=50)
assert_type(campaign, Campaign)
result = run_campaign(campaign, log="mt-campaigns/mr1", timeout=30.0)
assert_type(result, CampaignResult)
violations: int = sum(counts.violations for counts in result.sizes.values())
test_mr1_campaign = campaign_test(campaign, shards=4)
run_campaign(campaign, shards="4")  # type: ignore[arg-type]

# -- Violations ------------------------------------------------------------------------------
try:
    test_my_stack_on_synthetic_streets()
except MetamorphicViolation as error:
    followup_input: Any = error.followup
    source_output: Any = error.source_output
    relation_name: str = error.relation
    assert_type(error.verdict, Verdict | None)
    if error.verdict is not None:
        explanation: str = error.verdict.explanation
        facts: Mapping[str, Any] = error.verdict.details

# -- Follow-up transforms built by hand ------------------------------------------------------
dead = DropRings([0, 5])  # any sequence of ring numbers, as documented
assert_type(dead.rings, Sequence[int])
DropRings(0)  # type: ignore[arg-type]
