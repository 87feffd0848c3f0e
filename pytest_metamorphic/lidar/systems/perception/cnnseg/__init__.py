"""A learned system under test: Apollo-style CNN segmentation, trained here, run with
onnxruntime.

``CNNSegmentation(full_cloud=True)(frame) -> list[Box]``. Modules: :mod:`.features`
(Apollo's bird's-eye feature grid), :mod:`.network` (the ONNX model), :mod:`.cluster2d`
(cells grouped by predicted centres), :mod:`.detector` (the stages together),
:mod:`.targets` (training targets from rendered frames) and :mod:`.train` (the training
script; needs PyTorch, never imported by the package).
"""

from __future__ import annotations

from pytest_metamorphic.lidar.systems.perception.cnnseg.cluster2d import (
    cluster_cells,
    predicted_centers,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.detector import (
    CNNSegmentation,
    CNNSegParams,
    Segmentation,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import (
    CHANNELS,
    SHIPPED_GRID,
    GridSpec,
    bev_features,
    point_cells,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.network import (
    CLASSES,
    DEFAULT_MODEL,
    DEVICES,
    NetworkOutput,
    OnnxNetwork,
)

__all__ = [
    "CHANNELS",
    "CLASSES",
    "DEFAULT_MODEL",
    "DEVICES",
    "SHIPPED_GRID",
    "CNNSegParams",
    "CNNSegmentation",
    "GridSpec",
    "NetworkOutput",
    "OnnxNetwork",
    "Segmentation",
    "bev_features",
    "cluster_cells",
    "point_cells",
    "predicted_centers",
]
