"""Your detector on your recordings: another sensor than KITTI's, no labels, no HD map.

What a perception engineer copies to start: a detector of their own (30 lines of numpy and
scipy, boxes without point counts, as a converter's or a process's would be), real
recordings of a Velodyne VLP-16 and VLP-32C (Autoware's nebula driver) and an Ouster
OS1-64, and rendered VLP-16 and OS1-128 scenes.

* **The sensor**: each frame's sensor is identified from its cloud (the laser field under
  the driver's name, ``channel`` or ``ring``, or the elevations:
  :func:`~pytest_metamorphic.lidar.model.sensors.frame_sensor`), so dead lasers are the
  sensor's own and a lost packet is as wide as its packets. Pass ``sensor=`` to
  ``FrameCatalog`` when you know it.
* **The ROI**: no HD map, so the road is the corridor ahead of the car
  (:func:`~pytest_metamorphic.lidar.roi.corridor_roi`; with a Lanelet2 map,
  :func:`~pytest_metamorphic.lidar.roi.lanelet2_roi`).
* **Objects to insert**: the recordings have no labels, so insertion takes the built-in
  rendered road users
  (:func:`~pytest_metamorphic.lidar.followups.insert.catalogue.road_user_templates`: a
  child to an articulated lorry, and an adult, a cyclist and a car close by, which fit
  where a short-range recording sees ground), re-cast for each frame's sensor. Pass
  ``object_insertion(objects=...)`` for your own
  (:func:`~pytest_metamorphic.lidar.followups.insert.object_templates` of labelled
  recordings or rendered streets).

A relation that cannot act on a frame (no free place for an object, no lasers to lose)
says so in the summary (``n/a``, "NOTHING TESTED ... because ..."), never "passed".
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from scipy import ndimage

import conftest
from pytest_metamorphic import Followup, MetamorphicRelation, MetamorphicViolation, metamorphic
from pytest_metamorphic.lidar.followups.faults import DropRings
from pytest_metamorphic.lidar.followups.insert import InsertedDetected, InsertObject, Placement
from pytest_metamorphic.lidar.followups.insert.catalogue import (
    road_user_templates,
    solid_road_users,
)
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.model.domain import OperatingDomain
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, Label
from pytest_metamorphic.lidar.model.sensors import OS1_128, VLP16
from pytest_metamorphic.lidar.roi import corridor_roi
from pytest_metamorphic.lidar.synthetic import render
from pytest_metamorphic.lidar.synthetic.layout import random_scene
from pytest_metamorphic.relations.lidar import (
    CoveredObstaclesKept,
    lidar_relations,
    mr1_subset,
    object_insertion,
)

DATA = conftest.SHARED_DATA
RECORDINGS = {
    "VLP-16": (DATA / "nebula_velodyne" / "vlp16" / "1673400472138016708.pcd", None),
    "VLP-32C": (DATA / "nebula_velodyne" / "vlp32" / "1713492677464078412.pcd", None),
    "OS1-64": (DATA / "pointcloudset_ouster" / "test_converted.bag", "/os1_cloud_node/points"),
}
needs_recordings = pytest.mark.skipif(
    not all(path.exists() for path, _ in RECORDINGS.values()),
    reason=f"the VLP and Ouster recordings are not in {DATA} (set PYTEST_METAMORPHIC_DATA)",
)
LIDAR = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example]


def my_detector(frame: Frame, *, ground_cell: float = 2.0, max_range: float = 50.0) -> list[Box]:
    """Ground per ``ground_cell`` metre cell (its lowest return), obstacles 0.3-2.5 m above
    it, connected 25 cm cells as one obstacle, a class from its size."""
    xyz = np.unique(np.round(frame.cloud.xyz.astype(np.float64), 2), axis=0)
    xyz = xyz[np.hypot(xyz[:, 0], xyz[:, 1]) < max_range]
    if len(xyz) == 0:
        return []
    cells = np.floor(xyz[:, :2] / ground_cell)
    keys, inverse = np.unique(cells, axis=0, return_inverse=True)
    lowest = np.full(len(keys), np.inf)
    np.minimum.at(lowest, inverse.ravel(), xyz[:, 2])
    height = xyz[:, 2] - lowest[inverse.ravel()]
    above = xyz[(height > 0.3) & (height < 2.5)]
    if len(above) == 0:
        return []
    ij = np.floor(above[:, :2] / 0.25).astype(np.int64)
    low = ij.min(axis=0)
    grid = np.zeros(tuple(ij.max(axis=0) - low + 1), dtype=bool)
    grid[tuple((ij - low).T)] = True
    labels, count = ndimage.label(grid, structure=np.ones((3, 3)))
    of_point = labels[tuple((ij - low).T)]
    boxes = []
    for k in range(1, count + 1):
        part = above[of_point == k]
        if len(part) >= 5:
            boxes.append(_box(part))
    return sorted(boxes, key=lambda box: box.center)


def _box(part: np.ndarray) -> Box:
    lo, hi = part.min(axis=0), part.max(axis=0)
    size = np.maximum(hi - lo, 0.1)
    length, width = float(max(size[0], size[1])), float(min(size[0], size[1]))
    label: Label = "unknown"
    if 2.5 < length < 6.0 and 1.2 < width < 2.5:
        label = "car"
    elif length < 1.2 and 1.0 < size[2] < 2.1:
        label = "pedestrian"
    yaw = 0.0 if size[0] >= size[1] else float(np.pi / 2)
    return Box(tuple((lo + hi) / 2), (length, width, float(size[2])), yaw, label)


#: What my detector claims to cover: its own range (it drops returns beyond 50 m), not
#: the sensor's 100-120 m.
DOMAIN = OperatingDomain(max_range_m=50.0)

# Where the sensor sees no ground around an object, my ground (each 2 m cell's lowest
# return) is the object's own lowest return, and only what stands 0.3 m above that is
# kept: within 6.5 m of a VLP-16 1.73 m up (its lowest laser meets the road there) and
# around a car 35 m away (two of its lasers meet the car, none the road beside it). The
# search found both (the two tests after the next); my detector does not claim the near
# field nor the far field: objects are inserted near the range they were seen from.
AS_SEEN = object_insertion(reach=("as seen",), domain=DOMAIN)
RELATIONS = [
    AS_SEEN if relation.name == AS_SEEN.name else relation
    for relation in lidar_relations(domain=DOMAIN)
    if "near field" not in relation.name
]


@functools.cache
def recorded_frames() -> tuple[Frame, ...]:
    """One sweep of each recording, its road the 7 m corridor ahead."""
    return tuple(
        FrameCatalog(path, topic=topic, roi=corridor_roi(width=7.0))[0]
        for path, topic in RECORDINGS.values()
    )


@needs_recordings
@settings(max_examples=6, database=None, deadline=None, derandomize=True,
          suppress_health_check=LIDAR)  # fmt: skip
@metamorphic(
    source=st.deferred(lambda: st.sampled_from(recorded_frames())),
    relations=RELATIONS,
    followups=1,
)
def test_my_detector_on_my_recordings(frame: Frame) -> list[Box]:
    return my_detector(frame)


@functools.cache
def rendered_frames() -> tuple[Frame, ...]:
    """Two streets, each scanned by a VLP-16 and by an OS1-128 (``mst.scene_frames(
    sensor=...)`` draws such frames for a search). Road users within 25 m: a VLP-16's 16
    lasers leave fewer than 30 returns on most objects beyond, too few for the sensor
    faults and the weather to judge."""
    scenes = [
        random_scene(np.random.default_rng(seed), name=f"street {seed}", max_distance=25.0)
        for seed in (2, 7)
    ]
    return tuple(render(scene, beams=sensor) for scene in scenes for sensor in (VLP16, OS1_128))


# Dead lasers are not claimed for this detector on a VLP-16: its ground is each 2 m
# cell's lowest return, and a cell whose only ground returns came from the lost laser
# takes its ground from the object standing in it (the next test).
CLAIMED = [r for r in RELATIONS if not r.name.startswith("beams missing")]


@settings(max_examples=4, database=None, deadline=None, derandomize=True,
          suppress_health_check=LIDAR)  # fmt: skip
@metamorphic(
    source=st.deferred(lambda: st.sampled_from(rendered_frames())),
    relations=CLAIMED,
    followups=1,
)
def test_my_detector_on_rendered_scenes_of_other_sensors(frame: Frame) -> list[Box]:
    return my_detector(frame)


def _inserted(frame: Frame, insertion: InsertObject) -> MetamorphicRelation:
    """A relation whose one follow-up is ``frame`` with ``insertion``, judged as
    ``near_field_insertion()`` judges (found as any class)."""
    return MetamorphicRelation(
        f"{insertion.box.describe()} inserted => it is detected",
        lambda _: st.just(Followup(insertion.apply(frame), insertion.params())),
        InsertedDetected(classes="any"),
    )


def _check_once(frame: Frame, relation: MetamorphicRelation) -> None:
    @settings(max_examples=1, database=None, phases=[Phase.generate], deadline=None,
              suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=st.just(frame), relations=[relation], followups=1)
    def check(frame: Frame) -> list[Box]:
        return my_detector(frame)

    check()


def test_a_dead_laser_lifts_my_detectors_ground_into_an_object() -> None:
    # A real weakness of a cell-minimum ground, found by the search above: on street 7
    # rendered with a VLP-16, laser 4 held the only ground returns of the 2 m cells
    # around an obstacle 13.5 m behind the car (their lowest return rises from -1.65 m to
    # -1.19 m without it), so the obstacle's lower part becomes "ground" and it shrinks
    # from 4.7 m to 2.3 m, though it keeps all its returns.
    dead = DropRings((4,))
    relation = MetamorphicRelation(
        "laser 4 dead => well-covered obstacles kept",
        lambda frame: st.just(Followup(dead.apply(frame), dead.params())),
        CoveredObstaclesKept(),
    )
    with pytest.raises(MetamorphicViolation, match=r"unknown at \(-13\.\d, -0\.\d\) lost"):
        _check_once(rendered_frames()[2], relation)


def test_a_child_in_front_of_the_bumper_is_its_own_ground() -> None:
    # 3.5 m ahead of a VLP-16 1.73 m up, a 1.15 m child holds 68 returns over its top
    # 0.36 m, and no laser meets the road in its 2 m cell: the cell's lowest return is the
    # child's chin, and nothing stands 0.3 m above it.
    frame = rendered_frames()[0]
    child = next(t for t in solid_road_users() if t.source.endswith("[child]"))
    insertion = InsertObject.onto(frame, child, Placement(0.0, 3.5, -1.70), layout=VLP16)
    with pytest.raises(MetamorphicViolation, match=r"pedestrian at \(3\.5, 0\.0\).* not detected"):
        _check_once(frame, _inserted(frame, insertion))


def test_a_parked_row_35_m_away_is_its_own_ground() -> None:
    # Two of a VLP-16's lasers meet a row of parked cars 35 m ahead (at 0.2 m and 1.2 m
    # above the road), none the road between them: a cell holding only the upper one
    # takes it for the ground. The search found it 51 degrees to the left, on the road.
    frame = rendered_frames()[0]
    row = next(t for t in road_user_templates() if t.source.endswith("[row of parked cars]"))
    place = Placement(math.radians(51), 35.0, -1.70)
    insertion = InsertObject.onto(frame, row, place, layout=VLP16)
    with pytest.raises(MetamorphicViolation, match=r"car at \(22\.0, 27\.2\).* not detected"):
        _check_once(frame, _inserted(frame, insertion))


#: A realistic fault: ground cells of 8 m instead of 2 m. A cell that straddles the road's
#: edge takes its lowest return from off the road, so points added there (MR1's noise)
#: lower the ground under obstacles on the road, which then grow and change class.
GROUND_FAULT = 8.0


@needs_recordings
def test_mr1_catches_ground_cells_that_straddle_the_road_edge() -> None:
    # Derandomized: a test that asserts the fault is found must not depend on the seed.
    @settings(max_examples=10, database=None, deadline=None, derandomize=True,
              phases=[Phase.generate, Phase.shrink], suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(
        source=st.deferred(lambda: st.sampled_from(recorded_frames())),
        relations=[mr1_subset()],
        followups=2,
    )
    def check(frame: Frame) -> list[Box]:
        return my_detector(frame, ground_cell=GROUND_FAULT)

    with pytest.raises(MetamorphicViolation, match="has no match"):
        check()
