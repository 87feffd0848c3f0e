"""Testing a detector this project did not write: a clustering stack built from scikit-learn.

The detector is what many teams start from: a RANSAC ground plane
(``sklearn.linear_model.RANSACRegressor``), DBSCAN clusters of the points above it
(``sklearn.cluster.DBSCAN``) over the *whole sweep*, and an oriented box per cluster. It
reports obstacles everywhere, not only in the ROI, so these tests lean on the relations'
ROI scope: changes to obstacles off the road are counted, not judged.

Two versions of the ground fit:

* ``ground="roi"``: the plane is fitted to the points in the ROI. MR1 holds with the
  default scope (0 violations over the six KITTI sweeps); with ``scope="all"`` MR1 flags
  obstacles *outside* the ROI that noise merged with, the false alarms the scope removes.
* ``ground="sweep"``: the plane is fitted to every point, with a fixed RANSAC seed.
  RANSAC draws its samples by position in the array, so ten points added far off the
  road change the plane and obstacles *in* the ROI: a real MR1 violation (the same kind
  of fault as Apollo's ``use_full_cloud``), which the test shows.

Needs ``pip install '.[sklearn]'`` (included in ``[all]`` and ``[dev]``); the tests are
skipped, saying so, without it, and without the KITTI sweeps in ``../shared/data``.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

import conftest
from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.campaign import campaign_test
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.campaign import fault_campaign, mr1_campaign, symmetry_campaign
from pytest_metamorphic.lidar.followups.faults import DropRings
from pytest_metamorphic.lidar.followups.insert import (
    InsertObject,
    free_placements,
    object_templates,
)
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, Label
from pytest_metamorphic.relations.lidar import (
    beam_loss,
    lidar_relations,
    mr1_subset,
    object_insertion,
)

sklearn = pytest.importorskip(
    "sklearn", reason="scikit-learn is not installed: pip install '.[sklearn]'"
)
from sklearn.cluster import DBSCAN  # noqa: E402
from sklearn.linear_model import RANSACRegressor  # noqa: E402

KITTI = conftest.SHARED_DATA / "kitti_openpcdet" / "training"
needs_kitti = pytest.mark.skipif(not KITTI.is_dir(), reason=f"shared test data not found: {KITTI}")
LIDAR = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example]


class SklearnDetector:
    """RANSAC ground plane + DBSCAN clusters + PCA-oriented boxes, over the whole sweep."""

    def __init__(self, *, ground: Literal["roi", "sweep"] = "roi", max_range: float = 40.0):
        self.ground = ground
        self.max_range = max_range

    def __repr__(self) -> str:
        return f"SklearnDetector(ground={self.ground!r})"

    def __call__(self, frame: Frame) -> list[Box]:
        # Sorted unique points (1 cm): the result cannot depend on order or repeats.
        xyz = np.unique(np.round(frame.cloud.points[:, :3].astype(np.float64), 2), axis=0)
        xyz = xyz[np.hypot(xyz[:, 0], xyz[:, 1]) < self.max_range]
        fit = xyz[frame.roi.contains(xyz[:, :2])] if self.ground == "roi" else xyz
        plane = RANSACRegressor(residual_threshold=0.2, max_trials=50, random_state=0)
        plane.fit(fit[:, :2], fit[:, 2])
        height = xyz[:, 2] - plane.predict(xyz[:, :2])
        above = xyz[(height > 0.25) & (height < 3.0)]
        above = np.unique(np.round(above / 0.1) * 0.1, axis=0)  # 10 cm voxels
        if len(above) == 0:
            return []
        clusters = DBSCAN(eps=0.45, min_samples=4).fit_predict(above[:, :2])
        boxes = [_box(above[clusters == k]) for k in range(clusters.max() + 1)]
        return sorted(boxes, key=lambda box: box.center)


def _box(points: Any) -> Box:
    xy = points[:, :2]
    centre = xy.mean(axis=0)
    axis = np.linalg.eigh(np.cov((xy - centre).T))[1][:, -1] if len(xy) > 2 else (1.0, 0.0)
    yaw = float(np.arctan2(axis[1], axis[0]))
    turn = np.array([[np.cos(yaw), np.sin(yaw)], [-np.sin(yaw), np.cos(yaw)]])
    local = (xy - centre) @ turn.T
    low, high = local.min(axis=0), local.max(axis=0)
    middle = centre + ((low + high) / 2) @ turn
    length, width = (max(float(v), 0.1) for v in high - low)
    bottom, top = float(points[:, 2].min()), float(points[:, 2].max())
    height = max(top - bottom, 0.1)
    label: Label
    if 2.5 < length < 6 and 1.2 < width < 2.5:
        label = "car"
    elif length < 1.2 and width < 1.2 and 1.0 < height < 2.1:
        label = "pedestrian"
    else:
        label = "unknown"
    return Box(
        (*middle, (bottom + top) / 2), (length, width, height), yaw, label, points=len(points)
    )


def kitti_frames() -> st.SearchStrategy[Frame]:
    return st.deferred(lambda: mst.frames(str(KITTI), roi=kitti_label_region(), labels=False))


# Every relation but rotation, reflection, the sensor faults and insertion: RANSAC draws
# samples by position in the (sorted) array, and turning or mirroring the sweep re-sorts
# it, and any point taken away (a dead laser, a lost packet) or put in (an inserted object,
# with what it hides) shifts it, so the plane and the boxes near its threshold change.
# Insertion also finds the detector's 40 m range cap. Real properties of this detector that
# those relations report (see the dead-laser and inserted-car tests below); not tested here.
# (Fog, rain and range quantisation held in 36 + 18 follow-ups on the KITTI sweeps.)
FRAGILE = (
    "cloud and ROI turned",
    "cloud and ROI mirrored",
    "beams missing",
    "packets lost",
    "an object inserted",
)
RELATIONS = [r for r in lidar_relations() if not r.name.startswith(FRAGILE)]


# Derandomized, as every test here that asserts what a search finds (here: nothing): a
# random run under xdist once reported a violation that 10 further random runs did not
# see; a search for this detector's weaknesses belongs in a campaign, not in CI.
@needs_kitti
@settings(
    max_examples=4, database=None, deadline=None, derandomize=True, suppress_health_check=LIDAR
)
@metamorphic(source=kitti_frames(), relations=RELATIONS, followups=1)
def test_sklearn_detector_satisfies_the_relation_library(frame: Frame) -> list[Box]:
    return SklearnDetector()(frame)


@needs_kitti
def test_a_dead_laser_moves_the_ransac_plane_and_loses_a_pedestrian() -> None:
    """The lowest laser dead (ring 0, the ground nearest the car): the pedestrian at 14 m
    keeps all 38 of its points, but RANSAC's fixed-seed samples now come from other
    points, the plane tilts and most of the pedestrian falls below the 25 cm cut."""
    frame = FrameCatalog(str(KITTI), roi=kitti_label_region()).load(0)
    fault = DropRings([0])
    followup = fault.apply(frame)
    detector = SklearnDetector()
    verdict = beam_loss().relation.check(
        detector(frame), detector(followup), CheckContext(frame, followup, fault.params(), 0)
    )
    assert not verdict.holds
    lost = "pedestrian at (14.3, -4.7) lost although its box still holds 38 points"
    assert lost in verdict.explanation


@needs_kitti
def test_an_inserted_car_beyond_the_detectors_range_cap_is_not_detected() -> None:
    """The labelled car of KITTI sweep 1 seen at 70 m, put on free ground at 56 m (80 %
    of its range): its 132 returns are in the sweep, but the detector crops everything
    beyond 40 m. No relation that moves, drops or adds noise can show a range cap (the
    car was never reported in any run); an inserted object can."""
    frame = FrameCatalog(str(KITTI), roi=kitti_label_region()).load(1)  # with its labels
    template = object_templates(frame)[0]
    placement = free_placements(frame, template, limit=1)[0]
    insertion = InsertObject.onto(frame, template, placement)
    followup = insertion.apply(frame)
    detector = SklearnDetector()
    verdict = object_insertion().relation.check(
        detector(frame), detector(followup), CheckContext(frame, followup, insertion.params(), 0)
    )
    assert not verdict.holds
    # The message says what it knows: a labelled KITTI car, from which sweep.
    assert "the inserted car at (55.8, -0.4) (132 returns, a labelled car from " in (
        verdict.explanation
    )


@needs_kitti
def test_mr1_catches_a_ransac_plane_fitted_to_the_whole_sweep() -> None:
    # Derandomized: a test that asserts the bug is found must not depend on the seed.
    @settings(max_examples=6, database=None, deadline=None, derandomize=True,
              phases=[Phase.generate], suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=kitti_frames(), relations=[mr1_subset(n=10)], followups=2)
    def check(frame: Frame) -> list[Box]:
        return SklearnDetector(ground="sweep")(frame)

    with pytest.raises(MetamorphicViolation, match=r"inside the ROI's edge"):
        check()


def _catalog() -> FrameCatalog:
    return FrameCatalog(str(KITTI), roi=kitti_label_region())


if KITTI.is_dir():
    # pytest --mt-campaign: MR1 rates with Wilson intervals, 3 follow-ups per sweep and size.
    # A detector built from PyPI parts, with known weaknesses (see the tests above): these
    # campaigns measure how often they show (max_rate=None: reported, not gated). Gate
    # your own detector's with max_rate= or against main's reports (--mt-baseline).
    test_mr1_sklearn_roi_ground = campaign_test(
        mr1_campaign(
            SklearnDetector(), name="MR1 sklearn detector", frames=_catalog(), followups=3
        ),
        max_rate=None,
    )
    test_mr1_sklearn_sweep_ground = campaign_test(
        mr1_campaign(
            SklearnDetector(ground="sweep"),
            name="MR1 sklearn detector, sweep ground",
            frames=_catalog(),
            followups=3,
        ),
        max_rate=None,
    )
    # How fragile is it where it is not tested above? Rates per relation and severity:
    # quarter turns and the mirror (RANSAC re-sorts), dead lasers and lost packets.
    test_rotation_sklearn = campaign_test(
        symmetry_campaign(
            SklearnDetector(), symmetry="rotation", name="rotation sklearn detector",
            frames=_catalog(),
        ),
        max_rate=None,
    )  # fmt: skip
    test_mirror_sklearn = campaign_test(
        symmetry_campaign(
            SklearnDetector(), symmetry="mirror", name="mirror sklearn detector",
            frames=_catalog(),
        ),
        max_rate=None,
    )  # fmt: skip
    test_packet_loss_sklearn = campaign_test(
        fault_campaign(
            SklearnDetector(), fault="packet_loss", name="lost packets sklearn detector",
            frames=_catalog(), followups=3,
        ),
        max_rate=None,
    )  # fmt: skip
