"""Which relations the learned detector satisfies, measured: at least 1000 derandomized
follow-ups per relation and feature mode.

A relation is claimed for the learned detector (``CNNSegmentation``)
only when this finds no violation in its follow-ups (docs/learned-model.md lists the
counts); the example test (``examples/test_learned_detector.py``) then checks the claims
derandomized, so it never fails at random on a user's machine.

Each relation of ``lidar_relations(tolerance="learned")`` runs as its own derandomized
Hypothesis test (generation only: the first violation is reported as found, not
reduced) with ``--followups`` follow-ups per source and ``--examples`` sources, for
ROI-only features (``full_cloud=False``) and whole-sweep features (``True``). Sources:
``--source streets``, the strategies' rendered streets within 50 m (the example's), or
``--source real``, the nine real KITTI sweeps of the shared data (camera wedge as ROI), or
``--source recording:VLP-16`` (``VLP-32C``, ``OS1-64``), one sweep of the example's
recordings of other sensors (``examples/test_your_recordings.py``, a 7 m corridor as ROI;
use ``--examples 1``). Relations run in ``--workers`` processes.

    python bench/learned_claims.py [--examples 250] [--followups 4] [--source streets]

Prints one row per relation and mode (follow-ups judged, violation or none) and ends with
``RESULT relations=... followups_min=... held_roi=... held_full=...``.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from hypothesis import HealthCheck, Phase, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from pytest_metamorphic import MetamorphicViolation, metamorphic  # noqa: E402
from pytest_metamorphic import strategies as mst  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation  # noqa: E402
from pytest_metamorphic.relations.lidar import lidar_relations  # noqa: E402

LIDAR = [HealthCheck.too_slow, HealthCheck.large_base_example, HealthCheck.data_too_large,
         HealthCheck.filter_too_much]  # fmt: skip


def _sources(kind: str) -> Any:
    if kind == "real":
        from learned import RealSweeps  # bench/learned.py: the same nine sweeps

        sweeps = RealSweeps()
        return st.sampled_from([sweeps(None, i) for i in range(len(sweeps))])  # type: ignore[arg-type]
    if kind.startswith("recording:"):
        from judged_share import RECORDINGS  # the example's VLP-16, VLP-32C and OS1-64

        from pytest_metamorphic.lidar.io.catalog import FrameCatalog
        from pytest_metamorphic.lidar.roi import corridor_roi

        path, topic = RECORDINGS[kind.split(":", 1)[1]]
        return st.just(FrameCatalog(path, topic=topic, roi=corridor_roi(width=7.0))[0])
    return mst.scene_frames(mst.scenes(max_distance=50.0))


def run_one(job: tuple[str, bool, int, int, str]) -> tuple[str, bool, int, str, float]:
    """(relation, full_cloud, follow-ups judged, first violation or "", seconds)."""
    name, full_cloud, examples, followups, source = job
    (relation,) = [r for r in lidar_relations(tolerance="learned") if r.name == name]
    detector = CNNSegmentation(full_cloud)
    drawn = [0]

    def counted(frame: Any) -> Any:
        drawn[0] += 1
        return frame

    @settings(max_examples=examples, database=None, phases=[Phase.generate], deadline=None,
              derandomize=True, suppress_health_check=LIDAR)  # fmt: skip
    @metamorphic(source=_sources(source).map(counted), relations=[relation],
                 followups=followups, batch=True)  # fmt: skip
    def check(frames: list[Any]) -> list[Any]:
        return detector.detect_batch(frames)

    started = time.monotonic()
    found = ""
    try:
        check()
    except MetamorphicViolation as violation:
        # The first line names the relation and its check (the row says both already):
        # keep what was found.
        lines = str(violation).splitlines()
        found = "VIOLATED: " + " ".join(" ".join(lines[1:]).split())[:400]
    except Exception as error:
        found = f"ERROR {type(error).__name__}: {' '.join(str(error).split())[:200]}"
    judged = drawn[0] * followups
    return name, full_cloud, judged, found, time.monotonic() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=250)
    parser.add_argument("--followups", type=int, default=4)
    parser.add_argument(
        "--source",
        choices=("streets", "real", "recording:VLP-16", "recording:VLP-32C", "recording:OS1-64"),
        default="streets",
    )
    parser.add_argument("--relations", default="", help="comma-separated name prefixes")
    parser.add_argument("--modes", default="roi,full")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    names = [r.name for r in lidar_relations(tolerance="learned")]
    if args.relations:
        names = [n for n in names if n.startswith(tuple(args.relations.split(",")))]
    modes = [m == "full" for m in args.modes.split(",")]
    jobs = [(n, m, args.examples, args.followups, args.source) for m in modes for n in names]
    print(f"{len(names)} relations x {len(modes)} modes, {args.examples} sources x "
          f"{args.followups} follow-ups each, sources: {args.source}")  # fmt: skip
    held = {False: 0, True: 0}
    least = None
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for name, full, judged, found, seconds in pool.map(run_one, jobs):
            mode = "whole sweep" if full else "ROI only"
            verdict = found or "no violation"
            print(f"{name[:48]:<48} {mode:<11} {judged:>6} {seconds:>6.0f} s  {verdict}",
                  flush=True)  # fmt: skip
            if not found:
                held[full] += 1
                least = judged if least is None else min(least, judged)
    print(
        f"RESULT relations={len(names)} followups_min={least or 0} "
        f"held_roi={held[False]} held_full={held[True]}"
    )


if __name__ == "__main__":
    main()
