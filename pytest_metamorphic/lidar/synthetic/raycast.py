"""Casting LiDAR rays at a scene's triangles: Embree through embreex, or an exact numpy
intersector.
"""

from __future__ import annotations

import math
import weakref
from typing import Literal

import numpy as np
import trimesh
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.synthetic.meshes import SceneMesh

__all__ = ["CastEngine", "cast_rays", "default_engine"]

CastEngine = Literal["auto", "embree", "numpy"]


# Rays and triangles per block in the numpy intersector (bounds temporary memory).
_BLOCK_ELEMENTS = 1 << 21
_EPSILON = 1e-9


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
    # Both casters list the rays that hit in ascending order (np.flatnonzero).
    keep = distance <= max_distance
    return ray[keep], face[keep], distance[keep]


def _cast_embree(
    mesh: SceneMesh, directions: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """First hits through Embree, with trimesh's scaling and its exact plane-line ranges.

    The same arithmetic as ``RayMeshIntersector.intersects_id(multiple_hits=False,
    return_locations=True)`` (trimesh 4), so the points are bit-identical to it, without
    its multiple-hit bookkeeping: rays from the origin need no offsets, and the one
    pass it makes for first hits is all there is. Per-hit vectors are handled column by
    column (row sums of (n, 3) arrays are strided and slow); each sum keeps the order
    x + y + z of numpy's row reduction, so the values are the same.
    """
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise InvalidArgument(f"engine='embree' needs embreex: {error}") from None
    geometry = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    # trimesh's _EmbreeWrap: vertices moved to their minimum and scaled to a ~100 m box.
    origin = vertices.min(axis=0)
    scale = 100.0 / geometry.scale
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(
        scene=scene,
        vertices=((vertices - origin) * scale).astype(np.float32),
        indices=np.asarray(mesh.faces).astype(np.int32),
    )
    unit, unit32 = _unit_rays(directions)
    origins = np.empty(unit32.shape, dtype=np.float32)
    origins[:] = ((0.0 - origin) * scale).astype(np.float32)
    query = scene.run(origins, unit32)
    ray = np.flatnonzero(query != -1)
    face = query[ray].astype(np.intp)
    # trimesh.intersections.planes_lines with line origins at 0: t = (p0 . n) / (d . n).
    # Rows gathered with np.take (several times faster than fancy indexing of (n, 3)),
    # from plain arrays (trimesh's tracked arrays cost a hook per slice).
    normals = np.take(np.asarray(geometry.face_normals), face, axis=0)
    corner = np.take(vertices, np.take(np.asarray(mesh.faces)[:, 0], face), axis=0)
    along = trimesh.util.diagonal_dot(corner, normals)
    direction = np.take(unit, ray, axis=0)
    facing = trimesh.util.diagonal_dot(direction, normals)
    valid = np.abs(facing) > 1e-5
    if not valid.all():  # a ray grazing its triangle's plane: trimesh drops it
        ray, face, along, facing = ray[valid], face[valid], along[valid], facing[valid]
        direction = direction[valid]
    t = along / facing
    squared = np.square(direction[:, 0] * t)
    squared += np.square(direction[:, 1] * t)
    squared += np.square(direction[:, 2] * t)
    return ray, face, np.sqrt(squared)


# Unit ray directions (trimesh.util.unitize, and as float32 for Embree) per read-only
# ray array: every full sweep of a layout casts the same one (BeamLayout caches it).
_UNIT_RAYS: dict[
    int, tuple[weakref.ref[NDArray[np.float64]], NDArray[np.float64], NDArray[np.float32]]
] = {}


def _unit_rays(directions: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float32]]:
    """``(unitised, as float32)``, cached for read-only arrays that own their memory."""
    cacheable = not directions.flags.writeable and directions.base is None
    if cacheable:
        found = _UNIT_RAYS.get(id(directions))
        if found is not None and found[0]() is directions:
            return found[1], found[2]
    unit = trimesh.util.unitize(directions)
    unit32 = unit.astype(np.float32)
    if cacheable:
        unit.setflags(write=False)  # shared by every later render of the sweep
        unit32.setflags(write=False)
        key = id(directions)
        _UNIT_RAYS[key] = (
            weakref.ref(directions, lambda _: _UNIT_RAYS.pop(key, None)),
            unit,
            unit32,
        )
    return unit, unit32


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
