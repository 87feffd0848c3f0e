"""Adapters for the components stacks are built from: what they return, what they refuse."""

from __future__ import annotations

import numpy as np
import pytest

import conftest
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import GROUND, NOISE, Partition, PointLabels
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.systems.components import (
    PatchworkGround,
    ReferenceClusters,
    ReferenceGround,
    SklearnClusters,
)
from pytest_metamorphic.lidar.systems.components.clusterers import ClusterInput


def _street() -> Frame:
    """Flat ground at z = -1.7 with two 1 m posts standing on it, 10 m apart."""
    rng = np.random.default_rng(0)
    ground = np.column_stack(
        [rng.uniform(3, 30, 3000), rng.uniform(-8, 8, 3000), np.full(3000, -1.7)]
    )
    posts = [
        np.column_stack(
            [rng.normal(x, 0.1, 60), rng.normal(y, 0.1, 60), rng.uniform(-1.3, -0.7, 60)]
        )
        for x, y in ((10.0, 0.0), (10.0, 5.0))
    ]
    xyz = np.concatenate([ground, *posts]).astype(np.float32)
    cloud = PointCloud(np.column_stack([xyz, np.zeros(len(xyz), np.float32)]))
    roi = ROI.from_polygons([[(0, -6), (40, -6), (40, 6), (0, 6)]])
    return Frame(cloud, roi=roi)


def test_the_reference_ground_stage_labels_the_flat_ground_and_not_the_posts() -> None:
    labels = ReferenceGround()(_street())
    assert isinstance(labels, PointLabels) and len(labels) == 3120
    assert (labels.labels[:3000] == GROUND).mean() > 0.99
    assert not (labels.labels[3000:] == GROUND).any()


def test_a_clusterer_is_fed_the_rois_returns_that_are_not_ground() -> None:
    frame = _street()
    partition = ReferenceClusters(ground=ReferenceGround(), within_roi=True)(frame)
    assert isinstance(partition, Partition) and len(partition) == len(frame.cloud)
    assert partition.count == 2
    assert (partition.labels[:3000] == NOISE).mean() > 0.99
    assert len(set(partition.labels[3000:3060].tolist())) == 1


def test_sklearn_clusterers_are_cloned_for_every_call() -> None:
    sklearn_cluster = pytest.importorskip("sklearn.cluster")
    estimator = sklearn_cluster.DBSCAN(eps=0.5, min_samples=5)
    clusters = SklearnClusters(estimator, ground=ReferenceGround(), within_roi=True)
    first, second = clusters(_street()), clusters(_street())
    assert first == second and first.count == 2
    assert not hasattr(estimator, "labels_")  # the user's estimator is left untouched
    assert repr(clusters) == (
        "SklearnClusters(DBSCAN(), ground=ReferenceGround(), within_roi=True)"
    )


def test_the_roi_is_cut_before_the_ground_stage_sees_the_returns() -> None:
    seen: list[int] = []

    def ground(frame: Frame) -> PointLabels:
        seen.append(len(frame.cloud))
        return PointLabels(np.zeros(len(frame.cloud), dtype=int))

    frame = _street()
    ClusterInput(ground=ground, within_roi=True).mask(frame)
    inside = int(frame.roi.contains(frame.cloud.xyz[:, :2]).sum())
    assert seen == [inside] and inside < len(frame.cloud)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: SklearnClusters(object()), "has no fit_predict"),
        (lambda: ReferenceClusters(params="x"), "must be a ClusterParams"),  # type: ignore[arg-type]
        (lambda: ClusterInput(features="xz"), "features='xz' must be 'xyz' or 'xy'"),  # type: ignore[arg-type]
        (lambda: ClusterInput(ground=3), "must be a ground segmenter"),  # type: ignore[arg-type]
    ],
)
def test_bad_adapter_arguments_are_named(make, message) -> None:
    pytest.importorskip("sklearn")
    with pytest.raises(InvalidArgument, match=message):
        make()


def test_a_ground_segmenter_returning_the_wrong_length_is_named() -> None:
    feed = ClusterInput(ground=lambda frame: PointLabels([0, 1]))
    with pytest.raises(InvalidArgument, match=r"must return PointLabels for all 3120 returns"):
        feed.mask(_street())


def test_components_are_called_on_frames() -> None:
    with pytest.raises(InvalidArgument, match="ReferenceGround is called on a Frame, got ndarray"):
        ReferenceGround()(np.zeros((3, 4)))


def test_patchwork_labels_a_kitti_sweep_and_refuses_unknown_parameters() -> None:
    pytest.importorskip("pypatchworkpp", reason="pypatchworkpp is not installed")
    with pytest.raises(
        InvalidArgument, match=r"pypatchworkpp\.Parameters has no field .sensor_hight."
    ):
        PatchworkGround({"sensor_hight": 1.7})
    path = conftest.shared_data_path("kitti_openpcdet", "training")
    frame = FrameCatalog(str(path), roi=kitti_label_region())[1]
    fresh = PatchworkGround()
    first, again = fresh(frame), fresh(frame)
    assert first == again and 0.5 < (first.labels == GROUND).mean() < 0.8
    # A reused estimator labels its first sweep unlike the ones after it (its thresholds
    # adapt), then agrees with itself whatever came between.
    reused = PatchworkGround(reuse=True)
    one, two = reused(frame), reused(frame)
    reused(FrameCatalog(str(path))[0])
    three = reused(frame)
    assert one != two and two == three
    assert one.labels.tolist() == first.labels.tolist()


def test_open3d_components_label_and_cluster_the_street() -> None:
    from pytest_metamorphic.lidar.systems.components import Open3DClusters, Open3DPlaneGround

    try:
        ground = Open3DPlaneGround(distance=0.05)
    except InvalidArgument as error:  # open3d absent, or installed without its libraries
        if "needs open3d" not in str(error):
            raise
        pytest.skip(str(error))
    frame = _street()
    plane = ground(frame)
    assert (plane.labels[:3000] == GROUND).all() and not (plane.labels[3000:] == GROUND).any()
    assert Open3DPlaneGround(distance=0.05)(frame) == plane  # seeded: the same plane again
    clusters = Open3DClusters(eps=0.5, min_points=5, ground=ReferenceGround(), within_roi=True)(
        frame
    )
    assert clusters.count == 2 and len(clusters) == len(frame.cloud)
    with pytest.raises(InvalidArgument, match="ransac_n=2 must be an int"):
        Open3DPlaneGround(ransac_n=2)
