"""The CNN segmentation network's forward pass on a GPU, batch 1 against batch 8.

Needs PyTorch (and a CUDA device for the numbers that matter; without one it measures
PyTorch on the CPU and says so). The network is the shipped architecture
(:func:`~pytest_metamorphic.lidar.systems.perception.cnnseg.train.build_network`, 160 x 160 x 6
inputs) with freshly initialised weights: its cost does not depend on their values. Each
batch size runs ``--repeat`` timed forward passes after 20 warm-ups, synchronised, in
float32 and, on a GPU, in bfloat16 autocast; frames per second = batch x passes / time.

The CPU bench (``bench/learned.py``) measures the whole detector through the engine
(features, network, clustering, boxes); on a GPU only the network moves there, and this
bench says how much of the batch speed-up a GPU adds to that part.

    python bench/learned_gpu.py [--repeat N]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

from pytest_metamorphic.lidar.systems.perception.cnnseg.features import CHANNELS, GridSpec  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.train import Exported, build_network  # noqa: E402


def frames_per_second(network: torch.nn.Module, batch: int, repeat: int, device: str,
                      autocast: bool) -> float:  # fmt: skip
    grid = GridSpec()
    features = torch.rand(batch, len(CHANNELS), grid.size, grid.size, device=device)
    context = (
        torch.autocast(device_type="cuda", dtype=torch.bfloat16)
        if autocast
        else torch.autocast(device_type=device, enabled=False)
    )
    with torch.inference_mode(), context:
        for _ in range(20):
            network(features)
        if device == "cuda":
            torch.cuda.synchronize()
        started = time.perf_counter()
        for _ in range(repeat):
            network(features)
        if device == "cuda":
            torch.cuda.synchronize()
        elapsed = time.perf_counter() - started
    return batch * repeat / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=200)
    args = parser.parse_args()
    device = "cuda" if torch.cuda.is_available() else "cpu"
    threads = torch.get_num_threads()
    name = torch.cuda.get_device_name() if device == "cuda" else f"CPU ({threads} threads)"
    torch.manual_seed(0)
    network = Exported.wrap(build_network()).eval().to(device)
    print(f"device: {name}; torch {torch.__version__}")
    print(f"{'precision':<10} {'batch':>5} {'frames/s':>10} {'ms/frame':>9}")
    rates: dict[tuple[str, int], float] = {}
    for precision in ("float32", "bfloat16") if device == "cuda" else ("float32",):
        for batch in (1, 8, 32):
            rate = frames_per_second(network, batch, args.repeat, device, precision == "bfloat16")
            rates[precision, batch] = rate
            print(f"{precision:<10} {batch:>5} {rate:>10.1f} {1000 / rate:>9.3f}")
    speedup = rates["float32", 8] / rates["float32", 1]
    print(f"batch 8 / batch 1 (float32): {speedup:.2f}x")
    print(
        f"RESULT gpu={int(device == 'cuda')} batch_speedup={speedup:.3f} "
        f"ms_per_frame_b1={1000 / rates['float32', 1]:.4f} "
        f"ms_per_frame_b8={1000 / rates['float32', 8]:.4f}"
    )


if __name__ == "__main__":
    main()
