"""What Apollo's grid costs on a CPU: the learned detector's network and features per frame
at the shipped grid and at Apollo's.

Grids: 160 x 160 cells over +-40 m (the model shipped before 2026-11-28), 280 x 280 over
+-70 m (shipped: 0.5 m cells over Apollo's range), 512 x 512 over +-60 m (Apollo's older
HDL-64E model) and 672 x 672 over +-70 m (Apollo's HDL-64E model, 0.21 m cells). For each,
the shipped architecture (``cnnseg.train.build_network``, width 16) is exported with
freshly initialised weights (its cost does not depend on their values) and run with
onnxruntime on ``--threads`` CPU threads, ``--repeat`` timed calls after a warm-up; the
features (:func:`bev_features`) are computed from a real KITTI sweep. Needs PyTorch and
onnx (``pip install '.[train]'``) to export the networks.

    python bench/learned_grid_cost.py [--repeat N] [--threads 1,2]

Ends with ``RESULT ms_280=... ms_672=... ratio_672=...`` (network plus features, one
thread; the ratio is Apollo's grid over the shipped one).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import onnxruntime  # noqa: E402
import torch  # noqa: E402

from pytest_metamorphic.lidar.io.bin import read_bin  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import (  # noqa: E402
    GridSpec,
    bev_features,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.train import build_network, export  # noqa: E402

DATA = Path(os.environ.get("PYTEST_METAMORPHIC_DATA", ROOT.parent / "shared" / "data"))
SWEEP = DATA / "kitti_openpcdet" / "training" / "velodyne" / "000000.bin"
GRIDS = ((160, 40.0), (280, 70.0), (512, 60.0), (672, 70.0))


def timed(call: object, repeat: int) -> float:
    """Milliseconds per call, the best of three rounds of ``repeat`` calls."""
    best = float("inf")
    for _ in range(3):
        started = time.perf_counter()
        for _ in range(repeat):
            call()  # type: ignore[operator]
        best = min(best, (time.perf_counter() - started) / repeat)
    return 1000 * best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--threads", default="1,2")
    args = parser.parse_args()
    torch.manual_seed(0)
    network = build_network(16).eval()
    points = read_bin(SWEEP).points if SWEEP.is_file() else np.zeros((120_000, 4), np.float32)
    threads = [int(t) for t in args.threads.split(",")]
    print(f"sweep: {SWEEP.name if SWEEP.is_file() else 'zeros'} ({len(points)} points)")
    print(f"{'grid':<16} {'cell m':>6} {'features ms':>12} " +
          " ".join(f"{f'network ms ({t} thr)':>19}" for t in threads))  # fmt: skip
    total: dict[int, float] = {}
    with tempfile.TemporaryDirectory() as folder:
        for size, reach in GRIDS:
            grid = GridSpec(size=size, range=reach)
            path = Path(folder) / f"net{size}.onnx"
            export(network, path, grid, {})
            features = bev_features(points, grid)[None]
            features_ms = timed(lambda g=grid: bev_features(points, g), args.repeat)
            row = []
            for count in threads:
                options = onnxruntime.SessionOptions()
                options.intra_op_num_threads, options.inter_op_num_threads = count, 1
                session = onnxruntime.InferenceSession(
                    str(path), options, providers=["CPUExecutionProvider"]
                )
                session.run(None, {"features": features})
                ms = timed(lambda s=session, f=features: s.run(None, {"features": f}), args.repeat)
                row.append(ms)
                if count == 1:
                    total[size] = ms + features_ms
            print(f"{size} x {size} +-{reach:<4.0f} {grid.cell:>6.3f} {features_ms:>12.1f} " +
                  " ".join(f"{ms:>19.1f}" for ms in row), flush=True)  # fmt: skip
    print(
        f"RESULT ms_160={total[160]:.1f} ms_280={total[280]:.1f} ms_512={total[512]:.1f} "
        f"ms_672={total[672]:.1f} ratio_672={total[672] / total[280]:.2f}"
    )


if __name__ == "__main__":
    main()
