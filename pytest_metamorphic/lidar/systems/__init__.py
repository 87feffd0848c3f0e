"""Systems under test and adapters to systems from outside.

:mod:`.perception` (the reference pipeline, its mutants, the whole-scene variant and the
learned CNN segmentation), :mod:`.process` (a detector in another process, any language),
:mod:`.detectors` (outputs of OpenPCDet and mmdetection3d as boxes), :mod:`.offline`
(datasets exported for a detector farm, and its predictions read back).
"""
