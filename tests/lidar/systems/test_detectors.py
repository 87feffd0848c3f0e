"""Detector output converters, checked against real KITTI labels and calibration.

Each label of the six KITTI frames is rewritten the way each tool stores predictions
(computed here independently, from the raw label line and calibration matrices, with the
formulas the tools document), converted back, and compared with the KITTI route; the
boxes must enclose their objects' points, and the wrong convention must not.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import conftest
from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.lidar.io import read_bin
from pytest_metamorphic.lidar.io.kitti import read_kitti_calibration, read_kitti_labels
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.detectors import (
    CLASS_LABELS,
    boxes_to_array,
    from_mmdet3d,
    from_openpcdet,
    read_kitti_predictions,
)

CLASSES = ["Car", "Pedestrian", "Cyclist", "Van", "Truck", "Tram", "Misc", "Person_sitting"]


def _frames() -> list[int]:
    return list(range(6))


def _raw(index: int) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """OpenPCDet's own conversion of one label file: (N, 7) boxes, names, points, calib."""
    root = Path(conftest.shared_data_path("kitti_openpcdet", "training"))
    calib = read_kitti_calibration(root / "calib" / f"{index:06d}.txt")
    lines = [
        line.split()
        for line in (root / "label_2" / f"{index:06d}.txt").read_text().splitlines()
        if line.strip() and not line.startswith("DontCare")
    ]
    names = [parts[0] for parts in lines]
    values = np.array([[float(v) for v in parts[1:15]] for parts in lines]).reshape(-1, 14)
    h, w, length = values[:, 7], values[:, 8], values[:, 9]
    location, rotation_y = values[:, 10:13], values[:, 13]
    # pcdet/utils/box_utils.boxes3d_kitti_camera_to_lidar: rect -> LiDAR, lift z by h / 2,
    # heading -(r + pi / 2).
    rect = np.hstack([location, np.ones((len(location), 1))])
    lidar = (calib.rect_to_velo() @ rect.T).T[:, :3]
    lidar[:, 2] += h / 2
    boxes = np.column_stack([lidar, length, w, h, -(rotation_y + np.pi / 2)])
    points = read_bin(root / "velodyne" / f"{index:06d}.bin").points
    return boxes, names, points, calib


def _close(a: Box, b: Box) -> None:
    assert a.label == b.label
    assert np.allclose(a.center, b.center, atol=0.02), (a, b)
    assert np.allclose(a.size, b.size, atol=1e-6)
    assert abs(math.remainder(a.yaw - b.yaw, 2 * math.pi)) < 0.02


@pytest.mark.parametrize("index", _frames())
def test_openpcdet_boxes_match_the_kitti_route_and_enclose_their_points(index: int) -> None:
    rows, names, points, calib = _raw(index)
    labels = np.array([CLASSES.index(name) + 1 for name in names])
    scores = np.linspace(0.9, 0.5, len(rows))
    boxes = from_openpcdet(rows, labels, scores, class_names=CLASSES)
    root = Path(conftest.shared_data_path("kitti_openpcdet", "training"))
    truth = read_kitti_labels(root / "label_2" / f"{index:06d}.txt", calib)
    assert len(boxes) == len(truth) > 0
    for box, label, score in zip(boxes, truth, scores, strict=True):
        _close(box, label)
        assert box.score == pytest.approx(score)
    inside = [int(box.contains(points).sum()) for box in boxes]
    # The wrong conventions: the camera heading used as is, the bottom z taken as centre.
    unturned = [
        int(Box(b.center, b.size, -b.yaw - math.pi / 2).contains(points).sum()) for b in boxes
    ]
    sunk = [int(b.translated(0, 0, -b.size[2] / 2).contains(points).sum()) for b in boxes]
    seen = [i for i, count in enumerate(inside) if count >= 30]
    assert seen, "no labelled object with 30 points"
    for i in seen:
        elongated = boxes[i].size[0] - boxes[i].size[1] > 1.0
        if elongated:
            assert unturned[i] < 0.8 * inside[i], (names[i], inside[i], unturned[i])
    assert sum(sunk[i] for i in seen) < sum(inside[i] for i in seen)


@pytest.mark.parametrize("index", _frames())
def test_mmdet3d_boxes_bottom_centre_and_legacy_convention(index: int) -> None:
    rows, names, _, _ = _raw(index)
    labels = np.array([CLASSES.index(name) for name in names])  # 0-based
    expected = from_openpcdet(rows, labels + 1, class_names=CLASSES)
    bottom = rows.copy()
    bottom[:, 2] -= rows[:, 5] / 2
    for box, want in zip(from_mmdet3d(bottom, labels, class_names=CLASSES), expected, strict=True):
        _close(box, want)
    centre = from_mmdet3d(rows, labels, class_names=CLASSES, origin=(0.5, 0.5, 0.5))
    for box, want in zip(centre, expected, strict=True):
        _close(box, want)
    legacy = bottom.copy()
    legacy[:, [3, 4]] = bottom[:, [4, 3]]
    legacy[:, 6] = -bottom[:, 6] - math.pi / 2
    old = from_mmdet3d(legacy, labels, class_names=CLASSES, convention="v0")
    for box, want in zip(old, expected, strict=True):
        _close(box, want)


def test_kitti_prediction_files_with_scores(tmp_path: Path) -> None:
    root = Path(conftest.shared_data_path("kitti_openpcdet", "training"))
    text = (root / "label_2" / "000001.txt").read_text().splitlines()
    kept = [line for line in text if not line.startswith("DontCare")]
    scored = [f"{line} {0.9 - 0.3 * i:.2f}" for i, line in enumerate(kept)]
    path = tmp_path / "000001.txt"
    path.write_text("\n".join(scored) + "\n")
    calib = root / "calib" / "000001.txt"
    boxes = read_kitti_predictions(path, calib)
    assert [box.score for box in boxes] == pytest.approx([0.9 - 0.3 * i for i in range(len(kept))])
    assert len(read_kitti_predictions(path, calib, min_score=0.5)) == 2
    for box, label in zip(
        boxes, read_kitti_labels(root / "label_2" / "000001.txt", calib), strict=True
    ):
        _close(box, label)


def test_prediction_dicts_and_tensor_likes() -> None:
    class Tensor:  # what torch returns: .detach().cpu().numpy()
        def __init__(self, array):
            self.array = np.asarray(array)

        def detach(self):
            return self

        def cpu(self):
            return self

        def numpy(self):
            return self.array

    rows = [[10.0, 1.0, -0.9, 4.0, 1.7, 1.5, 0.3, 0.1, 0.0]]
    pcdet = from_openpcdet(
        {"pred_boxes": Tensor(rows), "pred_labels": Tensor([1]), "pred_scores": Tensor([0.8])},
        class_names=["Car"],
    )
    assert pcdet[0].label == "car" and pcdet[0].center == (10.0, 1.0, -0.9)
    mm = from_mmdet3d(
        {"bboxes_3d": Tensor(rows), "labels_3d": Tensor([0]), "scores_3d": Tensor([0.2])},
        class_names=["bicycle"],
        min_score=0.5,
    )
    assert mm == []
    assert from_mmdet3d(rows, [0], class_names=["barrier"])[0].label == "unknown"
    assert from_openpcdet(rows, [1], class_names=["Bollard"])[0].label == "unknown"
    assert (
        from_openpcdet(rows, [1], class_names=["Bollard"], label_map={"Bollard": "pedestrian"})[
            0
        ].label
        == "pedestrian"
    )
    assert np.allclose(boxes_to_array(pcdet), np.array(rows)[:, :7])
    assert CLASS_LABELS["Van"] == "car"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: from_openpcdet([[1, 2, 3]], [1], class_names=["Car"]), r"shape \(N, >=7\)"),
        (lambda: from_openpcdet([[0] * 7], [0], class_names=["Car"]), "1-based"),
        (lambda: from_openpcdet([[0, 0, 0, 1, 1, 1, 0]], [2], class_names=["Car"]), "1-based"),
        (lambda: from_openpcdet([[0, 0, 0, 1, 1, 1, 0]], [1, 1], class_names=["Car"]), "rows"),
        (lambda: from_openpcdet([[0, 0, 0, 1, 1, 1, 0]], [1], class_names="Car"), "class_names"),
        (lambda: from_openpcdet([[0, 0, 0, 0, 1, 1, 0]], [1], class_names=["Car"]), "row 0"),
        (lambda: from_openpcdet([[0] * 7], class_names=["Car"]), "pred_labels is required"),
        (lambda: from_openpcdet({"pred_boxes": []}, class_names=["Car"]), "pred_labels"),
        (
            lambda: from_mmdet3d(
                [[0, 0, 0, 1, 1, 1, 0]], [0], class_names=["Car"], convention="v2"
            ),
            "convention",
        ),
        (
            lambda: from_mmdet3d(
                [[0, 0, 0, 1, 1, 1, 0]], [0], class_names=["Car"], origin=(2, 0, 0)
            ),
            "origin",
        ),
        (lambda: from_openpcdet([["a"] * 7], [1], class_names=["Car"]), "pred_boxes cannot"),
        (
            lambda: from_openpcdet(
                [[0, 0, 0, 1, 1, 1, 0]], [1], class_names=["Car"], label_map={"Car": "truck"}
            ),
            "label_map",
        ),
    ],
)
def test_bad_detector_output_is_named(call, message: str) -> None:
    with pytest.raises(InvalidArgument, match=message):
        call()
