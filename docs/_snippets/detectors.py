"""Stand-ins for what docs/detectors.md names but a reader brings: a model, its forward
pass, a stack; the recording, the detector program (a test helper) and the server. DATA, PYTHON and
ROOT are defined by docs/snippets.py before this file."""

import os

import numpy as np
import pytest

from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.roi import corridor_roi
from pytest_metamorphic.lidar.systems.perception import ReferencePerception

SUBSTITUTE = {
    "recordings/*.pcd": f"{DATA}/nebula_velodyne/vlp16/*.pcd",
    '"/opt/venvs/pcdet/bin/python", "detect.py"': (
        f'"{PYTHON}", "{ROOT}/tests/lidar/systems/external_detector.py", "--format", "kitti"'
    ),
    '"ros2", "run", "my_pkg", "detector_bridge"': (
        f'"{PYTHON}", "{ROOT}/tests/lidar/systems/external_detector.py", "--serve"'
    ),
}
if not os.path.exists(f"{DATA}/nebula_velodyne/vlp16"):
    pytest.skip(f"the VLP-16 recording is not in {DATA}", allow_module_level=True)

frame = FrameCatalog(f"{DATA}/nebula_velodyne/vlp16/*.pcd", roi=corridor_roi())[0]
frames = [frame, frame]
my_stack = ReferencePerception()


def stack_on_points(points, name):
    return my_stack(points, None)


def model_forward(points):
    # OpenPCDet's output for one frame: a car 10 m ahead, a pedestrian 6 m left.
    boxes = np.array([[10.0, 0.0, -0.8, 4.2, 1.8, 1.5, 0.1], [3.0, 6.0, -0.9, 0.6, 0.6, 1.7, 0.0]])
    return [
        {"pred_boxes": boxes, "pred_scores": np.array([0.9, 0.8]), "pred_labels": np.array([1, 2])}
    ]


class _Instances:
    def to_dict(self):
        bottom = np.array([[10.0, 0.0, -1.55, 4.2, 1.8, 1.5, 0.1]])
        return {"bboxes_3d": bottom, "scores_3d": np.array([0.9]), "labels_3d": np.array([0])}


class _Result:
    pred_instances_3d = _Instances()


class _Model:
    def __init__(self):
        self.dataset_meta = {"classes": ["Car", "Pedestrian", "Cyclist"]}


model = _Model()


def inference_detector(model, points):
    return _Result()
