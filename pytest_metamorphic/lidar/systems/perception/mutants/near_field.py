"""Faulty variants of the reference pipeline that live in the first metres around the car:
a self-filter cut too wide, a cap on how many returns a cluster may hold, a classifier
that does not know road users close by.

Each is invisible on a recording whose first metres are empty (every KITTI sweep here,
every rendered street): nothing stands there, so the source and every follow-up that
leaves the near field alone agree. Only an object placed there
(:func:`~pytest_metamorphic.lidar.followups.insert.reach.domain_placements`, the
``"near field"`` band of insertion) shows them. See
:mod:`pytest_metamorphic.lidar.systems.perception.mutants` for the list.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.clustering import Clusters
from pytest_metamorphic.lidar.systems.perception.mutants.object_filters import _ClusterFilter
from pytest_metamorphic.lidar.systems.perception.pipeline import ReferencePerception

__all__ = ["NearPedestriansUnknown", "OversizedClusterDrop", "SelfCropMargin"]


class SelfCropMargin(ReferencePerception):
    """Returns within the car's own footprint grown by ``margin`` metres are dropped.

    Every stack crops the returns off its own body (Autoware's ``crop_box_filter`` on the
    vehicle's box: autoware_universe issue #703); a margin meant for mirrors and an open
    door that grows to a metre also drops whatever stands right beside or in front of the
    car, as Autoware's ``no_obstacle_segmentation_area`` ignored obstacles close to the
    car until a ``mandatory_detection_area`` was added (autoware_universe pull request
    #2864). The car is 4.4 x 1.8 m, centred under the sensor.
    """

    name = "self_crop_margin"
    half_length = 2.2
    half_width = 0.9
    margin = 1.0

    def prepare(self, points: NDArray[np.float32]) -> NDArray[np.float32]:
        inside = (np.abs(points[:, 0]) <= self.half_length + self.margin) & (
            np.abs(points[:, 1]) <= self.half_width + self.margin
        )
        return points[~inside]


class OversizedClusterDrop(_ClusterFilter):
    """Clusters of more than ``max_points`` returns are dropped.

    A cluster-size cap guards a tracker's buffers against a whole facade as one object;
    Autoware's voxel-grid clustering applies its ``max_cluster_size`` to the raw returns
    of a cluster and silently drops an oversized one (autoware_core issue #1379;
    autoware_universe pull request #7734 on the same cap). A car 5 m away holds a few
    thousand returns of a 64-beam sensor; a lorry or a bus beside the car holds tens of
    thousands, and is dropped.
    """

    name = "oversized_cluster_drop"
    max_points = 12_000

    def rejects(self, points: NDArray[np.float32], clusters: Clusters) -> NDArray[np.bool_]:
        counts = np.bincount(clusters.labels, minlength=clusters.count)
        return counts > self.max_points


class NearPedestriansUnknown(ReferencePerception):
    """Pedestrians nearer than ``near`` metres (bird's eye, box centre) reported as
    ``"unknown"``.

    A classifier learned on recordings where people are seen from metres away meets a
    person beside the car whose returns are denser than any it was trained on, and says
    "unknown": autoware_universe issue #7563 ("the perception system fails to detect and
    track the pedestrian when they are close to the car; it only recognizes the
    pedestrian once they move away"). An unknown obstacle is still avoided, but it gets
    no pedestrian's motion model: nothing predicts it stepping in front of the car.
    """

    name = "near_pedestrians_unknown"
    near = 6.0

    def review_boxes(self, boxes: list[Box], in_roi: NDArray[np.float32]) -> list[Box]:
        return [
            _relabelled(box)
            if box.label == "pedestrian" and math.hypot(box.center[0], box.center[1]) < self.near
            else box
            for box in boxes
        ]


def _relabelled(box: Box) -> Box:
    return dataclasses.replace(box, label="unknown")
