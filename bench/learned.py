"""The learned detector under test: its quality on real sweeps, the paper's MR1 table on
real sweeps, batch speed.

The system is :class:`~pytest_metamorphic.lidar.systems.perception.cnnseg.CNNSegmentation`, the
project's Apollo-style CNN segmentation (trained here on rendered streets, run with
onnxruntime). Parts, each printed as a table:

1. **Quality** (``quality``): recall and precision per class at BEV IoU 0.5 (objects with
   >= 10 returns) and false "cars" per sweep, on every labelled real sweep of the shared
   data: the six KITTI training sweeps (``kitti_openpcdet``) and KITTI 000134
   (``kitti_pointpillars_demo/val``), with KITTI's camera wedge as ROI (its labels cover
   nothing else), within 40 m and within the grid's 70 m, scored by KITTI's rules
   (:mod:`~pytest_metamorphic.lidar.systems.perception.cnnseg.quality`: detections of
   objects too sparse to count, or in DontCare regions, count neither way); then
   ``--held-out`` rendered scenes of the training distribution no training scene shares
   a seed with. None of the real sweeps was used in training or to choose anything about it.
2. **MR1 on real sweeps** (``mr1``, Zhou & Sun's protocol): the nine real KITTI sweeps of
   the shared data (the seven above, mmdetection3d's 000008 and PointPillars' testing
   000002; labels are not needed), 10 / 100 / 1000 points outside the camera wedge,
   ``--real-followups`` follow-ups per sweep and size (112: 1008 pairs per size), with
   ``full_cloud=True`` (Apollo's ``use_full_cloud``) and ``False``, beside the paper's
   2.7 / 12.1 / 33.5 %. Default ROI scope; strict MR1 with the learned tolerance.
   ``--sources N`` adds the same on N rendered scenes (``mr1-rendered``).
   Run in ``--workers`` processes (shards merge to the one-process result).
3. **Batches** (``batches``): an MR1 campaign over ``--batch-sources`` pre-rendered scenes
   through the engine with the detector taking batches of 1 and of 8; frames per
   second and what the engine adds per frame. After an untimed pass, batch 1 and 8
   alternate twice; the faster run counts.

Ends with ``RESULT kitti_car_recall=... kitti_false_cars_per_sweep=... mr1_full_1000=...
mr1_roi_1000=...`` (recall and false cars within the grid's 70 m; the MR1 keys are the
paper's check, |O| > |O'|, on the real sweeps).

Two more parts choose nothing by themselves: ``validation`` (car F1 within 70 m on the
40 validation streets ``held_out_frame(1000 + i)``, what retrained models are held to)
and ``scores`` (the same streets with objects under a score threshold dropped).

    python bench/learned.py [--parts quality,mr1,batches,validation,scores] [--workers N]
                            [--model PATH] [--max-lift METRES]
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
    CampaignResult,
    merge_results,
    run_campaign,
)
from pytest_metamorphic.core.intervals import wilson  # noqa: E402
from pytest_metamorphic.lidar.campaign import mr1_campaign  # noqa: E402
from pytest_metamorphic.lidar.campaign.sources import synthetic_frames  # noqa: E402
from pytest_metamorphic.lidar.io.bin import read_bin  # noqa: E402
from pytest_metamorphic.lidar.io.catalog import FrameCatalog  # noqa: E402
from pytest_metamorphic.lidar.io.kitti import (  # noqa: E402
    KittiDontCare,
    read_kitti_dont_care,
    read_kitti_labels,
)
from pytest_metamorphic.lidar.judging.evaluation import Evaluation, kitti_label_region  # noqa: E402
from pytest_metamorphic.lidar.judging.tolerance import LEARNED  # noqa: E402
from pytest_metamorphic.lidar.model.frame import Frame  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg import (  # noqa: E402
    CNNSegmentation,
    CNNSegParams,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import held_out_frame  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.quality import detection_quality  # noqa: E402
from pytest_metamorphic.reports.campaign import format_table  # noqa: E402

DATA = Path(os.environ.get("PYTEST_METAMORPHIC_DATA", ROOT.parent / "shared" / "data"))
KITTI = DATA / "kitti_openpcdet" / "training"
VAL = DATA / "kitti_pointpillars_demo" / "val"
UNLABELLED = (DATA / "mmdet3d_demo" / "kitti" / "000008.bin",
              DATA / "kitti_pointpillars_demo" / "test" / "000002.bin")  # fmt: skip
PAPER = {10: 2.7, 100: 12.1, 1000: 33.5}  # |O| > |O'| in % (Zhou & Sun, CACM 2019)
CLASSES = ("car", "pedestrian", "cyclist")
GRID_RANGE = 70.0


def _detector(full_cloud: bool, model: Any, **options: Any) -> CNNSegmentation:
    """``model`` is ``(ONNX path or None, CNNSegParams)``: picklable for the workers."""
    network, params = model
    return CNNSegmentation(full_cloud, network=network, params=params, **options)


SCORE_THRESHOLDS = (0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95)


def _f1(score: Any) -> float:
    precision, recall = score.precision or 0.0, score.recall or 0.0
    return 2 * precision * recall / (precision + recall) if precision + recall else 0.0


def validation(model: Any, streets: int = 40) -> dict[str, float]:
    """Car F1 within 70 m on the validation streets ``held_out_frame(1000 + i)``: what the
    model's and the detector's choices were made on (never a real sweep)."""
    print(f"== validation: {streets} streets held_out_frame(1000 + i), cars within 70 m ==")
    frames = (held_out_frame(1000 + i) for i in range(streets))
    car = detection_quality(_detector(True, model), frames, max_range=GRID_RANGE)["car"]
    f1 = _f1(car)
    print(f"found {car.true_positives}, false {car.false_positives}, missed "
          f"{car.false_negatives}: recall {car.recall or 0.0:.3f}, precision "
          f"{car.precision or 0.0:.3f}, F1 {f1:.4f}")  # fmt: skip
    return {"validation_car_f1": f1}


def scores(model: Any, streets: int = 40) -> dict[str, float]:
    """Validation F1 per class when objects whose score (mean objectness over their
    cells, 0.5 or more by construction) is under a threshold are dropped: Apollo's
    ``confidence_thresh``, asked of the validation streets only."""
    print(f"== object score thresholds: {streets} validation streets, within 70 m ==")
    frames = [held_out_frame(1000 + i) for i in range(streets)]
    detector = _detector(True, model)
    found = {frame.source: detector(frame) for frame in frames}
    header = "".join(f"{c + ': found / false / missed, F1':<40}" for c in CLASSES)
    print(f"{'score >=':<9}{header}")
    best = (0.0, -0.5)
    for threshold in SCORE_THRESHOLDS:

        def above(frame: Frame, threshold: float = threshold) -> list[Any]:
            return [b for b in found[frame.source] if b.score is not None and b.score >= threshold]

        result = detection_quality(above, frames, max_range=GRID_RANGE)
        per_class = {str(label): score for label, score in result.scores.items()}
        cells = [f"{per_class[c].true_positives} / {per_class[c].false_positives} / "
                 f"{per_class[c].false_negatives}, {_f1(per_class[c]):.4f}"
                 for c in CLASSES]  # fmt: skip
        print((f"{threshold:<9.2f}" + "".join(f"{cell:<40}" for cell in cells)).rstrip())
        best = max(best, (round(_f1(per_class["car"]), 4), -threshold))
    return {"score_best_threshold": -best[1], "score_best_car_f1": best[0]}


def labelled_sweeps() -> list[Frame]:
    """Every labelled real sweep of the shared data, KITTI's camera wedge as ROI."""
    roi = kitti_label_region(max_range=GRID_RANGE)
    frames = list(FrameCatalog(KITTI, roi=roi)) if KITTI.is_dir() else []
    if (VAL / "000134.bin").is_file():
        boxes = read_kitti_labels(VAL / "000134_gt.txt", VAL / "000134.txt")
        frames.append(Frame(read_bin(VAL / "000134.bin"), roi=roi, boxes=tuple(boxes),
                            source=str(VAL / "000134.bin")))  # fmt: skip
    return frames


def dont_care(frames: list[Frame]) -> dict[str, KittiDontCare]:
    """Each labelled sweep's DontCare regions (KITTI's evaluation ignores detections there)."""
    regions = {}
    for frame in frames:
        path = Path(str(frame.source))
        if path.parent == VAL:
            regions[str(path)] = read_kitti_dont_care(VAL / "000134_gt.txt", VAL / "000134.txt")
        else:
            root = path.parent.parent
            label, calib = (root / kind / f"{path.stem}.txt" for kind in ("label_2", "calib"))
            regions[str(path)] = read_kitti_dont_care(label, calib)
    return regions


class RealSweeps:
    """MR1's sources: the labelled sweeps and the unlabelled KITTI crops, in turn."""

    def __init__(self) -> None:
        self.paths = [*sorted((KITTI / "velodyne").glob("*.bin")), VAL / "000134.bin",
                      *UNLABELLED]  # fmt: skip
        self.paths = [path for path in self.paths if path.is_file()]
        self.roi = kitti_label_region(max_range=GRID_RANGE)

    def __len__(self) -> int:
        return len(self.paths)

    def __call__(self, rng: np.random.Generator, index: int) -> Frame:
        path = self.paths[index % len(self.paths)]
        return Frame(read_bin(path), roi=self.roi, source=str(path))


def _quality_rows(name: str, score: Evaluation, sweeps: int | None = None) -> list[str]:
    rows = []
    for label in CLASSES:
        s = score[label]  # type: ignore[index]
        recall = "n/a" if s.recall is None else f"{s.recall:.3f}"
        precision = "n/a" if s.precision is None else f"{s.precision:.3f}"
        truth = s.true_positives + s.false_negatives
        false = f"{s.false_positives / sweeps:.2f}" if sweeps else ""
        rows.append(f"{name:<40} {label:<11} {truth:>6} {s.true_positives:>6} {recall:>7} "
                    f"{precision:>9} {false:>10}")  # fmt: skip
    return rows


def quality(held_out: int, model: Any) -> dict[str, float]:
    print("== quality: BEV IoU >= 0.5, one to one, objects with >= 10 returns ==")
    print(f"{'frames':<40} {'class':<11} {'truth':>6} {'found':>6} {'recall':>7} "
          f"{'precision':>9} {'false/sweep':>10}")  # fmt: skip
    keys: dict[str, float] = {}
    frames = labelled_sweeps()
    regions = dont_care(frames)
    for reach in (40.0, GRID_RANGE):
        for full_cloud in (True, False):
            score = detection_quality(
                _detector(full_cloud, model), frames, max_range=reach,
                ignore=lambda frame, box: regions[str(frame.source)].covers(box),
            )  # fmt: skip
            name = f"{len(frames)} real KITTI sweeps, {reach:.0f} m, full={full_cloud}"
            print("\n".join(_quality_rows(name, score, len(frames))))
            if full_cloud and reach == GRID_RANGE:
                car = score["car"]
                keys["kitti_car_recall"] = car.recall or 0.0
                keys["kitti_false_cars_per_sweep"] = car.false_positives / len(frames)
                keys["kitti_cars"] = car.true_positives + car.false_negatives
            if full_cloud and reach == 40.0:
                keys["kitti_car_recall_40"] = score["car"].recall or 0.0
    for full_cloud in (True, False):
        score = detection_quality(
            _detector(full_cloud, model), (held_out_frame(i) for i in range(held_out))
        )
        name = f"{held_out} held-out rendered, 40 m, full={full_cloud}"
        print("\n".join(_quality_rows(name, score, held_out)))
        if full_cloud:
            keys["rendered_car_recall"] = score["car"].recall or 0.0
    return keys


def _campaign(full_cloud: bool, where: str, sources: int | None, seed: int, followups: int,
              model: Any) -> Any:  # fmt: skip
    frames = RealSweeps() if where == "real" else None
    return mr1_campaign(
        _detector(full_cloud, model), name=f"MR1 cnnseg {where} full_cloud={full_cloud}",
        frames=frames, sources=len(frames) if frames else sources, seed=seed,
        followups=followups, matcher=LEARNED.kept,
    )  # fmt: skip


def _shard(args: tuple[Any, ...]) -> CampaignResult:
    full_cloud, where, sources, seed, followups, model, shard, shards = args
    campaign = _campaign(full_cloud, where, sources, seed, followups, model)
    return run_campaign(campaign, shard=shard, shards=shards)


def _rate(k: int, n: int) -> str:
    rate = wilson(k, n)
    if rate.low is None or rate.high is None:
        return "  n/a (no pairs)"
    return f"{100 * k / n:5.1f} % [{100 * rate.low:.1f}, {100 * rate.high:.1f}]"


def mr1(where: str, sources: int | None, seed: int, workers: int, followups: int,
        model: Any) -> dict[bool, CampaignResult]:  # fmt: skip
    what = f"{sources} rendered scenes" if where == "rendered" else "nine real KITTI sweeps"
    print(f"\n== MR1 on {what} (seed {seed}, {followups} follow-up(s) per source and size) ==")
    results = {}
    for full_cloud in (True, False):
        started = time.monotonic()
        shards = max(workers * 4, 1) if where == "rendered" else len(RealSweeps())
        jobs = [(full_cloud, where, sources, seed, followups, model, k, shards)
                for k in range(shards)]  # fmt: skip
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


def _timed_run(frames: list[Any], size: int, threads: int, model: Any) -> tuple[float, float, int]:
    """(wall s, detector s, frames) of the MR1 campaign over ``frames`` at batch ``size``."""
    timed = _Timed(_detector(True, model, threads=threads, batch_size=size), size)
    campaign = mr1_campaign(timed, name=f"batch {size}", frames=lambda rng, i: frames[i],
                            sources=len(frames))  # fmt: skip
    timed(frames[0])  # onnxruntime builds its session on first use
    timed.seconds, timed.frames = 0.0, 0
    started = time.perf_counter()
    run_campaign(campaign)
    return time.perf_counter() - started, timed.seconds, timed.frames


def batches(sources: int, threads: int, model: Any) -> float:
    print(f"\n== batches: MR1 shape over {sources} pre-rendered scenes, ORT threads {threads} ==")
    render = synthetic_frames()
    frames = [render(np.random.default_rng([0, i]), i) for i in range(sources)]
    _timed_run(frames, 1, threads, model)  # untimed: every cache (ROI rasters, free cells) warm
    best: dict[int, tuple[float, float, int]] = {}
    for _ in range(2):
        for size in (1, 8):
            run = _timed_run(frames, size, threads, model)
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
    parser.add_argument("--sources", type=int, default=0, help="rendered MR1 sources (0: none)")
    parser.add_argument("--held-out", type=int, default=100)
    parser.add_argument("--batch-sources", type=int, default=40)
    parser.add_argument("--real-followups", type=int, default=112)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--model", type=Path, default=None, help="an ONNX file (default: shipped)")
    parser.add_argument(
        "--threads", type=int, default=2, help="onnxruntime threads in the batch part"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--max-lift",
        type=float,
        default=CNNSegParams().max_lift,
        help="CNNSegParams.max_lift in metres (0: none)",
    )
    parser.add_argument(
        "--parts",
        default="quality,mr1,batches",
        help="which parts to run (comma-separated; also: validation, scores)",
    )
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    model = (args.model, CNNSegParams(max_lift=args.max_lift or None))
    keys: dict[str, float] = {}
    if "validation" in parts:
        keys.update(validation(model))
    if "scores" in parts:
        keys.update(scores(model))
    if "quality" in parts:
        keys.update(quality(args.held_out, model))
    if "batches" in parts:
        # Before the campaigns: their worker processes must not share the cores with it.
        keys["batch_speedup"] = batches(args.batch_sources, args.threads, model)
    if "mr1" in parts:
        results = mr1("real", None, args.seed, args.workers, args.real_followups, model)
        full, roi = results[True].sizes[1000], results[False].sizes[1000]
        keys.update(
            mr1_full_1000=full.fewer / full.pairs,
            mr1_roi_1000=roi.fewer / roi.pairs,
            mr1_full_1000_strict=full.violations / full.pairs,
            mr1_roi_1000_strict=roi.violations / roi.pairs,
            mr1_pairs_1000=full.pairs,
        )
        if args.sources:
            mr1("rendered", args.sources, args.seed, args.workers, 1, model)
    print("RESULT " + " ".join(f"{key}={value:.4f}" for key, value in keys.items()))


if __name__ == "__main__":
    main()
