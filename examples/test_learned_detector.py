"""Testing a learned detector: Apollo-style CNN segmentation, trained here, run with ONNX.

The system under test is the project's own learned model
(:class:`~pytest_metamorphic.lidar.systems.perception.cnnseg.CNNSegmentation`): a small U-Net on
Apollo's bird's-eye feature grid, trained on rendered HDL-64E streets and shipped as an
ONNX file that onnxruntime runs on the CPU (no PyTorch needed). It comes in Apollo's two
configurations:

* ``full_cloud=True`` (Apollo 2.x/3.0's ``use_full_cloud: true``): the network's features
  are built from the whole sweep, so points added off the road change what it predicts
  for cars on the road: Zhou & Sun's MR1 finds this, as it found it in Apollo;
* ``full_cloud=False``: features from the ROI's points alone (the fix): nothing outside
  the ROI reaches the network.

A network is never exactly equivariant: turning or mirroring the sweep, repeating points,
changes its maps a little; boxes move by centimetres, a border cell flips, a pedestrian
comes out in two pieces. The relations therefore run with the *learned* tolerance
(``lidar_relations(tolerance="learned")``, :mod:`pytest_metamorphic.lidar.judging.tolerance`): a
violation is an obstacle gone or displaced by more than 0.5 m, never jitter. With it the
ROI-feature model satisfies the library but for what it does not claim: quarter turns
and the mirror (a network is not equivariant by construction: rare real inconsistencies
remain, see the README), object insertion (objects are put up to 1.5 times as far as
they were seen, past the network's 40 m grid) and weather, which shows a real weakness
below (it never saw rain in training).

    pytest examples/test_learned_detector.py                 # the Hypothesis tests
    pytest examples/test_learned_detector.py --mt-campaign   # + the paper's table on it

To test your own network, replace ``CNNSegmentation`` with a function ``Frame ->
list[Box]``, or give it ``run_batch(frames)`` and ``batch_size`` so that campaigns hand it
batches (``pytest_metamorphic.core.batching``).
"""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

from pytest_metamorphic import MetamorphicViolation, metamorphic
from pytest_metamorphic import strategies as mst
from pytest_metamorphic.core.campaign import campaign_test
from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.judging.tolerance import LEARNED
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.relations.lidar import adverse_weather, lidar_relations, mr1_subset

pytest.importorskip("onnxruntime", reason="onnxruntime is not installed: pip install '.[learned]'")

from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import held_out_frame

LIDAR = [HealthCheck.too_slow, HealthCheck.large_base_example, HealthCheck.data_too_large]
full_cloud = CNNSegmentation(full_cloud=True)
roi_only = CNNSegmentation(full_cloud=False)


# Not claimed (README, "Testing a learned detector"): turns and the mirror (a network is
# not equivariant by construction), insertion (past its 40 m grid) and moved objects (it
# calls moved pedestrians cars: docs/learned-model.md), weather (shown below).
NOT_CLAIMED = (
    "cloud and ROI turned",
    "cloud and ROI mirrored",
    "an object inserted",
    "an object moved",
    "fog or rain",
)
CLAIMED = [
    relation
    for relation in lidar_relations(tolerance="learned")
    if not relation.name.startswith(NOT_CLAIMED)
]


# The streets the model was trained on: obstacles within 50 m (random_scene's default, as
# in its training data); its grid covers 40 m, so farther obstacles are not claimed.
STREETS = mst.scene_frames(mst.scenes(max_distance=50.0))


@settings(max_examples=5, suppress_health_check=LIDAR, deadline=None)  # ~50 ms per call
@metamorphic(
    source=STREETS,
    relations=CLAIMED,
    followups=1,
    batch=True,  # the source and its follow-ups go through the network as one batch
)
def test_roi_features_satisfy_the_relation_library(frames: list[Frame]) -> list[list[Box]]:
    return roi_only.detect_batch(frames)


def test_mr1_catches_features_built_from_the_whole_sweep() -> None:
    # Derandomized: a test that asserts a fault is found must not depend on the seed.
    @settings(max_examples=40, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=STREETS, relations=[mr1_subset(matcher=LEARNED.kept)],
                 followups=2, batch=True)  # fmt: skip
    def check(frames: list[Frame]) -> list[list[Box]]:
        return full_cloud.detect_batch(frames)

    # Two points 39 m away, off the road, move a car near the ROI's edge by 0.6 m.
    with pytest.raises(MetamorphicViolation, match="has no match in follow-up"):
        check()


def test_rain_makes_the_network_lose_road_users_it_still_sees() -> None:
    # The network was trained on clear sweeps; droplet echoes within 22 m of the sensor
    # are new to it. A real weakness: in rain of 50 m visibility it loses road users
    # within about 15 m that keep nearly all their returns (5 of the first 18 held-out
    # scene and rain-seed pairs; here a cyclist 8 m away keeping 362 of its 364 returns).
    @settings(max_examples=10, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(
        source=st.just(held_out_frame(5)),
        relations=[adverse_weather(kinds=("rain",), visibilities=(50.0,))],
        followups=1,
        batch=True,
    )
    def check(frames: list[Frame]) -> list[list[Box]]:
        return roi_only.detect_batch(frames)

    with pytest.raises(MetamorphicViolation, match=r"cyclist at \(2\.0, 8\.2\) lost although"):
        check()


# The paper's protocol on the learned model (``--mt-campaign``): 200 rendered scenes,
# 10 / 100 / 1000 points outside the ROI, default ROI scope. bench/learned.py runs 1000.
SOURCES = 200
test_mr1_cnnseg_full_cloud = campaign_test(
    mr1_campaign(
        full_cloud, name="MR1 cnnseg full_cloud=True", sources=SOURCES, matcher=LEARNED.kept
    ),
    max_rate=None,  # Apollo's defect, measured (a rate below 1 %), not gated
)
test_mr1_cnnseg_roi_only = campaign_test(
    mr1_campaign(
        roi_only, name="MR1 cnnseg full_cloud=False", sources=SOURCES, matcher=LEARNED.kept
    ),
)
