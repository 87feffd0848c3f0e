"""Which point of a follow-up sweep is which point of its source.

Point-by-point relations (:mod:`.points`) compare the label or cluster a component gave a
return in the source with the one it gave the same return in the follow-up. Follow-ups
reorder, repeat, add and remove returns, and turn or mirror the whole sweep; the same
return is found by its coordinates: each follow-up point is brought back into the source's
frame (undoing the turn, mirror or shift its parameters name) and matched to a source
point within ``tolerance`` (a turned coordinate is rounded to float32 again, so a turn
needs a millimetre; unmoved points match exactly). A follow-up point that matches none is
*new* (noise, an inserted object, a re-cast beam); a source point no follow-up point
matches was *removed*. Both are the follow-up's change; relations judge the points farther
than a stated radius from it.

Returns recorded twice in the source (the same coordinates) form one group: a group whose
copies the component labelled differently cannot say which label a follow-up copy should
keep, so it is not judged (:attr:`PointCorrespondence.source_group`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box

__all__ = [
    "ALIGNED_TOLERANCE",
    "PointCorrespondence",
    "align_to_source",
    "box_to_source",
    "corresponding_points",
    "row_keys",
    "same_returns",
]

ALIGNED_TOLERANCE = 1e-3
"""Metres within which a turned or mirrored follow-up point, turned back, is its source
point (float32 rounding of a coordinate 120 m out is 8 micrometres)."""


def align_to_source(
    xyz: NDArray[np.floating[Any]], params: Mapping[str, Any]
) -> tuple[NDArray[np.float64], bool]:
    """Follow-up coordinates in the source's frame, undoing the transform ``params``
    names (``theta_deg``: a turn about the sensor; ``mirrored``: y -> -y; ``shift_x_m``,
    ``shift_y_m``: a shift); and whether anything was undone."""
    out = np.asarray(xyz, dtype=np.float64).copy()
    moved = False
    if "shift_x_m" in params or "shift_y_m" in params:
        out[:, 0] -= float(params.get("shift_x_m", 0.0))
        out[:, 1] -= float(params.get("shift_y_m", 0.0))
        moved = True
    if "theta_deg" in params:
        theta = -math.radians(float(params["theta_deg"]))
        c, s = math.cos(theta), math.sin(theta)
        x, y = out[:, 0].copy(), out[:, 1].copy()
        out[:, 0], out[:, 1] = c * x - s * y, s * x + c * y
        moved = True
    if "mirrored" in params:
        out[:, 1] = -out[:, 1]
        moved = True
    return out, moved


def box_to_source(box: Box, params: Mapping[str, Any]) -> Box:
    """A follow-up box in the source's frame: :func:`align_to_source` for boxes."""
    if "shift_x_m" in params or "shift_y_m" in params:
        dx, dy = float(params.get("shift_x_m", 0.0)), float(params.get("shift_y_m", 0.0))
        box = box.translated(-dx, -dy)
    if "theta_deg" in params:
        box = box.rotated(-math.radians(float(params["theta_deg"])))
    if "mirrored" in params:
        box = box.mirrored()
    return box


@dataclass(frozen=True)
class PointCorrespondence:
    """How a follow-up's points relate to its source's.

    Attributes
    ----------
    origin : (m,) intp
        For each follow-up point, the source point it is (-1: a new point).
    kept : (n,) bool
        Source points that some follow-up point is.
    changed : (k, 3) float64
        Where the follow-up changed the sweep, in the source's frame: its new points and
        the source points it removed.
    source_group : (n,) intp
        Source points with equal coordinates share a group id.
    """

    origin: NDArray[np.intp]
    kept: NDArray[np.bool_]
    changed: NDArray[np.float64]
    source_group: NDArray[np.intp]

    def far_from_change(self, xyz: NDArray[np.floating[Any]], radius: float) -> NDArray[np.bool_]:
        """(n,) bool: which of ``xyz`` lie farther than ``radius`` metres from every change
        (all of them when ``radius`` is 0 or nothing changed)."""
        if radius <= 0 or len(self.changed) == 0:
            return np.ones(len(xyz), dtype=bool)
        distance, _ = cKDTree(self.changed).query(
            np.asarray(xyz, dtype=np.float64), distance_upper_bound=radius
        )
        return ~np.isfinite(distance)


def row_keys(xyz: NDArray[np.float32]) -> NDArray[np.uint64]:
    """One 64-bit key per row of float32 coordinates (equal rows, equal keys; -0.0 and
    0.0 are one coordinate). Different rows share a key with odds of about 2**-64 per
    pair; :func:`corresponding_points` checks every match."""
    bits = (np.ascontiguousarray(xyz, dtype=np.float32) + np.float32(0.0)).view(np.uint32)
    bits = bits.astype(np.uint64)
    with np.errstate(over="ignore"):
        return (
            bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
            ^ bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
            ^ bits[:, 2] * np.uint64(0x165667B19E3779F9)
        )


def same_returns(
    source: NDArray[np.float32],
    followup: NDArray[np.float32],
    keys: NDArray[np.uint64] | None = None,
) -> NDArray[np.intp]:
    """(m,) intp: for each row of ``followup`` (m, 3), a row of ``source`` (n, 3) with the
    same float32 coordinates (-1: none). ``keys``: ``row_keys(source)``, when known."""
    keys = row_keys(source) if keys is None else keys
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    wanted = row_keys(followup)
    at = np.minimum(np.searchsorted(sorted_keys, wanted), max(len(keys) - 1, 0))
    origin = np.where(sorted_keys[at] == wanted, order[at], -1).astype(np.intp)
    found = origin >= 0
    same = np.all(source[origin[found]] == followup[found], axis=1)
    origin[np.flatnonzero(found)[~same]] = -1  # a key collision, not the same return
    return origin


def corresponding_points(
    source: Frame, followup: Frame, params: Mapping[str, Any]
) -> PointCorrespondence:
    """Match the follow-up's points to the source's (see the module docstring)."""
    for value, name in ((source, "source input"), (followup, "follow-up input")):
        if not isinstance(value, Frame):
            raise InvalidArgument(
                f"a point-by-point relation needs Frames; the {name} is {type(value).__name__}"
            )
    source_xyz = source.cloud.xyz.astype(np.float64)
    followup_xyz, moved = align_to_source(followup.cloud.xyz, params)
    keys = row_keys(source.cloud.xyz)
    origin = np.full(len(followup_xyz), -1, dtype=np.intp)
    if len(source_xyz) and len(followup_xyz):
        if moved:
            distance, nearest = cKDTree(source_xyz).query(
                followup_xyz, distance_upper_bound=ALIGNED_TOLERANCE
            )
            found = np.isfinite(distance)
            origin[found] = nearest[found]
        else:
            origin = same_returns(source.cloud.xyz, followup.cloud.xyz, keys)
    # Equal source points form a group; a match to one of them keeps the whole group.
    _, group = np.unique(keys, return_inverse=True)
    group = np.asarray(group, dtype=np.intp).reshape(-1)
    kept_groups = np.zeros(int(group.max()) + 1 if len(group) else 0, dtype=bool)
    kept_groups[group[origin[origin >= 0]]] = True
    kept = kept_groups[group] if len(group) else np.zeros(0, dtype=bool)
    changed = np.concatenate([followup_xyz[origin < 0], source_xyz[~kept]])
    return PointCorrespondence(origin, kept, changed, group)
