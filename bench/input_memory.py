"""Peak memory per input byte of the readers of outside files.

A reader of outside data must take memory in proportion to what it parses, not to the
file, and never blow up on a file made to look big: before, Apollo's text readers took
~170 bytes of RAM per input byte (an 8 MiB file: 1.4 GB). Each reader here reads files
of growing size made for the purpose; the figure is tracemalloc's peak (Python and numpy
allocations) divided by the file's size, at the largest size, and the ratio of the
largest to the smallest file's figure shows whether memory follows the size linearly
(~1) or worse.

* apollo_roi: Apollo's labelled ROI points, ``x y label`` text rows (``read_apollo_roi_points``).
* apollo_poly: one polygon of many ``x y z`` vertices (``read_apollo_poly``).
* osm: an OSM extract of N nodes in ways of 10 (``read_osm``).
* pcd: a binary PCD of N points (``read_pcd``).
* predictions: a JSON predictions file of N boxes (``read_json_predictions``).

    python bench/input_memory.py [--scale K]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from pytest_metamorphic.driving.osm import read_osm
from pytest_metamorphic.lidar.io import (
    read_apollo_poly,
    read_apollo_roi_points,
    read_pcd,
    write_pcd,
)
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.systems.process import read_json_predictions


def roi_points(path: Path, n: int) -> None:
    rng = np.random.default_rng(0)
    rows = rng.uniform(-80, 80, (n, 2))
    labels = np.where(rng.random(n) < 0.5, 1, -1)
    with path.open("w") as handle:
        handle.write(f"{n}\n")
        handle.writelines(
            f"{x:.6f} {y:.6f} {label}\n" for (x, y), label in zip(rows, labels, strict=True)
        )


def polygon(path: Path, n: int) -> None:
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    with path.open("w") as handle:
        handle.write(f"1\n{n}\n")
        handle.writelines(f"{50 * np.cos(a):.6f} {50 * np.sin(a):.6f} 0.0\n" for a in angles)


def osm(path: Path, n: int) -> None:
    with path.open("w") as handle:
        handle.write('<?xml version="1.0"?>\n<osm version="0.6">\n')
        for i in range(n):
            handle.write(
                f'<node id="{i + 1}" lat="{48 + i * 1e-7:.7f}" lon="{10 + i * 1e-7:.7f}"/>\n'
            )
        for w in range(n // 10):
            refs = "".join(f'<nd ref="{w * 10 + k + 1}"/>' for k in range(10))
            handle.write(f'<way id="{w + 1}">{refs}<tag k="highway" v="residential"/></way>\n')
        handle.write("</osm>\n")


def pcd(path: Path, n: int) -> None:
    points = np.random.default_rng(0).random((n, 4), dtype=np.float32)
    write_pcd(PointCloud(points), path, overwrite=True)


def predictions(path: Path, n: int) -> None:
    box = {"center": [10.0, 1.0, -1.0], "size": [4.2, 1.8, 1.5], "yaw": 0.1, "label": "Car",
           "score": 0.9}  # fmt: skip
    path.write_text(json.dumps({"boxes": [box] * n}))


READERS: dict[str, tuple[Callable[[Path, int], None], Callable[[Path], object], str, int]] = {
    "apollo_roi": (roi_points, lambda p: read_apollo_roi_points(p), "roi.txt", 20_000),
    "apollo_poly": (polygon, read_apollo_poly, "roi.poly", 20_000),
    "osm": (osm, read_osm, "map.osm", 5_000),
    "pcd": (pcd, read_pcd, "cloud.pcd", 50_000),
    "predictions": (predictions, read_json_predictions, "p.json", 2_000),
}


def peak_per_byte(read: Callable[[Path], object], path: Path) -> float:
    tracemalloc.start()
    try:
        result = read(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    del result
    return peak / path.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=int, default=8, help="largest file = scale x smallest")
    options = parser.parse_args()
    print(f"{'reader':12} {'small MB':>9} {'large MB':>9} {'B/B small':>10} {'B/B large':>10} "
          f"{'growth':>7}")  # fmt: skip
    result = []
    with tempfile.TemporaryDirectory() as folder:
        for name, (make, read, filename, n) in READERS.items():
            figures = []
            for count in (n, n * options.scale):
                path = Path(folder) / filename
                make(path, count)
                figures.append((path.stat().st_size, peak_per_byte(read, path)))
            (small_size, small), (large_size, large) = figures
            growth = large / small
            print(f"{name:12} {small_size / 1e6:9.2f} {large_size / 1e6:9.2f} {small:10.1f} "
                  f"{large:10.1f} {growth:7.2f}")  # fmt: skip
            result.append(f"{name}_bytes_per_byte={large:.2f} {name}_growth={growth:.3f}")
    print("RESULT " + " ".join(result))


if __name__ == "__main__":
    main()
