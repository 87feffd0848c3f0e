"""The learned detector under test: its quality, the paper's MR1 table on it, batch speed.

The system is :class:`~pytest_metamorphic.lidar.systems.perception.cnnseg.CNNSegmentation`, the
project's Apollo-style CNN segmentation (trained here on rendered scenes, run with
onnxruntime on the CPU). Three parts, each printed as a table:

1. **Quality**: recall and precision per class at BEV IoU 0.5 on ``--held-out`` rendered
   scenes no training scene shares a seed with (objects within 40 m with >= 10 returns),
   for features from the whole sweep and from the ROI only, and on the six labelled KITTI
   sweeps (the camera wedge as ROI; a model trained on rendered streets, so expect less).
2. **MR1** (Zhou & Sun's protocol): ``--sources`` rendered scenes (the campaigns' default
   street scenes), 10 / 100 / 1000 points outside the ROI, one follow-up each, then the
   six KITTI sweeps with ``--kitti-followups`` follow-ups per size, with
   ``full_cloud=True`` (Apollo's ``use_full_cloud``) and ``False``, beside the paper's
   2.7 / 12.1 / 33.5 %. Default ROI scope (obstacles wholly inside the ROI are judged);
   strict MR1 with the learned tolerance (a judged obstacle is lost when no follow-up
   obstacle of its class has its centre within 0.5 m;
   :mod:`pytest_metamorphic.lidar.judging.tolerance`).
   Run in ``--workers`` processes (shards merge to the one-process result).
3. **Batches**: the same MR1 campaign shape over ``--batch-sources`` pre-rendered scenes
   (rendering excluded), through the engine (``run_campaign``) with the detector taking
   batches of 1 and of 8 (:mod:`pytest_metamorphic.core.batching`); frames per second and
   what the engine adds per frame (campaign time minus the detector's own time). After
   an untimed pass (caches warm), batch 1 and 8 alternate twice; the faster run counts.

Ends with ``RESULT car_recall=... batch_speedup=... mr1_full_1000=... mr1_roi_1000=...``.

    python bench/learned.py [--sources N] [--held-out N] [--workers N] [--threads N]
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

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pytest_metamorphic.core.campaign import (  # noqa: E402
    Campaign,
    CampaignResult,
    merge_results,
    run_campaign,
)
from pytest_metamorphic.core.intervals import wilson  # noqa: E402
from pytest_metamorphic.lidar.campaign import mr1_campaign  # noqa: E402
from pytest_metamorphic.lidar.campaign.sources import synthetic_frames  # noqa: E402
from pytest_metamorphic.lidar.io.catalog import FrameCatalog  # noqa: E402
from pytest_metamorphic.lidar.judging.evaluation import Evaluation, kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.judging.tolerance import LEARNED  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import held_out_frame  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.quality import detection_quality  # noqa: E402
from pytest_metamorphic.reports.campaign import format_table  # noqa: E402

DATA = Path(os.environ.get("PYTEST_METAMORPHIC_DATA", ROOT.parent / "shared" / "data"))
KITTI = DATA / "kitti_openpcdet" / "training"
PAPER = {10: 2.7, 100: 12.1, 1000: 33.5}  # |O| > |O'| in % (Zhou & Sun, CACM 2019)
CLASSES = ("car", "pedestrian", "cyclist")


def _quality_rows(name: str, score: Evaluation) -> list[str]:
    rows = []
    for label in CLASSES:
        s = score[label]  # type: ignore[index]
        recall = "n/a" if s.recall is None else f"{s.recall:.3f}"
        precision = "n/a" if s.precision is None else f"{s.precision:.3f}"
        truth = s.true_positives + s.false_negatives
        rows.append(f"{name:<34} {label:<11} {truth:>6} {recall:>7} {precision:>9}")
    return rows


def quality(held_out: int) -> float:
    print("== quality: recall / precision per class, BEV IoU >= 0.5, within 40 m ==")
    print(f"{'frames':<34} {'class':<11} {'truth':>6} {'recall':>7} {'precision':>9}")
    car_recall = float("nan")
    for full_cloud in (True, False):
        detector = CNNSegmentation(full_cloud)
        frames = (held_out_frame(i) for i in range(held_out))
        score = detection_quality(detector, frames)
        name = f"{held_out} held-out rendered, full={full_cloud}"
        print("\n".join(_quality_rows(name, score)))
        if full_cloud:
            car_recall = score["car"].recall or 0.0
    if KITTI.is_dir():
        catalog = FrameCatalog(KITTI, roi=kitti_label_region())
        for full_cloud in (True, False):
            score = detection_quality(
                CNNSegmentation(full_cloud), (catalog.load(i) for i in range(len(catalog)))
            )
            print(
                "\n".join(_quality_rows(f"{len(catalog)} KITTI sweeps, full={full_cloud}", score))
            )
    else:
        print(f"(KITTI sweeps not found at {KITTI}: skipped)")
    return car_recall


def _campaign(full_cloud: bool, where: str, sources: int, seed: int, followups: int) -> Campaign:
    frames = FrameCatalog(KITTI, roi=kitti_label_region()) if where == "kitti" else None
    return mr1_campaign(
        CNNSegmentation(full_cloud), name=f"MR1 cnnseg {where} full_cloud={full_cloud}",
        frames=frames, sources=sources, seed=seed, followups=followups, matcher=LEARNED.kept,
    )  # fmt: skip


def _shard(args: tuple[bool, str, int | None, int, int, int, int]) -> CampaignResult:
    full_cloud, where, sources, seed, followups, shard, shards = args
    campaign = _campaign(full_cloud, where, sources, seed, followups)  # type: ignore[arg-type]
    return run_campaign(campaign, shard=shard, shards=shards)


def _rate(k: int, n: int) -> str:
    rate = wilson(k, n)
    if rate.low is None or rate.high is None:
        return "  n/a (no pairs)"
    return f"{100 * k / n:5.1f} % [{100 * rate.low:.1f}, {100 * rate.high:.1f}]"


def mr1(
    where: str, sources: int | None, seed: int, workers: int, followups: int
) -> dict[bool, CampaignResult]:
    what = f"{sources} rendered scenes" if where == "rendered" else "the six KITTI sweeps"
    print(f"\n== MR1 on {what} (seed {seed}, {followups} follow-up(s) per size) ==")
    results = {}
    for full_cloud in (True, False):
        started = time.monotonic()
        shards = max(workers * 4, 1) if where == "rendered" else 6
        jobs = [(full_cloud, where, sources, seed, followups, k, shards) for k in range(shards)]
        with ProcessPoolExecutor(max_workers=workers) as pool:
            result = merge_results(pool.map(_shard, jobs))
        results[full_cloud] = result
        print("\n".join(format_table(result)))
        print(f"({time.monotonic() - started:.0f} s)")
    print(f"\n{where}: |O| > |O'| (the paper's check) and strict MR1, Wilson 95 %")
    print(f"{'n':>4}  {'paper':>6}  {'full_cloud=True':>28} {'strict':>26}  "
          f"{'full_cloud=False':>26} {'strict':>26}")  # fmt: skip
    for n, paper in PAPER.items():
        full, roi = results[True].sizes[n], results[False].sizes[n]
        print(
            f"{n:>4}  {paper:>5.1f}%  {_rate(full.fewer, full.pairs):>28} "
            f"{_rate(full.violations, full.pairs):>26}  {_rate(roi.fewer, roi.pairs):>26} "
            f"{_rate(roi.violations, roi.pairs):>26}"
        )
    return results


class _Timed:
    """The detector, timing its own calls (single and batch)."""

    def __init__(self, detector: CNNSegmentation, batch_size: int) -> None:
        self.detector = detector
        self.batch_size = batch_size
        self.seconds = 0.0
        self.frames = 0

    def __call__(self, frame: Any) -> Any:
        started = time.perf_counter()
        try:
            return self.detector(frame)
        finally:
            self.seconds += time.perf_counter() - started
            self.frames += 1

    def run_batch(self, frames: Any) -> Any:
        started = time.perf_counter()
        try:
            return self.detector.detect_batch(frames)
        finally:
            self.seconds += time.perf_counter() - started
            self.frames += len(frames)


def _timed_run(frames: list[Any], size: int, threads: int) -> tuple[float, float, int]:
    """(wall s, detector s, frames) of the MR1 campaign over ``frames`` at batch ``size``."""
    timed = _Timed(CNNSegmentation(True, threads=threads, batch_size=size), size)
    campaign = mr1_campaign(timed, name=f"batch {size}", frames=lambda rng, i: frames[i],
                            sources=len(frames))  # fmt: skip
    timed(frames[0])  # onnxruntime builds its session on first use
    timed.seconds, timed.frames = 0.0, 0
    started = time.perf_counter()
    run_campaign(campaign)
    return time.perf_counter() - started, timed.seconds, timed.frames


def batches(sources: int, threads: int) -> float:
    print(f"\n== batches: MR1 shape over {sources} pre-rendered scenes, ORT threads {threads} ==")
    render = synthetic_frames()
    frames = [render(np.random.default_rng([0, i]), i) for i in range(sources)]
    _timed_run(frames, 1, threads)  # untimed: every cache (ROI rasters, free cells) warm
    best: dict[int, tuple[float, float, int]] = {}
    for _ in range(2):
        for size in (1, 8):
            run = _timed_run(frames, size, threads)
            if size not in best or run[0] < best[size][0]:
                best[size] = run
    rates = {}
    print(f"{'batch':>5} {'frames':>7} {'wall s':>7} {'frames/s':>9} {'detector ms/frame':>18} "
          f"{'engine ms/frame':>16}")  # fmt: skip
    for size, (wall, detector_s, count) in best.items():
        rates[size] = count / wall
        engine = (wall - detector_s) / count * 1000
        print(f"{size:>5} {count:>7} {wall:>7.1f} {rates[size]:>9.1f} "
              f"{detector_s / count * 1000:>18.1f} {engine:>16.2f}")  # fmt: skip
    speedup = rates[8] / rates[1]
    print(f"batch 8 / batch 1: {speedup:.2f}x frames per second")
    return speedup


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sources", type=int, default=1000)
    parser.add_argument("--held-out", type=int, default=200)
    parser.add_argument("--batch-sources", type=int, default=40)
    parser.add_argument("--kitti-followups", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--threads", type=int, default=2, help="onnxruntime threads in the batch part"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--parts", default="quality,mr1,batches", help="which parts to run (comma-separated)"
    )
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    keys: dict[str, float] = {}
    if "quality" in parts:
        keys["car_recall"] = quality(args.held_out)
    if "batches" in parts:
        # Before the campaigns: their worker processes must not share the cores with it.
        keys["batch_speedup"] = batches(args.batch_sources, args.threads)
    if "mr1" in parts:
        results = mr1("rendered", args.sources, args.seed, args.workers, 1)
        if KITTI.is_dir():
            mr1("kitti", None, args.seed, args.workers, args.kitti_followups)
        full, roi = results[True].sizes[1000], results[False].sizes[1000]
        keys.update(
            mr1_full_1000=full.fewer / full.pairs,
            mr1_roi_1000=roi.fewer / roi.pairs,
            mr1_full_1000_strict=full.violations / full.pairs,
            mr1_roi_1000_strict=roi.violations / roi.pairs,
            sources=args.sources,
        )
    print("RESULT " + " ".join(f"{key}={value:.4f}" for key, value in keys.items()))


if __name__ == "__main__":
    main()
