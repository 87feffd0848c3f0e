"""Frame: validation, follow-up construction, compact repr."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box

CLOUD = PointCloud(np.zeros((10, 4)))
CAR = Box((10, 0, 0), (4, 2, 1.5), label="car")
WALKER = Box((5, 2, 0), (0.6, 0.5, 1.8), label="pedestrian")


def test_defaults_and_normalisation():
    frame = Frame(CLOUD, boxes=[CAR], index=np.int64(3), source="a.bin")
    assert frame.boxes == (CAR,) and frame.index == 3 and type(frame.index) is int
    assert frame.roi is None and frame.pose is None


def test_pose_is_a_read_only_float64_matrix():
    pose = np.eye(4, dtype=np.float32)
    pose[0, 3] = 2.5
    frame = Frame(CLOUD, pose=pose)
    assert frame.pose.dtype == np.float64 and frame.pose[0, 3] == 2.5
    with pytest.raises(ValueError, match="read-only"):
        frame.pose[0, 0] = 5
    assert pose[0, 0] == 1  # the caller's array was copied, not frozen


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cloud": np.zeros((3, 4))}, "cloud must be a PointCloud"),
        ({"boxes": [CAR, "car"]}, "iterable of Box"),
        ({"boxes": 3}, "iterable of Box"),
        ({"pose": np.eye(3)}, r"shape \(4, 4\), got \(3, 3\)"),
        ({"pose": np.full((4, 4), np.nan)}, "NaN"),
        ({"pose": np.ones((4, 4))}, "last row"),
        ({"pose": "identity"}, "cannot be converted"),
        ({"index": -1}, "index=-1 must be >= 0"),
        ({"index": 1.5}, "must be an integer"),
        ({"index": True}, "must be an integer"),
    ],
)
def test_bad_arguments(kwargs, message):
    arguments = {"cloud": CLOUD, **kwargs}
    with pytest.raises(InvalidArgument, match=message):
        Frame(**arguments)


def test_with_cloud_keeps_context():
    roi = object()
    frame = Frame(CLOUD, roi=roi, boxes=(CAR,), pose=np.eye(4), source="s", index=2)
    other = PointCloud(np.ones((3, 4)))
    follow = frame.with_cloud(other)
    assert follow.cloud is other and follow.roi is roi and follow.boxes == (CAR,)
    assert follow.source == "s" and follow.index == 2 and np.array_equal(follow.pose, np.eye(4))


def test_frames_are_immutable_and_compare_by_identity():
    frame = Frame(CLOUD)
    with pytest.raises(AttributeError):
        frame.index = 4
    assert frame == frame and frame != Frame(CLOUD)


def test_repr_is_compact():
    class ROI:
        pass

    frame = Frame(
        CLOUD,
        roi=ROI(),
        boxes=(CAR, WALKER, CAR),
        pose=np.eye(4),
        source="kitti/000001.bin",
        index=1,
    )
    assert repr(frame) == (
        "Frame(kitti/000001.bin#1; 10 points; 2 car, 1 pedestrian; roi=ROI; pose)"
    )
    assert repr(Frame(CLOUD)) == "Frame(<memory>#0; 10 points)"


def test_hypothesis_prints_a_frame_as_its_repr_not_field_by_field():
    from hypothesis.vendor.pretty import pretty

    frame = Frame(CLOUD, boxes=(CAR,), source="kitti/000001.bin", index=1)
    assert pretty(frame) == repr(frame) == "Frame(kitti/000001.bin#1; 10 points; 1 car)"
