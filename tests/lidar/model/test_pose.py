"""The sensor's pose and the operating domain: what a pitched, rolled or raised sensor
receives, and the ranges a test varies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN, OperatingDomain
from pytest_metamorphic.lidar.model.pose import SensorPose
from tests.core.lidar_cases import GROUND_Z, street


def test_a_sensor_pitched_nose_down_sees_the_road_ahead_rise_and_behind_drop() -> None:
    pose = SensorPose(pitch_deg=2.0)
    ahead, behind = pose.transform(np.array([[20.0, 0.0, GROUND_Z], [-20.0, 0.0, GROUND_Z]]))
    rise = 20.0 * math.sin(math.radians(2.0))
    assert ahead[2] == pytest.approx(GROUND_Z * math.cos(math.radians(2.0)) + rise, abs=1e-9)
    assert behind[2] == pytest.approx(GROUND_Z * math.cos(math.radians(2.0)) - rise, abs=1e-9)


def test_a_sensor_rolled_left_side_up_sees_the_road_on_its_left_drop() -> None:
    left, right = SensorPose(roll_deg=2.0).transform(np.array([[0, 5.0, GROUND_Z],
                                                               [0, -5.0, GROUND_Z]]))  # fmt: skip
    assert left[2] < GROUND_Z < right[2]


def test_a_raised_sensor_sees_everything_lower_and_nothing_moved_in_the_plane() -> None:
    frame = street()
    raised = SensorPose(height_m=0.12).apply(frame)
    assert np.allclose(raised.cloud.xyz[:, :2], frame.cloud.xyz[:, :2])
    assert np.allclose(raised.cloud.xyz[:, 2], frame.cloud.xyz[:, 2] - 0.12, atol=1e-5)
    assert raised.roi is frame.roi


def test_a_pose_is_rigid_and_keeps_every_return_and_field() -> None:
    frame = street()
    pose = SensorPose(pitch_deg=2.7, roll_deg=-1.9, height_m=-0.08)
    posed = pose.apply(frame)
    assert len(posed.cloud) == len(frame.cloud)
    assert np.array_equal(posed.cloud.points[:, 3], frame.cloud.points[:, 3])  # intensity
    # Distances between returns are kept (a rigid motion), up to float32 rounding.
    a, b = frame.cloud.xyz[:500:7].astype(np.float64), posed.cloud.xyz[:500:7].astype(np.float64)
    before = np.linalg.norm(a[:, None] - a[None], axis=2)
    after = np.linalg.norm(b[:, None] - b[None], axis=2)
    assert np.allclose(before, after, atol=1e-3)


def test_the_labels_move_with_their_returns() -> None:
    frame = street()
    pose = SensorPose(pitch_deg=3.0, roll_deg=2.5, height_m=0.15)
    posed = pose.apply(frame)
    for box, moved in zip(frame.boxes, posed.boxes, strict=True):
        inside = box.contains(frame.cloud.xyz)
        # The returns inside the label stay inside it, moved (its footprint tilted by
        # 3 degrees covers up to height * sin 3 degrees more: a margin of 10 cm).
        grown = type(moved)(moved.center, tuple(s + 0.2 for s in moved.size), moved.yaw,
                            moved.label)  # fmt: skip
        assert grown.contains(posed.cloud.xyz[inside]).mean() > 0.99
        assert abs(math.remainder(moved.yaw - box.yaw, math.pi)) < math.radians(1.0)


def test_a_pose_is_validated_and_describes_itself() -> None:
    assert SensorPose(1.5, 0.0, 0.1).describe() == "pitched 1.5° nose down, raised 0.1 m"
    assert SensorPose(-1.0, -2.0).describe() == "pitched 1° nose up, rolled 2° right side up"
    assert SensorPose().describe() == "as recorded"
    assert SensorPose(1, 2, 0.3).params() == {"pitch_deg": 1.0, "roll_deg": 2.0, "height_m": 0.3}
    for bad in ({"pitch_deg": math.nan}, {"roll_deg": 90.0}, {"height_m": "1"},
                {"pitch_deg": True}):  # fmt: skip
        with pytest.raises(InvalidArgument, match=next(iter(bad))):
            SensorPose(**bad)  # type: ignore[arg-type]


def test_the_default_domain_is_a_passenger_car_on_ordinary_roads() -> None:
    assert DEFAULT_DOMAIN.pitch_deg == (-3.0, 3.0)
    assert DEFAULT_DOMAIN.height_m == (-0.15, 0.15)
    assert "pitch ±3°" in DEFAULT_DOMAIN.describe()
    van = OperatingDomain(pitch_deg=(-2, 4), height_m=(-0.12, 0.05), max_range_m=80)
    assert van.pitch_deg == (-2.0, 4.0)
    assert "pitch -2 to +4°" in van.describe() and "far field 80 m" in van.describe()


@pytest.mark.parametrize(
    ("field", "value"),
    [("pitch_deg", (3.0, -3.0)), ("pitch_deg", (0, 20)), ("roll_deg", 2.0),
     ("height_m", (0, math.inf)), ("grade_percent", "steep"), ("near_field_m", 0),
     ("max_range_m", -5.0), ("near_field_m", True)],
)  # fmt: skip
def test_a_domain_names_the_range_it_refuses(field: str, value: object) -> None:
    with pytest.raises(InvalidArgument, match=field):
        OperatingDomain(**{field: value})  # type: ignore[arg-type]
