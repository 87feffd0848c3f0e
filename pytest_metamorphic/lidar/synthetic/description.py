"""What a synthetic scene is: sensor height, ROI, obstacles with mesh shapes, background objects."""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import trimesh
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import Box, Label
from pytest_metamorphic.lidar.model.terrain import Terrain
from pytest_metamorphic.lidar.roi import ROI

__all__ = [
    "BACKGROUND_INSTANCE",
    "BACKGROUND_KINDS",
    "BUILTIN_SHAPES",
    "GROUND_INSTANCE",
    "BackgroundObject",
    "MeshShape",
    "Obstacle",
    "Scene",
]

BackgroundKind = Literal["building", "pole", "tree"]
BACKGROUND_KINDS: tuple[BackgroundKind, ...] = ("building", "pole", "tree")
BUILTIN_SHAPES = ("car", "pedestrian", "cyclist", "box")

GROUND_INSTANCE = -1
"""``instance`` field value of points on the ground."""
BACKGROUND_INSTANCE = -2
"""``instance`` field value of points on background objects (buildings, poles, trees)."""

# Diffuse reflectivity (0-1) per surface; intensity = reflectivity x |cos(incidence)|.
# Asphalt is dark, paint and retro-reflective parts bright (KITTI intensities are 0-1).
_REFLECTIVITY: Mapping[str, float] = {
    "car": 0.6,
    "pedestrian": 0.35,
    "cyclist": 0.45,
    "box": 0.5,
    "building": 0.3,
    "pole": 0.55,
    "tree": 0.2,
    "ground": 0.12,
}
_SHAPE_OF_LABEL: Mapping[str, str] = {
    "car": "car",
    "pedestrian": "pedestrian",
    "cyclist": "cyclist",
    "unknown": "box",
}


@dataclass(frozen=True)
class MeshShape:
    """A user-supplied mesh used as an obstacle shape; it is stretched to fill the box.

    Build with :meth:`from_file` (any format trimesh reads: OBJ, STL, PLY, GLB, ...) or
    :meth:`from_arrays`. The mesh's own axis-aligned bounds are mapped onto the obstacle
    box: +x of the mesh becomes the box heading, +z up, the lowest point the box bottom.

    Attributes
    ----------
    name : str
    vertices : (k, 3) float64
    faces : (m, 3) int64
    digest : str
      SHA-256 of the geometry; equality and hashing use it (not the arrays).
    """

    name: str
    vertices: NDArray[np.float64] = field(repr=False, compare=False)
    faces: NDArray[np.int64] = field(repr=False, compare=False)
    digest: str = field(default="", repr=False)

    def __post_init__(self) -> None:
        vertices = np.array(self.vertices, dtype=np.float64)
        faces = np.array(self.faces)
        where = self.name or "mesh"
        if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) < 3:
            raise DataError(f"{where}: vertices must have shape (k >= 3, 3), got {vertices.shape}")
        if not np.isfinite(vertices).all():
            raise DataError(f"{where}: vertices contain NaN or infinite values")
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise DataError(f"{where}: faces must have shape (m >= 1, 3), got {faces.shape}")
        if not np.issubdtype(faces.dtype, np.integer):
            raise DataError(f"{where}: faces must be integer vertex indices, got {faces.dtype}")
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise DataError(f"{where}: faces index vertices outside 0..{len(vertices) - 1}")
        extent = vertices.max(axis=0) - vertices.min(axis=0)
        if (extent <= 0).any():
            raise DataError(
                f"{where}: the mesh is flat (extent {extent.tolist()}); it needs volume"
            )
        faces = faces.astype(np.int64)
        vertices.setflags(write=False)
        faces.setflags(write=False)
        digest = hashlib.sha256(vertices.tobytes() + faces.tobytes()).hexdigest()
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "digest", digest)

    @classmethod
    def from_arrays(cls, vertices: Any, faces: Any, *, name: str = "mesh") -> MeshShape:
        """A shape from vertex and face arrays."""
        return cls(name, vertices, faces)

    @classmethod
    def from_file(cls, path: str | Path, *, name: str | None = None) -> MeshShape:
        """Load a mesh file with trimesh; scenes in the file are merged into one mesh."""
        path = Path(path)
        if not path.is_file():
            raise DataError("no such mesh file", path=path)
        try:
            mesh = trimesh.load(path, force="mesh")
        except Exception as error:  # trimesh raises many types for bad files
            raise DataError(f"cannot read mesh: {error}", path=path) from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise DataError("the file holds no triangles", path=path)
        try:
            return cls(name or path.stem, mesh.vertices, mesh.faces)
        except DataError as error:
            raise DataError(str(error), path=path) from None

    def unit_geometry(self) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Vertices mapped into the unit box ``[-.5, .5] x [-.5, .5] x [0, 1]``, and faces."""
        low, high = self.vertices.min(axis=0), self.vertices.max(axis=0)
        unit = (self.vertices - low) / (high - low) - np.array([0.5, 0.5, 0.0])
        return unit, self.faces


@dataclass(frozen=True)
class Obstacle:
    """An object the perception stack should detect: its ground-truth box and its look.

    Parameters
    ----------
    box : Box
      Centre, size, heading, label. The mesh fills this box.
    shape : {"auto", "car", "pedestrian", "cyclist", "box"} or MeshShape
      ``"auto"`` picks the built-in shape of the box's label ("box" for "unknown").
    reflectivity : float, optional
      0-1; a per-shape default when omitted.
    """

    box: Box
    shape: str | MeshShape = "auto"
    reflectivity: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.box, Box):
            raise InvalidArgument(f"Obstacle.box must be a Box, got {type(self.box).__name__}")
        if isinstance(self.shape, str) and self.shape not in ("auto", *BUILTIN_SHAPES):
            raise InvalidArgument(
                f"Obstacle.shape={self.shape!r} must be 'auto', one of {BUILTIN_SHAPES} or a "
                "MeshShape"
            )
        if not isinstance(self.shape, (str, MeshShape)):
            raise InvalidArgument(f"Obstacle.shape must be a str or MeshShape, got {self.shape!r}")
        _check_reflectivity(self.reflectivity, "Obstacle.reflectivity")

    @property
    def shape_name(self) -> str:
        """The built-in shape used, or the user mesh's name."""
        if isinstance(self.shape, MeshShape):
            return self.shape.name
        return _SHAPE_OF_LABEL[self.box.label] if self.shape == "auto" else self.shape

    @property
    def label(self) -> Label:
        return self.box.label

    def describe(self) -> str:
        length, width, height = self.box.size
        return (
            f"{self.box.describe()} {length:.1f}x{width:.1f}x{height:.1f} m "
            f"yaw {math.degrees(self.box.yaw):.0f}° ({self.shape_name})"
        )


@dataclass(frozen=True)
class BackgroundObject:
    """Clutter outside the ROI that the ROI filter should remove.

    Parameters
    ----------
    kind : {"building", "pole", "tree"}
    center : (x, y)
      Footprint centre in metres; the object stands on the ground.
    size : (length, width, height)
      Metres. Poles use length as diameter; trees use length as crown diameter.
    yaw : float
      Radians (buildings only; poles and trees are round).
    """

    kind: BackgroundKind
    center: tuple[float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in BACKGROUND_KINDS:
            raise InvalidArgument(f"kind={self.kind!r} must be one of {BACKGROUND_KINDS}")
        center = tuple(float(v) for v in self.center)
        size = tuple(float(v) for v in self.size)
        if len(center) != 2 or len(size) != 3:
            raise InvalidArgument(f"center needs 2 values and size 3, got {center}, {size}")
        if not all(math.isfinite(v) for v in (*center, *size, self.yaw)) or min(size) <= 0:
            raise InvalidArgument(f"BackgroundObject needs finite values and size > 0: {self}")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "yaw", float(self.yaw))

    def footprint_radius(self) -> float:
        """Radius of a circle around the footprint, in metres."""
        return math.hypot(self.size[0], self.size[1]) / 2.0

    def describe(self) -> str:
        return f"{self.kind} at ({self.center[0]:.1f}, {self.center[1]:.1f})"


@dataclass(frozen=True)
class Scene:
    """A synthetic scene around a LiDAR on a vehicle.

    Parameters
    ----------
    sensor_height : float
      Metres above flat ground (KITTI's HDL-64E: 1.73).
    roi : ROI or None
      The HD-map region of interest in the sensor frame; carried into the frame.
    obstacles : tuple of Obstacle
    background : tuple of BackgroundObject
    ground : bool
      Whether there is a ground plane.
    name : str
    terrain : Terrain or None
      The road's shape (:class:`~pytest_metamorphic.lidar.model.terrain.Terrain`): the
      ground follows it and every obstacle and background object stands on it, tilted
      with the road (an obstacle's box stays upright, its bottom on the road under its
      centre). None: flat. Build a scene on a terrain with :meth:`on_terrain`.
    """

    sensor_height: float = 1.73
    roi: ROI | None = None
    obstacles: tuple[Obstacle, ...] = ()
    background: tuple[BackgroundObject, ...] = ()
    ground: bool = True
    name: str = "scene"
    terrain: Terrain | None = None

    def __post_init__(self) -> None:
        height = self.sensor_height
        if isinstance(height, bool) or not isinstance(height, (int, float)):
            raise InvalidArgument(f"sensor_height={height!r} must be a number of metres")
        if not (math.isfinite(height) and 0 < height < 10):
            raise InvalidArgument(f"sensor_height={height!r} must be in (0, 10) metres")
        if self.roi is not None and not isinstance(self.roi, ROI):
            raise InvalidArgument(f"roi must be an ROI or None, got {type(self.roi).__name__}")
        obstacles = tuple(self.obstacles)
        background = tuple(self.background)
        for index, item in enumerate(obstacles):
            if not isinstance(item, Obstacle):
                raise InvalidArgument(
                    f"obstacles[{index}] is {type(item).__name__}; wrap boxes in Obstacle(box)"
                )
        for index, thing in enumerate(background):
            if not isinstance(thing, BackgroundObject):
                raise InvalidArgument(f"background[{index}] is {type(thing).__name__}")
        if self.terrain is not None and not isinstance(self.terrain, Terrain):
            raise InvalidArgument(f"terrain must be a Terrain or None, got {self.terrain!r}")
        object.__setattr__(self, "sensor_height", float(height))
        object.__setattr__(self, "obstacles", obstacles)
        object.__setattr__(self, "background", background)

    def on_terrain(self, terrain: Terrain) -> Scene:
        """The same scene on ``terrain``: each obstacle raised (or lowered) by the road's
        height under its centre, its box with it; the sensor keeps its height above the
        road under it."""
        if not isinstance(terrain, Terrain):
            raise InvalidArgument(f"terrain must be a Terrain, got {terrain!r}")
        if self.terrain is not None:
            raise InvalidArgument(f"{self.name!r} already stands on a terrain")
        raised = []
        for obstacle in self.obstacles:
            x, y, _ = obstacle.box.center
            dz = float(terrain.height(x, y))
            raised.append(dataclasses.replace(obstacle, box=obstacle.box.translated(0, 0, dz)))
        return dataclasses.replace(self, obstacles=tuple(raised), terrain=terrain)

    @property
    def boxes(self) -> tuple[Box, ...]:
        """Ground-truth boxes of the obstacles, in order."""
        return tuple(obstacle.box for obstacle in self.obstacles)

    def describe(self) -> str:
        parts = ", ".join(o.describe() for o in self.obstacles) or "no obstacles"
        roi = f"; {self.roi.describe()}" if self.roi is not None else ""
        return (
            f"Scene {self.name!r}: sensor {self.sensor_height:.2f} m, {parts}; "
            f"{len(self.background)} background object(s){roi}"
        )


def _check_reflectivity(value: Any, name: str) -> None:
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1:
        raise InvalidArgument(f"{name}={value!r} must be a number in [0, 1]")
