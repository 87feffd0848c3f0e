"""What is inserted: an object's returns from a real or rendered sweep, meshed as the
sensor saw them, and where it stands."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import Delaunay, QhullError

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.edit import (
    RemoveObject,
    removal_candidates,
)
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.obstacles import Box, Label
from pytest_metamorphic.lidar.model.sensors import BeamLayout, frame_sensor
from pytest_metamorphic.lidar.synthetic.meshes import SceneMesh

__all__ = ["ObjectTemplate", "Placement", "object_templates"]

# Normalising spacings for the mesh when the sensor is not known (HDL-64E: firings 0.17
# degrees apart, lasers 0.3-0.6); otherwise the frame's sensor's (_spacings).
_AZIMUTH_SPACING = math.radians(0.17)
_ELEVATION_SPACING = math.radians(0.45)
_MAX_GAP = 3.0  # triangles wider than this many spacings span a hole
_MAX_DEPTH_STEP = 1.0  # metres: a longer triangle edge joins two surfaces
_MIN_RETURNS = 10


@dataclass(frozen=True, eq=False)
class ObjectTemplate:
    """An object's surface as a LiDAR saw it, ready to be placed into other sweeps.

    Attributes
    ----------
    label : str
    size : (3,) float
        Length, width, height of its box in metres.
    vertices : (k, 3) float64
        Its returns in object coordinates: x along the heading, y to the left, z up from
        the local ground under it.
    faces : (m, 3) int64
        Triangles joining neighbouring returns.
    intensity : (k,) float32
        Each return's intensity.
    view : float
        Heading minus bearing (radians): which face the sensor saw.
    range, bearing : float
        Metres and radians from the sensor to the box centre when it was seen.
    source : str
        Where it was taken from, for messages.
    spacing : (2,) float
        Radians between neighbouring returns of the sensor that saw it (azimuth,
        elevation): each return stands for a patch of surface that size (see
        :meth:`mesh_at`).
    solid : bool
        Whether ``vertices`` and ``faces`` are a whole closed surface (a rendered road
        user's mesh, :meth:`from_mesh`) rather than the faces a sensor saw: it may be
        placed at any range and turned to any heading, the near field included, where a
        sensor looks down onto roofs and shoulders no recording's template holds.
    """

    label: Label
    size: tuple[float, float, float]
    vertices: NDArray[np.float64] = field(repr=False)
    faces: NDArray[np.int64] = field(repr=False)
    intensity: NDArray[np.float32] = field(repr=False)
    view: float
    range: float
    bearing: float
    source: str = ""
    spacing: tuple[float, float] = (_AZIMUTH_SPACING, _ELEVATION_SPACING)
    solid: bool = False

    @classmethod
    def from_mesh(
        cls,
        vertices: NDArray[np.float64],
        faces: NDArray[np.int64],
        *,
        label: Label,
        reflectivity: float,
        source: str,
        seen_range: float = 10.0,
    ) -> ObjectTemplate:
        """A whole closed surface as a template (``solid``): ``vertices`` (k, 3) in object
        coordinates (x along the heading, y to the left, z up from the ground), ``faces``
        (m, 3). Every return cast onto it gets intensity ``reflectivity``; ``seen_range``
        is where :func:`free_placements` starts from (as the range a template was seen
        from)."""
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or f.ndim != 2 or f.shape[1] != 3:
            raise InvalidArgument(
                f"a solid template needs (k, 3) vertices and (m, 3) faces, got {v.shape}, {f.shape}"
            )
        low, high = v.min(axis=0), v.max(axis=0)
        size = (float(high[0] - low[0]), float(high[1] - low[1]), float(high[2]))
        return cls(
            label=label, size=size, vertices=v, faces=f,
            intensity=np.full(len(v), reflectivity, dtype=np.float32),
            view=0.0, range=float(seen_range), bearing=0.0, source=source, solid=True,
        )  # fmt: skip

    @classmethod
    def from_frame(cls, frame: Frame, box: Box, *, margin: float = 0.15) -> ObjectTemplate:
        """The returns of the object in ``box`` (grown by ``margin``, above the local ground)
        of ``frame``, meshed. Raises :class:`InvalidArgument` when fewer than 10 returns
        lie on it or they do not form a surface."""
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        removal = RemoveObject(box, margin)
        ground_z, _ = removal.ground_height(frame)
        points = frame.cloud.points[removal.removed(frame, ground_z)].astype(np.float64)
        where = f"{box.describe()} in {frame!r}"
        if len(points) < _MIN_RETURNS:
            raise InvalidArgument(
                f"{where} has {len(points)} returns; a template needs >= {_MIN_RETURNS}"
            )
        bearing = math.atan2(box.center[1], box.center[0])
        spacing = _spacings(frame)
        faces = _surface(points[:, :3], bearing, spacing)
        if len(faces) == 0:
            raise InvalidArgument(f"the returns of {where} do not form a surface")
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        offset = points[:, :3] - np.array([box.center[0], box.center[1], ground_z])
        local = np.column_stack(
            [
                c * offset[:, 0] + s * offset[:, 1],
                -s * offset[:, 0] + c * offset[:, 1],
                offset[:, 2],
            ]
        )
        return cls(
            label=box.label,
            size=box.size,
            vertices=local,
            faces=faces,
            intensity=points[:, 3].astype(np.float32),
            view=math.remainder(box.yaw - bearing, 2 * math.pi),
            range=math.hypot(box.center[0], box.center[1]),
            bearing=bearing,
            source=f"{frame.source or '<memory>'}#{frame.index}",
            spacing=spacing,
        )

    def box_at(self, placement: Placement) -> Box:
        """The template's box standing at ``placement``, turned so the same face is seen
        (then by the placement's ``turn``)."""
        x, y = (
            placement.range * math.cos(placement.bearing),
            placement.range * math.sin(placement.bearing),
        )
        yaw = math.remainder(placement.bearing + self.view + placement.turn, 2 * math.pi)
        centre = (x, y, placement.ground_z + self.size[2] / 2)
        return Box(centre, self.size, yaw, self.label)

    def mesh_at(self, placement: Placement) -> SceneMesh:
        """The template's triangles at ``placement`` (sensor frame), and a patch per return.

        The triangles join neighbouring returns; a return also stands for the patch of
        surface its beam lit, one beam spacing wide and high where it was seen, upright and
        square to that beam (a "splat"). Without the patches, returns on thin or sparse
        parts (a car's far roof edge, a bicycle's frame) join no triangle or lie on a
        triangle's edge, and casting the same beams again loses them: a car 13.5 m away
        re-cast where it stood came out 1 m shorter (its far end lost).
        """
        box = self.box_at(placement)
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        v, faces = self._splatted()
        world = np.column_stack(
            [
                box.center[0] + c * v[:, 0] - s * v[:, 1],
                box.center[1] + s * v[:, 0] + c * v[:, 1],
                placement.ground_z + v[:, 2],
            ]
        )
        m = len(faces)
        return SceneMesh(world, faces, np.zeros(m, np.int32), np.zeros(m), ((0, m),))

    def _splatted(self) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Vertices and faces with a square patch (two triangles) added per return
        (none for a solid template: its faces are the whole surface)."""
        v = self.vertices
        if self.solid:
            return v, self.faces
        # Where the sensor stood, in object coordinates: the beam to each return.
        c, s = math.cos(self.view), math.sin(self.view)
        sensor = np.array([-self.range * c, self.range * s])
        ray = v[:, :2] - sensor
        distance = np.maximum(np.hypot(ray[:, 0], ray[:, 1]), 1e-6)
        across = np.column_stack([-ray[:, 1], ray[:, 0]]) / distance[:, None]
        half_width = 0.5 * self.spacing[0] * distance
        half_height = 0.5 * self.spacing[1] * distance
        corners = []
        for sign_a, sign_h in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            corner = v.copy()
            corner[:, :2] += sign_a * half_width[:, None] * across
            corner[:, 2] += sign_h * half_height
            corners.append(corner)
        k = len(v)
        first = k + 4 * np.arange(k, dtype=np.int64)
        quads = np.concatenate(
            [
                np.column_stack([first, first + 1, first + 2]),
                np.column_stack([first, first + 2, first + 3]),
            ]
        )
        patches = np.stack(corners, axis=1).reshape(-1, 3)
        return np.concatenate([v, patches]), np.concatenate([self.faces, quads])

    def scaled(self, factor: float) -> ObjectTemplate:
        """The same object ``factor`` times as large in every dimension (semLidarFuzz's
        scale), about its centre on the ground; its returns, and the patches they stand
        for, scale with it."""
        if isinstance(factor, bool) or not isinstance(factor, (int, float)):
            raise InvalidArgument(f"factor={factor!r} must be a positive number")
        if not (math.isfinite(factor) and factor > 0):
            raise InvalidArgument(f"factor={factor!r} must be a positive number")
        if factor == 1:
            return self
        # Patches keep the angular size they had where the object was seen when the
        # object keeps its range: scale the spacing with it.
        spacing = (self.spacing[0] * factor, self.spacing[1] * factor)
        return dataclasses.replace(
            self,
            size=(self.size[0] * factor, self.size[1] * factor, self.size[2] * factor),
            vertices=self.vertices * factor,
            spacing=spacing,
            source=f"{self.source} x{factor:g}",
        )

    @property
    def origin(self) -> str:
        """Where it was cut from, for messages: the file's name, not the folder it lies in on
        the machine that made it (``000001.bin #3``, ``drive.bag [/points #0]``)."""
        path, bracket, rest = str(self.source).partition(" [")
        return Path(path).name + bracket + rest

    def describe(self) -> str:
        if self.solid:
            return f"{self.label}, a whole mesh ({self.origin})"
        return (
            f"{self.label} seen at {self.range:.1f} m ({len(self.vertices)} returns, {self.origin})"
        )


def _spacings(frame: Frame) -> tuple[float, float]:
    """(azimuth, elevation) radians between neighbouring returns of the frame's sensor
    (a VLP-16's lasers are 2 degrees apart, an HDL-64E's 0.3-0.6); the HDL-64E's when the
    sensor is not known."""
    sensor = frame_sensor(frame).sensor
    if not isinstance(sensor, BeamLayout) or sensor.lasers < 2:
        return _AZIMUTH_SPACING, _ELEVATION_SPACING
    gaps = np.diff(np.sort(sensor.elevations))
    return max(sensor.azimuth_step, _AZIMUTH_SPACING), float(np.median(gaps[gaps > 1e-6]))


def _surface(
    xyz: NDArray[np.float64],
    bearing: float,
    spacings: tuple[float, float] = (_AZIMUTH_SPACING, _ELEVATION_SPACING),
) -> NDArray[np.int64]:
    """Triangles joining returns that neighbour each other in the sensor's view (azimuth
    taken relative to ``bearing``, so an object behind the sensor does not straddle ±π;
    angles in units of the sensor's ``spacings``)."""
    azimuth = _relative_bearing(xyz, bearing)
    planar = np.hypot(xyz[:, 0], xyz[:, 1])
    view = np.column_stack([azimuth / spacings[0], np.arctan2(xyz[:, 2], planar) / spacings[1]])
    try:
        faces = Delaunay(view).simplices.astype(np.int64)
    except (QhullError, ValueError):
        return np.empty((0, 3), dtype=np.int64)
    edges = [(0, 1), (1, 2), (2, 0)]
    wide = np.zeros(len(faces), dtype=bool)
    for a, b in edges:
        wide |= np.linalg.norm(view[faces[:, a]] - view[faces[:, b]], axis=1) > _MAX_GAP
        wide |= np.linalg.norm(xyz[faces[:, a]] - xyz[faces[:, b]], axis=1) > _MAX_DEPTH_STEP
    return faces[~wide]


@dataclass(frozen=True)
class Placement:
    """Where a template goes: ``range`` metres from the sensor at ``bearing`` radians, its
    underside at ``ground_z``, turned ``turn`` radians about its own centre from the
    heading that shows the sensor the face it saw (0: the same face)."""

    bearing: float
    range: float
    ground_z: float
    turn: float = 0.0


def object_templates(
    frames: Frame | Iterable[Frame], *, min_returns: int = 30, scope: ScopeLike = "all"
) -> list[ObjectTemplate]:
    """Objects to insert, taken from ``frames``: every labelled car, pedestrian and cyclist
    (ground truth: a frame's boxes, KITTI labels or a rendered scene's) with at least
    ``min_returns`` returns, nearest first within each frame. ``scope`` picks which of
    them are taken (default: all).

    Only ground truth: an insertion claims that a real object of its class was put back,
    which a detector's guess (a fragment, a wall taken for a car) cannot back. A frame
    without labels gives no template."""
    if isinstance(min_returns, bool) or not isinstance(min_returns, int) or min_returns < 10:
        raise InvalidArgument(f"min_returns={min_returns!r} must be an int >= 10")
    chosen = [frames] if isinstance(frames, Frame) else list(frames)
    templates = []
    for index, frame in enumerate(chosen):
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frames[{index}] is {frame!r}, not a Frame")
        for box in removal_candidates(frame, scope=scope, labelled_only=True):
            try:
                template = ObjectTemplate.from_frame(frame, box)
            except InvalidArgument:  # too few returns, or no surface (a thin pole)
                continue
            if len(template.vertices) >= min_returns:
                templates.append(template)
    return templates


def _bearing_window(vertices: NDArray[np.float64], bearing: float) -> tuple[float, float]:
    """Bearings the mesh covers, relative to ``bearing`` (radians)."""
    offset = _relative_bearing(vertices, bearing)
    return float(offset.min()), float(offset.max())


def _relative_bearing(xyz: NDArray[np.float64], bearing: float) -> NDArray[np.float64]:
    """Bearing of each point minus ``bearing``, in [-π, π)."""
    return _wrapped(np.arctan2(xyz[:, 1], xyz[:, 0]) - bearing)


def _wrapped(angle: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.remainder(angle + math.pi, 2 * math.pi) - math.pi
