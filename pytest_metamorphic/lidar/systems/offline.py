"""Offline campaigns: export every input as a KITTI-style dataset, evaluate predictions later.

For detectors that run only somewhere else (a GPU cluster, a vendor's evaluation
pipeline, a ROS 2 replay): :func:`export_dataset` writes each source and follow-up
input of a campaign as a KITTI-style folder, the user runs the detector over it however
they like, and :func:`offline_campaign` turns the prediction files back into the same
campaign, so that ``run_campaign`` reports exactly what the online run would have (the
inputs are regenerated from the same seeds and recognised by their contents).

Dataset layout (``folder/``)::

    velodyne/000000.bin     float32 x, y, z, intensity: one file per input
    calib/000000.txt        KITTI calibration (the axis-swap sensor_calibration: camera
                            at the LiDAR, so KITTI labels map back exactly)
    roi/000000.json         the frame's ROI polygons, for ROI-first stacks
    ImageSets/test.txt      every id, one per line (OpenPCDet's and mmdetection3d's lists)
    manifest.json           the campaign header, and per id: source, size, follow-up,
                            the perturbation's parameters and the cloud's SHA-1

Predictions: one file per id in a folder, ``000000.txt`` (KITTI labels, with scores, as
OpenPCDet and mmdetection3d write them) or ``000000.json`` (see
:func:`~pytest_metamorphic.lidar.systems.process.read_json_predictions`).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pytest_metamorphic.core.campaign import Campaign, campaign_inputs
from pytest_metamorphic.core.errors import DataError, ExternalSystemError, InvalidArgument
from pytest_metamorphic.core.files import field, inside, read_json, read_regular
from pytest_metamorphic.core.locks import exclusive
from pytest_metamorphic.lidar.io import write_bin
from pytest_metamorphic.lidar.io.kitti import (
    read_kitti_labels,
    sensor_calibration,
    write_kitti_calibration,
)
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.process import read_json_predictions

__all__ = ["OfflinePredictions", "export_dataset", "frame_digest", "offline_campaign"]

MANIFEST = "manifest.json"
FORMAT = "pytest-metamorphic offline dataset"


def frame_digest(frame: Any) -> str:
    """SHA-1 of a frame's points as float32 x, y, z, intensity: how inputs are recognised."""
    cloud = getattr(frame, "cloud", frame)
    points = np.ascontiguousarray(getattr(cloud, "points", cloud), dtype=np.float32)
    return hashlib.sha1(points.tobytes()).hexdigest()


def _summary(params: Any) -> dict[str, Any]:
    """JSON-safe perturbation parameters for the manifest (objects by name and size)."""
    summary: dict[str, Any] = {}
    for key, value in dict(params).items():
        if isinstance(value, (str, int, float, bool)) or value is None:
            summary[key] = value
        elif hasattr(value, "params") and callable(value.params):
            summary[key] = {"type": type(value).__name__, "elements": len(value)}
        else:
            summary[key] = repr(value)[:200]
    return summary


def export_dataset(
    campaign: Campaign,
    folder: str | os.PathLike[str],
    *,
    sources: Iterable[int] | None = None,
) -> Path:
    """Write every input of ``campaign`` (sources and follow-ups) as a KITTI-style dataset.

    Parameters
    ----------
    campaign : Campaign
        A LiDAR campaign (inputs are :class:`~pytest_metamorphic.lidar.model.frame.Frame`).
    folder : path-like
        Created if needed; it must not hold another dataset's manifest.
    sources : iterable of int, optional
        Only these source indices (default all): to split the export over machines.

    Returns
    -------
    Path
        The manifest.
    """
    if not isinstance(campaign, Campaign):
        raise InvalidArgument(f"campaign={campaign!r} must be a Campaign")
    root = Path(folder)
    # One export per folder at a time: two would mix their files (the lock dies with
    # the process; core/locks.py).
    with exclusive(root / ".export.lock", what=f"export folder {root}"):
        return _export(campaign, root, sources)


def _export(campaign: Campaign, root: Path, sources: Iterable[int] | None) -> Path:
    manifest_path = root / MANIFEST
    if manifest_path.exists():
        raise InvalidArgument(
            f"{manifest_path} exists: export each campaign to a fresh folder (nothing is "
            "overwritten)"
        )
    for name in ("velodyne", "calib", "roi", "ImageSets"):
        (root / name).mkdir(parents=True, exist_ok=True)
    calibration = sensor_calibration()
    entries = []
    for number, item in enumerate(campaign_inputs(campaign, sources)):
        frame = item.input
        if not isinstance(frame, Frame):
            raise InvalidArgument(
                f"input of source {item.source} is {type(frame).__name__}; offline export "
                "writes LiDAR frames"
            )
        key = f"{number:06d}"
        write_bin(frame.cloud, root / "velodyne" / f"{key}.bin", overwrite=True)
        write_kitti_calibration(root / "calib" / f"{key}.txt", calibration)
        polygons = [np.asarray(p).tolist() for p in getattr(frame.roi, "polygons", ())]
        (root / "roi" / f"{key}.json").write_text(json.dumps({"polygons": polygons}))
        entries.append(
            {
                "id": key,
                "source": item.source,
                "size": item.size,
                "followup": item.followup,
                "points": len(frame.cloud),
                "sha1": frame_digest(frame),
                "params": _summary(item.params),
            }
        )
    (root / "ImageSets" / "test.txt").write_text("".join(f"{e['id']}\n" for e in entries))
    document = {"format": FORMAT, "campaign": campaign.header(), "inputs": entries}
    temporary = manifest_path.with_suffix(".tmp")
    temporary.write_text(json.dumps(document, indent=1))
    os.replace(temporary, manifest_path)  # the manifest appears only when all is written
    return manifest_path


class OfflinePredictions:
    """A system under test that answers from prediction files of an exported dataset.

    Parameters
    ----------
    dataset : path-like
        The folder :func:`export_dataset` wrote.
    predictions : path-like
        The folder holding one prediction file per id.
    format : {"kitti", "json"}
    class_names : sequence of str, optional
        For JSON predictions in OpenPCDet's or mmdetection3d's array layout.
    """

    def __init__(
        self,
        dataset: str | os.PathLike[str],
        predictions: str | os.PathLike[str],
        *,
        format: Literal["kitti", "json"] = "kitti",
        class_names: Sequence[str] | None = None,
    ) -> None:
        if format not in ("kitti", "json"):
            raise InvalidArgument(f"format={format!r} must be 'kitti' or 'json'")
        self.dataset = Path(dataset)
        self.predictions = Path(predictions)
        self.format = format
        self.class_names = None if class_names is None else list(class_names)
        manifest = self.dataset / MANIFEST
        document = read_json(manifest, what="offline dataset manifest")
        if field(document, "format", str, where="the manifest", path=manifest) != FORMAT:
            raise DataError(f"not a {FORMAT} manifest", path=manifest)
        if not self.predictions.is_dir():
            raise InvalidArgument(f"predictions={self.predictions} is not a folder")
        self.header = field(document, "campaign", dict, where="the manifest", path=manifest)
        self.ids = _manifest_ids(
            field(document, "inputs", list, where="the manifest", path=manifest), manifest
        )
        self._verified: set[str] = set()

    def __repr__(self) -> str:
        return f"OfflinePredictions({str(self.predictions)!r}, {self.format})"

    def __call__(self, frame: Any, roi: Any = None) -> list[Box]:
        digest = frame_digest(frame)
        key = self.ids.get(digest)
        if key is None:
            raise ExternalSystemError(
                f"this input is not in the dataset {self.dataset} (exported from another "
                "campaign, seed or version?)"
            )
        self._verify(key, digest)
        suffix = ".txt" if self.format == "kitti" else ".json"
        path = inside(self.predictions, f"{key}{suffix}", field=f"prediction file of {key}")
        if not path.exists():
            raise ExternalSystemError(f"no predictions for input {key}: {path} is missing")
        if self.format == "json":
            return read_json_predictions(path, class_names=self.class_names)
        return read_kitti_labels(path, sensor_calibration())

    def _verify(self, key: str, digest: str) -> None:
        """The exported cloud of ``key`` is the input the manifest says (checked once per
        id): an edited manifest or swapped files cannot pair an input with the predictions
        of another."""
        if key in self._verified:
            return
        cloud = inside(self.dataset / "velodyne", f"{key}.bin", field=f"input {key}")
        if hashlib.sha1(read_regular(cloud, what="exported input")).hexdigest() != digest:
            raise DataError(
                f"the manifest pairs this input with id {key}, but velodyne/{key}.bin holds "
                "another cloud: the manifest was edited or the files were swapped",
                path=self.dataset / MANIFEST,
            )
        self._verified.add(key)


_ID = re.compile(r"[A-Za-z0-9_-]{1,64}")
_SHA1 = re.compile(r"[0-9a-f]{40}")


def _manifest_ids(entries: list[Any], manifest: Path) -> dict[str, str]:
    """sha1 -> id of the manifest's inputs; ids are plain, unique file names."""
    ids: dict[str, str] = {}
    seen: set[str] = set()
    for number, entry in enumerate(entries):
        where = f"the manifest's inputs[{number}]"
        key = field(entry, "id", str, where=where, path=manifest)
        digest = field(entry, "sha1", str, where=where, path=manifest)
        if not _ID.fullmatch(key):
            raise DataError(
                f"{where}: id {key[:40]!r} is not a plain file name (letters, digits, _ and -)",
                path=manifest,
            )
        if key in seen:
            raise DataError(f"{where}: id {key!r} appears twice", path=manifest)
        if not _SHA1.fullmatch(digest):
            raise DataError(f"{where}: sha1 is not 40 hexadecimal digits", path=manifest)
        seen.add(key)
        # Identical inputs (a follow-up equal to its source) share one prediction file.
        ids[digest] = key
    return ids


def offline_campaign(campaign: Campaign, predictions: OfflinePredictions) -> Campaign:
    """``campaign`` with its system replaced by the prediction files; run it as usual.

    The dataset must have been exported from this very campaign (same name, relation,
    seed, sizes, sources and follow-ups); ``run_campaign`` then gives the report the
    online run would have given with the detector that wrote the predictions.
    """
    if not isinstance(predictions, OfflinePredictions):
        raise InvalidArgument(f"predictions={predictions!r} must be OfflinePredictions")
    if predictions.header != campaign.header():
        raise InvalidArgument(
            f"the dataset {predictions.dataset} was exported from campaign "
            f"{predictions.header}, not {campaign.header()}"
        )
    return replace(campaign, system=predictions)
