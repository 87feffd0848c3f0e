"""How an artifact stores the inputs of a violation: LiDAR frames as PCD (and a bag when
they came from one), AEB scenarios as JSON, plain JSON values as they are; and how it reads
them back for ``--mt-replay``."""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import DataError

__all__ = [
    "RECORD",
    "box_json",
    "decode_input",
    "encode_input",
    "is_box",
    "roi_json",
    "round_trips",
]

RECORD = "record.json"
_FRAME_RE = re.compile(r"^(?P<path>.*) \[(?P<topic>/\S*) #(?P<index>\d+)\]$")
_BAG_SUFFIXES = (".bag", ".db3", ".mcap")


def is_box(value: Any) -> bool:
    cls = type(value)
    return cls.__name__ == "Box" and cls.__module__.endswith("lidar.model.obstacles")


def box_json(box: Any) -> dict[str, Any]:
    return {**box.to_json(), "describe": box.describe()}


def roi_json(roi: Any) -> dict[str, Any] | None:
    if roi is None:
        return None
    from pytest_metamorphic.lidar.roi import ROI

    if not isinstance(roi, ROI):
        return {"repr": describe_value(roi)}
    return {
        "polygons": [polygon.tolist() for polygon in roi.polygons],
        "cell_size": roi.cell_size,
        "extend_dist": roi.extend_dist,
        "raster_range": roi.raster_range,
    }


def _bag_origin(origin: str) -> tuple[str, str] | None:
    """``(bag path, topic)`` when a frame's origin names a bag message."""
    match = _FRAME_RE.match(origin)
    if match is None:
        return None
    path = Path(match["path"])
    if path.suffix.lower() in _BAG_SUFFIXES or (path / "metadata.yaml").is_file():
        return str(path), match["topic"]
    return None


def encode_input(value: Any, folder: Path, name: str) -> dict[str, Any]:
    """Write ``value`` under ``folder`` (or inline) and describe how to read it back."""
    from pytest_metamorphic.lidar.model.frame import Frame

    if isinstance(value, Frame):
        from pytest_metamorphic.lidar.io import write_bag, write_pcd

        write_pcd(value.cloud, folder / f"{name}.pcd")
        spec: dict[str, Any] = {
            "kind": "frame",
            "cloud": f"{name}.pcd",
            "points": len(value.cloud),
            "roi": roi_json(value.roi),
            "boxes": [box_json(box) for box in value.boxes],
            "pose": None if value.pose is None else value.pose.tolist(),
            "origin": value.source,
            "index": value.index,
        }
        bag = _bag_origin(value.source)
        if bag is not None:
            write_bag(value.cloud, folder / f"{name}.bag", topic=bag[1])
            spec["bag"] = f"{name}.bag"
            spec["topic"] = bag[1]
        return spec
    from pytest_metamorphic.reports import aeb_artifacts

    if aeb_artifacts.is_scenario(value):
        return aeb_artifacts.encode_scenario(value)
    if round_trips(value):
        return {"kind": "json", "value": value}
    return {
        "kind": "unsupported",
        "type": f"{type(value).__module__}.{type(value).__qualname__}",
        "repr": describe_value(value),
    }


def decode_input(spec: Mapping[str, Any], folder: Path, name: str) -> Any:
    kind = spec.get("kind")
    if kind == "json":
        return spec["value"]
    if kind == "aeb_scenario":
        from pytest_metamorphic.reports.aeb_artifacts import decode_scenario

        try:
            return decode_scenario(spec)
        except DataError as error:
            raise DataError(f"{name}: {error}", path=folder / RECORD) from None
    if kind == "frame":
        from pytest_metamorphic.lidar.io import read_pcd
        from pytest_metamorphic.lidar.model.frame import Frame
        from pytest_metamorphic.lidar.model.obstacles import Box
        from pytest_metamorphic.lidar.roi import ROI

        cloud = read_pcd(folder / spec["cloud"], zeros="keep")
        roi = spec.get("roi")
        if roi is not None:
            if "polygons" not in roi:
                raise DataError(
                    f"{name}: the ROI ({roi.get('repr')}) is not an ROI and cannot be restored",
                    path=folder / RECORD,
                )
            roi = ROI.from_polygons(
                roi["polygons"],
                cell_size=roi["cell_size"],
                extend_dist=roi["extend_dist"],
                raster_range=roi["raster_range"],
            )
        boxes = tuple(
            Box(b["center"], b["size"], b["yaw"], b["label"], b["score"], b["points"])
            for b in spec.get("boxes", ())
        )
        return Frame(
            cloud,
            roi=roi,
            boxes=boxes,
            pose=spec.get("pose"),
            source=spec.get("origin", ""),
            index=spec.get("index", 0),
        )
    raise DataError(
        f"the {name} input ({spec.get('type', kind)}: {spec.get('repr', '')}) was not saved in "
        "a form that can be read back; only LiDAR frames, AEB scenarios and JSON values replay",
        path=folder / RECORD,
    )


def round_trips(value: Any) -> bool:
    try:
        text = json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        return False
    loaded = json.loads(text)
    return type(loaded) is type(value) and loaded == value
