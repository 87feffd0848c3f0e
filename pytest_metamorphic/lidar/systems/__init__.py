"""Systems under test and adapters to systems from outside.

:mod:`.perception` (the reference pipeline, its mutants, the whole-scene variant and the
learned CNN segmentation), :mod:`.process` (a detector in another process, any language),
:mod:`.detectors` (outputs of OpenPCDet and mmdetection3d as boxes), :mod:`.offline`
(datasets exported for a detector farm, and its predictions read back),
:mod:`.components` (ground segmenters and clusterers from PyPI: Patchwork++, Open3D,
scikit-learn), :mod:`.stages` (a pipeline declared as stages, and the stage a violation is
blamed on).
"""
