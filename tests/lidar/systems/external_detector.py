"""A detector run as a separate process, for the ProcessDetector tests (not a test module).

    python external_detector.py [--format json|kitti] [--sleep S] [--die] [--garbage] INPUT OUTPUT
    python external_detector.py --serve [...]    (reads "INPUT<TAB>OUTPUT" lines on stdin)

It reads a KITTI .bin frame with numpy, runs the whole-scene variant of the reference
pipeline and writes JSON or KITTI label predictions.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from pytest_metamorphic.lidar.io.kitti import sensor_calibration, write_kitti_labels
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.systems.perception.whole_scene import WholeScenePerception
from pytest_metamorphic.lidar.systems.process import boxes_to_json


def detect(source: str, target: str, options: argparse.Namespace, detector) -> None:
    if options.sleep:
        time.sleep(options.sleep)
    if options.die:
        print("CUDA error: out of memory (simulated)", file=sys.stderr)
        sys.exit(3)
    if options.garbage:
        with open(target, "w") as handle:
            handle.write("this is not a prediction\n")
        return
    points = np.fromfile(source, dtype="<f4").reshape(-1, 4)
    boxes = detector(PointCloud(points))
    if options.format == "json":
        with open(target, "w") as handle:
            json.dump(boxes_to_json(boxes), handle)
    else:
        write_kitti_labels(target, boxes, sensor_calibration())


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--format", default="json")
    parser.add_argument("--sleep", type=float, default=0.0)
    parser.add_argument("--die", action="store_true")
    parser.add_argument("--garbage", action="store_true")
    parser.add_argument("--serve", action="store_true")
    parser.add_argument("files", nargs="*")
    options = parser.parse_args()
    detector = WholeScenePerception()  # "loading the model": once per process
    if not options.serve:
        detect(*options.files, options, detector)
        return
    print("model loaded", file=sys.stderr)
    for line in sys.stdin:
        # One frame per line, or a batch: INPUT<TAB>OUTPUT pairs one after another.
        parts = line.rstrip("\n").split("\t")
        for source, target in zip(parts[::2], parts[1::2], strict=True):
            detect(source, target, options, detector)
        # The answer names the frames it answers (the protocol's contract).
        print("done\t" + "\t".join(parts[::2]), flush=True)


if __name__ == "__main__":
    main()
