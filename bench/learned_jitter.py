"""How much the learned detector's output moves when its input changes in a way that must
not matter: the numbers behind the "learned" tolerance profile (docs/learned-model.md,
"Why a tolerance profile for networks").

The system is :class:`~pytest_metamorphic.lidar.systems.perception.cnnseg.CNNSegmentation`
with ROI features (the configuration whose claims are measured). Sources: ``--streets``
held-out rendered streets (``held_out_frame(i)``, the training distribution, seeds no
training scene uses). Transforms: a quarter turn of cloud and ROI about the sensor, the
mirror y -> -y, and the sweep repeated (every return twice). Each source obstacle the
profile judges (wholly in the ROI, the relations' default scope; >= 10 returns) is mapped
into the follow-up's frame and paired with the follow-up obstacle whose centre is
nearest; the table gives the centre shift (median, 95th percentile, largest), the largest
change of length, width or height, how many pairs changed class, and how many obstacles
have no follow-up obstacle within 0.5 m (what the profile calls a violation).

Ends with ``RESULT judged=<per transform> shift_median_cm=... shift_max_cm=...
size_max_cm=... class_changed=... lost=...`` (over all three transforms).

    python bench/learned_jitter.py [--streets 30]
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from pytest_metamorphic.lidar.followups.perturb.edits import RotateAboutSensor  # noqa: E402
from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX  # noqa: E402
from pytest_metamorphic.lidar.judging.scope import as_scope  # noqa: E402
from pytest_metamorphic.lidar.model.cloud import PointCloud  # noqa: E402
from pytest_metamorphic.lidar.model.frame import Frame  # noqa: E402
from pytest_metamorphic.lidar.model.obstacles import Box  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import held_out_frame  # noqa: E402

MIN_RETURNS = 10  # the learned profile judges obstacles of at least this many returns
GONE = 0.5  # metres: no follow-up centre this close is what the profile calls lost

# name: (the follow-up frame, a source box mapped into the follow-up's frame)
TRANSFORMS: dict[str, tuple[Callable[[Frame], Frame], Callable[[Box], Box]]] = {
    "quarter turn": (RotateAboutSensor(math.pi / 2).apply, lambda box: box.rotated(math.pi / 2)),
    "mirror": (MirrorAcrossX().apply, lambda box: box.mirrored()),
    "sweep repeated": (
        lambda frame: frame.with_cloud(PointCloud.concatenate([frame.cloud, frame.cloud])),
        lambda box: box,
    ),
}


def _judged(boxes: list[Box], frame: Frame) -> list[Box]:
    """What the relations judge (the default ROI scope) of >= MIN_RETURNS returns."""
    return [box for box in as_scope("roi").select(boxes, frame) if (box.points or 0) >= MIN_RETURNS]


def pairs(
    detector: CNNSegmentation, frames: list[Frame], name: str
) -> list[tuple[Box, Box | None]]:
    """(source obstacle mapped into the follow-up's frame, nearest follow-up obstacle)."""
    transform, mapped = TRANSFORMS[name]
    found: list[tuple[Box, Box | None]] = []
    for frame in frames:
        source = _judged(detector(frame), frame)
        followup = detector(transform(frame))
        for box in source:
            moved = mapped(box)
            if not followup:
                found.append((moved, None))
                continue
            nearest = min(followup, key=lambda other: math.dist(other.center[:2], moved.center[:2]))
            found.append((moved, nearest))
    return found


def summary(found: list[tuple[Box, Box | None]]) -> dict[str, float]:
    matched = [(a, b) for a, b in found if b is not None]
    shifts = np.array([math.dist(a.center[:2], b.center[:2]) for a, b in matched])
    close = [(a, b) for (a, b), d in zip(matched, shifts, strict=True) if d <= GONE]
    kept = 100 * shifts[shifts <= GONE] if close else np.zeros(1)  # cm
    sizes = [max(abs(x - y) for x, y in zip(a.size, b.size, strict=True)) for a, b in close]
    return {
        "judged": len(found),
        "shift_median_cm": float(np.median(kept)),
        "shift_p95_cm": float(np.percentile(kept, 95)),
        "shift_max_cm": float(kept.max()),
        "size_max_cm": 100 * max(sizes, default=0.0),
        "class_changed": sum(a.label != b.label for a, b in close),
        "lost": len(found) - len(close),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--streets", type=int, default=30)
    args = parser.parse_args()
    if args.streets < 1:
        parser.error(f"--streets must be at least 1, got {args.streets}")
    started = time.perf_counter()
    detector = CNNSegmentation(full_cloud=False)
    frames = [held_out_frame(i) for i in range(args.streets)]
    print(f"{'transform':<16} {'judged':>6} {'median cm':>9} {'p95 cm':>7} {'max cm':>7} "
          f"{'size max cm':>11} {'class changed':>13} {'lost':>5}")  # fmt: skip
    everything: list[tuple[Box, Box | None]] = []
    for name in TRANSFORMS:
        found = pairs(detector, frames, name)
        everything += found
        s = summary(found)
        print(f"{name:<16} {s['judged']:>6} {s['shift_median_cm']:>9.1f} {s['shift_p95_cm']:>7.1f} "
              f"{s['shift_max_cm']:>7.1f} {s['size_max_cm']:>11.1f} {s['class_changed']:>13} "
              f"{s['lost']:>5}")  # fmt: skip
    if not everything:
        sys.exit("no obstacle was judged on these streets: nothing was measured")
    total = summary(everything)
    print(f"({time.perf_counter() - started:.0f} s)")
    print(
        f"RESULT judged={len(everything) // len(TRANSFORMS)} "
        f"shift_median_cm={total['shift_median_cm']:.1f} shift_max_cm={total['shift_max_cm']:.1f} "
        f"size_max_cm={total['size_max_cm']:.1f} class_changed={total['class_changed']} "
        f"lost={total['lost']}"
    )


if __name__ == "__main__":
    main()
