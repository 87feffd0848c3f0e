"""Converters from what 3-D detectors emit to
:class:`~pytest_metamorphic.lidar.model.obstacles.Box`.

So that a test of a learned detector is one line, not a page of box arithmetic. All three
conventions were checked against the real KITTI labels and calibration in
``../shared/data/kitti_openpcdet`` (``tests/lidar/systems/test_detectors.py``): a label converted
through each route gives the same box, and that box encloses its object's points.

================================  ============================================  ==================
source                            box layout (LiDAR frame: x forward, y left)   heading
================================  ============================================  ==================
OpenPCDet                         ``pred_boxes`` (N, 7): x, y, z of the box     yaw about +z,
(:func:`from_openpcdet`)          **centre**, dx, dy, dz (length, width,        counter-clockwise
                                  height); ``pred_labels`` 1-based into the     from +x
                                  config's ``CLASS_NAMES``; ``pred_scores``
mmdetection3d >= 1.0              ``LiDARInstance3DBoxes`` / ``bboxes_3d``      the same
(:func:`from_mmdet3d`)            (N, 7+): x, y, z of the **bottom** centre
                                  (origin (0.5, 0.5, 0)), x_size, y_size,
                                  z_size; ``labels_3d`` 0-based; ``scores_3d``
mmdetection3d < 1.0               (N, 7): bottom centre, **w, l**, h            ``-yaw - pi/2``
(``convention="v0"``)
KITTI label files                 camera frame, bottom centre, h w l,           ``rotation_y`` about
(:func:`read_kitti_predictions`)  ``rotation_y``, optional score; converted     camera y
                                  with the frame's calibration
================================  ============================================  ==================

Class names map onto the project's labels with :data:`CLASS_LABELS` (KITTI's and
nuScenes' names; motor vehicles are ``car`` as in Apollo, two-wheelers ``cyclist``);
a name it does not know becomes ``"unknown"``, or pass ``label_map``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.io.kitti import KITTI_LABELS, KittiCalibration, read_kitti_labels
from pytest_metamorphic.lidar.model.obstacles import LABELS, Box, Label

__all__ = [
    "CLASS_LABELS",
    "boxes_to_array",
    "from_mmdet3d",
    "from_openpcdet",
    "label_mapping",
    "read_kitti_predictions",
]

CLASS_LABELS: Mapping[str, Label] = {
    **KITTI_LABELS,  # OpenPCDet's and mmdetection3d's CLASS_NAMES for KITTI
    # nuScenes detection classes
    "car": "car",
    "truck": "car",
    "bus": "car",
    "trailer": "car",
    "construction_vehicle": "car",
    "pedestrian": "pedestrian",
    "bicycle": "cyclist",
    "motorcycle": "cyclist",
    "barrier": "unknown",
    "traffic_cone": "unknown",
    # Waymo
    "Vehicle": "car",
    "Sign": "unknown",
}
"""Class names of KITTI, nuScenes and Waymo -> the project's labels (``label_map`` adds)."""


def _array(value: Any, name: str, *, dtype: Any = np.float64) -> NDArray[Any]:
    """A numpy array from numpy, lists or torch tensors (moved to the CPU, detached)."""
    if hasattr(value, "tensor") and not isinstance(value, np.ndarray):
        value = value.tensor  # mmdet3d's BaseInstance3DBoxes
    if hasattr(value, "detach"):
        value = value.detach()
    if hasattr(value, "cpu"):
        value = value.cpu()
    if hasattr(value, "numpy") and not isinstance(value, np.ndarray):
        value = value.numpy()
    try:
        return np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"{name} cannot be read as numbers: {error}") from None


def label_mapping(label_map: Mapping[str, Label] | None) -> Mapping[str, Label]:
    """Class name -> label: :data:`CLASS_LABELS` with ``label_map``'s entries on top
    (checked: every value one of the project's labels)."""
    if label_map is None:
        return CLASS_LABELS
    if not isinstance(label_map, Mapping):
        raise InvalidArgument(f"label_map={label_map!r} must map class names to labels")
    for name, label in label_map.items():
        if label not in LABELS:
            raise InvalidArgument(f"label_map[{name!r}]={label!r} must be one of {LABELS}")
    return {**CLASS_LABELS, **label_map}


def _labels(
    indices: NDArray[np.int64], class_names: Sequence[str], first: int, what: str, mapping: Any
) -> list[Label]:
    if isinstance(class_names, str) or not isinstance(class_names, Sequence) or not class_names:
        raise InvalidArgument(f"class_names={class_names!r} must be a non-empty list of names")
    labels: list[Label] = []
    for row, index in enumerate(indices.tolist()):
        position = index - first
        if not 0 <= position < len(class_names):
            raise InvalidArgument(
                f"{what}[{row}]={index} is not a class index: {what} are {first}-based into "
                f"class_names, which has {len(class_names)} names"
            )
        labels.append(mapping.get(class_names[position], "unknown"))
    return labels


def _boxes(
    rows: NDArray[np.float64],
    labels: list[Label],
    scores: NDArray[np.float64] | None,
    min_score: float,
    what: str,
) -> list[Box]:
    if not math.isfinite(min_score):
        raise InvalidArgument(f"min_score={min_score!r} must be a finite number")
    boxes = []
    for row, values in enumerate(rows.tolist()):
        score = None if scores is None else float(scores[row])
        if score is not None and score < min_score:
            continue
        x, y, z, length, width, height, yaw = values
        try:
            boxes.append(Box((x, y, z), (length, width, height), yaw, labels[row], score))
        except InvalidArgument as error:
            raise InvalidArgument(f"{what} row {row} ({values}): {error}") from None
    return boxes


def _check_rows(boxes: NDArray[np.float64], name: str, columns: int = 7) -> NDArray[np.float64]:
    if boxes.ndim != 2 or boxes.shape[1] < columns:
        raise InvalidArgument(f"{name} must have shape (N, >={columns}), got {boxes.shape}")
    return boxes[:, :columns].copy()


def _check_length(values: NDArray[Any] | None, count: int, name: str, boxes: str) -> None:
    if values is not None and values.shape != (count,):
        raise InvalidArgument(f"{name} has shape {values.shape}; {boxes} has {count} rows")


def _unpack(
    given: tuple[Any, Any, Any], names: tuple[str, str, str], first: int
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64] | None]:
    """(rows, label indices, scores or None) from arrays or from one prediction dict."""
    boxes, labels, scores = given
    box_key, label_key, score_key = names
    if isinstance(boxes, Mapping):
        if labels is not None or scores is not None:
            raise InvalidArgument(f"pass a prediction dict alone, or {box_key} with {label_key}")
        missing = {box_key, label_key} - set(boxes)
        if missing:
            raise InvalidArgument(f"the prediction dict has no {sorted(missing)}")
        boxes, labels, scores = boxes[box_key], boxes[label_key], boxes.get(score_key)
    if labels is None:
        raise InvalidArgument(f"{label_key} is required ({first}-based indices into class_names)")
    rows = _check_rows(_array(boxes, box_key), box_key)
    indices = _array(labels, label_key, dtype=np.int64).reshape(-1)
    values = None if scores is None else _array(scores, score_key).reshape(-1)
    _check_length(indices, len(rows), label_key, box_key)
    _check_length(values, len(rows), score_key, box_key)
    return rows, indices, values


def from_openpcdet(
    pred_boxes: Any,
    pred_labels: Any = None,
    pred_scores: Any = None,
    *,
    class_names: Sequence[str],
    min_score: float = 0.0,
    label_map: Mapping[str, Label] | None = None,
) -> list[Box]:
    """Boxes from one frame of OpenPCDet predictions.

    Parameters
    ----------
    pred_boxes : (N, 7+) array_like or dict
        x, y, z (box centre), dx, dy, dz, heading; extra columns (velocities) ignored. Or
        one of OpenPCDet's ``pred_dicts`` items (keys ``pred_boxes``, ``pred_labels``,
        ``pred_scores``). numpy arrays and torch tensors both work.
    pred_labels : (N,) int
        1-based indices into ``class_names``.
    pred_scores : (N,) float, optional
    class_names : sequence of str
        The model config's ``CLASS_NAMES``, e.g. ``["Car", "Pedestrian", "Cyclist"]``.
    min_score : float
        Boxes scoring below it are dropped.
    label_map : mapping, optional
        Extra class-name -> label entries on top of :data:`CLASS_LABELS`.
    """
    rows, indices, scores = _unpack(
        (pred_boxes, pred_labels, pred_scores), ("pred_boxes", "pred_labels", "pred_scores"), 1
    )
    labels = _labels(indices, class_names, 1, "pred_labels", label_mapping(label_map))
    return _boxes(rows, labels, scores, min_score, "pred_boxes")


def from_mmdet3d(
    bboxes_3d: Any,
    labels_3d: Any = None,
    scores_3d: Any = None,
    *,
    class_names: Sequence[str],
    min_score: float = 0.0,
    origin: tuple[float, float, float] = (0.5, 0.5, 0.0),
    convention: Literal["v1", "v0"] = "v1",
    label_map: Mapping[str, Label] | None = None,
) -> list[Box]:
    """Boxes from one frame of mmdetection3d LiDAR predictions.

    Parameters
    ----------
    bboxes_3d : LiDARInstance3DBoxes, (N, 7+) array_like, or dict
        x, y, z of the point given by ``origin`` (default the bottom centre), x_size,
        y_size, z_size, yaw; extra columns (nuScenes velocities) ignored. Or
        ``pred_instances_3d`` as a dict (keys ``bboxes_3d``, ``labels_3d``, ``scores_3d``).
    labels_3d : (N,) int
        0-based indices into ``class_names``.
    scores_3d : (N,) float, optional
    class_names : sequence of str
        The dataset's classes (``model.dataset_meta["classes"]``).
    origin : (3,) float
        The box point the coordinates give, relative to the box (mmdetection3d's
        ``origin`` argument); (0.5, 0.5, 0.5) for box centres.
    convention : {"v1", "v0"}
        ``"v1"`` for mmdetection3d >= 1.0; ``"v0"`` for older releases, whose LiDAR boxes
        stored (w, l, h) and a heading of ``-yaw - pi/2`` (the v1.0 coordinate refactor).
    min_score, label_map
        As for :func:`from_openpcdet`.
    """
    rows, indices, scores = _unpack(
        (bboxes_3d, labels_3d, scores_3d), ("bboxes_3d", "labels_3d", "scores_3d"), 0
    )
    if convention not in ("v1", "v0"):
        raise InvalidArgument(f"convention={convention!r} must be 'v1' or 'v0'")
    given = _array(origin, "origin").reshape(-1)
    if given.shape != (3,) or not ((given >= 0) & (given <= 1)).all():
        raise InvalidArgument(f"origin={origin!r} must be 3 numbers in [0, 1]")
    if convention == "v0":
        rows[:, [3, 4]] = rows[:, [4, 3]]
        rows[:, 6] = -rows[:, 6] - math.pi / 2
    # Move the given point to the centre: only the vertical origin matters for yaw-only
    # boxes whose x/y origin is the middle; a corner origin moves along the box axes.
    shift = 0.5 - given
    along, across = shift[0] * rows[:, 3], shift[1] * rows[:, 4]
    rows[:, 0] += along * np.cos(rows[:, 6]) - across * np.sin(rows[:, 6])
    rows[:, 1] += along * np.sin(rows[:, 6]) + across * np.cos(rows[:, 6])
    rows[:, 2] += shift[2] * rows[:, 5]
    labels = _labels(indices, class_names, 0, "labels_3d", label_mapping(label_map))
    return _boxes(rows, labels, scores, min_score, "bboxes_3d")


def read_kitti_predictions(
    path: str | os.PathLike[str],
    calibration: str | os.PathLike[str] | KittiCalibration,
    *,
    min_score: float = 0.0,
) -> list[Box]:
    """Boxes of a KITTI-format prediction file (as OpenPCDet and mmdetection3d write them).

    Lines are KITTI label lines with a 16th value, the score (a 15-value line has none and
    is kept); locations are in the rectified camera frame, converted with the frame's
    ``calib`` file (see :mod:`pytest_metamorphic.lidar.io.kitti`).
    """
    boxes = read_kitti_labels(path, calibration)
    return [box for box in boxes if box.score is None or box.score >= min_score]


def boxes_to_array(boxes: Sequence[Box]) -> NDArray[np.float64]:
    """(N, 7) float64: x, y, z (centre), length, width, height, yaw: OpenPCDet's layout."""
    rows = [(*box.center, *box.size, box.yaw) for box in boxes]
    return np.array(rows, dtype=np.float64).reshape(-1, 7)
