"""The LiDAR data model: point clouds, frames, obstacle boxes and the sensor's beams.

:mod:`.cloud` (:class:`PointCloud`, a structured array of points), :mod:`.frame`
(:class:`Frame`: a cloud with its ground-truth boxes and where it came from),
:mod:`.obstacles` (:class:`Box`, labels, size priors, box geometry and matchers),
:mod:`.hdl64` (the Velodyne HDL-64E's beam layout). Everything else in ``lidar`` is built
on these; they import nothing from it.
"""
