"""A library of objects to insert, saved once and shared: templates cut from labelled
recordings or rendered scenes, for insertion into recordings that have no labels.

:func:`save_templates` writes them to one ``.npz`` file (numpy arrays and a JSON index,
no pickles); :func:`load_templates` reads it back, checking every array, so a library
downloaded from elsewhere is as safe to load as a point cloud.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import write_atomically
from pytest_metamorphic.core.npz import NpzArchive
from pytest_metamorphic.lidar.followups.insert.template import ObjectTemplate
from pytest_metamorphic.lidar.model.obstacles import LABELS

__all__ = ["load_templates", "save_templates"]

_FORMAT = "pytest-metamorphic object templates 1"
_MAX_TEMPLATES = 10_000


def save_templates(path: str | os.PathLike[str], templates: Sequence[ObjectTemplate]) -> Path:
    """Write ``templates`` to ``path`` (a ``.npz`` file, replaced atomically); a whole
    mesh (``solid``, :meth:`~pytest_metamorphic.lidar.followups.insert.ObjectTemplate.from_mesh`)
    stays one, and goes to the near field when loaded."""
    chosen = list(templates)
    if not chosen or not all(isinstance(t, ObjectTemplate) for t in chosen):
        raise InvalidArgument("templates must be a non-empty sequence of ObjectTemplate")
    arrays: dict[str, np.ndarray] = {}
    index = []
    for i, template in enumerate(chosen):
        arrays[f"v{i}"] = np.asarray(template.vertices, dtype=np.float64)
        arrays[f"f{i}"] = np.asarray(template.faces, dtype=np.int64)
        arrays[f"i{i}"] = np.asarray(template.intensity, dtype=np.float32)
        index.append(
            {
                "label": template.label,
                "size": [float(v) for v in template.size],
                "view": template.view,
                "range": template.range,
                "bearing": template.bearing,
                "source": template.source,
                "spacing": [float(v) for v in template.spacing],
                "solid": template.solid,
            }
        )
    arrays["index"] = np.frombuffer(
        json.dumps({"format": _FORMAT, "templates": index}).encode(), dtype=np.uint8
    )
    target = Path(path)

    def write(tmp: Path) -> None:
        with tmp.open("wb") as handle:
            np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]

    write_atomically(target, write, what="the template library")
    return target


def load_templates(path: str | os.PathLike[str]) -> list[ObjectTemplate]:
    """The templates saved in ``path`` by :func:`save_templates`.

    Raises
    ------
    DataError
        Not such a file, or an array or field that does not fit (named); an array that
        holds Python objects or declares more than :mod:`pytest_metamorphic.core.npz`'s
        bounds is refused before it is read.
    """
    source = Path(path)
    # Every member checked before numpy allocates it: no object arrays, no declared shape
    # or inflated size past core.npz's bounds (a 4 MB file must not ask for 4 GiB).
    with NpzArchive(source, what="object-template library") as archive:
        try:
            meta = json.loads(bytes(archive["index"]).decode())
        except DataError:
            raise
        except (KeyError, ValueError, UnicodeDecodeError):
            raise DataError(
                "not an object-template library: no readable index", path=source
            ) from None
        if not isinstance(meta, dict) or meta.get("format") != _FORMAT:
            raise DataError(f"not an object-template library (format {_FORMAT!r})", path=source)
        entries = meta.get("templates")
        if not isinstance(entries, list) or not 0 < len(entries) <= _MAX_TEMPLATES:
            raise DataError("the index holds no template list", path=source)
        return [_template(archive, i, entry, source) for i, entry in enumerate(entries)]


def _template(archive: NpzArchive, i: int, entry: object, source: Path) -> ObjectTemplate:
    where = f"template {i}"
    try:
        vertices, faces, intensity = archive[f"v{i}"], archive[f"f{i}"], archive[f"i{i}"]
    except KeyError as error:
        raise DataError(f"{where}: array {error} is missing", path=source) from None
    if not isinstance(entry, dict):
        raise DataError(f"{where}: its index entry is not an object", path=source)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.isfinite(vertices).all():
        raise DataError(
            f"{where}: vertices must be finite (k, 3), got {vertices.shape}", path=source
        )
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise DataError(f"{where}: faces must be (m, 3), got {faces.shape}", path=source)
    if faces.dtype.kind not in "iu" or faces.min() < 0 or faces.max() >= len(vertices):
        raise DataError(f"{where}: faces index vertices that do not exist", path=source)
    if intensity.shape != (len(vertices),) or not np.isfinite(intensity).all():
        raise DataError(f"{where}: intensity must be finite, one per vertex", path=source)
    label = entry.get("label")
    if label not in LABELS:
        raise DataError(f"{where}: label {label!r} is not one of {LABELS}", path=source)
    try:
        size = tuple(float(v) for v in entry["size"])
        numbers = [float(entry[key]) for key in ("view", "range", "bearing")]
    except (KeyError, TypeError, ValueError):
        raise DataError(
            f"{where}: size, view, range and bearing must be numbers", path=source
        ) from None
    if len(size) != 3 or not all(math.isfinite(v) and v > 0 for v in size):
        raise DataError(f"{where}: size must be 3 positive lengths", path=source)
    if not all(math.isfinite(v) for v in numbers) or numbers[1] <= 0:
        raise DataError(f"{where}: view, range and bearing must be finite, range > 0", path=source)
    spacing = _spacing(entry.get("spacing"), where, source)
    solid = entry.get("solid", False)  # libraries written before it hold recorded faces
    if not isinstance(solid, bool):
        raise DataError(f"{where}: solid must be true or false, got {solid!r}", path=source)
    template = ObjectTemplate(
        label=label,
        size=size,
        vertices=vertices.astype(np.float64),
        faces=faces.astype(np.int64),
        intensity=intensity.astype(np.float32),
        view=numbers[0],
        range=numbers[1],
        bearing=numbers[2],
        source=str(entry.get("source", "")),
        solid=solid,
    )
    return dataclasses.replace(template, spacing=spacing["spacing"]) if spacing else template


def _spacing(value: object, where: str, source: Path) -> dict[str, tuple[float, float]]:
    """The ``spacing`` keyword of a library entry ({} for libraries written before it)."""
    if value is None:
        return {}
    try:
        azimuth, elevation = (float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise DataError(f"{where}: spacing must be two angles in radians", path=source) from None
    if not all(math.isfinite(v) and 0 < v < 0.2 for v in (azimuth, elevation)):
        raise DataError(
            f"{where}: spacing must be two angles in radians (0 < angle < 0.2)", path=source
        )
    return {"spacing": (azimuth, elevation)}
