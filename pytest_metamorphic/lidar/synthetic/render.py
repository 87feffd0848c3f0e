"""Rendering a scene with a beam layout into a labelled
:class:`~pytest_metamorphic.lidar.model.frame.Frame`.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import HDL64E
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.sensors.layout import Rays, ScanPattern
from pytest_metamorphic.lidar.synthetic.description import Scene
from pytest_metamorphic.lidar.synthetic.meshes import SceneMesh, scene_mesh
from pytest_metamorphic.lidar.synthetic.raycast import CastEngine, cast_rays

__all__ = ["Rendering", "render", "rendering_of"]


@dataclass(frozen=True)
class Rendering:
    """How a frame was rendered: what :func:`render` was given, to render it again
    (another terrain, the same beams and noise)."""

    scene: Scene
    beams: ScanPattern
    seed: int
    range_noise: float | None
    azimuth_range: tuple[float, float] | None
    engine: CastEngine

    def again(self, scene: Scene) -> Frame:
        """``scene`` rendered as this frame was."""
        return render(
            scene, beams=self.beams, seed=self.seed, range_noise=self.range_noise,
            azimuth_range=self.azimuth_range, engine=self.engine,
        )  # fmt: skip


# The rendering of each frame render() made (while the frame lives).
_RENDERINGS: weakref.WeakKeyDictionary[Frame, Rendering] = weakref.WeakKeyDictionary()


def rendering_of(frame: Frame) -> Rendering | None:
    """How ``frame`` was rendered, when :func:`render` made it (None: a recording, or a
    follow-up edited from a rendered frame)."""
    return _RENDERINGS.get(frame)


def render(
    scene: Scene,
    *,
    beams: ScanPattern = HDL64E,
    seed: int = 0,
    range_noise: float | None = None,
    azimuth_range: tuple[float, float] | None = None,
    engine: CastEngine = "auto",
) -> Frame:
    """Scan a scene with a spinning LiDAR; deterministic for a given scene and seed.

    Parameters
    ----------
    scene : Scene
    beams : ScanPattern
      The sensor (default: the real HDL-64E layout, 133,312 rays; any model of
      :mod:`pytest_metamorphic.lidar.model.sensors`, e.g. ``VLP16``, ``OS1_128``,
      ``LIVOX_MID40``).
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
      ``ring`` (uint8, 0 = lowest beam; absent for a scanner without rings) and
      ``instance`` (int32: obstacle index,
      :data:`GROUND_INSTANCE` or :data:`BACKGROUND_INSTANCE`); ``roi``: the scene's ROI;
      ``boxes``: every obstacle's box with ``points`` set to its number of returns;
      ``source``: ``"synthetic:<scene name>"``; ``sensor``: ``beams``.
    """
    if not isinstance(scene, Scene):
        raise InvalidArgument(f"scene must be a Scene, got {type(scene).__name__}")
    if not isinstance(beams, ScanPattern):
        raise InvalidArgument(
            f"beams must be a sensor model (lidar.model.sensors), got {type(beams).__name__}"
        )
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
    directions = np.take(rays.directions, ray, axis=0)
    intensity = mesh.face_reflectivity[face] * _cos_incidence(mesh, face, directions)
    points = np.empty((len(ray), 4), dtype=np.float32)
    points[:, :3] = directions * measured[:, None]
    points[:, 3] = np.clip(intensity, 0.0, 1.0)
    instance = mesh.face_instance[face]
    fields: dict[str, NDArray[Any]] = {"instance": instance.astype(np.int32)}
    if beams.has_rings:
        fields = {"ring": rays.ring[ray], **fields}
    cloud = PointCloud(points, fields=fields, frame_id="velodyne")
    counts = np.bincount(instance[instance >= 0], minlength=len(scene.obstacles))
    boxes = tuple(
        Box(o.box.center, o.box.size, o.box.yaw, o.box.label, o.box.score, int(counts[i]))
        for i, o in enumerate(scene.obstacles)
    )
    frame = Frame(cloud, roi=scene.roi, boxes=boxes, source=f"synthetic:{scene.name}", sensor=beams)
    _RENDERINGS[frame] = Rendering(scene, beams, int(seed), range_noise, azimuth_range, engine)
    return frame


def _cos_incidence(
    mesh: SceneMesh, face: NDArray[np.intp], directions: NDArray[np.float64]
) -> NDArray[np.float64]:
    # Unit normals per face (a few thousand), gathered per hit (~120k): the same
    # row-wise arithmetic as per hit, so the same values, at a fraction of the cost.
    triangles = mesh.vertices[mesh.faces]
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(normal, axis=1)
    normal = normal / np.where(length > 0, length, 1.0)[:, None]
    # Column by column, in the order of numpy's row sum (x + y + z): the same values.
    per_hit = np.take(normal, face, axis=0)
    cosine = per_hit[:, 0] * directions[:, 0]
    cosine += per_hit[:, 1] * directions[:, 1]
    cosine += per_hit[:, 2] * directions[:, 2]
    return np.abs(cosine)
