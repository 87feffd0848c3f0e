"""KITTI object labels (``label_2/*.txt``) and calibration (``calib/*.txt``).

Labels give boxes in the rectified camera-0 frame (x right, y down, z forward; the
location is the centre of the box's *bottom* face; ``rotation_y`` about camera y).
:func:`read_kitti_labels` converts them to the LiDAR frame (x forward, y left, z up)
through the file's own ``R0_rect`` and ``Tr_velo_to_cam`` (full inverse transforms, not
the usual axis-swap approximation), with the box centre lifted to mid-height.

KITTI classes map onto the project's labels as Apollo's perception groups them (Apollo
has one VEHICLE type for every motor vehicle):

=======================================  ==============
KITTI ``type``                           label
=======================================  ==============
Car, Van, Truck, Tram                    ``car``
Pedestrian, Person_sitting               ``pedestrian``
Cyclist                                  ``cyclist``
Misc                                     ``unknown``
DontCare                                 not objects: image regions
                                         (:func:`read_kitti_dont_care`)
=======================================  ==============

:func:`read_kitti_objects` keeps everything else a label line says (original type,
truncation, occlusion, alpha, 2-D box) beside the converted :class:`Box`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.core.files import open_regular
from pytest_metamorphic.lidar.model.obstacles import Box, Label

__all__ = [
    "KITTI_LABELS",
    "KittiCalibration",
    "KittiDontCare",
    "KittiObject",
    "read_kitti_calibration",
    "read_kitti_dont_care",
    "read_kitti_labels",
    "read_kitti_objects",
    "sensor_calibration",
    "write_kitti_calibration",
    "write_kitti_labels",
]

KITTI_LABELS: dict[str, Label] = {
    "Car": "car",
    "Van": "car",
    "Truck": "car",
    "Tram": "car",
    "Pedestrian": "pedestrian",
    "Person_sitting": "pedestrian",
    "Cyclist": "cyclist",
    "Misc": "unknown",
}

# Object-benchmark names first, tracking-benchmark aliases second.
_KEYS = {
    "P2": ("P2",),
    "R0_rect": ("R0_rect", "R_rect"),
    "Tr_velo_to_cam": ("Tr_velo_to_cam", "Tr_velo_cam"),
}
MAX_TEXT_BYTES = 1 << 20


@dataclass(frozen=True)
class KittiCalibration:
    """The calibration a frame's labels need.

    Attributes
    ----------
    P2 : (3, 4) float64
      Left colour camera projection (rectified).
    R0_rect : (3, 3) float64
      Rectifying rotation of camera 0.
    Tr_velo_to_cam : (3, 4) float64
      LiDAR to camera-0 rigid transform.
    """

    P2: NDArray[np.float64]
    R0_rect: NDArray[np.float64]
    Tr_velo_to_cam: NDArray[np.float64]

    def rect_to_velo(self) -> NDArray[np.float64]:
        """(4, 4) float64 taking rectified camera coordinates to LiDAR coordinates."""
        rect = np.eye(4)
        rect[:3, :3] = self.R0_rect
        velo_to_cam = np.eye(4)
        velo_to_cam[:3, :] = self.Tr_velo_to_cam
        return np.asarray(np.linalg.inv(rect @ velo_to_cam), dtype=np.float64)


@dataclass(frozen=True)
class KittiObject:
    """One label line: the KITTI record and the box converted to the LiDAR frame."""

    type: str
    truncated: float
    occluded: int
    alpha: float
    bbox: tuple[float, float, float, float]
    box: Box


def _read_text(path: Path, what: str) -> str:
    with open_regular(path, what=what) as handle:
        raw = handle.read(MAX_TEXT_BYTES + 1)
    if len(raw) > MAX_TEXT_BYTES:
        raise DataError(f"{what} is over {MAX_TEXT_BYTES} bytes; not a KITTI text file", path=path)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise DataError(f"{what} is not text (byte {error.start})", path=path) from None


def _numbers(parts: list[str], path: Path, where: str) -> list[float]:
    try:
        values = [float(part) for part in parts]
    except ValueError:
        raise DataError(
            f"{where}: non-numeric value in {' '.join(parts)[:80]!r}", path=path
        ) from None
    if not all(math.isfinite(value) for value in values):
        raise DataError(f"{where}: non-finite value", path=path)
    return values


def read_kitti_calibration(path: str | os.PathLike[str]) -> KittiCalibration:
    """Read a KITTI object (or tracking) calibration file.

    Raises
    ------
    DataError
      A required matrix (P2, R0_rect, Tr_velo_to_cam) is missing or malformed.
    """
    path = Path(path)
    entries: dict[str, list[float]] = {}
    for number, line in enumerate(_read_text(path, "calibration").splitlines(), 1):
        if not line.strip():
            continue
        key, colon, rest = line.partition(":")
        if not colon:
            key, _, rest = line.strip().partition(" ")  # tracking files have no colons
        entries[key.strip()] = _numbers(rest.split(), path, f"line {number} ({key.strip()})")
    matrices = {}
    for name, shape in (("P2", (3, 4)), ("R0_rect", (3, 3)), ("Tr_velo_to_cam", (3, 4))):
        found = next((k for k in _KEYS[name] if k in entries), None)
        if found is None:
            raise DataError(
                f"no {name} matrix (keys present: {sorted(entries) or 'none'}); "
                "is this a KITTI object calibration file?",
                path=path,
            )
        values = entries[found]
        if len(values) != shape[0] * shape[1]:
            raise DataError(
                f"{found} has {len(values)} numbers, expected {shape[0] * shape[1]}", path=path
            )
        matrices[name] = np.array(values, np.float64).reshape(shape)
    if abs(np.linalg.det(matrices["R0_rect"])) < 1e-6:
        raise DataError("R0_rect is singular", path=path)
    if abs(np.linalg.det(matrices["Tr_velo_to_cam"][:, :3])) < 1e-6:
        raise DataError("Tr_velo_to_cam has a singular rotation", path=path)
    return KittiCalibration(**matrices)


def _calibration(calibration: str | os.PathLike[str] | KittiCalibration) -> KittiCalibration:
    """``calibration`` itself, or the calibration file it names, read."""
    if isinstance(calibration, KittiCalibration):
        return calibration
    return read_kitti_calibration(calibration)


def read_kitti_objects(
    label_path: str | os.PathLike[str],
    calibration: str | os.PathLike[str] | KittiCalibration,
) -> list[KittiObject]:
    """Every object of a KITTI label file except DontCare, boxes in the LiDAR frame.

    Parameters
    ----------
    label_path : path-like
      15 values per line (ground truth) or 16 (detections, with a score).
    calibration : path-like or KittiCalibration
      The frame's ``calib/*.txt``.
    """
    label_path = Path(label_path)
    calib = _calibration(calibration)
    to_velo = calib.rect_to_velo()
    objects = []
    for number, line in enumerate(_read_text(label_path, "label file").splitlines(), 1):
        parts = line.split()
        if not parts or parts[0] == "DontCare":
            continue
        where = f"line {number}"
        if len(parts) not in (15, 16):
            raise DataError(f"{where} has {len(parts)} values, expected 15 or 16", path=label_path)
        kind = parts[0]
        if kind not in KITTI_LABELS:
            raise DataError(
                f"{where}: unknown KITTI type {kind[:40]!r} (known: {sorted(KITTI_LABELS)}, "
                "DontCare)",
                path=label_path,
            )
        values = _numbers(parts[1:], label_path, where)
        truncated, occluded, alpha = values[0], values[1], values[2]
        bbox = tuple(values[3:7])
        height, width, length = values[7:10]
        if min(height, width, length) <= 0:
            raise DataError(f"{where}: box size h={height} w={width} l={length}", path=label_path)
        box = _to_lidar(values[10:13], (length, width, height), values[13], to_velo)
        box = Box(
            box.center,
            box.size,
            box.yaw,
            label=KITTI_LABELS[kind],
            score=values[14] if len(values) == 15 else None,
        )
        objects.append(KittiObject(kind, truncated, int(occluded), alpha, bbox, box))  # type: ignore[arg-type]
    return objects


def read_kitti_labels(
    label_path: str | os.PathLike[str],
    calib_path: str | os.PathLike[str] | KittiCalibration,
) -> list[Box]:
    """Ground-truth boxes of a KITTI label file in the LiDAR frame (DontCare skipped).

    See the module docstring for the class mapping and the conversion.
    """
    return [item.box for item in read_kitti_objects(label_path, calib_path)]


@dataclass(frozen=True)
class KittiDontCare:
    """The image regions a KITTI label file marks DontCare, where nothing was labelled.

    KITTI's annotators drew DontCare boxes in the left colour image over objects they did
    not label (mostly ones too far away or too hidden). KITTI's evaluation neither
    rewards nor counts as false a detection that falls in one: :meth:`covers` says
    whether a LiDAR-frame box does, by the devkit's rule (the share of the detection's
    image rectangle inside the region, against the class's overlap threshold).

    Attributes
    ----------
    regions : tuple of (left, top, right, bottom)
        Pixels in image 2.
    calibration : KittiCalibration
        The frame's own, to project boxes into image 2.
    """

    regions: tuple[tuple[float, float, float, float], ...]
    calibration: KittiCalibration

    def image_rectangle(self, box: Box) -> tuple[float, float, float, float] | None:
        """The box's 8 corners projected into image 2, as (left, top, right, bottom).

        None when a corner lies less than 0.1 m in front of the camera (not in the image).
        """
        calib = self.calibration
        bev = box.corners_bev()
        low, high = box.center[2] - box.size[2] / 2.0, box.center[2] + box.size[2] / 2.0
        corners = np.array([[x, y, z, 1.0] for x, y in bev for z in (low, high)])
        camera = calib.R0_rect @ (calib.Tr_velo_to_cam @ corners.T)
        if np.any(camera[2] < 0.1):
            return None
        image = calib.P2 @ np.vstack([camera, np.ones(len(corners))])
        u, v = image[0] / image[2], image[1] / image[2]
        return float(u.min()), float(v.min()), float(u.max()), float(v.max())

    def covers(self, box: Box, *, share: float = 0.5) -> bool:
        """Whether more than ``share`` of ``box``'s image rectangle lies in one region."""
        if not self.regions:
            return False
        rectangle = self.image_rectangle(box)
        if rectangle is None:
            return False
        left, top, right, bottom = rectangle
        area = (right - left) * (bottom - top)
        if area <= 0:
            return False
        for a, b, c, d in self.regions:
            wide = max(min(right, c) - max(left, a), 0.0)
            high = max(min(bottom, d) - max(top, b), 0.0)
            if wide * high / area > share:
                return True
        return False


def read_kitti_dont_care(
    label_path: str | os.PathLike[str],
    calibration: str | os.PathLike[str] | KittiCalibration,
) -> KittiDontCare:
    """The DontCare regions of a KITTI label file, with the frame's calibration.

    Raises
    ------
    DataError
      A DontCare line without four numeric image coordinates (left <= right, top <= bottom).
    """
    label_path = Path(label_path)
    calib = _calibration(calibration)
    regions = []
    for number, line in enumerate(_read_text(label_path, "label file").splitlines(), 1):
        parts = line.split()
        if not parts or parts[0] != "DontCare":
            continue
        if len(parts) < 8:
            raise DataError(f"line {number}: DontCare has no 2-D box", path=label_path)
        left, top, right, bottom = _numbers(parts[4:8], label_path, f"line {number}")
        if left > right or top > bottom:
            raise DataError(
                f"line {number}: DontCare box ({left}, {top}, {right}, {bottom}) is inverted",
                path=label_path,
            )
        regions.append((left, top, right, bottom))
    return KittiDontCare(tuple(regions), calib)


def _to_lidar(
    location: list[float],
    size: tuple[float, float, float],
    rotation_y: float,
    to_velo: NDArray[np.float64],
) -> Box:
    length, width, height = size
    x, y, z = location
    # The label's location is the bottom face's centre; camera y points down.
    centre = to_velo @ np.array([x, y - height / 2.0, z, 1.0])
    # Heading: rotation_y = 0 faces camera +x; the direction is (cos r, 0, -sin r).
    heading = to_velo[:3, :3] @ np.array([math.cos(rotation_y), 0.0, -math.sin(rotation_y)])
    yaw = math.atan2(heading[1], heading[0])
    return Box(tuple(centre[:3]), (length, width, height), yaw)


def sensor_calibration() -> KittiCalibration:
    """A calibration whose camera sits at the LiDAR, looking along +x.

    For exporting frames that have no calibration of their own (rendered scenes, other
    sensors) as a KITTI-style dataset: ``R0_rect`` is the identity and
    ``Tr_velo_to_cam`` only swaps axes (camera x right = -y, y down = -z, z forward = x),
    so labels written and read with it are the LiDAR boxes exactly.
    """
    axes = np.array([[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    projection = np.array([[721.5377, 0.0, 609.5593, 0.0], [0.0, 721.5377, 172.854, 0.0],
                           [0.0, 0.0, 1.0, 0.0]])  # fmt: skip
    return KittiCalibration(P2=projection, R0_rect=np.eye(3), Tr_velo_to_cam=axes)


def write_kitti_calibration(path: str | os.PathLike[str], calibration: KittiCalibration) -> None:
    """Write ``calibration`` as a KITTI object ``calib/*.txt`` file (P0-P3, R0_rect, Tr)."""
    path = Path(path)
    lines = [f"P{i}: " + _row(calibration.P2) for i in range(4)]
    lines.append("R0_rect: " + _row(calibration.R0_rect))
    lines.append("Tr_velo_to_cam: " + _row(calibration.Tr_velo_to_cam))
    lines.append("Tr_imu_to_velo: " + _row(np.eye(4)[:3]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _row(matrix: NDArray[np.float64]) -> str:
    return " ".join(f"{value:.12e}" for value in np.asarray(matrix, dtype=np.float64).ravel())


_KITTI_TYPES = {"car": "Car", "pedestrian": "Pedestrian", "cyclist": "Cyclist", "unknown": "Misc"}


def write_kitti_labels(
    path: str | os.PathLike[str],
    boxes: list[Box],
    calibration: KittiCalibration,
    *,
    precision: int = 6,
) -> None:
    """Write LiDAR-frame boxes as KITTI label lines (a 16th value when a box has a score).

    The inverse of :func:`read_kitti_labels` through ``calibration``: locations are the
    bottom centres in the rectified camera frame. KITTI's own files keep 2 decimals;
    ``precision`` (default 6) keeps round trips within a micrometre. The 2-D box and
    alpha are written as 0 (they need the image, and no LiDAR evaluation reads them).
    """
    velo_to_rect = np.linalg.inv(calibration.rect_to_velo())
    lines = []
    for box in boxes:
        length, width, height = box.size
        # The inverse of _to_lidar: the centre to the camera, then down camera y by h / 2.
        x, y, z = (velo_to_rect @ np.array([*box.center, 1.0]))[:3]
        y += height / 2.0
        heading = velo_to_rect[:3, :3] @ np.array([math.cos(box.yaw), math.sin(box.yaw), 0.0])
        rotation_y = math.atan2(-heading[2], heading[0])
        values = [0.0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, height, width, length, x, y, z, rotation_y]
        text = " ".join(
            str(v) if isinstance(v, int) else f"{float(v):.{precision}f}" for v in values
        )
        score = "" if box.score is None else f" {box.score:.{precision}f}"
        lines.append(f"{_KITTI_TYPES[box.label]} {text}{score}")
    Path(path).write_text("\n".join(lines) + ("\n" if lines else ""), encoding="utf-8")
