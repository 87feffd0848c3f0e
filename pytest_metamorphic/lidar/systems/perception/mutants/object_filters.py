"""Faulty variants of the reference pipeline: filters that judge a cluster by properties of
its returns (lasers, ranges, reflectance, azimuth fill) to drop ghosts, spray and
vegetation.

Each is a plausible rule from a real stack, tuned on clear, complete sweeps, and each
drops a real object once a sensor fault or the weather changes the property it reads:
a fault relation aimed at that fault should show it (issue 26: "power on faults nobody
wrote for it").
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.lidar.model.cloud import intensity_scale
from pytest_metamorphic.lidar.model.hdl64 import HDL64E
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.systems.perception.clustering import Clusters
from pytest_metamorphic.lidar.systems.perception.pipeline import ReferencePerception

__all__ = ["ConstantRangeFilter", "DimClusterFilter", "FewLasersFilter", "SeeThroughFilter"]


class _ClusterFilter(ReferencePerception):
    """Drops whole clusters, before their boxes are built, by :meth:`rejects`."""

    def rejects(self, points: NDArray[np.float32], clusters: Clusters) -> NDArray[np.bool_]:
        """(count,) bool: the clusters to drop."""
        raise NotImplementedError

    def build_boxes(
        self, points: NDArray[np.float32], ground_z: NDArray[np.float32], clusters: Clusters
    ) -> list[Box]:
        if clusters.count == 0:
            return []
        kept = ~self.rejects(points, clusters)
        rows = kept[clusters.labels]
        renumber = np.cumsum(kept) - 1  # the kept clusters keep their order
        remaining = Clusters(
            labels=renumber[clusters.labels[rows]].astype(np.intp),
            count=int(kept.sum()),
            cells=clusters.cells[kept],
            cell_index=clusters.cell_index[rows],
        )
        return super().build_boxes(points[rows], ground_z[rows], remaining)


def _per_cluster_distinct(
    values: NDArray[np.int64], labels: NDArray[np.intp], count: int
) -> NDArray[np.intp]:
    """(count,) intp: how many distinct ``values`` each cluster's points take."""
    pairs = np.unique(np.column_stack([labels, values]), axis=0)
    return np.bincount(pairs[:, 0], minlength=count)


class FewLasersFilter(_ClusterFilter):
    """Clusters whose returns come from fewer than ``min_lasers`` lasers are dropped as
    ghosts (a single-beam reflection off a wet road or a window).

    The laser of each return is the HDL-64E's beam nearest its elevation. On complete
    sweeps every solid object of 30 returns spans several lasers; a low object (a kerb, a
    low wall, a car's bumper far away) seen by three lasers keeps its top and bottom rows
    when the middle laser dies, and is then dropped although most of its returns remain.
    """

    name = "few_lasers_filter"
    min_lasers = 3

    def rejects(self, points: NDArray[np.float32], clusters: Clusters) -> NDArray[np.bool_]:
        xyz = points[:, :3].astype(np.float64)
        elevation = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
        order = np.argsort(HDL64E.elevations)
        beams = HDL64E.elevations[order]
        right = np.clip(np.searchsorted(beams, elevation), 1, len(beams) - 1)
        nearer_left = elevation - beams[right - 1] < beams[right] - elevation
        laser = np.where(nearer_left, right - 1, right).astype(np.int64)
        lasers = _per_cluster_distinct(laser, clusters.labels, clusters.count)
        return lasers < self.min_lasers


class ConstantRangeFilter(_ClusterFilter):
    """Clusters whose returns take at most ``max_ranges`` distinct ranges (whole
    millimetres) are dropped as ghosts: a multipath echo appears at one constant range.

    At the HDL-64E's 2 mm range steps no real object of a few returns lies at one or two
    ranges; a sensor (or a compressed recording) with coarser range steps puts every
    shallow object there.
    """

    name = "constant_range_filter"
    max_ranges = 2

    def rejects(self, points: NDArray[np.float32], clusters: Clusters) -> NDArray[np.bool_]:
        millimetres = np.round(np.linalg.norm(points[:, :3].astype(np.float64), axis=1) * 1000)
        ranges = _per_cluster_distinct(
            millimetres.astype(np.int64), clusters.labels, clusters.count
        )
        return ranges <= self.max_ranges


class DimClusterFilter(_ClusterFilter):
    """Clusters whose mean intensity is below ``floor`` (of the sweep's intensity scale)
    are dropped as spray or exhaust, which reflect weakly.

    Tuned in clear weather, where no car is that dark on average; fog and rain attenuate
    every return with range, and a car 20 m away whose returns all arrive turns "dim".
    """

    name = "dim_cluster_filter"
    floor = 0.05

    def rejects(self, points: NDArray[np.float32], clusters: Clusters) -> NDArray[np.bool_]:
        intensity = points[:, 3].astype(np.float64) / intensity_scale(points[:, 3])
        total = np.bincount(clusters.labels, weights=intensity, minlength=clusters.count)
        count = np.bincount(clusters.labels, minlength=clusters.count)
        return total / np.maximum(count, 1) < self.floor


class SeeThroughFilter(_ClusterFilter):
    """Clusters spanning at least ``min_span`` degrees of azimuth whose returns fill less
    than ``min_fill`` of the 0.2-degree bearings across them are dropped as vegetation
    (see-through; a hedge's returns are gappy).

    A solid object seen whole fills every bearing it spans (the HDL-64E fires every
    0.17 degrees). A lost packet cuts a 1.04-degree gap into an object close enough that
    the gap does not split its cluster, and the object is then dropped.
    """

    name = "see_through_filter"
    bin_degrees = 0.2
    min_span = 1.0
    min_fill = 0.7

    def rejects(self, points: NDArray[np.float32], clusters: Clusters) -> NDArray[np.bool_]:
        xy = points[:, :2].astype(np.float64)
        bearing = np.arctan2(xy[:, 1], xy[:, 0])
        # Each cluster's bearings relative to its mean direction (no wrap at +-180 degrees).
        sums = np.column_stack(
            [
                np.bincount(clusters.labels, np.cos(bearing), clusters.count),
                np.bincount(clusters.labels, np.sin(bearing), clusters.count),
            ]
        )
        mean = np.arctan2(sums[:, 1], sums[:, 0])
        relative = np.degrees((bearing - mean[clusters.labels] + np.pi) % (2 * np.pi) - np.pi)
        low = np.full(clusters.count, np.inf)
        high = np.full(clusters.count, -np.inf)
        np.minimum.at(low, clusters.labels, relative)
        np.maximum.at(high, clusters.labels, relative)
        bins = np.floor((relative - low[clusters.labels]) / self.bin_degrees).astype(np.int64)
        filled = _per_cluster_distinct(bins, clusters.labels, clusters.count)
        span = high - low
        width = np.floor(span / self.bin_degrees) + 1
        return (span >= self.min_span) & (filled / width < self.min_fill)
