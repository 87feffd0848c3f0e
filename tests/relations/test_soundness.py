"""Soundness: every relation of the library against detectors the project did not write
(issue 26). A violation on one of them must be a real weakness of that detector, named
below with its mechanism (and in docs/lidar.md, "Detectors from outside"); any other
violation is a false alarm of the library and fails this module.

Detectors: the scikit-learn example (RANSAC ground on the ROI, DBSCAN on 10 cm voxels,
PCA boxes; ``examples/test_sklearn_detector.py``) and a DBSCAN detector with ties
(cell-minimum ground, DBSCAN in the sweep's own order; ``tests/lidar/systems/
ties_detector.py``). The whole-scene variant of the reference has its own module
(``tests/lidar/systems/perception/test_whole_scene.py``, every relation on KITTI and
rendered streets). Frames: labelled KITTI sweeps (labels give insertion its templates)
and a rendered street. Follow-ups: each relation's own strategy, derandomized, so the
run is the same on every machine; the default suite runs a slice, ``-m slow`` all of it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from pytest_metamorphic.core.cases import Followup, MetamorphicRelation
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.judging.tolerance import ToleranceLike
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.relations.lidar import lidar_relations
from tests.core.lidar_cases import labelled_kitti, street

pytest.importorskip("sklearn", reason="scikit-learn is not installed: pip install '.[sklearn]'")
import conftest
from examples.test_sklearn_detector import SklearnDetector
from examples.test_your_recordings import my_detector
from pytest_metamorphic.lidar.systems.perception import ReferencePerception
from tests.lidar.systems.ties_detector import TiesDetector

#: (detector, relation name prefix) -> the real weakness a violation shows.
KNOWN: dict[tuple[str, str], str] = {
    ("reference", "packets lost"): (
        "an obstacle surrounding the sensor itself on the VLP-16 recording: see "
        "_open_reference_finding, which holds the reference to that one case"
    ),
    ("scikit-learn", "cloud and ROI turned"): (
        "RANSAC's 50 random trials fit another plane to the turned sweep's ROI points "
        "(its random_state draws rows by index): objects move or vanish"
    ),
    ("scikit-learn", "cloud and ROI mirrored"): "the same RANSAC plane change as turns",
    ("scikit-learn", "beams missing"): "a dead laser moves the RANSAC plane",
    ("scikit-learn", "packets lost"): "a lost packet moves the RANSAC plane",
    ("scikit-learn", "an object inserted"): (
        "its 40 m range cap: an object put beyond it (the far field); and, as for removal, "
        "the inserted returns change the rows RANSAC's seeded samples pick: another plane (a "
        "pedestrian 9.5 m from an inserted row of parked cars lost on KITTI sweep 5). In the "
        "near field a van or lorry beside the car holds more returns than the road around "
        "it (11,000-15,000 of a KITTI sweep's 120,000): RANSAC's plane runs through its face "
        "(measured on KITTI sweep 3, a van 5.8 m ahead: the fitted slope 0.52 in x, 0.015 "
        "without it), the van is not detected and cars 10-30 m away lose their match"
    ),
    ("scikit-learn", "sensor pitched"): (
        "its DBSCAN (eps 0.45 m) clusters the bird's-eye positions of the sensor's frame: "
        "tilted by 1.8 deg of pitch and 1.2 deg of roll, the returns 2-3 m up lean by 8-11 "
        "cm and two parked cars 30 m away on KITTI sweep 4 chain into one unknown box; its "
        "ground plane follows the tilt (a deterministic plane in place of RANSAC fails "
        "alike), and each angle alone keeps them apart"
    ),
    ("scikit-learn", "fog or rain"): "droplet echoes tilt the RANSAC plane (3.4 deg in fog)",
    # Checked on the other sensors' frames: with a deterministic robust plane
    # (HuberRegressor, no sampling of rows) in place of RANSAC, the quantisation, removal,
    # dead-laser and fog violations there all vanish; only the range cap's remains.
    ("scikit-learn", "ranges quantized"): (
        "5 cm range steps move the returns RANSAC's samples are judged by: another plane"
    ),
    ("scikit-learn", "an object removed"): (
        "the removed returns shift every later row RANSAC's seeded samples pick: another plane"
    ),
    ("example's detector", "an object inserted"): (
        "its 50 m range cap: a car put at 62 m (1.5x where it was seen) is cropped; with "
        "max_range=1000 the search finds nothing"
    ),
    ("DBSCAN ties", "an object inserted"): (
        "it has no cyclist class (the example's size rules), so an inserted cyclist can be a "
        "'pedestrian'; and its ground is each 0.5 m cell's lowest return: a car far away, "
        "whose surrounding ground is unseen, loses its lowest rows to it (29 of 36 returns of "
        "a car at 43.5 m) and the rest is too sparse for DBSCAN"
    ),
    ("DBSCAN ties", "sensor pitched"): (
        "its height cut is absolute, z < 1.5 m in the sensor frame (a level sensor's): "
        "pitched 1.8 deg nose down, a car 29 m ahead on KITTI sweep 4 rises by 0.9 m and 81 "
        "of its 209 returns go above the cut (measured; rolled or raised alone it holds)"
    ),
    ("DBSCAN ties", "an object moved"): (
        "DBSCAN over its cell-minimum ground chains a pedestrian moved 30 % farther (to 11.4 "
        "m on KITTI sweep 0) into the roadside object 2 m from it: one 8.8 x 4 m unknown box"
    ),
    ("DBSCAN ties", "points repeated"): (
        "no de-duplication: repeated returns double the density DBSCAN counts, so new "
        "clusters appear and small ones merge"
    ),
}


@dataclass(frozen=True)
class Found:
    detector: str
    relation: str
    frame: str
    params: str
    explanation: str

    def __str__(self) -> str:
        return f"{self.detector} / {self.relation} / {self.frame} {self.params}: {self.explanation}"


def violations(
    name: str,
    detector: Callable[[Frame], Any],
    frames: dict[str, Frame],
    *,
    examples: int,
    tolerance: ToleranceLike = "exact",
) -> list[Found]:
    """Every violation of every relation of the library by ``detector``: ``examples``
    derandomized follow-ups per relation and frame, under the ``tolerance`` profile."""
    found: list[Found] = []
    for label, frame in frames.items():
        source_output = detector(frame)
        for relation in lidar_relations(tolerance=tolerance):
            found += _search(name, detector, relation, label, frame, source_output, examples)
    return found


def _search(
    name: str,
    detector: Callable[[Frame], Any],
    relation: MetamorphicRelation,
    label: str,
    frame: Frame,
    source_output: Any,
    examples: int,
) -> list[Found]:
    found: list[Found] = []
    relation = MetamorphicRelation(relation.name, relation.followup, _SkipAware(relation.relation))

    @settings(
        max_examples=examples,
        derandomize=True,
        database=None,
        deadline=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(st.data())
    def run(data: st.DataObject) -> None:
        drawn = data.draw(relation.followup(frame))
        followup = drawn if isinstance(drawn, Followup) else Followup(drawn)
        context = CheckContext(frame, followup.input, followup.params, 0)
        compared = followup.compared_output(detector, source_output)  # a history's baseline
        verdict = relation.relation.check(compared, detector(followup.input), context)
        if not verdict.holds:
            shown = {k: v for k, v in followup.params.items() if _plain(v)}
            found.append(Found(name, relation.name, label, str(shown), verdict.explanation))

    run()
    return found


class _SkipAware(Relation):
    """A follow-up the transform could not make (no free place, ...) tests nothing: it
    holds. (Not a filter in ``run``: its source seeds the derandomized search.)"""

    def __init__(self, relation: Relation) -> None:
        self.relation, self.name = relation, relation.name

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        if "not_applicable" in context.params:
            return Verdict(True, self.name)
        return self.relation.check(source_output, followup_output, context)


def _plain(value: Any) -> bool:
    return isinstance(value, (int, float, str)) or (
        isinstance(value, (list, tuple)) and len(value) <= 8
    )


def unexplained(found: list[Found]) -> list[str]:
    return [
        str(item)
        for item in found
        if not any(
            item.detector == detector and item.relation.startswith(prefix)
            for detector, prefix in KNOWN
        )
    ]


DETECTORS = {"scikit-learn": SklearnDetector, "DBSCAN ties": TiesDetector}


@pytest.mark.parametrize(
    "name",
    # DBSCAN ties take 40 s here: with the slow tests, which run them on every sweep too
    [
        pytest.param(n, marks=pytest.mark.slow) if n == "DBSCAN ties" else n
        for n in sorted(DETECTORS)
    ],
)
def test_every_relation_on_two_kitti_sweeps_and_a_rendered_street(name: str) -> None:
    frames = {"KITTI 1": labelled_kitti(1), "KITTI 4": labelled_kitti(4), "street": street()}
    found = violations(name, DETECTORS[name](), frames, examples=2)
    assert unexplained(found) == []
    if name == "DBSCAN ties":  # the search does see violations: the known weakness shows
        # (on which sweeps depends on the derandomized draws, which follow this file's code)
        assert {item.frame for item in found if item.relation.startswith("points repeated")}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(DETECTORS))
def test_every_relation_on_every_kitti_sweep(name: str) -> None:
    frames = {f"KITTI {i}": labelled_kitti(i) for i in range(6)} | {"street": street()}
    assert unexplained(violations(name, DETECTORS[name](), frames, examples=4)) == []


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(DETECTORS))
def test_every_relation_under_the_learned_profile(name: str) -> None:
    """The learned profile is looser (places, not sizes or headings of turned obstacles),
    and judges classes where the exact one does: it raises no alarm of its own."""
    frames = {"KITTI 1": labelled_kitti(1), "KITTI 4": labelled_kitti(4), "street": street()}
    found = violations(name, DETECTORS[name](), frames, examples=2, tolerance="learned")
    assert unexplained(found) == []


def test_an_unnamed_violation_fails_the_module() -> None:
    mine = Found("DBSCAN ties", "points reordered => O == O'", "KITTI 1", "{}", "lost")
    known = Found("DBSCAN ties", "points repeated => O == O'", "KITTI 1", "{}", "new")
    assert unexplained([mine, known]) == [str(mine)]


def other_sensor_frames() -> dict[str, Frame]:
    """One sweep each of the real VLP-16, VLP-32C and OS1-64 recordings (no labels, a 7 m
    corridor ROI, the sensor identified from the cloud) and a street rendered with a
    VLP-16 and with an OS1-128."""
    from examples.test_your_recordings import recorded_frames, rendered_frames

    recorded = dict(zip(("VLP-16", "VLP-32C", "OS1-64"), recorded_frames(), strict=True))
    rendered = rendered_frames()
    return recorded | {"rendered VLP-16": rendered[0], "rendered OS1-128": rendered[1]}


OTHER_SENSORS = {
    "reference": ReferencePerception,
    "example's detector": lambda: my_detector,
    **DETECTORS,
}


@pytest.mark.parametrize(
    "name",
    # The clustering detectors take 20-60 s here: with the slow tests.
    [
        pytest.param(n, marks=pytest.mark.slow) if n in DETECTORS else n
        for n in sorted(OTHER_SENSORS)
    ],
)
def test_every_relation_on_other_sensors_recordings_and_renders(name: str) -> None:
    conftest.shared_data_path("nebula_velodyne")
    found = violations(name, OTHER_SENSORS[name](), other_sensor_frames(), examples=2)
    assert unexplained(found) == []
    if name == "reference":  # a correct system: nothing but its one open finding
        assert [item for item in found if not _open_reference_finding(item)] == []


def _open_reference_finding(item: Found) -> bool:
    """The reference's one known violation on these recordings, found when this module's
    derandomized draws shifted (2026-11-28; the same input does it on 1c1f714): on the
    VLP-16 recording an obstacle surrounding the sensor itself (its platform's returns,
    2.5 x 1.2 x 0.3 m at (0.4, -0.1)) is in no follow-up box once a packet behind the
    sensor is lost, although 1,434 of its 2,012 returns above the ground remain. Not yet
    pinned down (MinBox picks the hull edges facing the sensor, and here the sensor stands
    inside the hull): kept open here so that any other violation still fails."""
    return (
        item.detector == "reference"
        and item.relation.startswith("packets lost")
        and item.frame == "VLP-16"
        and "unknown at (0.4, -0.1)" in item.explanation
    )
