"""How many relation runs tested something: the share of (system, frames, relation) runs in
which the relation changed the input and judged at least one obstacle.

A relation "passes" vacuously when it could not make a follow-up (no object to insert, no
lasers to lose), every follow-up equalled its source, or it judged no obstacle; the
engine reports that as NOTHING TESTED (:func:`pytest_metamorphic.core.stats.nothing_tested`).
Each run here is one derandomized ``@metamorphic`` test of every relation of
``lidar_relations()`` (the ``"learned"`` tolerance profile for the learned model;
insertion takes a frame's own labelled objects and the built-in rendered road users, the
only objects a frame without labels has), 3 sources, 1 follow-up each.

* **own**: the pairs the project's examples run: the reference pipeline on two labelled
  KITTI sweeps and a rendered HDL-64E street, the scikit-learn detector on the KITTI
  sweeps, the learned model (ROI features) on rendered streets, and the example's own
  detector (``examples/test_your_recordings.py``) on rendered VLP-16 and OS1-128 streets.
* **other**: every system on one sweep each of the real VLP-16, VLP-32C and OS1-64
  recordings (a 7 m corridor ROI, no labels, sensors identified from the clouds), and the
  reference and scikit-learn detectors on the rendered VLP-16 and OS1-128 streets.

Prints a line per run that tested nothing, with the reason, and ends with
``RESULT judged_share=<own> judged_share_other=<other> violations=<n>``.

    python bench/judged_share.py
"""

from __future__ import annotations

import importlib
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import conftest  # noqa: E402

# The examples are loaded by name: mypy checks them as files of their own (examples/ is no
# package), and a static import would make it see each twice.
_sklearn_example = importlib.import_module("examples.test_sklearn_detector")
_your_recordings = importlib.import_module("examples.test_your_recordings")
SklearnDetector = _sklearn_example.SklearnDetector
RECORDINGS = _your_recordings.RECORDINGS
my_detector = _your_recordings.my_detector
from pytest_metamorphic import MetamorphicViolation, metamorphic  # noqa: E402
from pytest_metamorphic.core.stats import Recorder, nothing_tested, recording  # noqa: E402
from pytest_metamorphic.lidar.io.catalog import FrameCatalog  # noqa: E402
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.judging.tolerance import as_tolerance  # noqa: E402
from pytest_metamorphic.lidar.model.frame import Frame  # noqa: E402
from pytest_metamorphic.lidar.model.sensors import HDL64E, OS1_128, VLP16  # noqa: E402
from pytest_metamorphic.lidar.roi import corridor_roi  # noqa: E402
from pytest_metamorphic.lidar.synthetic import render  # noqa: E402
from pytest_metamorphic.lidar.synthetic.layout import random_scene  # noqa: E402
from pytest_metamorphic.lidar.systems.perception import ReferencePerception  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation  # noqa: E402
from pytest_metamorphic.relations.lidar import lidar_relations  # noqa: E402

KITTI = conftest.SHARED_DATA / "kitti_openpcdet" / "training"
SEARCH = settings(
    max_examples=3,
    database=None,
    deadline=None,
    derandomize=True,
    suppress_health_check=list(HealthCheck),
)


def _streets(sensor: Any, seeds: Sequence[int]) -> list[Frame]:
    return [
        render(random_scene(np.random.default_rng(seed), name=f"street {seed}"), beams=sensor)
        for seed in seeds
    ]


def frame_sets() -> dict[str, list[Frame]]:
    kitti = FrameCatalog(str(KITTI / "velodyne"), roi=kitti_label_region(), labels=True)
    return {
        "KITTI + street": [kitti[1], kitti[4], *_streets(HDL64E, (3,))],
        "KITTI": [kitti[1], kitti[4]],
        "rendered HDL-64E": _streets(HDL64E, (2, 3, 7)),
        "rendered VLP-16 + OS1-128": [*_streets(VLP16, (2, 7)), *_streets(OS1_128, (2, 7))],
        "VLP-16, VLP-32C, OS1-64 recordings": [
            FrameCatalog(path, topic=topic, roi=corridor_roi(width=7.0))[0]
            for path, topic in RECORDINGS.values()
        ],
    }


def relations(tolerance: str) -> list[Any]:
    """The library with the given tolerance profile."""
    return lidar_relations(tolerance=as_tolerance(tolerance))  # type: ignore[arg-type]


def run(
    system: Callable[[Frame], Any], frames: list[Frame], tolerance: str = "exact"
) -> tuple[dict[str, str | None], list[str]]:
    """Every relation on ``frames``: {relation: why it tested nothing, or None}, and the
    relations violated."""
    recorder = Recorder(followups=1, check_determinism=False, minimize_budget=0)
    violations = []
    for mr in relations(tolerance):

        @SEARCH
        @metamorphic(source=st.sampled_from(frames), relations=[mr], followups=1)
        def test(frame: Frame) -> Any:
            return system(frame)

        try:
            with recording(recorder), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                test()
        except MetamorphicViolation:
            violations.append(mr.name)
    verdicts = {
        name: nothing_tested(stats, recorder.reasons.get(name, ""))
        for name, stats in recorder.relations.items()
    }
    for name, stats in recorder.relations.items():
        if stats.violations:  # a violation judged something
            verdicts[name] = None
    return verdicts, violations


def main() -> None:
    sets = frame_sets()
    reference, sklearn = ReferencePerception(), SklearnDetector()
    learned = CNNSegmentation(full_cloud=False)
    recordings = sets["VLP-16, VLP-32C, OS1-64 recordings"]
    other_sensors = sets["rendered VLP-16 + OS1-128"]
    plan: list[tuple[str, str, Callable[[Frame], Any], list[Frame]]] = [
        ("own", "reference", reference, sets["KITTI + street"]),
        ("own", "scikit-learn", sklearn, sets["KITTI"]),
        ("own", "learned (ROI features)", learned, sets["rendered HDL-64E"]),
        ("own", "example's detector", my_detector, other_sensors),
        *(
            ("other", name, system, recordings)
            for name, system in (
                ("reference", reference),
                ("scikit-learn", sklearn),
                ("learned (ROI features)", learned),
                ("example's detector", my_detector),
            )
        ),
        ("other", "reference", reference, other_sensors),
        ("other", "scikit-learn", sklearn, other_sensors),
    ]
    tested: dict[str, list[bool]] = {"own": [], "other": []}
    total_violations = 0
    started = time.perf_counter()
    for kind, name, system, frames in plan:
        verdicts, violated = run(system, frames, "learned" if system is learned else "exact")
        total_violations += len(violated)
        where = frames[0].source.split("/")[-1] if kind == "other" else kind
        judged = sum(reason is None for reason in verdicts.values())
        print(f"{kind:5} {name:24} {len(frames)} frames ({where}): {judged}/{len(verdicts)} "
              f"relations tested something, violated: {violated or 'none'}")  # fmt: skip
        for relation, reason in verdicts.items():
            if reason is not None:
                print(f"      nothing tested: {relation}: {reason}")
        tested[kind] += [reason is None for reason in verdicts.values()]
    own = sum(tested["own"]) / len(tested["own"])
    other = sum(tested["other"]) / len(tested["other"])
    print(f"({time.perf_counter() - started:.0f} s)")
    print(f"RESULT judged_share={own:.3f} judged_share_other={other:.3f} "
          f"violations={total_violations}")  # fmt: skip


if __name__ == "__main__":
    main()
