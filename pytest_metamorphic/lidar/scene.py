"""Synthetic LiDAR scenes: a small description, triangle meshes, a deterministic HDL-64E scan.

A :class:`Scene` is a handful of parameters (sensor height, ROI, obstacles as labelled
:class:`~pytest_metamorphic.lidar.obstacles.Box` es with a mesh shape, background objects
outside the ROI, flat ground). :func:`render` builds trimesh meshes for it, casts the rays
of a :class:`~pytest_metamorphic.lidar.hdl64.BeamLayout` (the real HDL-64E by default)
from the sensor, and returns a :class:`~pytest_metamorphic.lidar.frame.Frame` whose cloud
carries ``ring`` and ``instance`` fields and whose boxes are the ground truth.

Ray casting uses Embree through ``embreex`` when it is importable, and otherwise a numpy
Möller-Trumbore intersector that culls rays per object with bounding-box slab tests:
slower, exact in float64, and the reference the Embree path is tested against.

Coordinates are the sensor frame: x forward, y left, z up, origin at the sensor, ground at
``z = -sensor_height``. Every obstacle mesh fills its box exactly (its axis-aligned bounds
in the box frame are the box), so the box is the tight ground truth.
"""

from __future__ import annotations

import functools
import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import trimesh
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.lidar.cloud import PointCloud
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.hdl64 import HDL64E, BeamLayout, Rays
from pytest_metamorphic.lidar.obstacles import Box, Label
from pytest_metamorphic.lidar.roi import ROI

__all__ = [
    "BACKGROUND_INSTANCE",
    "BACKGROUND_KINDS",
    "BUILTIN_SHAPES",
    "GROUND_INSTANCE",
    "BackgroundObject",
    "CastEngine",
    "MeshShape",
    "Obstacle",
    "Scene",
    "SceneMesh",
    "cast_rays",
    "default_engine",
    "render",
    "scene_mesh",
]

CastEngine = Literal["auto", "embree", "numpy"]
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
# Rays and triangles per block in the numpy intersector (bounds temporary memory).
_BLOCK_ELEMENTS = 1 << 21
_EPSILON = 1e-9


# -- scene description -------------------------------------------------------------------------


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
    """

    sensor_height: float = 1.73
    roi: ROI | None = None
    obstacles: tuple[Obstacle, ...] = ()
    background: tuple[BackgroundObject, ...] = ()
    ground: bool = True
    name: str = "scene"

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
        for index, item in enumerate(background):
            if not isinstance(item, BackgroundObject):
                raise InvalidArgument(f"background[{index}] is {type(item).__name__}")
        object.__setattr__(self, "sensor_height", float(height))
        object.__setattr__(self, "obstacles", obstacles)
        object.__setattr__(self, "background", background)

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


# -- meshes ------------------------------------------------------------------------------------


def _hull(points: Sequence[Sequence[float]]) -> trimesh.Trimesh:
    return trimesh.Trimesh(vertices=np.asarray(points, dtype=np.float64)).convex_hull


def _cuboid(
    x: tuple[float, float], y: tuple[float, float], z: tuple[float, float]
) -> trimesh.Trimesh:
    return _hull([(a, b, c) for a in x for b in y for c in z])


def _wheel(x: float, y: tuple[float, float], radius: float, sections: int = 10) -> trimesh.Trimesh:
    """A cylinder with its axis along y, resting on z = 0."""
    angles = np.linspace(0, 2 * math.pi, sections, endpoint=False)
    ring = [(x + radius * math.cos(a), radius + radius * math.sin(a)) for a in angles]
    return _hull([(px, py, pz) for px, pz in ring for py in y])


def _ellipsoid(centre: Sequence[float], radii: Sequence[float]) -> trimesh.Trimesh:
    sphere = trimesh.creation.icosphere(subdivisions=1)
    return trimesh.Trimesh(sphere.vertices * np.asarray(radii) + np.asarray(centre), sphere.faces)


def _unit(parts: Sequence[trimesh.Trimesh]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Merge parts and stretch them to exactly fill ``[-.5, .5]^2 x [0, 1]``."""
    mesh = trimesh.util.concatenate(list(parts))
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    unit = (vertices - low) / (high - low) - np.array([0.5, 0.5, 0.0])
    return unit, np.asarray(mesh.faces, dtype=np.int64)


@functools.cache
def _builtin_shape(name: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Low-poly unit meshes (x: heading, y: left, z: up from 0 to 1)."""
    if name == "box":
        parts = [_cuboid((-0.5, 0.5), (-0.5, 0.5), (0, 1))]
    elif name == "car":
        parts = [
            _cuboid((-0.5, 0.5), (-0.5, 0.5), (0.17, 0.58)),
            # Cabin with sloped windscreen and rear window.
            _hull(
                [(x, y, 0.58) for x in (-0.36, 0.26) for y in (-0.46, 0.46)]
                + [(x, y, 1.0) for x in (-0.26, 0.08) for y in (-0.4, 0.4)]
            ),
            *(_wheel(x, (s * 0.5, s * 0.36), 0.18) for x in (-0.31, 0.31) for s in (-1, 1)),
        ]
    elif name == "pedestrian":
        parts = [
            # Legs mid-stride, hip to foot.
            _hull(
                [(x, y, 0.5) for x in (-0.1, 0.1) for y in (0.02, 0.3)]
                + [(x, y, 0.0) for x in (0.22, 0.5) for y in (0.02, 0.3)]
            ),
            _hull(
                [(x, y, 0.5) for x in (-0.1, 0.1) for y in (-0.3, -0.02)]
                + [(x, y, 0.0) for x in (-0.5, -0.22) for y in (-0.3, -0.02)]
            ),
            _cuboid((-0.22, 0.22), (-0.5, 0.5), (0.48, 0.84)),
            _ellipsoid((0.0, 0.0, 0.92), (0.16, 0.2, 0.08)),
        ]
    elif name == "cyclist":
        parts = [
            _wheel(-0.3, (-0.05, 0.05), 0.2),
            _wheel(0.3, (-0.05, 0.05), 0.2),
            _hull(
                [
                    (x, y, z)
                    for x, z in ((-0.3, 0.2), (0.3, 0.2), (0.22, 0.55), (-0.12, 0.52))
                    for y in (-0.05, 0.05)
                ]
            ),
            _cuboid((0.2, 0.28), (-0.5, 0.5), (0.55, 0.6)),  # handlebar
            _cuboid((-0.16, 0.06), (-0.22, 0.22), (0.25, 0.56)),  # legs
            _hull(  # torso leaning forward
                [(x, y, 0.52) for x in (-0.2, 0.02) for y in (-0.35, 0.35)]
                + [(x, y, 0.84) for x in (-0.04, 0.16) for y in (-0.33, 0.33)]
            ),
            _ellipsoid((0.08, 0.0, 0.92), (0.08, 0.12, 0.08)),
        ]
    else:  # pragma: no cover - guarded by Obstacle
        raise InvalidArgument(f"unknown shape {name!r}")
    vertices, faces = _unit(parts)
    vertices.setflags(write=False)
    faces.setflags(write=False)
    return vertices, faces


def _place(
    unit: NDArray[np.float64], size: Sequence[float], yaw: float, centre: Sequence[float]
) -> NDArray[np.float64]:
    """Scale a unit mesh to ``size``, turn it by ``yaw`` and put its bottom centre at ``centre``."""
    scaled = unit * np.asarray(size, dtype=np.float64)
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return scaled @ rotation.T + np.asarray(centre, dtype=np.float64)


@functools.cache
def _background_shape(kind: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    if kind == "building":
        parts = [_cuboid((-0.5, 0.5), (-0.5, 0.5), (0, 1))]
    elif kind == "pole":
        parts = [trimesh.creation.cylinder(radius=0.5, height=1.0, sections=8)]
    else:  # tree: trunk and crown
        parts = [
            trimesh.creation.cylinder(
                radius=0.08, height=0.5, sections=6, transform=_z_shift(0.25)
            ),
            _ellipsoid((0.0, 0.0, 0.68), (0.5, 0.5, 0.32)),
        ]
    return _unit(parts)


def _z_shift(dz: float) -> NDArray[np.float64]:
    transform = np.eye(4)
    transform[2, 3] = dz
    return transform


@dataclass(frozen=True)
class SceneMesh:
    """All triangles of a scene, with what each belongs to.

    Attributes
    ----------
    vertices : (k, 3) float64
    faces : (m, 3) int64
    face_instance : (m,) int32
      Obstacle index, :data:`GROUND_INSTANCE` or :data:`BACKGROUND_INSTANCE`.
    face_reflectivity : (m,) float64
    groups : tuple of (start, stop)
      Face ranges of the individual objects (for per-object culling).
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    face_instance: NDArray[np.int32]
    face_reflectivity: NDArray[np.float64]
    groups: tuple[tuple[int, int], ...]


def scene_mesh(scene: Scene, *, ground_extent: float = 130.0) -> SceneMesh:
    """Build the triangle meshes of a scene (obstacles, background, ground square)."""
    ground_z = -scene.sensor_height
    pieces: list[tuple[NDArray[np.float64], NDArray[np.int64], int, float]] = []
    for index, obstacle in enumerate(scene.obstacles):
        box = obstacle.box
        if isinstance(obstacle.shape, MeshShape):
            unit, faces = obstacle.shape.unit_geometry()
            default = _REFLECTIVITY["box"]
        else:
            unit, faces = _builtin_shape(obstacle.shape_name)
            default = _REFLECTIVITY[obstacle.shape_name]
        bottom = (box.center[0], box.center[1], box.bottom_z)
        vertices = _place(unit, box.size, box.yaw, bottom)
        reflectivity = default if obstacle.reflectivity is None else obstacle.reflectivity
        pieces.append((vertices, faces, index, reflectivity))
    for item in scene.background:
        unit, faces = _background_shape(item.kind)
        vertices = _place(unit, item.size, item.yaw, (*item.center, ground_z))
        pieces.append((vertices, faces, BACKGROUND_INSTANCE, _REFLECTIVITY[item.kind]))
    if scene.ground:
        e = float(ground_extent)
        vertices = np.array(
            [[-e, -e, ground_z], [e, -e, ground_z], [e, e, ground_z], [-e, e, ground_z]]
        )
        faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
        pieces.append((vertices, faces, GROUND_INSTANCE, _REFLECTIVITY["ground"]))
    if not pieces:
        return SceneMesh(
            np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int32), np.empty(0), ()
        )
    all_vertices, all_faces, instance, reflectivity, groups = [], [], [], [], []
    offset = face_start = 0
    for vertices, faces, owner, value in pieces:
        all_vertices.append(vertices)
        all_faces.append(faces + offset)
        instance.append(np.full(len(faces), owner, np.int32))
        reflectivity.append(np.full(len(faces), value))
        groups.append((face_start, face_start + len(faces)))
        offset += len(vertices)
        face_start += len(faces)
    return SceneMesh(
        np.concatenate(all_vertices),
        np.concatenate(all_faces),
        np.concatenate(instance),
        np.concatenate(reflectivity),
        tuple(groups),
    )


# -- ray casting -------------------------------------------------------------------------------


def default_engine() -> Literal["embree", "numpy"]:
    """``"embree"`` when embreex is importable, else ``"numpy"``."""
    try:
        import embreex  # noqa: F401
    except ImportError:
        return "numpy"
    return "embree"


def cast_rays(
    mesh: SceneMesh,
    directions: NDArray[np.float64],
    *,
    max_distance: float = math.inf,
    engine: CastEngine = "auto",
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """First hits of rays from the origin.

    Parameters
    ----------
    mesh : SceneMesh
    directions : (r, 3) float64
      Unit vectors.
    max_distance : float
      Hits farther than this are ignored.
    engine : {"auto", "embree", "numpy"}

    Returns
    -------
    ray : (h,) intp
      Indices of the rays that hit, ascending.
    face : (h,) intp
      The triangle each of them hits first.
    distance : (h,) float64
      Distance along the ray (the ray is a unit vector, so this is the range).
    """
    if engine == "auto":
        engine = default_engine()
    directions = np.ascontiguousarray(directions, dtype=np.float64)
    if directions.ndim != 2 or directions.shape[1] != 3:
        raise InvalidArgument(f"directions must have shape (r, 3), got {directions.shape}")
    if len(mesh.faces) == 0 or len(directions) == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty.copy(), np.empty(0)
    if engine == "embree":
        ray, face, distance = _cast_embree(mesh, directions)
    elif engine == "numpy":
        ray, face, distance = _cast_numpy(mesh, directions, max_distance)
    else:
        raise InvalidArgument(f"engine={engine!r} must be 'auto', 'embree' or 'numpy'")
    keep = distance <= max_distance
    ray, face, distance = ray[keep], face[keep], distance[keep]
    order = np.argsort(ray, kind="stable")
    return ray[order], face[order], distance[order]


def _cast_embree(
    mesh: SceneMesh, directions: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise InvalidArgument(f"engine='embree' needs embreex: {error}") from None
    geometry = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    intersector = RayMeshIntersector(geometry)
    origins = np.zeros_like(directions)
    face, ray, locations = intersector.intersects_id(
        origins, directions, multiple_hits=False, return_locations=True
    )
    distance = np.sqrt((np.asarray(locations, dtype=np.float64) ** 2).sum(axis=1))
    return np.asarray(ray, dtype=np.intp), np.asarray(face, dtype=np.intp), distance


def _cast_numpy(
    mesh: SceneMesh, directions: NDArray[np.float64], max_distance: float
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    best = np.full(len(directions), np.inf)
    best_face = np.full(len(directions), -1, dtype=np.intp)
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / directions
    for start, stop in mesh.groups:
        triangles = mesh.vertices[mesh.faces[start:stop]]  # (f, 3, 3)
        low = triangles.reshape(-1, 3).min(axis=0)
        high = triangles.reshape(-1, 3).max(axis=0)
        candidates = _slab_hits(inverse, low, high, min(max_distance, 1e12))
        if len(candidates) == 0:
            continue
        block = max(1, _BLOCK_ELEMENTS // len(triangles))
        for begin in range(0, len(candidates), block):
            rays = candidates[begin : begin + block]
            t, face = _moller_trumbore(directions[rays], triangles)
            closer = t < best[rays]
            best[rays[closer]] = t[closer]
            best_face[rays[closer]] = face[closer] + start
    hit = np.flatnonzero(np.isfinite(best))
    return hit, best_face[hit], best[hit]


def _slab_hits(
    inverse: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64], limit: float
) -> NDArray[np.intp]:
    """Rays from the origin that pass through the (slightly padded) box [low, high]."""
    pad = 1e-6 * (1.0 + np.abs(high - low).max())
    low, high = low - pad, high + pad
    with np.errstate(invalid="ignore"):
        t1 = low * inverse
        t2 = high * inverse
    # 0 * inf is NaN for rays parallel to a slab through the origin's plane: such a ray is
    # inside that slab for all t exactly when 0 lies in [low, high].
    inside = (low <= 0) & (high >= 0)
    t_near = np.where(
        np.isnan(t1) | np.isnan(t2), np.where(inside, -np.inf, np.inf), np.minimum(t1, t2)
    )
    t_far = np.where(
        np.isnan(t1) | np.isnan(t2), np.where(inside, np.inf, -np.inf), np.maximum(t1, t2)
    )
    enter = t_near.max(axis=1)
    leave = t_far.min(axis=1)
    return np.flatnonzero((enter <= leave) & (leave >= 0) & (enter <= limit))


def _moller_trumbore(
    directions: NDArray[np.float64], triangles: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Nearest hit distance (inf if none) and triangle per ray; rays start at the origin."""
    v0 = triangles[None, :, 0, :]
    e1 = triangles[None, :, 1, :] - v0
    e2 = triangles[None, :, 2, :] - v0
    d = directions[:, None, :]
    p = np.cross(d, e2)
    det = (e1 * p).sum(axis=2)
    parallel = np.abs(det) < _EPSILON * (np.abs(e1).sum(axis=2) * np.abs(e2).sum(axis=2) + _EPSILON)
    inv_det = 1.0 / np.where(parallel, 1.0, det)
    tvec = -v0
    u = (tvec * p).sum(axis=2) * inv_det
    q = np.cross(tvec, e1)
    v = (d * q).sum(axis=2) * inv_det
    t = (e2 * q).sum(axis=2) * inv_det
    valid = ~parallel & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > _EPSILON)
    t = np.where(valid, t, np.inf)
    face = np.argmin(t, axis=1)
    return t[np.arange(len(t)), face], face


# -- rendering ---------------------------------------------------------------------------------


def render(
    scene: Scene,
    *,
    beams: BeamLayout = HDL64E,
    seed: int = 0,
    range_noise: float | None = None,
    azimuth_range: tuple[float, float] | None = None,
    engine: CastEngine = "auto",
) -> Frame:
    """Scan a scene with a spinning LiDAR; deterministic for a given scene and seed.

    Parameters
    ----------
    scene : Scene
    beams : BeamLayout
      The sensor (default: the real HDL-64E layout, 133,312 rays).
    seed : int
      Seeds the range noise (numpy PCG64); the same seed gives the same cloud.
    range_noise : float, optional
      Gaussian range error in metres; ``beams.range_noise`` (2 cm) by default, 0 for none.
    azimuth_range : (float, float), optional
      Only fire between these azimuths (radians), for partial sweeps.
    engine : {"auto", "embree", "numpy"}
      Ray caster; both give the same points up to float rounding.

    Returns
    -------
    Frame
      ``cloud``: x, y, z, intensity (0-1) as float32, in firing order, with fields
      ``ring`` (uint8, 0 = lowest beam) and ``instance`` (int32: obstacle index,
      :data:`GROUND_INSTANCE` or :data:`BACKGROUND_INSTANCE`); ``roi``: the scene's ROI;
      ``boxes``: every obstacle's box with ``points`` set to its number of returns;
      ``source``: ``"synthetic:<scene name>"``.
    """
    if not isinstance(scene, Scene):
        raise InvalidArgument(f"scene must be a Scene, got {type(scene).__name__}")
    if not isinstance(beams, BeamLayout):
        raise InvalidArgument(f"beams must be a BeamLayout, got {type(beams).__name__}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidArgument(f"seed={seed!r} must be a non-negative int")
    sigma = beams.range_noise if range_noise is None else float(range_noise)
    if not (math.isfinite(sigma) and sigma >= 0):
        raise InvalidArgument(f"range_noise={range_noise!r} must be >= 0")
    rays: Rays = beams.rays(azimuth_range=azimuth_range)
    mesh = scene_mesh(scene, ground_extent=beams.max_range + 10.0)
    ray, face, distance = cast_rays(
        mesh, rays.directions, max_distance=beams.max_range + 1.0, engine=engine
    )
    # One noise value per ray, drawn whether or not it hits: hits do not shift the stream.
    noise = np.random.default_rng(int(seed)).normal(0.0, 1.0, len(rays)) * sigma
    measured = distance + noise[ray]
    keep = (measured >= beams.min_range) & (measured <= beams.max_range)
    ray, face, measured = ray[keep], face[keep], measured[keep]
    directions = rays.directions[ray]
    xyz = directions * measured[:, None]
    intensity = mesh.face_reflectivity[face] * _cos_incidence(mesh, face, directions)
    points = np.empty((len(ray), 4), dtype=np.float32)
    points[:, :3] = xyz
    points[:, 3] = np.clip(intensity, 0.0, 1.0)
    instance = mesh.face_instance[face]
    cloud = PointCloud(
        points,
        fields={"ring": rays.ring[ray], "instance": instance.astype(np.int32)},
        frame_id="velodyne",
    )
    counts = np.bincount(instance[instance >= 0], minlength=len(scene.obstacles))
    boxes = tuple(
        Box(o.box.center, o.box.size, o.box.yaw, o.box.label, o.box.score, int(counts[i]))
        for i, o in enumerate(scene.obstacles)
    )
    return Frame(cloud, roi=scene.roi, boxes=boxes, source=f"synthetic:{scene.name}")


def _cos_incidence(
    mesh: SceneMesh, face: NDArray[np.intp], directions: NDArray[np.float64]
) -> NDArray[np.float64]:
    triangles = mesh.vertices[mesh.faces[face]]
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(normal, axis=1)
    normal = normal / np.where(length > 0, length, 1.0)[:, None]
    return np.abs((normal * directions).sum(axis=1))
