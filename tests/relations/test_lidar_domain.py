"""The operating domain's near field and terrain: a correct detector holds the relations
that reach them, and each fault written after a real bug report for them is killed by
the relation aimed at it (issue 61)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from pytest_metamorphic import InvalidArgument, MetamorphicViolation, metamorphic
from pytest_metamorphic.core.relations import CheckContext
from pytest_metamorphic.lidar.model.domain import OperatingDomain
from pytest_metamorphic.lidar.model.terrain import Terrain
from pytest_metamorphic.lidar.synthetic.render import rendering_of
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from pytest_metamorphic.lidar.systems.perception.mutants import mutant
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception
from pytest_metamorphic.relations.lidar import lidar_relations, near_field_insertion, road_terrain
from tests.core.lidar_cases import labelled_kitti, street

SEARCH = settings(
    max_examples=20, derandomize=True, database=None, deadline=None,
    suppress_health_check=list(HealthCheck),
)  # fmt: skip
# A fault is killed by the first violation: no shrinking (minutes of re-runs of a mutant).
KILL = settings(SEARCH, phases=[Phase.explicit, Phase.generate])


def _search(system: Any, relation: Any, frames: list[Any], *, kill: bool = False) -> None:
    @(KILL if kill else SEARCH)
    @metamorphic(source=st.sampled_from(frames), relations=[relation])
    def check(frame):  # type: ignore[no-untyped-def]
        return system(frame)

    check()


@pytest.mark.parametrize("system", [ReferencePerception(), WholeScenePerception()],
                         ids=["reference", "whole-scene"])  # fmt: skip
def test_a_correct_detector_finds_what_stands_right_beside_the_car(system: Any) -> None:
    _search(system, near_field_insertion(), [labelled_kitti(0), labelled_kitti(1), street()])


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("self_crop_margin", "is not detected"),
        ("oversized_cluster_drop", "is not detected"),
        ("near_pedestrians_unknown", "demoted"),
    ],
)
def test_each_near_field_fault_is_killed_by_the_near_field_insertion(
    name: str, message: str
) -> None:
    with pytest.raises(MetamorphicViolation, match=message) as failure:
        _search(mutant(name), near_field_insertion(), [street(), labelled_kitti(0)], kill=True)
    assert "near field" in str(failure.value)


def test_the_near_field_insertion_is_in_the_library() -> None:
    names = [relation.name for relation in lidar_relations()]
    assert "an object inserted in the near field => it is detected and the others kept" in names


def test_the_library_places_and_moves_objects_within_the_domains_far_limit() -> None:
    # A detector that claims 40 m: no insertion nor move beyond 90 % of it.
    domain = OperatingDomain(max_range_m=40.0)
    names = ("an object inserted =>", "an object moved =>")
    frame = labelled_kitti(3)
    for bound in (None, domain):
        relations = [r for r in lidar_relations(domain=bound) if r.name.startswith(names)]
        assert len(relations) == 2
        farthest = 0.0

        @settings(max_examples=40, database=None, derandomize=True, deadline=None,
                  phases=[Phase.generate], suppress_health_check=list(HealthCheck))  # fmt: skip
        @given(st.sampled_from(relations).flatmap(lambda r: r.followup(frame)))
        def draw(followup: Any) -> None:
            nonlocal farthest
            if followup.skipped is not None:
                return
            edit = followup.params.get("insert_object") or followup.params["relocate_object"]
            box = getattr(edit, "insertion", edit).box
            farthest = max(farthest, float(np.hypot(*box.center[:2])))

        draw()
        if bound is None:
            assert farthest > 40.0  # the HDL-64E's own 120 m reach farther
        else:
            assert 0 < farthest <= 0.9 * 40.0 + 0.5
    with pytest.raises(InvalidArgument, match="domain="):
        lidar_relations(domain={"max_range_m": 40})  # type: ignore[arg-type]


def _rendered() -> list[Any]:
    from examples.test_your_recordings import rendered_frames

    return [street(), *rendered_frames()]


def _outside(name: str) -> Any:
    """The detectors written apart from the reference: a grid detector, DBSCAN with ties."""
    if name == "grid example":
        from examples.test_your_recordings import my_detector

        return my_detector
    from tests.lidar.systems.ties_detector import TiesDetector

    return TiesDetector()


@pytest.mark.parametrize("system", ["reference", "whole-scene", "grid example", "DBSCAN ties"])
def test_a_correct_detector_keeps_its_road_users_on_slopes_crests_and_camber(system: str) -> None:
    detector = {"reference": ReferencePerception, "whole-scene": WholeScenePerception}.get(system)
    _search(detector() if detector else _outside(system), road_terrain(), _rendered())


def test_a_single_ransac_plane_takes_an_uphill_road_for_an_obstacle() -> None:
    # The scikit-learn example fits one plane to the ROI's returns: a road 7 % uphill from
    # 20 m ahead (over a 40 m curve) stands 0.28 m above the plane of the near road 38 m
    # ahead, and becomes an obstacle. A real limit of one plane per sweep.
    pytest.importorskip("sklearn", reason="scikit-learn is not installed: pip install '.[sklearn]'")
    from examples.test_sklearn_detector import SklearnDetector

    with pytest.raises(MetamorphicViolation, match="the road became an obstacle"):
        _search(SklearnDetector(), road_terrain(), _rendered(), kill=True)


@pytest.mark.parametrize("name", ["level_ground", "slope_capped_ground"])
def test_a_ground_that_cannot_follow_the_road_is_killed_by_the_terrain(name: str) -> None:
    with pytest.raises(MetamorphicViolation, match="road's new shape"):
        _search(mutant(name), road_terrain(), _rendered(), kill=True)


def test_the_terrain_follow_up_renders_the_same_scene_on_the_new_road() -> None:
    frame = street()
    relation = road_terrain(domain=OperatingDomain(grade_percent=(4, 4), camber_percent=(0, 0)))

    @settings(max_examples=3, derandomize=True, database=None, deadline=None)
    @metamorphic(source=st.just(frame), relations=[relation])
    def record(frame):  # type: ignore[no-untyped-def]
        return ReferencePerception()(frame)

    seen: list[dict[str, Any]] = []
    original = relation.relation.check

    def spy(source: Any, followup: Any, context: CheckContext) -> Any:
        seen.append(dict(context.params))
        scene = rendering_of(context.followup_input).scene  # type: ignore[union-attr]
        assert scene.terrain == Terrain(4, context.params["grade_start_m"],
                                        context.params["grade_curve_m"])  # fmt: skip
        # Same objects, raised with the road under their centres.
        for before, after in zip(rendering_of(frame).scene.obstacles, scene.obstacles,  # type: ignore[union-attr]
                                 strict=True):  # fmt: skip
            x, y, z = before.box.center
            assert after.box.center[2] == pytest.approx(z + float(scene.terrain.height(x, y)))
        return original(source, followup, context)

    relation.relation.check = spy  # type: ignore[method-assign]
    record()
    assert seen and all(params["grade_percent"] == 4 for params in seen)


def test_on_a_recording_the_terrain_tests_nothing_and_says_why() -> None:
    relation = road_terrain()

    @settings(max_examples=1, database=None, deadline=None)
    @given(relation.followup(labelled_kitti(0)))
    def drawn(followup: Any) -> None:
        assert "rendered scenes only" in followup.params["not_applicable"]

    drawn()
    with pytest.raises(InvalidArgument, match="varies neither"):
        road_terrain(domain=OperatingDomain(grade_percent=(0, 0), camber_percent=(0, 0)))


def test_a_terrain_is_validated_and_described() -> None:
    road = Terrain(grade_percent=6, start_m=10, curve_m=20, camber_percent=2)
    assert float(road.height(10, 0)) == 0.0
    assert float(road.height(30, 0)) == pytest.approx(0.06 * 20 / 2)  # the parabola
    assert float(road.height(40, 0)) == pytest.approx(0.6 + 0.06 * 10)  # then the grade
    assert float(road.height(0, 3)) == pytest.approx(-0.06)  # camber falls to the kerb
    assert road.describe() == "a road 6 % uphill from 10 m ahead (over a 20 m curve) and 2 % camber"
    for bad in ({"grade_percent": 40}, {"curve_m": 0}, {"camber_percent": "2"}):
        with pytest.raises(InvalidArgument):
            Terrain(**bad)  # type: ignore[arg-type]
