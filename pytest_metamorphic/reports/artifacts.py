"""Violation artifacts: everything needed to look at, and re-run, one metamorphic failure.

One folder per violation, ``<root>/<test>/<relation>/``::

    record.json        relation, verdict, Hypothesis seed, transform parameters (full and
                       minimal), the minimization (k, indices, proven or not, SUT calls),
                       both outputs, the hidden obstacles, and how to replay
    source.pcd         the source frame's cloud (LiDAR sources), plus source.bag when the
    followup.pcd       frame came from a bag; the follow-up is the *minimal* one
    perturbation.pcd   the minimal injected points (point perturbations only)
    birdseye.png       ROI, points, boxes of O and O', hidden obstacle, minimal points

Inputs that are not frames are stored inline in ``record.json`` when they survive a JSON
round trip exactly (numbers, strings, lists, dicts), so those artifacts replay too.
No pickle anywhere: every file is JSON, PCD, a ROS bag or PNG.

A folder is written into a hidden temporary sibling and renamed into place, so it is
either complete or absent. The engine reports the first violation of each relation at
once (before Hypothesis starts shrinking: an interrupted run still leaves it), then the
final, shrunk and reduced one, which replaces it.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_metamorphic.core.comparison import describe_value
from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import field, inside, read_json, staging_sibling
from pytest_metamorphic.core.perturbation import as_reducible
from pytest_metamorphic.reports.inputs import (
    RECORD,
    box_json,
    decode_input,
    encode_input,
    is_box,
)
from pytest_metamorphic.reports.violation_picture import (
    _hidden,
    _injected_points,
    _picture_title,
    draw_violation,
)

__all__ = [
    "RECORD",
    "Artifact",
    "ArtifactWriter",
    "check_folder",
    "load_artifact",
    "load_case",
    "to_jsonable",
    "write_artifact",
    "write_folder_atomically",
]

FORMAT = "pytest-metamorphic violation artifact"
VERSION = 1
_MAX_ARRAY = 100_000
# Perturbation arrays longer than this many rows go to a .npy file beside record.json,
# which then names the file: 10^6 noise points written into the JSON made a 221 MB record
# (twice: reduced and unreduced); the paper's sizes (10-1000) stay inline.
INLINE_ROWS = 10_000
# Perturbations that can be rebuilt from their JSON (type name -> module, class, field).
_PERTURBATIONS = {
    "NoiseOutsideROI": ("pytest_metamorphic.lidar.followups.perturb", "points"),
    "NoiseInsideROI": ("pytest_metamorphic.lidar.followups.perturb", "points"),
    "DropPoints": ("pytest_metamorphic.lidar.followups.perturb", "indices"),
    "DuplicatePoints": ("pytest_metamorphic.lidar.followups.perturb", "indices"),
}
# Object edits that rebuild themselves from their own JSON (``cls.from_json``).
_EDITS = {
    "RemoveObject": "pytest_metamorphic.lidar.followups.edit",
    "InsertObject": "pytest_metamorphic.lidar.followups.insert",
    "RelocateObject": "pytest_metamorphic.lidar.followups.insert.relocation",
    "EarlierSweeps": "pytest_metamorphic.lidar.followups.history",
}


# -- JSON ---------------------------------------------------------------------------------------


def to_jsonable(value: Any, *, depth: int = 0) -> Any:
    """A JSON-safe rendering of ``value`` for records (lossless where it matters).

    Boxes become dicts, numpy values lists or numbers, reducible perturbations their
    ``to_json()``; anything else unknown becomes ``{"repr": ...}``. Non-finite floats
    become the strings ``"nan"``, ``"inf"``, ``"-inf"``.
    """
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if depth > 20:
        return {"repr": describe_value(value)}
    if is_box(value):
        return box_json(value)
    if isinstance(value, Mapping):
        return {str(key): to_jsonable(item, depth=depth + 1) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(item, depth=depth + 1) for item in value]
    module = type(value).__module__
    if module == "numpy":
        if hasattr(value, "shape") and getattr(value, "ndim", 0) > 0:
            if value.size > _MAX_ARRAY:
                return {"shape": list(value.shape), "dtype": str(value.dtype)}
            return to_jsonable(value.tolist(), depth=depth + 1)
        return to_jsonable(value.item(), depth=depth + 1)
    to_json = getattr(value, "to_json", None)
    if not callable(to_json):
        to_json = getattr(as_reducible(value), "to_json", None)
    if callable(to_json):
        return to_json()
    return {"repr": describe_value(value)}


# -- inputs -------------------------------------------------------------------------------------


def _decode_params(params: Mapping[str, Any], path: Path | None = None) -> dict[str, Any]:
    """Transform parameters with known perturbations rebuilt as objects (their arrays read
    from the record's folder when saved apart, :data:`INLINE_ROWS`).

    Raises
    ------
    DataError
        A perturbation or edit whose saved fields do not rebuild it (naming the parameter).
    """
    decoded: dict[str, Any] = {}
    folder = None if path is None else path.parent
    for key, value in params.items():
        try:
            decoded[key] = _decode_param(value, folder, "file")
        except DataError as error:
            raise DataError(f"params.{key}: {error}", path=path) from None
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            detail = f"{type(error).__name__}: {error}"[:200]
            raise DataError(f"params.{key} cannot be rebuilt ({detail})", path=path) from None
    return decoded


def _decode_param(value: Any, folder: Path | None, where: str) -> Any:
    import importlib

    import numpy as np

    kind = value.get("type") if isinstance(value, Mapping) else None
    if kind in _PERTURBATIONS:
        module, attribute = _PERTURBATIONS[kind]
        cls = getattr(importlib.import_module(module), kind)
        saved = _saved_array(value, folder, where) if "file" in value else None
        raw = saved if saved is not None else value[attribute]
        array = np.asarray(raw, dtype=np.float32 if attribute == "points" else int)
        if attribute == "points":
            array = array.reshape(-1, 4)
        return cls(array)
    if kind in _EDITS:
        return getattr(importlib.import_module(_EDITS[kind]), kind).from_json(value)
    return value


def _saved_array(value: Mapping[str, Any], folder: Path | None, where: str) -> Any:
    """The array a perturbation's ``file`` names, read from inside the record's folder."""
    from pytest_metamorphic.core.npz import read_npy

    if folder is None:
        raise DataError(f"{where}: an array saved apart needs the record's folder")
    path = inside(folder, value["file"], field=where, path=folder / RECORD)
    array = read_npy(path, what=f"{where} ({value['file']})")
    if array.dtype.kind not in "fiu":
        raise DataError(f"{where}: holds {array.dtype}, not numbers", path=path)
    return array


def _spilled(value: Any, folder: Path, stem: str) -> dict[str, Any] | None:
    """``value``'s JSON with its array in ``<stem>.npy`` beside the record, when it is a
    known perturbation of more than :data:`INLINE_ROWS` rows; else None."""
    import numpy as np

    if type(value).__name__ not in _PERTURBATIONS:  # a reduction wraps its perturbation
        value = getattr(value, "perturbation", value)
    kind = type(value).__name__
    if kind not in _PERTURBATIONS:
        return None
    array = np.asarray(getattr(value, _PERTURBATIONS[kind][1], ()))
    if len(array) <= INLINE_ROWS:
        return None
    name = f"{stem}.npy"
    np.save(folder / name, np.ascontiguousarray(array), allow_pickle=False)
    return {"type": kind, "file": name, "rows": len(array)}


def _params_json(params: Any, folder: Path, stem: str) -> Any:
    """``params`` for the record, long perturbation arrays saved apart (:func:`_spilled`)."""
    if not isinstance(params, Mapping):
        return to_jsonable(params)
    return {
        str(key): _spilled(value, folder, f"{stem}.{_slug(str(key), 40)}") or to_jsonable(value)
        for key, value in params.items()
    }


# -- writing ------------------------------------------------------------------------------------


def _slug(text: str, limit: int = 60) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_.") or "x"
    if len(cleaned) <= limit:
        return cleaned
    digest = f"{zlib.crc32(text.encode('utf-8')):08x}"
    return f"{cleaned[: limit - 9]}-{digest}"


def _boxes_or_none(value: Any) -> list[Any] | None:
    if isinstance(value, (list, tuple)) and all(is_box(box) for box in value):
        return list(value)
    return None


def _minimization_json(record: Any, folder: Path) -> dict[str, Any] | None:
    import numpy as np

    reduction = record.reduction
    if reduction is None:
        return None
    perturbation = _spilled(reduction.perturbation, folder, "minimization.perturbation")
    kept: dict[str, Any] = {"indices": list(reduction.indices)}
    if len(reduction.indices) > INLINE_ROWS:
        name = "minimization.indices.npy"
        np.save(folder / name, np.asarray(reduction.indices, dtype=np.int64), allow_pickle=False)
        kept = {"indices_file": name}
    return {
        "key": reduction.key,
        "original_size": reduction.original_size,
        "size": reduction.size,
        **kept,
        "proven_minimal": reduction.proven_minimal,
        "sut_calls": reduction.calls,
        "budget": reduction.budget,
        "seconds": reduction.seconds,
        "timed_out": reduction.timed_out,
        "crashes": reduction.crashes,
        "fails_without_elements": reduction.fails_without_elements,
        "summary": reduction.summary(),
        "perturbation": perturbation or to_jsonable(reduction.perturbation),
    }


def write_artifact(
    record: Any,
    folder: str | os.PathLike[str],
    *,
    status: str,
    sut_calls: int | None = None,
    extra: Mapping[str, Any] | None = None,
) -> Path:
    """Write one violation's artifact folder atomically (replacing an older one).

    Parameters
    ----------
    record : ViolationRecord
        From the engine (:class:`pytest_metamorphic.core.engine.ViolationRecord`).
    folder : path-like
        The artifact folder to create or replace; its parent is created.
    status : str
        ``"found"`` (first sight, before shrinking) or ``"final"``.
    sut_calls : int, optional
        SUT calls the test had made when the violation was raised.
    extra : mapping, optional
        More JSON-ready entries for the record (a campaign case's ``"campaign"``).

    Returns
    -------
    Path
        ``folder``.
    """
    target = Path(folder)
    return write_folder_atomically(
        target,
        lambda staging: _fill(
            record, staging, status=status, sut_calls=sut_calls, final_path=target, extra=extra
        ),
    )


def write_folder_atomically(folder: str | os.PathLike[str], fill: Callable[[Path], Any]) -> Path:
    """Create or replace ``folder`` with what ``fill(staging)`` writes into a hidden
    sibling, renamed into place: the folder is either complete or absent."""
    target = Path(folder)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = staging_sibling(target)
    staging.mkdir()
    try:
        fill(staging)
        _swap_in(staging, target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return target


def _swap_in(staging: Path, target: Path) -> None:
    """Move ``staging`` to ``target``; an existing ``target`` is replaced."""
    if target.exists():
        old = staging_sibling(target, "old")
        os.replace(target, old)
        os.replace(staging, target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(staging, target)


def _fill(
    record: Any,
    folder: Path,
    *,
    status: str,
    sut_calls: int | None,
    final_path: Path,
    extra: Mapping[str, Any] | None = None,
) -> None:
    followup = record.minimal_followup
    source_spec = encode_input(record.source, folder, "source")
    followup_spec = encode_input(followup.input, folder, "followup")
    minimal_points = _injected_points(followup.params)
    if minimal_points is not None and source_spec["kind"] == "frame":
        from pytest_metamorphic.lidar.io import write_pcd
        from pytest_metamorphic.lidar.model.cloud import PointCloud

        minimal_cloud = PointCloud(minimal_points, name="minimal perturbation")
        write_pcd(minimal_cloud, folder / "perturbation.pcd")
    hidden = _hidden(record)
    picture, picture_note = draw_violation(record, folder, source_spec)
    aeb = None
    if source_spec["kind"] == "aeb_scenario" and followup_spec["kind"] == "aeb_scenario":
        from pytest_metamorphic.reports.aeb_artifacts import write_aeb_files

        aeb = write_aeb_files(
            folder,
            source=record.source,
            followup=followup.input,
            source_output=record.source_output,
            followup_output=record.minimal_output,
            relevant_time=record.minimal_verdict.details.get("relevant_time"),
            title=_picture_title(record),
        )
        picture = aeb["picture"]
        picture_note = "; ".join(aeb["notes"])
    reduction = record.reduction
    document = {
        "format": FORMAT,
        "version": VERSION,
        "status": status,
        "nodeid": record.nodeid,
        "relation": record.relation,
        "check": record.minimal_verdict.relation,
        "followup_index": record.index,
        "followups": record.total,
        "explanation": record.minimal_verdict.explanation,
        "explanation_unreduced": record.verdict.explanation,
        "details": to_jsonable(record.minimal_verdict.details),
        "seed": to_jsonable(record.seed),
        "params": _params_json(followup.params, folder, "params"),
        "params_unreduced": _params_json(record.followup.params, folder, "params_unreduced"),
        "minimization": _minimization_json(record, folder),
        "minimization_note": record.reduction_note,
        "sut_calls": {
            "test": sut_calls,
            "minimization": reduction.calls if reduction else 0,
        },
        "source": source_spec,
        "followup": followup_spec,
        "outputs": {
            "source": to_jsonable(record.source_output),
            "followup": to_jsonable(record.minimal_output),
            "followup_unreduced": to_jsonable(record.followup_output),
        },
        "hidden": to_jsonable(hidden),
        "picture": picture,
        "picture_note": picture_note,
        "aeb": aeb,
        "replay": f"pytest --mt-replay {final_path}",
        **to_jsonable(dict(extra or {})),
    }
    files = sorted(p.name for p in folder.iterdir())
    document["files"] = [*files, RECORD]
    with (folder / RECORD).open("w", encoding="utf-8") as handle:
        json.dump(document, handle, indent=1, allow_nan=False)


class ArtifactWriter:
    """The recorder's ``on_violation``: saves violations of one test under ``root``.

    The first violation of each relation is saved as soon as it is seen (status
    ``"found"``); the final one (Hypothesis' last replay, reduced) replaces it. Writing
    never raises: a failure is reported in the violation message instead.
    """

    def __init__(self, root: str | os.PathLike[str], nodeid: str, recorder: Any = None) -> None:
        self.root = Path(root)
        self.nodeid = nodeid
        self.recorder = recorder
        self._found: set[str] = set()
        self._finals: dict[str, int] = {}
        self.written: list[Path] = []

    def folder(self, relation: str, final_number: int = 1) -> Path:
        suffix = "" if final_number <= 1 else f"-{final_number}"
        test = _slug(self.nodeid.replace("::", "__").replace("/", "_") or "test", 80)
        return self.root / test / f"{_slug(relation)}{suffix}"

    def __call__(self, record: Any, final: bool) -> str | None:
        if final:
            number = self._finals.get(record.relation, 0) + 1
            self._finals[record.relation] = number
            folder = self.folder(record.relation, number)
        elif record.relation in self._found:
            return None
        else:
            folder = self.folder(record.relation)
        self._found.add(record.relation)
        calls = getattr(self.recorder, "sut_calls", None)
        try:
            write_artifact(record, folder, status="final" if final else "found", sut_calls=calls)
        except Exception as error:
            return f"not saved to {folder} ({type(error).__name__}: {error})"
        self.written.append(folder)
        return f"{folder}  (replay: pytest --mt-replay {folder})"


# -- reading ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Artifact:
    """A saved violation, read back.

    Attributes
    ----------
    folder : Path
    record : dict
        The parsed ``record.json``.
    """

    folder: Path
    record: Mapping[str, Any]

    @property
    def nodeid(self) -> str:
        return str(self.record["nodeid"])

    @property
    def relation(self) -> str:
        return str(self.record["relation"])

    def source(self) -> Any:
        """The source input, rebuilt from the saved files."""
        return decode_input(self.record["source"], self.folder, "source")

    def followup(self) -> Any:
        """The (minimal) follow-up as a :class:`~pytest_metamorphic.core.engine.Followup`."""
        from pytest_metamorphic.core.engine import Followup

        value = decode_input(self.record["followup"], self.folder, "followup")
        params = _decode_params(self.record.get("params") or {}, self.folder / RECORD)
        return Followup(value, params)


def load_artifact(path: str | os.PathLike[str]) -> Artifact:
    """Read an artifact folder (or its ``record.json``).

    Raises
    ------
    DataError
        The folder has no readable record, or the record is not an artifact.
    """
    folder = Path(path)
    if folder.name == RECORD and folder.is_file():
        folder = folder.parent
    record_path = folder / RECORD
    if not record_path.exists():
        raise DataError(f"not an artifact folder: no {RECORD} in it", path=folder)
    record = read_json(record_path, what="artifact record")
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise DataError("not a pytest-metamorphic artifact record", path=record_path)
    if record.get("version") != VERSION:
        raise DataError(
            f"artifact version {record.get('version')!r}; this pytest-metamorphic reads "
            f"version {VERSION}",
            path=record_path,
        )
    for key in ("nodeid", "relation"):
        field(record, key, str, where="the record", path=record_path)
    for key in ("source", "followup"):
        field(record, key, dict, where="the record", path=record_path)
    field(record, "params", (dict, type(None)), where="the record", path=record_path, default=None)
    return Artifact(folder, record)


def load_case(path: str | os.PathLike[str]) -> Any:
    """A :class:`~pytest_metamorphic.core.engine.MetamorphicCase` for ``@example(case=...)``.

    The case holds the saved source and the saved (minimal) follow-up for the saved
    relation only; the engine runs no other relation on it. Use it to keep a found
    violation as a regression example::

        @example(case=load_case(Path(__file__).parent / "mt-regressions" / "MR1"))
        @metamorphic(...)
        def test_perception(frame): ...
    """
    from pytest_metamorphic.core.engine import MetamorphicCase

    artifact = load_artifact(path)
    return MetamorphicCase(artifact.source(), {artifact.relation: (artifact.followup(),)})


def check_folder(path: str | os.PathLike[str]) -> Path:
    """``path`` as an artifact folder, or InvalidArgument naming it."""
    folder = Path(path)
    if folder.name == RECORD:
        folder = folder.parent
    if not (folder / RECORD).is_file():
        raise InvalidArgument(f"{path} is not an artifact folder (no {RECORD})")
    return folder
