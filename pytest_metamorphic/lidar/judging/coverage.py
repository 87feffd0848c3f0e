"""Which part of the operating domain a follow-up reached: the coverage of a run.

A green run says nothing about the parts of the car's world its follow-ups never reached.
:func:`domain_cells` names, for one checked follow-up, the cells it reached, each a string
``"<dimension>: <band>"``:

* ``judged distance``, ``judged bearing``, ``judged class``, ``judged returns``: the
  obstacles of the source output the relation judges (its scope), when the check judged
  any: their bird's-eye distance from the sensor (the near field of
  :class:`~pytest_metamorphic.lidar.model.domain.OperatingDomain`, then 20, 40 and 70 m),
  their bearing (front, left, rear, right: quarters centred on the axes), their class and
  how many returns support them (dense objects: 1000 or more);
* ``placed distance``, ``placed bearing``, ``placed class``: where an inserted or moved
  object went;
* ``pose pitch``, ``pose roll``, ``pose height``: the sensor's pose a follow-up drew, in
  bands of 1 degree and 5 cm.

The engine counts them per relation (:class:`~pytest_metamorphic.core.stats.RelationStats`
``coverage``); the summary lists each dimension's bands with their counts and names the
bands no follow-up reached (:func:`unreached`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pytest_metamorphic.core.relations import CheckContext, Verdict, judged_count
from pytest_metamorphic.lidar.judging.scope import DEFAULT_SCOPE, ObstacleScope
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN
from pytest_metamorphic.lidar.model.obstacles import Box, as_boxes, box_support

__all__ = ["BANDS", "domain_cells", "unreached"]

_NEAR = DEFAULT_DOMAIN.near_field_m
_DISTANCES = (
    (0.0, _NEAR, f"0-{_NEAR:g} m (near field)"),
    (_NEAR, 20.0, f"{_NEAR:g}-20 m"),
    (20.0, 40.0, "20-40 m"),
    (40.0, 70.0, "40-70 m"),
    (70.0, math.inf, "70 m and beyond"),
)
_BEARINGS = ("front", "left", "rear", "right")
_CLASSES = ("car", "pedestrian", "cyclist", "unknown")
_RETURNS = ((0, 30, "< 30"), (30, 100, "30-99"), (100, 1000, "100-999"),
            (1000, math.inf, "1000 or more (dense)"))  # fmt: skip

#: Every band of the dimensions whose gaps :func:`unreached` names.
BANDS: dict[str, tuple[str, ...]] = {
    "judged distance": tuple(band for _, _, band in _DISTANCES),
    "judged bearing": _BEARINGS,
    "judged class": _CLASSES[:3],
    "judged returns": tuple(band for _, _, band in _RETURNS),
    "placed distance": tuple(band for _, _, band in _DISTANCES),
    "placed bearing": _BEARINGS,
}


def _distance(box: Box) -> str:
    reach = math.hypot(box.center[0], box.center[1])
    return next(band for low, high, band in _DISTANCES if low <= reach < high)


def _bearing(box: Box) -> str:
    degrees = math.degrees(math.atan2(box.center[1], box.center[0])) % 360.0
    return _BEARINGS[int(((degrees + 45.0) % 360.0) // 90.0)]


def _returns(count: int) -> str:
    return next(band for low, high, band in _RETURNS if low <= count < high)


def _object_cells(prefix: str, boxes: Sequence[Box], support: Sequence[int] | None) -> list[str]:
    cells = []
    for index, box in enumerate(boxes):
        cells += [f"{prefix} distance: {_distance(box)}", f"{prefix} bearing: {_bearing(box)}",
                  f"{prefix} class: {box.label}"]  # fmt: skip
        if support is not None:
            cells.append(f"{prefix} returns: {_returns(int(support[index]))}")
    return cells


def _pose_cells(params: Mapping[str, Any]) -> list[str]:
    cells = []
    for key, name, unit, step in (("pitch_deg", "pitch", "°", 1.0), ("roll_deg", "roll", "°", 1.0),
                                  ("height_m", "height", " m", 0.05)):  # fmt: skip
        value = params.get(key)
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not value:
            continue
        band = math.floor(abs(value) / step) * step
        sign = "+" if value > 0 else "-"
        cells.append(f"pose {name}: {sign}{band:g} to {sign}{band + step:g}{unit}")
    return cells


def _placed(params: Mapping[str, Any]) -> list[Box]:
    """The inserted or moved object's box where it went, when the follow-up has one."""
    placed = []
    for key in ("insert_object", "relocate_object"):
        edit = params.get(key)
        box = getattr(edit, "box", None)
        if isinstance(box, Box):
            placed.append(box)
    return placed


def domain_cells(
    context: CheckContext,
    source_output: Any,
    followup_output: Any,
    verdict: Verdict,
    *,
    scope: ObstacleScope = DEFAULT_SCOPE,
) -> list[str]:
    """The cells of the operating domain one checked follow-up reached (module docstring):
    the judged obstacles of the source output when the check judged any, the placed
    object, the pose drawn. Outputs that are not boxes reach no object cell."""
    cells = _pose_cells(context.params)
    cells += _object_cells("placed", _placed(context.params), None)
    if judged_count(verdict) == 0:
        return cells
    try:
        boxes = as_boxes(source_output, "source")
    except Exception:  # not a detector's boxes (a component's labels): no object cells
        return cells
    source = context.source_input
    if not boxes or getattr(source, "cloud", None) is None:
        return cells
    judged = np.asarray(scope.judged(boxes, source), dtype=bool)
    chosen = [box for box, keep in zip(boxes, judged, strict=True) if keep]
    support = box_support(chosen, source.cloud.xyz) if chosen else None
    return cells + _object_cells("judged", chosen, None if support is None else support.tolist())


def unreached(coverage: Mapping[str, int]) -> list[str]:
    """``"<dimension>: <bands>"`` for each dimension of :data:`BANDS` that ``coverage``
    reached somewhere but not in every band (a dimension it never reached is not named:
    the relation does not vary it)."""
    lines = []
    for dimension, bands in BANDS.items():
        seen = {cell.split(": ", 1)[1] for cell in coverage if cell.startswith(dimension + ": ")}
        if seen:
            missing = [band for band in bands if band not in seen]
            if missing:
                lines.append(f"{dimension}: none {', none '.join(missing)}")
    return lines
