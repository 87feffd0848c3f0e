"""Triangle meshes for a scene: built-in obstacle shapes, background objects and the ground."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.terrain import Terrain
from pytest_metamorphic.lidar.synthetic.description import (
    _REFLECTIVITY,
    BACKGROUND_INSTANCE,
    GROUND_INSTANCE,
    MeshShape,
    Obstacle,
    Scene,
)

__all__ = ["SceneMesh", "obstacle_geometry", "scene_mesh"]


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
    mesh: Any = trimesh.util.concatenate(list(parts))  # a Trimesh (typed as any geometry)
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


def obstacle_geometry(
    obstacle: Obstacle,
) -> tuple[NDArray[np.float64], NDArray[np.int64], float]:
    """An obstacle's mesh in its own coordinates (x along its heading, y to its left, z up
    from its underside), scaled to its box, and its reflectivity."""
    if isinstance(obstacle.shape, MeshShape):
        unit, faces = obstacle.shape.unit_geometry()
        default = _REFLECTIVITY["box"]
    else:
        unit, faces = _builtin_shape(obstacle.shape_name)
        default = _REFLECTIVITY[obstacle.shape_name]
    reflectivity = default if obstacle.reflectivity is None else obstacle.reflectivity
    return _place(unit, obstacle.box.size, 0.0, (0.0, 0.0, 0.0)), faces, reflectivity


_TERRAIN_CELL = 1.0  # metres between the height field's vertices


def _tilt(gradient: tuple[float, float]) -> NDArray[np.float64]:
    """The rotation that stands a thing upright on a road of ``gradient`` (dz/dx, dz/dy):
    its up axis along the road's normal."""
    gx, gy = gradient
    normal = np.array([-gx, -gy, 1.0]) / math.sqrt(gx * gx + gy * gy + 1.0)
    up = np.array([0.0, 0.0, 1.0])
    axis = np.cross(up, normal)
    sine, cosine = float(np.linalg.norm(axis)), float(normal[2])
    if sine < 1e-12:
        return np.eye(3)
    k = axis / sine
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + sine * cross + (1.0 - cosine) * cross @ cross


def _lowest_under(terrain: Terrain, centre: tuple[float, float], radius: float) -> float:
    angles = np.linspace(0.0, 2 * math.pi, 9)
    x = np.r_[centre[0], centre[0] + radius * np.cos(angles)]
    y = np.r_[centre[1], centre[1] + radius * np.sin(angles)]
    return float(terrain.height(x, y).min())


def _ground(
    ground_z: float, extent: float, terrain: Terrain | None
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The ground: a square of two triangles when flat, else a height field of 1 m cells
    (a vertex row on the crown line, so the camber's ridge is exact)."""
    if terrain is None or terrain.flat:
        e = extent
        vertices = np.array(
            [[-e, -e, ground_z], [e, -e, ground_z], [e, e, ground_z], [-e, e, ground_z]]
        )
        return vertices, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    steps = math.ceil(extent / _TERRAIN_CELL)
    xs = np.arange(-steps, steps + 1) * _TERRAIN_CELL
    ys = xs + (terrain.crown_y_m % _TERRAIN_CELL)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    gz = ground_z + terrain.height(gx, gy)
    vertices = np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()])
    n = len(ys)
    i, j = np.meshgrid(np.arange(len(xs) - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    b, c, d = a + n, a + n + 1, a + 1
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return vertices, faces.astype(np.int64)


def scene_mesh(scene: Scene, *, ground_extent: float = 130.0) -> SceneMesh:
    """Build the triangle meshes of a scene (obstacles, background, ground square)."""
    ground_z = -scene.sensor_height
    pieces: list[tuple[NDArray[np.float64], NDArray[np.int64], int, float]] = []
    terrain = scene.terrain
    for index, obstacle in enumerate(scene.obstacles):
        box = obstacle.box
        local, faces, reflectivity = obstacle_geometry(obstacle)
        c, s = math.cos(box.yaw), math.sin(box.yaw)
        rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        vertices = local @ rotation.T
        if terrain is not None:  # it stands on the road's slope (its box stays upright)
            vertices = vertices @ _tilt(terrain.gradient(box.center[0], box.center[1])).T
        vertices = vertices + np.array([box.center[0], box.center[1], box.bottom_z])
        pieces.append((vertices, faces, index, reflectivity))
    for item in scene.background:
        unit, faces = _background_shape(item.kind)
        base = ground_z
        if terrain is not None:  # on the road's lowest point under it: nothing floats
            base += _lowest_under(terrain, item.center, item.footprint_radius())
        vertices = _place(unit, item.size, item.yaw, (*item.center, base))
        pieces.append((vertices, faces, BACKGROUND_INSTANCE, _REFLECTIVITY[item.kind]))
    if scene.ground:
        vertices, faces = _ground(ground_z, float(ground_extent), terrain)
        pieces.append((vertices, faces, GROUND_INSTANCE, _REFLECTIVITY["ground"]))
    if not pieces:
        return SceneMesh(
            np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int32), np.empty(0), ()
        )
    all_vertices: list[NDArray[np.float64]] = []
    all_faces: list[NDArray[np.int64]] = []
    instance: list[NDArray[np.int32]] = []
    face_reflectivity: list[NDArray[np.float64]] = []
    groups: list[tuple[int, int]] = []
    offset = face_start = 0
    for vertices, faces, owner, value in pieces:
        all_vertices.append(vertices)
        all_faces.append(faces + offset)
        instance.append(np.full(len(faces), owner, np.int32))
        face_reflectivity.append(np.full(len(faces), value))
        groups.append((face_start, face_start + len(faces)))
        offset += len(vertices)
        face_start += len(faces)
    return SceneMesh(
        np.concatenate(all_vertices),
        np.concatenate(all_faces),
        np.concatenate(instance),
        np.concatenate(face_reflectivity),
        tuple(groups),
    )
