"""Testing the components a stack is built from: ground segmenters and clusterers from PyPI.

What an engineer prototyping with Patchwork++, scikit-learn and Open3D copies: each
component wrapped as a system under test
(:mod:`pytest_metamorphic.lidar.systems.components`), judged point by point by the
component relations (:mod:`pytest_metamorphic.relations.lidar.components`) on a KITTI
sweep (HDL-64E) and the Velodyne VLP-16 and VLP-32C recordings of Autoware's nebula driver.

Each component gets the relations it claims (``docs/findings/README.md`` says which, and
why the others are not faults): DBSCAN is local, symmetric and per-sweep, but counts a
repeated return twice; Patchwork++ made afresh for each sweep is order-free and per-sweep; the
reference pipeline's ground stage is local within its 7 m window. The last tests show what
the relations find: scikit-learn's HDBSCAN clusters the same returns differently in another
order (a defect, ``docs/findings/sklearn-hdbscan-row-order.md``), and DBSCAN turns a noise
return into a cluster when it is recorded twice.

Needs ``pip install '.[components]'`` (scikit-learn, pypatchworkpp; Open3D's tests also
need ``open3d``); each test says what it skips for.
"""

from __future__ import annotations

import functools
from typing import Any

import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

import conftest
from pytest_metamorphic import InvalidArgument, MetamorphicViolation, metamorphic
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import Partition, PointLabels
from pytest_metamorphic.lidar.roi import corridor_roi
from pytest_metamorphic.lidar.systems.components import (
    Open3DClusters,
    PatchworkGround,
    ReferenceGround,
    SklearnClusters,
)
from pytest_metamorphic.relations.lidar.components import (
    component_relations,
    noise_locality,
    removal_locality,
    reordered_returns,
    repeated_returns,
    repeated_sweep,
)

sklearn_cluster = pytest.importorskip(
    "sklearn.cluster", reason="scikit-learn is not installed: pip install '.[components]'"
)

DATA = conftest.SHARED_DATA
KITTI = DATA / "kitti_openpcdet" / "training"
VLP16 = DATA / "nebula_velodyne" / "vlp16" / "1673400472138016708.pcd"
VLP32 = DATA / "nebula_velodyne" / "vlp32" / "1713492677464078412.pcd"
needs_data = pytest.mark.skipif(
    not (KITTI.is_dir() and VLP16.exists() and VLP32.exists()),
    reason=f"the KITTI sweeps or the nebula recordings are not in {DATA}",
)
LIDAR = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example]
# Derandomized: every test here asserts what the relations find (or that they find nothing)
# on these recordings, so it must not depend on the seed.
QUICK = settings(
    max_examples=2, deadline=None, database=None, derandomize=True, suppress_health_check=LIDAR
)
EPS = 0.5  # DBSCAN's radius, metres; a border point within it of two clusters may go to either


@functools.cache
def recordings() -> tuple[Frame, ...]:
    """KITTI 000001 with the camera wedge as ROI; one sweep of each nebula recording with
    the 7 m corridor ahead as ROI."""
    corridor = corridor_roi(width=7.0)
    return (
        FrameCatalog(str(KITTI), roi=kitti_label_region())[1],
        FrameCatalog(str(VLP16), roi=corridor)[0],
        FrameCatalog(str(VLP32), roi=corridor)[0],
    )


def frames() -> st.SearchStrategy[Frame]:
    return st.integers(0, 2).map(lambda i: recordings()[i])


# -- what a stack feeds its clusterer: the ROI's returns that are not ground -------------

GROUND = ReferenceGround()
DBSCAN = SklearnClusters(
    sklearn_cluster.DBSCAN(eps=EPS, min_samples=5), ground=GROUND, within_roi=True
)

# DBSCAN is order-free except for border points, local within eps (the ROI feed ignores
# the noise outright), symmetric and per-sweep. It counts a repeated return twice, so
# repeats are not in its relations (see test_dbscan_counts_a_repeated_return_twice).
DBSCAN_RELATIONS = [
    relation
    for relation in component_relations("clusters", border=EPS, symmetric=True)
    if not relation.name.startswith("points repeated")
]


@needs_data
@QUICK
@metamorphic(source=frames(), relations=DBSCAN_RELATIONS, followups=1)
def test_dbscan_keeps_every_return_in_its_cluster(frame: Frame) -> Partition:
    return DBSCAN(frame)


@needs_data
@QUICK
@metamorphic(source=frames(), relations=DBSCAN_RELATIONS, followups=1)
def test_open3d_dbscan_keeps_every_return_in_its_cluster(frame: Frame) -> Partition:
    try:
        clusters = Open3DClusters(eps=EPS, min_points=5, ground=GROUND, within_roi=True)
    except InvalidArgument as error:  # open3d absent, or installed without its libraries
        if "needs open3d" not in str(error):
            raise
        pytest.skip(str(error))
    return clusters(frame)


@needs_data
@QUICK
@metamorphic(
    source=frames(),
    relations=[
        reordered_returns("labels"),
        repeated_returns("labels"),
        noise_locality("labels", radius=6.0),
        removal_locality("labels", radius=6.0),
        repeated_sweep("labels"),
    ],
    followups=1,
)
def test_the_reference_ground_stage_is_local_within_its_window(frame: Frame) -> PointLabels:
    # The local ground is the lowest return of a 7 x 7 window of 1 m cells: a return's label
    # depends on returns up to 5.7 m away, so locality is claimed beyond 6 m.
    return GROUND(frame)


@needs_data
@QUICK
@metamorphic(
    source=st.sampled_from([0, 2]).map(lambda i: recordings()[i]),
    relations=[reordered_returns("labels"), repeated_sweep("labels")],
    followups=1,
)
def test_patchwork_made_afresh_is_a_per_sweep_component(frame: Frame) -> PointLabels:
    pytest.importorskip(
        "pypatchworkpp", reason="pypatchworkpp is not installed: pip install pypatchworkpp"
    )
    return patchwork()(frame)


@functools.cache
def patchwork() -> PatchworkGround:
    """One fresh-per-sweep Patchwork++ (its defaults: KITTI's HDL-64E, 1.723 m up)."""
    return PatchworkGround()


# -- what the relations find ---------------------------------------------------------------


def _violation(
    system: Any, relation: Any, *, source: st.SearchStrategy[Frame] | None = None
) -> str:
    @settings(
        max_examples=2,
        deadline=None,
        database=None,
        derandomize=True,
        phases=[Phase.explicit, Phase.generate, Phase.shrink],
        suppress_health_check=LIDAR,
    )
    @metamorphic(source=source or frames(), relations=[relation], followups=1)
    def check(frame: Frame) -> Any:
        return system(frame)

    with pytest.raises(MetamorphicViolation) as failure:
        check()
    return str(failure.value)


@needs_data
def test_hdbscan_clusters_the_same_returns_differently_in_another_order() -> None:
    hdbscan = SklearnClusters(
        sklearn_cluster.HDBSCAN(min_cluster_size=10, copy=True), ground=GROUND, within_roi=True
    )
    message = _violation(hdbscan, reordered_returns("clusters"))
    assert "points reordered => every return keeps its cluster" in message
    assert "cluster -> noise" in message or "joined another cluster" in message


@pytest.mark.slow
@needs_data
def test_dbscan_counts_a_repeated_return_twice() -> None:
    # One return recorded twice reaches min_samples and becomes a core point: noise turns
    # into a cluster. The reduction finds the one return that matters.
    message = _violation(DBSCAN, repeated_returns("clusters", border=EPS))
    assert "noise -> a cluster" in message
    assert "minimal follow-up: 1 of" in message
