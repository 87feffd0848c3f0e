"""The sensor-pose relation: a sensor pitched, rolled or raised within the operating
domain keeps every well-seen road user and its class, on the reference and its whole-
scene variant; a ground taken from a level sensor's mount height fails it."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from pytest_metamorphic import InvalidArgument, MetamorphicViolation, metamorphic
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.model.domain import OperatingDomain
from pytest_metamorphic.lidar.model.pose import SensorPose
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception
from pytest_metamorphic.relations.lidar import lidar_relations, sensor_pose
from tests.core.lidar_cases import labelled_kitti, street

FAST = settings(
    max_examples=8, derandomize=True, database=None, deadline=None,
    suppress_health_check=list(HealthCheck),
)  # fmt: skip

# The corners of the default domain and poses between them: the checks the relation's
# 100-return floor was measured on (its docstring).
CORNERS = [SensorPose(p, r, h) for p, r, h in (
    (3, 0, 0), (-3, 0, 0), (0, 2.5, 0), (0, -2.5, 0), (0, 0, 0.15), (0, 0, -0.15),
    (3, 2.5, 0.15), (-3, -2.5, -0.15), (1.7, -0.6, 0.05), (-0.9, 1.3, -0.11),
)]  # fmt: skip


def _checks(system: Any, relation: Any, frames: list[Any]) -> tuple[int, list[str]]:
    """(road users judged, violation messages) over ``frames`` and :data:`CORNERS`."""
    judged, failures = 0, []
    for frame in frames:
        source = system(frame)
        for pose in CORNERS:
            posed = pose.apply(frame)
            context = CheckContext(frame, posed, pose.params(), 0)
            verdict = relation.check(source, system(posed), context)
            judged += verdict.details["judged"]
            if not verdict.holds:
                failures.append(f"{frame.source} {pose.describe()}: {verdict.explanation}")
    return judged, failures


@pytest.mark.parametrize("system", [ReferencePerception(), WholeScenePerception()],
                         ids=["reference", "whole-scene"])  # fmt: skip
def test_the_pose_keeps_every_well_seen_road_user_of_a_correct_detector(system: Any) -> None:
    frames = [labelled_kitti(i) for i in range(6)] + [street()]
    judged, failures = _checks(system, sensor_pose().relation, frames)
    assert not failures, failures[:3]
    assert judged >= len(frames) * len(CORNERS) * 0.8  # judged, not a silent pass


def test_sparse_road_users_are_left_out_because_their_fate_is_decided_by_centimetres() -> None:
    # With the 30-return floor of the fault relations the reference's far sparse cars
    # change class or box under a few degrees of pitch (the docstring's measurement).
    frames = [labelled_kitti(i) for i in (1, 4, 5)]
    _, failures = _checks(ReferencePerception(), sensor_pose(min_points=30).relation, frames)
    assert failures


def test_a_ground_assumed_from_a_level_sensor_loses_road_users_when_the_car_pitches() -> None:
    frames = st.sampled_from([street(), labelled_kitti(0)])
    level = mutant("level_ground")

    @FAST
    @metamorphic(source=frames, relations=[sensor_pose()])
    def check(frame):  # type: ignore[no-untyped-def]
        return level(frame)

    with pytest.raises(MetamorphicViolation, match="seen from the posed sensor") as failure:
        check()
    assert "pitch_deg" in str(failure.value)


def test_the_pose_is_drawn_from_the_domain_and_only_what_it_varies() -> None:
    seen: list[dict[str, Any]] = []
    domain = OperatingDomain(pitch_deg=(0.0, 1.0), height_m=(-0.05, 0.0))
    relation = sensor_pose(domain=domain, vary=("pitch", "height"))

    @FAST
    @metamorphic(source=st.just(street()), relations=[relation])
    def record(frame):  # type: ignore[no-untyped-def]
        return ReferencePerception()(frame)

    original = relation.relation.check

    def spy(source: Any, followup: Any, context: CheckContext) -> Any:
        seen.append(dict(context.params))
        return original(source, followup, context)

    relation.relation.check = spy  # type: ignore[method-assign]
    record()
    assert seen
    for params in seen:
        assert 0.0 <= params["pitch_deg"] <= 1.0 and -0.05 <= params["height_m"] <= 0.0
        assert params["roll_deg"] == 0.0
        assert (params["pitch_deg"], params["height_m"]) != (0.0, 0.0)


def test_the_pose_relation_is_in_the_library_and_refuses_what_it_cannot_vary() -> None:
    assert any(r.name.startswith("sensor pitched") for r in lidar_relations())
    for bad in ({"vary": ()}, {"vary": "pitch"}, {"vary": ("yaw",)}, {"domain": {"pitch": 1}},
                {"domain": OperatingDomain(roll_deg=(0, 0)), "vary": ("roll",)}):  # fmt: skip
        with pytest.raises(InvalidArgument):
            sensor_pose(**bad)  # type: ignore[arg-type]
