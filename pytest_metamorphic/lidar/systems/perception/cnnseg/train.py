"""Train the CNN segmentation network on rendered scenes and export it to ONNX.

Reproducible from a seed; needs PyTorch (``pip install 'pytest-metamorphic[train]'``, a
CPU build is enough) and ``onnx``. The package never imports this module: the shipped
``cnnseg.onnx`` runs with onnxruntime alone. Run::

    python -m pytest_metamorphic.lidar.systems.perception.cnnseg.train --out cnnseg.onnx

The defaults (3,500 scenes, 7 epochs, seed 0, the shipped grid) reproduce the shipped
model. Data: ``--scenes`` rendered streets (:mod:`.data`). Each scene gives two examples:
features from the whole sweep and from the ROI's points alone, so the one network serves
``full_cloud=True`` and ``False``; each is a 160 x 160-cell window of the grid (the
network is fully convolutional and runs on the whole grid), so a step costs the same at
Apollo's 672-cell grid (``--grid-size 672 --grid-range 70``). Every batch is turned by a
random quarter turn and mirrored at random (the grid is anchored at the sensor, so these
are exact).

Measured on 2 CPU cores: 391 s to render and degrade 3,500 scenes, 350-370 s per epoch
(about 0.05 s per window per training step); 49 minutes in all for the shipped model.
A GPU is used when PyTorch sees one.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import (
    CHANNELS,
    SHIPPED_GRID,
    GridSpec,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.network import CLASSES, OUTPUTS


def build_network(width: int = 16) -> Any:
    """The U-Net: three stride-2 stages down, three up with skips; 9 output channels
    (objectness, offset x and y, three class scores, top height, heading cos and sin)."""
    import torch
    from torch import nn

    def conv(i: int, o: int, stride: int = 1) -> nn.Module:
        return nn.Sequential(
            nn.Conv2d(i, o, 3, stride, 1, bias=False), nn.BatchNorm2d(o), nn.ReLU(inplace=True)
        )

    class CNNSeg(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            w = width
            self.e1 = nn.Sequential(conv(len(CHANNELS), w), conv(w, w))
            self.e2 = nn.Sequential(conv(w, 2 * w, 2), conv(2 * w, 2 * w))
            self.e3 = nn.Sequential(conv(2 * w, 4 * w, 2), conv(4 * w, 4 * w))
            self.e4 = nn.Sequential(conv(4 * w, 4 * w, 2), conv(4 * w, 4 * w), conv(4 * w, 4 * w))
            self.up = nn.Upsample(scale_factor=2, mode="nearest")
            self.d3 = conv(8 * w, 4 * w)
            self.d2 = conv(6 * w, 2 * w)
            self.d1 = conv(3 * w, w)
            self.head = nn.Conv2d(w, 1 + 2 + len(CLASSES) + 1 + 2, 1)

        def forward(self, x: Any) -> Any:
            a = self.e1(x)
            b = self.e2(a)
            c = self.e3(b)
            d = self.e4(c)
            c = self.d3(torch.cat([self.up(d), c], 1))
            b = self.d2(torch.cat([self.up(c), b], 1))
            a = self.d1(torch.cat([self.up(b), a], 1))
            return self.head(a)

    return CNNSeg()


class Exported:
    """The network with its output activations, as the ONNX file holds it."""

    @staticmethod
    def wrap(network: Any) -> Any:
        import torch
        from torch import nn

        class WithActivations(nn.Module):
            def __init__(self) -> None:
                super().__init__()
                self.network = network

            def forward(self, features: Any) -> Any:
                raw = self.network(features)
                k = len(CLASSES)
                return (
                    torch.sigmoid(raw[:, 0:1]),
                    raw[:, 1:3],
                    torch.softmax(raw[:, 3 : 3 + k], dim=1),
                    raw[:, 3 + k : 4 + k],
                    raw[:, 4 + k : 6 + k],
                )

        return WithActivations()


def _augment(batch: dict[str, Any], rng: np.random.Generator) -> dict[str, Any]:
    """A random quarter turn and mirror of the whole batch (features, targets, offsets,
    headings: a mirror negates the doubled angle, a quarter turn adds 180 degrees to it)."""
    import torch

    turns = int(rng.integers(4))
    mirror = bool(rng.integers(2))
    out = {}
    for key, value in batch.items():
        if mirror:  # y -> -y: columns reversed
            value = torch.flip(value, dims=(-1,))
        out[key] = torch.rot90(value, turns, dims=(-2, -1)) if turns else value
    dx, dy = out["offset"][:, 0], out["offset"][:, 1]
    if mirror:
        dy = -dy
    for _ in range(turns):  # (x, y) -> (-y, x)
        dx, dy = -dy, dx
    out["offset"] = torch.stack([dx, dy], dim=1)
    cos, sin = out["heading"][:, 0], out["heading"][:, 1]
    if mirror:
        sin = -sin
    if turns % 2:
        cos, sin = -cos, -sin
    out["heading"] = torch.stack([cos, sin], dim=1)
    return out


def _loss(raw: Any, batch: dict[str, Any]) -> tuple[Any, dict[str, float]]:
    import torch
    import torch.nn.functional as F

    k = len(CLASSES)
    objectness = batch["objectness"]
    positive = objectness > 0.5
    count = positive.sum().clamp(min=1)
    object_loss = F.binary_cross_entropy_with_logits(
        raw[:, 0], objectness, pos_weight=torch.tensor(4.0, device=raw.device)
    )
    mask = positive.unsqueeze(1)
    offset_loss = (
        F.smooth_l1_loss(raw[:, 1:3], batch["offset"], reduction="none") * mask
    ).sum() / count
    class_loss = (
        F.cross_entropy(raw[:, 3 : 3 + k], batch["label"].clamp(min=0), reduction="none") * positive
    ).sum() / count
    height_loss = (
        F.smooth_l1_loss(raw[:, 3 + k], batch["height"], reduction="none") * positive
    ).sum() / count
    oriented = (batch["heading"].abs().sum(dim=1) > 0.5).unsqueeze(1)  # cars, cyclists
    heading_loss = (
        F.smooth_l1_loss(raw[:, 4 + k : 6 + k], batch["heading"], reduction="none") * oriented
    ).sum() / oriented.sum().clamp(min=1)
    total = 4.0 * object_loss + offset_loss + class_loss + height_loss + heading_loss
    parts = {
        "objectness": object_loss.item(),
        "offset": offset_loss.item(),
        "class": class_loss.item(),
        "height": height_loss.item(),
        "heading": heading_loss.item(),
    }
    return total, parts


def _pick(data: dict[str, np.ndarray], full: str, roi: str, scene: np.ndarray,
          view: np.ndarray, dtype: Any) -> Any:  # fmt: skip
    """Each chosen scene's whole-sweep (view 0) or ROI-only (view 1) array, as a tensor."""
    import torch

    chosen = np.stack(
        [data[full][s] if v == 0 else data[roi][s] for s, v in zip(scene, view, strict=True)]
    )
    return torch.from_numpy(chosen.astype(dtype))


def train(
    data: dict[str, np.ndarray],
    *,
    epochs: int,
    batch_size: int,
    seed: int,
    width: int,
    learning_rate: float,
    log: Any = print,  # called with flush=True
) -> Any:
    """Train the U-Net on ``data`` (from :func:`dataset`); returns it in eval mode."""
    import torch

    torch.manual_seed(seed)
    device = "cuda" if torch.cuda.is_available() else "cpu"
    network = build_network(width).to(device)
    scenes = len(data["full"])
    steps_per_epoch = math.ceil(2 * scenes / batch_size)
    optimiser = torch.optim.AdamW(network.parameters(), lr=learning_rate, weight_decay=1e-4)
    schedule = torch.optim.lr_scheduler.OneCycleLR(
        optimiser, max_lr=learning_rate, total_steps=epochs * steps_per_epoch, pct_start=0.1
    )
    rng = np.random.default_rng(seed)
    started = time.monotonic()
    for epoch in range(epochs):
        network.train()
        # Every scene twice per epoch: once with whole-sweep features, once ROI-only.
        order = rng.permutation(2 * scenes)
        totals: dict[str, float] = {}
        for step in range(steps_per_epoch):
            chosen = order[step * batch_size : (step + 1) * batch_size]
            scene, view = chosen % scenes, chosen // scenes
            batch = {
                "features": _pick(data, "full", "roi", scene, view, np.float32),
                "objectness": _pick(
                    data, "full_objectness", "roi_objectness", scene, view, np.float32
                ),
                "offset": _pick(data, "full_offset", "roi_offset", scene, view, np.float32),
                "label": _pick(data, "full_label", "roi_label", scene, view, np.int64),
                "height": _pick(data, "full_height", "roi_height", scene, view, np.float32),
                "heading": _pick(data, "full_heading", "roi_heading", scene, view, np.float32),
            }
            batch = {key: value.to(device) for key, value in _augment(batch, rng).items()}
            raw = network(batch["features"])
            loss, parts = _loss(raw, batch)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
            for key, value in parts.items():
                totals[key] = totals.get(key, 0.0) + value / steps_per_epoch
        log(
            f"epoch {epoch + 1}/{epochs}  "
            + "  ".join(f"{k} {v:.4f}" for k, v in totals.items())
            + f"  ({time.monotonic() - started:.0f} s)",
            flush=True,
        )
    network.eval()
    return network.cpu()


def export(network: Any, path: Path, grid: GridSpec, metadata: dict[str, Any]) -> None:
    """Write the network, with its activations and metadata, as ONNX."""
    import onnx
    import torch

    wrapped = Exported.wrap(network).eval()
    dummy = torch.zeros(1, len(CHANNELS), grid.size, grid.size)
    torch.onnx.export(
        wrapped,
        (dummy,),
        str(path),
        input_names=["features"],
        output_names=list(OUTPUTS),
        dynamic_axes={name: {0: "batch"} for name in ("features", *OUTPUTS)},
        opset_version=17,
        dynamo=False,
    )
    model = onnx.load(str(path))
    entries = {"grid": json.dumps(grid.to_json()), **{k: str(v) for k, v in metadata.items()}}
    for key, value in entries.items():
        prop = model.metadata_props.add()
        prop.key, prop.value = key, value
    onnx.save(model, str(path))


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("cnnseg.onnx"))
    parser.add_argument("--scenes", type=int, default=3500)
    parser.add_argument("--epochs", type=int, default=7)
    parser.add_argument("--batch-size", type=int, default=8)
    parser.add_argument("--width", type=int, default=16)
    parser.add_argument("--learning-rate", type=float, default=3e-3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--grid-size", type=int, default=SHIPPED_GRID.size,
                        help="cells a side (Apollo's HDL-64E model: 672)")  # fmt: skip
    parser.add_argument("--grid-range", type=float, default=SHIPPED_GRID.range,
                        help="half the side in metres (Apollo: 70)")  # fmt: skip
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads")
    args = parser.parse_args(argv)
    import torch

    # Rendering needs trimesh; imported here so that the network alone (build_network)
    # loads where only PyTorch is installed (a GPU machine measuring throughput).
    from pytest_metamorphic.lidar.systems.perception.cnnseg.data import (
        CROP,
        SCENE_OPTIONS,
        dataset,
    )

    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        grid = GridSpec(size=args.grid_size, range=args.grid_range)
    except InvalidArgument as error:
        parser.error(str(error))
    if grid.size < CROP:
        parser.error(f"--grid-size must be at least the training window ({CROP} cells)")
    started = time.monotonic()
    seeds = [args.seed * 10_000_000 + i for i in range(args.scenes)]
    data = dataset(seeds, grid, args.workers)
    print(
        f"rendered {args.scenes} training scenes in {time.monotonic() - started:.0f} s", flush=True
    )
    network = train(
        data,
        epochs=args.epochs,
        batch_size=args.batch_size,
        seed=args.seed,
        width=args.width,
        learning_rate=args.learning_rate,
    )
    metadata = {
        "seed": args.seed,
        "training_scenes": args.scenes,
        "epochs": args.epochs,
        "width": args.width,
        "scene_options": json.dumps({k: v for k, v in SCENE_OPTIONS.items()}),
        "training_data": "cnnseg.data: 80% streetscape streets (with loose wall pieces), "
        "20% random_scene; "
        "HDL-64E 80%, other sensors 20%; degraded (noise, dropout, dead lasers, lost "
        "packets, reflectance, tilt, camera crops)",
        "training_window": CROP,
        "trained_seconds": round(time.monotonic() - started),
        "torch": torch.__version__,
    }
    export(network, args.out, grid, metadata)
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
