"""LiDAR domain code, grouped the way a metamorphic test runs through it.

=================  =========================================================================
``model``          point clouds, frames, obstacle boxes, the HDL-64E's beams
``io``             reading and writing recordings: ``.bin``, PCD, rosbags, KITTI, Apollo
``roi``            HD-map regions of interest: polygons, rasters, scans, roads
``synthetic``      rendered scenes: street layouts, meshes, ray casting
``judging``        which obstacles a relation judges, and when two are the same
``systems``        systems under test: the reference pipeline, the learned detector,
                   detectors in another process, offline predictions
``followups``      follow-up inputs: noise, sensor faults, weather, symmetries, edits,
                   and their reduction to minimal sets
``campaign``       violation rates per size or severity
=================  =========================================================================

Each group imports only from the groups above it in this table. The flat module paths of
earlier releases (``pytest_metamorphic.lidar.obstacles`` and so on) still import, as
aliases of the new ones (:mod:`._moved`).
"""

from pytest_metamorphic.lidar._moved import install as _install_moved_paths

_install_moved_paths()
