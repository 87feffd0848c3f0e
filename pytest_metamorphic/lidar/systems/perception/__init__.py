"""The reference LiDAR obstacle pipeline (a system under test without learned weights).

``ReferencePerception()(cloud, roi) -> list[Box]``: HD-map ROI filter, ground removal,
grid segmentation, Apollo's MinBox builder, rule-based classes. Faulty variants for
mutation testing live in :mod:`.mutants`.
"""

from __future__ import annotations

from pytest_metamorphic.lidar.systems.perception.minbox import MinBox, min_box, min_boxes
from pytest_metamorphic.lidar.systems.perception.mutants import MUTANTS, mutant
from pytest_metamorphic.lidar.systems.perception.pipeline import (
    PerceptionParams,
    ReferencePerception,
    Stages,
)

__all__ = [
    "MUTANTS",
    "MinBox",
    "PerceptionParams",
    "ReferencePerception",
    "Stages",
    "min_box",
    "min_boxes",
    "mutant",
]
