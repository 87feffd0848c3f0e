"""Components people compose perception stacks from, as systems under test.

A ground segmenter is called on a frame and returns
:class:`~pytest_metamorphic.lidar.model.point_outputs.PointLabels` (``GROUND`` / ``NOT_GROUND``
for every return); a clusterer returns a
:class:`~pytest_metamorphic.lidar.model.point_outputs.Partition`. The component relations
(:func:`pytest_metamorphic.relations.lidar.components.component_relations`) judge them
point by point.

:mod:`.ground`: Patchwork++ (``pypatchworkpp``), Open3D's RANSAC plane and the reference
pipeline's own ground stage; :mod:`.clusterers`: scikit-learn's DBSCAN, HDBSCAN and
OPTICS (any estimator with ``fit_predict``), Open3D's DBSCAN and the reference's grid
segmentation, each optionally after a ground segmenter and the ROI (the way a stack feeds
them). The libraries are optional extras (``pip install 'pytest-metamorphic[components]'``);
an adapter says which one is missing when it is made.
"""

from pytest_metamorphic.lidar.systems.components.clusterers import (
    Open3DClusters,
    ReferenceClusters,
    SklearnClusters,
)
from pytest_metamorphic.lidar.systems.components.ground import (
    Open3DPlaneGround,
    PatchworkGround,
    ReferenceGround,
)

__all__ = [
    "Open3DClusters",
    "Open3DPlaneGround",
    "PatchworkGround",
    "ReferenceClusters",
    "ReferenceGround",
    "SklearnClusters",
]
