"""Synthetic LiDAR scenes: a small description, triangle meshes, a deterministic HDL-64E scan.

A :class:`Scene` is a handful of parameters (sensor height, ROI, obstacles as labelled
:class:`~pytest_metamorphic.lidar.model.obstacles.Box` es with a mesh shape, background objects
outside the ROI, flat ground). :func:`render` builds trimesh meshes for it, casts the rays
of a :class:`~pytest_metamorphic.lidar.model.hdl64.BeamLayout` (the real HDL-64E by default)
from the sensor, and returns a :class:`~pytest_metamorphic.lidar.model.frame.Frame` whose cloud
carries ``ring`` and ``instance`` fields and whose boxes are the ground truth.

Ray casting uses Embree through ``embreex`` when it is importable, and otherwise a numpy
Möller-Trumbore intersector that culls rays per object with bounding-box slab tests:
slower, exact in float64, and the reference the Embree path is tested against.

Coordinates are the sensor frame: x forward, y left, z up, origin at the sensor, ground at
``z = -sensor_height``. Every obstacle mesh fills its box exactly (its axis-aligned bounds
in the box frame are the box), so the box is the tight ground truth.

Modules: :mod:`.description` (what a scene is), :mod:`.meshes` (trimesh shapes for it),
:mod:`.raycast` (Embree or numpy ray casting) and :mod:`.render` (:func:`render`).
"""

from pytest_metamorphic.lidar.synthetic.description import (
    BACKGROUND_INSTANCE,
    BACKGROUND_KINDS,
    BUILTIN_SHAPES,
    GROUND_INSTANCE,
    BackgroundObject,
    MeshShape,
    Obstacle,
    Scene,
)
from pytest_metamorphic.lidar.synthetic.meshes import SceneMesh, scene_mesh
from pytest_metamorphic.lidar.synthetic.raycast import CastEngine, cast_rays, default_engine
from pytest_metamorphic.lidar.synthetic.render import render

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
