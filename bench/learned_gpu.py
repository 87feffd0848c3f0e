"""The whole learned detector on a GPU: frames per second at batch 1 and 8, and its boxes
against the CPU's.

The detector is the shipped
:class:`~pytest_metamorphic.lidar.systems.perception.cnnseg.CNNSegmentation` with
``device="cuda"`` (onnxruntime's CUDA provider: ``pip install onnxruntime-gpu``): the
network runs on the GPU, features, Cluster2D and boxes on the CPU, as in Apollo. Over
``--frames`` pre-rendered streets of the training distribution (rendering excluded),
each batch size runs after an untimed warm-up pass; frames per second = frames / wall
time of ``detect_batch`` calls. The same frames go through the CPU detector: every box
of one must have a partner of the same class within 0.5 m in the other (the learned
tolerance profile), counted as ``agree``.

Without a CUDA provider it measures the CPU alone and says so (``gpu=0``).

    python bench/learned_gpu.py [--frames N] [--threads N]

Ends with ``RESULT gpu=... fps_b1=... fps_b8=... batch_speedup=... cpu_fps_b1=...
cpu_fps_b8=... agree=...``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import onnxruntime  # noqa: E402

from pytest_metamorphic.lidar.judging.tolerance import LEARNED  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg import CNNSegmentation  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import held_out_frame  # noqa: E402


def frames_per_second(detector: CNNSegmentation, frames: list[Any], batch: int) -> float:
    """Frames per second of ``detect_batch`` over ``frames`` in batches of ``batch``."""
    chunks = [frames[i : i + batch] for i in range(0, len(frames), batch)]
    for chunk in chunks[:2]:  # warm-up: sessions, CUDA kernels, caches
        detector.detect_batch(chunk)
    started = time.perf_counter()
    for chunk in chunks:
        detector.detect_batch(chunk)
    return len(frames) / (time.perf_counter() - started)


def agreement(first: list[list[Any]], second: list[list[Any]]) -> float:
    """Share of boxes (both ways) with a partner of their class within 0.5 m."""
    kept = LEARNED.kept
    assert kept is not None  # the learned profile judges MR1 by it
    matched = total = 0
    for a, b in zip(first, second, strict=True):
        for left, right in ((a, b), (b, a)):
            if not left:
                continue
            near, _ = kept.pairwise(left, right)
            matched += int(near.any(axis=1).sum()) if len(right) else 0
            total += len(left)
    return matched / total if total else 1.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default all)")
    args = parser.parse_args()
    gpu = "CUDAExecutionProvider" in onnxruntime.get_available_providers()
    frames = [held_out_frame(i) for i in range(args.frames)]
    cpu = CNNSegmentation(True, device="cpu", threads=args.threads)
    providers = onnxruntime.get_available_providers()
    print(f"onnxruntime {onnxruntime.__version__}; providers {providers}")
    print(f"{args.frames} held-out rendered streets, grid {cpu.grid.size} cells a side")
    rates: dict[tuple[str, int], float] = {}
    detectors = {"cpu": cpu}
    if gpu:
        detectors["cuda"] = CNNSegmentation(True, device="cuda", threads=args.threads)
    for name, detector in detectors.items():
        for batch in (1, 8):
            rates[name, batch] = frames_per_second(detector, frames, batch)
            print(f"{name:<5} batch {batch}: {rates[name, batch]:7.1f} frames/s")
    agree = 1.0
    if gpu:
        on_gpu = detectors["cuda"].network.on_gpu
        print(f"network on the GPU: {on_gpu}")
        agree = agreement(cpu.detect_batch(frames), detectors["cuda"].detect_batch(frames))
        print(f"boxes with a same-class partner within 0.5 m on the other device: {agree:.4f}")
    device = "cuda" if gpu else "cpu"
    print(
        f"RESULT gpu={int(gpu)} fps_b1={rates[device, 1]:.2f} fps_b8={rates[device, 8]:.2f} "
        f"batch_speedup={rates[device, 8] / rates[device, 1]:.3f} "
        f"cpu_fps_b1={rates['cpu', 1]:.2f} cpu_fps_b8={rates['cpu', 8]:.2f} agree={agree:.4f}"
    )


if __name__ == "__main__":
    main()
