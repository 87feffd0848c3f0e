"""Point edits and a rotation: follow-ups that drop, repeat, reorder or turn points.

* :class:`DropPoints`, :class:`DuplicatePoints`, :class:`PermutePoints`.
* :class:`RotateAboutSensor` - the cloud, the ROI and the boxes turned together about z.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame

__all__ = ["DropPoints", "DuplicatePoints", "PermutePoints", "RotateAboutSensor"]

SHOWN_ITEMS = 8
"""Points or indices a perturbation's ``repr`` shows before "... n more"."""


def _indices(values: Any, name: str) -> NDArray[np.intp]:
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"{name} cannot be converted to an array: {error}") from None
    if array.size == 0:
        return np.empty(0, dtype=np.intp)
    if array.ndim != 1 or not np.issubdtype(array.dtype, np.integer) or array.min() < 0:
        raise InvalidArgument(f"{name} must be a 1-D list of non-negative ints")
    return array.astype(np.intp)


def _check_in_cloud(indices: NDArray[np.intp], frame: Frame, name: str) -> None:
    if not isinstance(frame, Frame):
        raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
    if len(indices) and indices.max() >= len(frame.cloud):
        raise InvalidArgument(
            f"{name} holds index {int(indices.max())} but the frame has {len(frame.cloud)} points"
        )


@dataclass(frozen=True, eq=False)
class DropPoints:
    """Remove the points at ``indices`` (repeats are fine)."""

    indices: NDArray[np.intp]

    def __post_init__(self) -> None:
        object.__setattr__(self, "indices", _indices(self.indices, "indices"))

    def apply(self, frame: Frame) -> Frame:
        _check_in_cloud(self.indices, frame, "DropPoints.indices")
        keep = np.ones(len(frame.cloud), dtype=bool)
        keep[self.indices] = False
        return frame.with_cloud(frame.cloud[keep])

    def params(self) -> dict[str, Any]:
        # The object itself, so the engine can reduce a violating drop to the few that matter.
        return {"dropped": len(np.unique(self.indices)), "drop_points": self}

    def __repr__(self) -> str:
        return f"DropPoints({_short_list(self.indices)})"


@dataclass(frozen=True, eq=False)
class DuplicatePoints:
    """Append copies of the points at ``indices`` to the end of the cloud."""

    indices: NDArray[np.intp]

    def __post_init__(self) -> None:
        object.__setattr__(self, "indices", _indices(self.indices, "indices"))

    def apply(self, frame: Frame) -> Frame:
        _check_in_cloud(self.indices, frame, "DuplicatePoints.indices")
        copies = frame.cloud[self.indices]
        return frame.with_cloud(PointCloud.concatenate([frame.cloud, copies]))

    def params(self) -> dict[str, Any]:
        return {"duplicated": len(self.indices), "duplicate_points": self}

    def __repr__(self) -> str:
        return f"DuplicatePoints({_short_list(self.indices)})"


@dataclass(frozen=True)
class PermutePoints:
    """Reorder all points by a permutation drawn from ``numpy.random.default_rng(seed)``."""

    seed: int

    def __post_init__(self) -> None:
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, (int, np.integer))
            or self.seed < 0
        ):
            raise InvalidArgument(f"seed={self.seed!r} must be a non-negative int")

    def order(self, n: int) -> NDArray[np.intp]:
        """The permutation applied to a cloud of ``n`` points."""
        return np.random.default_rng(int(self.seed)).permutation(n)

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        return frame.with_cloud(frame.cloud[self.order(len(frame.cloud))])

    def params(self) -> dict[str, Any]:
        return {"permutation_seed": int(self.seed)}


@dataclass(frozen=True)
class RotateAboutSensor:
    """Turn the cloud, the ROI and the boxes by ``theta`` radians about the sensor's z axis."""

    theta: float

    def __post_init__(self) -> None:
        if isinstance(self.theta, bool) or not isinstance(self.theta, (int, float)):
            raise InvalidArgument(f"theta={self.theta!r} must be a number of radians")
        if not math.isfinite(self.theta):
            raise InvalidArgument(f"theta={self.theta!r} must be finite")
        object.__setattr__(self, "theta", float(self.theta))

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        c, s = math.cos(self.theta), math.sin(self.theta)
        xyz = frame.cloud.points[:, :3].astype(np.float64)
        points = frame.cloud.points.copy()
        points[:, 0] = c * xyz[:, 0] - s * xyz[:, 1]
        points[:, 1] = s * xyz[:, 0] + c * xyz[:, 1]
        roi = frame.roi
        if roi is not None:
            rotate = getattr(roi, "rotated", None)
            if not callable(rotate):
                raise InvalidArgument(f"the frame's roi ({type(roi).__name__}) has no rotated()")
            roi = rotate(self.theta)
        return dataclasses.replace(
            frame,
            cloud=frame.cloud.with_points(points),
            roi=roi,
            boxes=tuple(box.rotated(self.theta) for box in frame.boxes),
        )

    def params(self) -> dict[str, Any]:
        return {"theta_deg": round(math.degrees(self.theta), 6)}


def _short_list(values: NDArray[np.intp]) -> str:
    shown = ", ".join(str(v) for v in values[:SHOWN_ITEMS])
    more = f", ... {len(values) - SHOWN_ITEMS} more" if len(values) > SHOWN_ITEMS else ""
    return f"[{shown}{more}]"
