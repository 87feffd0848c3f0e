"""Testing a learned detector: Apollo-style CNN segmentation, trained here, run with ONNX.

The system under test is the project's own learned model
(:class:`~pytest_metamorphic.lidar.systems.perception.cnnseg.CNNSegmentation`): a small U-Net on
Apollo's bird's-eye feature grid (280 x 280 cells of 0.5 m, Apollo's +-70 m), trained on
rendered streets with the clutter of real ones and shipped as an ONNX file that
onnxruntime runs on the CPU, or on a GPU where onnxruntime has one. It comes in Apollo's
two configurations:

* ``full_cloud=True`` (Apollo 2.x/3.0's ``use_full_cloud: true``): the network's features
  are built from the whole sweep, so points added off the road change what it predicts
  for cars on the road: Zhou & Sun's MR1 finds this on real KITTI sweeps, as it found it
  in Apollo;
* ``full_cloud=False``: features from the ROI's points alone (the fix): nothing outside
  the ROI reaches the network.

A network is never exactly equivariant: turning or mirroring the sweep, repeating points,
changes its maps a little. The relations therefore run with the *learned* tolerance
(``lidar_relations(tolerance="learned")``, :mod:`pytest_metamorphic.lidar.judging.tolerance`): a
violation is an obstacle gone or displaced by more than 0.5 m, never jitter. What the
ROI-feature model is claimed to satisfy was measured, not sampled: ``bench/learned_claims.py``
ran at least 1000 derandomized follow-ups per relation (docs/learned-model.md has the
counts), and bench/mutation_score.py searched them again on its own scenes; the test below
checks those claims derandomized, so it never fails at random. What failed is documented
as a weakness, the real ones each with a fixed case below.

    pytest examples/test_learned_detector.py                 # the Hypothesis tests
    pytest examples/test_learned_detector.py --mt-campaign   # + the paper's table on it

To test your own network, replace ``CNNSegmentation`` with a function ``Frame ->
list[Box]``, or give it ``run_batch(frames)`` and ``batch_size`` so that campaigns hand it
batches (``pytest_metamorphic.core.batching``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable

import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

import conftest
from pytest_metamorphic import Followup, MetamorphicRelation, MetamorphicViolation, metamorphic
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.campaign import campaign_test
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.followups.faults import DropAzimuthBlock, DropRings
from pytest_metamorphic.lidar.io.bin import read_bin
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region
from pytest_metamorphic.lidar.judging.tolerance import LEARNED
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, Label
from pytest_metamorphic.lidar.model.pose import SensorPose
from pytest_metamorphic.lidar.roi import ROI
from pytest_metamorphic.lidar.synthetic import BackgroundObject, Obstacle, Scene, render
from pytest_metamorphic.relations.lidar import (
    CoveredObstaclesKept,
    adverse_weather,
    lidar_relations,
    mr1_subset,
)

pytest.importorskip("onnxruntime", reason="onnxruntime is not installed: pip install '.[learned]'")

from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import held_out_frame

LIDAR = [HealthCheck.too_slow, HealthCheck.large_base_example, HealthCheck.data_too_large]
full_cloud = CNNSegmentation(full_cloud=True)
roi_only = CNNSegmentation(full_cloud=False)


# Not claimed: each failed its 1000 derandomized follow-ups in bench/learned_claims.py,
# or (the sensor's pose) a derandomized search of this module and a fixed case below,
# or held them and failed where else it was looked for: lost packets in
# bench/mutation_score.py's search, range steps on a real KITTI sweep, object removal on
# held-out street 27, a dead laser on that junction and on the Ouster recording
# (docs/learned-model.md, "Every relation on it", has what each found).
NOT_CLAIMED = (
    "points repeated",
    "cloud and ROI turned",
    "cloud and ROI mirrored",
    "beams missing",
    "packets lost",
    "ranges quantized",
    "an object removed",
    "an object inserted",
    "an object moved",
    "fog or rain",
    "sensor pitched",
)
LEARNED_RELATIONS = lidar_relations(tolerance="learned")
CLAIMED = [relation for relation in LEARNED_RELATIONS if not relation.name.startswith(NOT_CLAIMED)]


# The strategies' rendered streets within 50 m: where bench/learned_claims.py measured
# the claims.
STREETS = mst.scene_frames(mst.scenes(max_distance=50.0))


# Derandomized: the claims were measured on 1000 follow-ups each; five examples a run
# re-check them and never fail at random on a user's machine.
@settings(max_examples=5, derandomize=True, database=None, suppress_health_check=LIDAR,
          deadline=None)  # fmt: skip
@metamorphic(
    source=STREETS,
    relations=CLAIMED,
    followups=1,
    batch=True,  # the source and its follow-ups go through the network as one batch
)
def test_roi_features_satisfy_the_relation_library(frames: list[Frame]) -> list[list[Box]]:
    return roi_only.detect_batch(frames)


KITTI_000134 = conftest.SHARED_DATA / "kitti_pointpillars_demo" / "val" / "000134.bin"


@pytest.mark.skipif(not KITTI_000134.is_file(), reason=f"{KITTI_000134} is not there "
                    "(set PYTEST_METAMORPHIC_DATA to the shared data)")  # fmt: skip
def test_mr1_catches_features_built_from_the_whole_sweep_on_a_real_sweep() -> None:
    # KITTI 000134 (a real HDL-64E sweep, cropped to the camera's view) with KITTI's camera
    # wedge as ROI. Derandomized: a test that asserts a fault is found must not depend on
    # the seed.
    sweep = Frame(read_bin(KITTI_000134), roi=kitti_label_region(max_range=70.0))

    @settings(max_examples=20, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=st.just(sweep), relations=[mr1_subset(matcher=LEARNED.kept)],
                 followups=5, batch=True)  # fmt: skip
    def check(frames: list[Frame]) -> list[list[Box]]:
        return full_cloud.detect_batch(frames)

    # Three points outside the wedge, 26-34 m from the sensor, hide a pedestrian 3.9 m
    # inside it, 5-16 m from them (reduced from 1000 points, proven 1-minimal).
    with pytest.raises(MetamorphicViolation, match=r"hidden: pedestrian at \(26\.8, -17\.5\)"):
        check()


KITTI_000004 = conftest.SHARED_DATA / "kitti_openpcdet" / "training" / "velodyne" / "000004.bin"


@pytest.mark.skipif(not KITTI_000004.is_file(), reason=f"{KITTI_000004} is not there "
                    "(set PYTEST_METAMORPHIC_DATA to the shared data)")  # fmt: skip
def test_range_steps_of_centimetres_make_the_network_lose_a_car_on_a_real_sweep() -> None:
    # A real weakness on real sweeps (the claims bench's rendered streets held 1028
    # follow-ups on this model; an earlier one lost a car there after 988): a driver
    # that rounds ranges to a few centimetres changes which cells the network calls
    # objects. Here, on KITTI 000004
    # (camera wedge as ROI), 10.7 cm steps lose a "car" 62 m away that keeps 63 of its 68
    # returns.
    sweep = Frame(read_bin(KITTI_000004), roi=kitti_label_region(max_range=70.0))
    (quantized,) = [r for r in LEARNED_RELATIONS if r.name.startswith("ranges quantized")]

    @settings(max_examples=20, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=st.just(sweep), relations=[quantized], followups=1, batch=True)
    def check(frames: list[Frame]) -> list[list[Box]]:
        return roi_only.detect_batch(frames)

    with pytest.raises(MetamorphicViolation, match=r"car at \(58\.4, 21\.4\) lost although"):
        check()


def _junction() -> Frame:
    """bench/mutation_score.py's junction: two cars and a pedestrian, a building at the
    corner, rendered with the HDL-64E."""
    junction = ROI.from_polygons([
        [(-30.0, -5.0), (60.0, -5.0), (60.0, 5.0), (-30.0, 5.0)],
        [(20.0, -40.0), (30.0, -40.0), (30.0, 40.0), (20.0, 40.0)],
    ])  # fmt: skip

    def standing(x: float, y: float, size: tuple[float, float, float], yaw: float,
                 label: Label) -> Obstacle:  # fmt: skip
        return Obstacle(Box((x, y, -1.73 + size[2] / 2), size, yaw, label))

    scene = Scene(
        roi=junction,
        obstacles=(
            standing(25.0, 12.0, (4.4, 1.8, 1.5), 1.9, "car"),
            standing(14.0, 1.5, (4.2, 1.8, 1.4), 0.6, "car"),
            standing(24.0, -9.0, (0.7, 0.6, 1.8), 0.3, "pedestrian"),
        ),
        background=(
            BackgroundObject("building", (15.0, 16.0), (12.0, 6.0, 8.0)),
            BackgroundObject("tree", (8.0, -9.0), (3.0, 3.0, 6.0)),
            BackgroundObject("pole", (4.0, -7.5), (0.3, 0.3, 5.0)),
        ),
        name="junction",
    )
    return render(scene)


# The "pedestrian" the network reports at the junction's building corner (20.5, 13.2),
# 32.8 degrees from the sensor, with about 70 returns, which each fault below leaves in
# place. What the tests are about is that the fault takes none of its returns (the
# count after the fault equals the count before), not the count itself: the ray
# caster's release decides whether the corner holds 69 or 70 of them (embreex 4.4 and
# trimesh 5.2 render 70), and a test must not hinge on that.
CORNER_PEDESTRIAN_LOST = (
    r"pedestrian at \(20\.5, 13\.2\) lost although its box still holds (?P<after>\d+) "
    r"points after the fault \((?P<before>\d+) before"
)


def _assert_untouched_pedestrian_lost(error: pytest.ExceptionInfo[MetamorphicViolation]) -> None:
    """The violation lost the corner's pedestrian, and the fault took none of its returns."""
    found = re.search(CORNER_PEDESTRIAN_LOST, str(error.value))
    assert found, str(error.value)
    assert found["after"] == found["before"], found.group(0)
    assert int(found["after"]) >= 30  # well covered: the relation's own floor


def _check_on_the_junction(name: str, fault: DropAzimuthBlock | DropRings) -> Callable[[], None]:
    """A one-example metamorphic test: the junction, and ``fault`` applied to it, through
    the ROI-feature network, well-covered obstacles kept."""
    relation = MetamorphicRelation(
        name,
        lambda frame: st.just(Followup(fault.apply(frame), fault.params())),
        CoveredObstaclesKept(),
    )

    @settings(max_examples=1, database=None, phases=[Phase.generate], deadline=None,
              suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=st.just(_junction()), relations=[relation], followups=1, batch=True)
    def check(frames: list[Frame]) -> list[list[Box]]:
        return roi_only.detect_batch(frames)

    return check


def test_two_lost_packets_beside_it_make_the_network_drop_a_pedestrian() -> None:
    # A real weakness, found by bench/mutation_score.py's 100-case search on its junction:
    # the network reports a "pedestrian" at (20.5, 13.2), at the building's corner (32.8
    # degrees), with about 70 returns, and loses it when the two packets at 29.7-31.7 degrees
    # are lost, which hold none of them. A detection near the network's threshold flips
    # when its surroundings change; so lost packets are not claimed for this model.
    check = _check_on_the_junction(
        "two packets beside it lost => well-covered obstacles kept",
        DropAzimuthBlock(math.radians(29.663), math.radians(2.074)),
    )
    with pytest.raises(MetamorphicViolation) as error:
        check()
    _assert_untouched_pedestrian_lost(error)


def test_one_dead_laser_makes_the_network_drop_the_same_pedestrian() -> None:
    # The same "pedestrian" at the junction's building corner, lost when laser 45 of the
    # HDL-64E is dead, which takes none of its returns (of the 64 single dead lasers,
    # 45 and 52 lose it): so dead lasers are not claimed for this model either.
    check = _check_on_the_junction("laser 45 dead => well-covered obstacles kept", DropRings([45]))
    with pytest.raises(MetamorphicViolation) as error:
        check()
    _assert_untouched_pedestrian_lost(error)


@pytest.mark.slow  # about a minute: the follow-up's reduction runs 500 SUT calls
def test_repeating_returns_makes_the_detector_report_a_cyclist_it_drops_otherwise() -> None:
    # A real non-invariance, found on the first held-out street: a cyclist 31 m away
    # seen by 8 returns is below the detector's 10-return minimum (Apollo's min_pts_num
    # counts points too); with every return repeated it has 16 and is reported, as a
    # "pedestrian". A sensor in dual-return mode, or two drivers publishing one topic,
    # does this.
    (repeated,) = [r for r in LEARNED_RELATIONS if r.name.startswith("points repeated")]

    @settings(max_examples=3, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=st.just(held_out_frame(0)), relations=[repeated], followups=1, batch=True)
    def check(frames: list[Frame]) -> list[list[Box]]:
        return roi_only.detect_batch(frames)

    with pytest.raises(
        MetamorphicViolation, match=r"pedestrian at \(26\.0, -16\.1\) has no match in the source"
    ):
        check()


def test_removing_a_car_moves_another_12_m_away() -> None:
    # A real weakness (the claims bench found it on an earlier model; this one held its
    # 1048 follow-ups): the network reads an object's surroundings, so removing one road
    # user (its returns, with the ground behind it filled in) can change what it reports
    # for another. Here, on held-out street 27 (the only one of streets 0-39 where ten
    # derandomized removals find one), removing a
    # car 53 m from the sensor moves the box of a car 67 m away (their footprints 12 m
    # apart), whose returns it does not touch, by 0.85 m.
    (removed,) = [r for r in LEARNED_RELATIONS if r.name.startswith("an object removed")]

    @settings(max_examples=10, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=st.just(held_out_frame(27)), relations=[removed], followups=1, batch=True)
    def check(frames: list[Frame]) -> list[list[Box]]:
        return roi_only.detect_batch(frames)

    with pytest.raises(
        MetamorphicViolation,
        match=r"car at \(-38\.2, 55\.1\) \(12\.0 m from the removed car at "
        r"\(-35\.6, 39\.1\)\) has no match",
    ):
        check()


def test_rain_makes_the_network_lose_road_users_it_still_sees() -> None:
    # The network was trained on clear sweeps; droplet echoes within 22 m of the sensor
    # are new to it. A real weakness: in rain of 50 m visibility it loses road users near
    # the sensor that keep nearly all their returns (4 of the first 10 held-out streets;
    # here a car 6 m away keeping 5834 of its 5900 returns).
    @settings(max_examples=10, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(
        source=st.just(held_out_frame(4)),
        relations=[adverse_weather(kinds=("rain",), visibilities=(50.0,))],
        followups=1,
        batch=True,
    )
    def check(frames: list[Frame]) -> list[list[Box]]:
        return roi_only.detect_batch(frames)

    with pytest.raises(MetamorphicViolation, match=r"car at \(5\.9, 1\.6\) lost although"):
        check()


def test_a_pitch_of_three_degrees_makes_the_network_lose_most_of_a_car() -> None:
    # A real weakness: the network was trained on level sensors (and a tilt of the
    # training sweeps' degradations), yet on held-out street 18 the sensor pitched 3
    # degrees nose down, as under hard braking, leaves a car 27 m away with fewer than
    # half of its returns in the car the network reports there. The relation's own
    # search on rendered streets found a car 10 m away turned into a "cyclist" by a pitch
    # of 1 degree; on held-out streets 0-39, 4 of 480 poses fail (this one the clearest).
    (posed,) = [r for r in LEARNED_RELATIONS if r.name.startswith("sensor pitched")]
    pitched = SensorPose(pitch_deg=3.0)
    relation = MetamorphicRelation(
        posed.name,
        lambda frame: st.just(Followup(pitched.apply(frame), pitched.params())),
        posed.relation,
    )

    @settings(max_examples=1, database=None, phases=[Phase.generate], deadline=None,
              suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=st.just(held_out_frame(18)), relations=[relation], followups=1, batch=True)
    def check(frames: list[Frame]) -> list[list[Box]]:
        return roi_only.detect_batch(frames)

    with pytest.raises(MetamorphicViolation, match=r"source car at \(25\.\d, -7\.\d\) \(seen from"):
        check()


# The paper's protocol on the learned model (``--mt-campaign``): 200 rendered scenes,
# 10 / 100 / 1000 points outside the ROI, default ROI scope. bench/learned.py runs it on
# the real KITTI sweeps (the README's table).
SOURCES = 200
test_mr1_cnnseg_full_cloud = campaign_test(
    mr1_campaign(
        full_cloud, name="MR1 cnnseg full_cloud=True", sources=SOURCES, matcher=LEARNED.kept
    ),
    max_rate=None,  # Apollo's defect, measured, not gated
)
test_mr1_cnnseg_roi_only = campaign_test(
    mr1_campaign(
        roi_only, name="MR1 cnnseg full_cloud=False", sources=SOURCES, matcher=LEARNED.kept
    ),
)
