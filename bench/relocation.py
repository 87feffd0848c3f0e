"""Moved and inserted objects on correct detectors: classes, how far boxes stray, and
every violation.

Every car, pedestrian and cyclist of the six labelled KITTI sweeps and the three rendered
streets of ``bench/mutation_score.py`` that can move is moved by up to six of its free
moves of each kind (spread over the list, smallest first:
``Movable.moves``), and :func:`~pytest_metamorphic.relations.lidar.object_relocation`'s
checks judge each detector's output. Printed per detector: the moves judged, the
violations with their messages, and per kind of move the quantiles of how far the found
box's centre lies outside the moved footprint (m) and how far its heading is off
(degrees, long narrow boxes only): the margins the default tolerances (0.5 m, 30 degrees)
leave. Then the classes of inserted objects: every template of those frames put at
every sixth of its free places, and the class of the obstacle holding most of its
returns (what :func:`~pytest_metamorphic.relations.lidar.object_insertion` judges).

    python bench/relocation.py [--detectors reference,whole_scene,sklearn,ties,cnnseg_roi]
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from mutation_score import KITTI, rendered_scenes  # noqa: E402

from pytest_metamorphic.core.relations import CheckContext  # noqa: E402
from pytest_metamorphic.lidar.followups.edit import removal_candidates  # noqa: E402
from pytest_metamorphic.lidar.followups.insert.relocation import Movable  # noqa: E402
from pytest_metamorphic.lidar.io.catalog import FrameCatalog  # noqa: E402
from pytest_metamorphic.lidar.judging.evaluation import kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.judging.scope import as_scope  # noqa: E402
from pytest_metamorphic.lidar.model.sensors import BeamLayout, frame_sensor  # noqa: E402
from pytest_metamorphic.relations.lidar import object_relocation  # noqa: E402

PER_KIND = 6


def detector(name: str) -> Any:
    if name == "reference":
        from pytest_metamorphic.lidar.systems.perception import ReferencePerception

        return ReferencePerception()
    if name == "whole_scene":
        from pytest_metamorphic.lidar.systems.perception.whole_scene import (
            WholeScenePerception,
        )

        return WholeScenePerception()
    # Imported by name: the example and the test detector are files, not a package.
    if name == "sklearn":
        return importlib.import_module("examples.test_sklearn_detector").SklearnDetector()
    if name == "ties":
        return importlib.import_module("tests.lidar.systems.ties_detector").TiesDetector()
    if name == "cnnseg_roi":
        from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation

        return CNNSegmentation(full_cloud=False)
    from pytest_metamorphic.lidar.systems.perception.mutants import mutant

    return mutant(name)


def _layout(frame: Any) -> BeamLayout:
    sensor = frame_sensor(frame).sensor
    assert isinstance(sensor, BeamLayout), f"{frame!r}: no spinning sensor to re-cast with"
    return sensor


def measure(name: str, frames: dict[str, Any]) -> tuple[int, int]:
    system = detector(name)
    check = object_relocation().relation
    scope = as_scope("roi")
    judged = violations = 0
    margins: dict[str, list[tuple[float, float | None]]] = defaultdict(list)
    kind: str
    started = time.perf_counter()
    for label, frame in frames.items():
        layout = _layout(frame)
        source = system(frame)
        for box in removal_candidates(frame, scope=scope):
            item = Movable.of(frame, box)
            if item is None:
                continue
            for kind, moves in item.moves(layout=layout, scope=scope).items():
                for move in moves[:: max(1, len(moves) // PER_KIND)][:PER_KIND]:
                    relocation = item.relocate(move, layout=layout)
                    if relocation is None:
                        continue
                    followup = relocation.apply(frame)
                    context = CheckContext(frame, followup, relocation.params(), 0)
                    verdict = check.check(source, system(followup), context)
                    # The first part's details: RelocatedFound's (then OthersKept's).
                    found = next(iter(verdict.details.values()))
                    if found.get("judged"):
                        judged += 1
                        margins[kind].append(
                            (found.get("outside_footprint", 0.0), found.get("heading_gap"))
                        )
                    if not verdict.holds:
                        violations += 1
                        print(f"  VIOLATION {label} {box.describe()} {move.describe()}: "
                              f"{verdict.explanation[-300:]}")  # fmt: skip
    seconds = time.perf_counter() - started
    print(f"{name}: {judged} moves judged, {violations} violation(s) in {seconds:.0f} s")
    for kind, values in margins.items():  # kind: "range", "bearing" or "turn"
        outside = np.array([v[0] for v in values])
        heading = np.array([v[1] for v in values if v[1] is not None])
        spread = np.round(np.quantile(outside, [0.5, 0.9, 1.0]), 2)
        line = f"  {kind:8s} {len(values):4d}  outside footprint q50/q90/max {spread}"
        if len(heading):
            turns = np.round(np.quantile(heading, [0.5, 0.9, 1.0]), 1)
            line += f"  heading q50/q90/max {turns}"
        print(line)
    return judged, violations


def insertion_classes(name: str, frames: dict[str, Any]) -> tuple[int, int]:
    """(insertions judged, found as another road-user class), printing the tally."""
    from pytest_metamorphic.lidar.followups.insert import (
        InsertObject,
        free_placements,
        object_templates,
    )

    system = detector(name)
    tally: Counter[tuple[str, str]] = Counter()
    for frame in frames.values():
        layout = _layout(frame)
        for template in object_templates(frame, scope="roi"):
            for place in free_placements(frame, template, layout=layout)[::6]:
                insertion = InsertObject.onto(frame, template, place, layout=layout)
                if len(insertion) < 30:
                    continue
                points = insertion.points[:, :3]
                boxes = system(insertion.apply(frame))
                held = [int(box.grown(0.1).contains(points).sum()) for box in boxes]
                best = int(np.argmax(held)) if held else -1
                found = boxes[best].label if held and 2 * held[best] >= len(points) else "missed"
                tally[(template.label, found)] += 1
    wrong = sum(
        n for (truth, found), n in tally.items() if found not in (truth, "unknown", "missed")
    )
    shown = ", ".join(f"{truth} as {found}: {n}" for (truth, found), n in sorted(tally.items()))
    print(f"{name} insertions: {sum(tally.values())} ({shown}); another class: {wrong}")
    return sum(tally.values()), wrong


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--detectors", default="reference,whole_scene,sklearn,ties,cnnseg_roi")
    args = parser.parse_args()
    if not KITTI.is_dir():
        sys.exit(f"KITTI frames not found at {KITTI} (set PYTEST_METAMORPHIC_DATA)")
    catalog = FrameCatalog(KITTI, roi=kitti_label_region())
    frames = {f"KITTI {i}": catalog.load(i) for i in range(6)}
    frames |= {f"street {i}": frame for i, frame in enumerate(rendered_scenes())}
    names = [name for name in args.detectors.split(",") if name]
    results = {name: measure(name, frames) for name in names}
    classes = {name: insertion_classes(name, frames) for name in names}
    print(
        "RESULT "
        + " ".join(
            f"{name}_moves={judged} {name}_violations={count} "
            f"{name}_insertions={classes[name][0]} {name}_other_class={classes[name][1]}"
            for name, (judged, count) in results.items()
        )
    )


if __name__ == "__main__":
    main()
