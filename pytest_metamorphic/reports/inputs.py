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
from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import field, inside

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
    """Whether ``value`` is a LiDAR :class:`~pytest_metamorphic.lidar.model.obstacles.Box`
    (told by its class's name and module: AEB-only reports never import the LiDAR code)."""
    cls = type(value)
    return cls.__name__ == "Box" and cls.__module__.endswith("lidar.model.obstacles.box")


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
            "sensor": _sensor_key(value.sensor),
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
    """The input saved as ``spec`` (the record's ``source`` or ``followup``), rebuilt.

    Raises
    ------
    DataError
        A field of the wrong type, a cloud file outside ``folder``, or an input kind that
        cannot be read back; naming the field and the record.
    """
    record = folder / RECORD
    kind = field(spec, "kind", str, where=name, path=record)
    if kind == "json":
        return field(spec, "value", object, where=name, path=record)
    if kind == "aeb_scenario":
        from pytest_metamorphic.reports.aeb_artifacts import decode_scenario

        try:
            return decode_scenario(spec)
        except DataError as error:
            raise DataError(f"{name}: {error}", path=folder / RECORD) from None
    if kind == "frame":
        try:
            return _decode_frame(spec, folder, name)
        except DataError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            # e.g. an InvalidArgument of Box or ROI for a value of the right JSON type
            detail = f"{type(error).__name__}: {error}"[:200]
            raise DataError(
                f"{name}: the frame cannot be rebuilt ({detail})", path=record
            ) from None
    raise DataError(
        f"the {name} input ({str(spec.get('type', kind))[:80]}: {str(spec.get('repr', ''))[:80]}) "
        "was not saved in "
        "a form that can be read back; only LiDAR frames, AEB scenarios and JSON values replay",
        path=folder / RECORD,
    )


def _decode_frame(spec: Mapping[str, Any], folder: Path, name: str) -> Any:
    from pytest_metamorphic.lidar.io import read_pcd
    from pytest_metamorphic.lidar.model.frame import Frame
    from pytest_metamorphic.lidar.model.obstacles import Box
    from pytest_metamorphic.lidar.roi import ROI

    record = folder / RECORD
    cloud_file = inside(folder, spec.get("cloud"), field=f"{name}.cloud", path=record)
    try:
        cloud = read_pcd(cloud_file, zeros="keep")
    except DataError as error:
        # the record points at the file: name both, so a user knows which record to fix
        raise DataError(f"{name}.cloud ({cloud_file.name}): {error}", path=record) from None
    roi = field(spec, "roi", (dict, type(None)), where=name, path=record, default=None)
    if roi is not None:
        if "polygons" not in roi:
            raise DataError(
                f"{name}: the ROI ({str(roi.get('repr'))[:80]}) is not an ROI and cannot be "
                "restored",
                path=record,
            )
        where = f"{name}.roi"
        try:
            roi = ROI.from_polygons(
                field(roi, "polygons", list, where=where, path=record),
                cell_size=field(roi, "cell_size", (int, float), where=where, path=record),
                extend_dist=field(roi, "extend_dist", (int, float), where=where, path=record),
                raster_range=field(roi, "raster_range", (int, float), where=where, path=record),
            )
        except InvalidArgument as error:  # range-checked on load, named by the record
            raise DataError(f"{where}: {error}", path=record) from None
    boxes = []
    for index, box in enumerate(field(spec, "boxes", list, where=name, path=record, default=[])):
        where = f"{name}.boxes[{index}]"
        boxes.append(
            Box(
                field(box, "center", list, where=where, path=record),
                field(box, "size", list, where=where, path=record),
                field(box, "yaw", (int, float), where=where, path=record),
                field(box, "label", str, where=where, path=record),
                field(
                    box, "score", (int, float, type(None)), where=where, path=record, default=None
                ),
                field(box, "points", (int, type(None)), where=where, path=record, default=None),
            )
        )
    return Frame(
        cloud,
        roi=roi,
        boxes=tuple(boxes),
        pose=field(spec, "pose", (list, type(None)), where=name, path=record, default=None),
        source=field(spec, "origin", str, where=name, path=record, default=""),
        index=field(spec, "index", int, where=name, path=record, default=0),
        sensor=_sensor(
            field(spec, "sensor", (str, type(None)), where=name, path=record, default=None), record
        ),
    )


def _sensor_key(sensor: Any) -> str | None:
    """The catalogue key of a frame's sensor (a model of one's own is identified afresh
    from the saved cloud on replay)."""
    from pytest_metamorphic.lidar.model.sensors import SENSORS

    return next((key for key, known in SENSORS.items() if known is sensor), None)


def _sensor(key: str | None, record: Any) -> Any:
    from pytest_metamorphic.lidar.model.sensors import sensor_named

    if key is None:
        return None
    try:
        return sensor_named(key)
    except InvalidArgument:
        raise DataError(f"{record}: unknown sensor {key!r}") from None


def round_trips(value: Any) -> bool:
    try:
        text = json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        return False
    loaded = json.loads(text)
    return type(loaded) is type(value) and loaded == value
