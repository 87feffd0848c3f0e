"""Clusterers as systems under test: a frame in, a cluster for every return out.

A stack clusters the returns its earlier stages left: those in the ROI, minus the ground
(found among the ROI's returns: the ROI is cut first, as Apollo's pipeline does).
Each adapter here takes those stages as arguments (``ground=`` any ground segmenter of
:mod:`.ground` or a callable returning
:class:`~pytest_metamorphic.lidar.model.point_outputs.PointLabels`, ``within_roi=``), clusters
what is left and returns a :class:`~pytest_metamorphic.lidar.model.point_outputs.Partition`
of the whole sweep in the cloud's order (returns it did not cluster are ``NOISE``).

* :class:`SklearnClusters` - any scikit-learn estimator with ``fit_predict``
  (``DBSCAN``, ``HDBSCAN``, ``OPTICS``), cloned for every call;
* :class:`Open3DClusters` - Open3D's ``cluster_dbscan``;
* :class:`ReferenceClusters` - the reference pipeline's grid segmentation.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import GROUND, NOISE, Partition, PointLabels
from pytest_metamorphic.lidar.systems.components.ground import require
from pytest_metamorphic.lidar.systems.perception.clustering import ClusterParams, cluster_points

__all__ = ["ClusterInput", "Open3DClusters", "ReferenceClusters", "SklearnClusters"]

Features = Literal["xyz", "xy"]


class ClusterInput:
    """The returns a clusterer is fed: in the ROI (``within_roi``) and not ground (``ground``).

    Parameters
    ----------
    ground : callable, optional
        ``ground(frame) -> PointLabels``: returns it labels ``GROUND`` are not clustered.
    within_roi : bool
        Cluster only returns inside the frame's ROI.
    features : {"xyz", "xy"}
        Coordinates the clusterer sees (``"xy"``: the bird's-eye view).
    """

    def __init__(
        self,
        *,
        ground: Callable[[Frame], PointLabels] | None = None,
        within_roi: bool = False,
        features: Features = "xyz",
    ) -> None:
        if ground is not None and not callable(ground):
            raise InvalidArgument(f"ground={ground!r} must be a ground segmenter (a callable)")
        if features not in ("xyz", "xy"):
            raise InvalidArgument(f"features={features!r} must be 'xyz' or 'xy'")
        self.ground, self.within_roi, self.features = ground, bool(within_roi), features

    def mask(self, frame: Frame) -> NDArray[np.bool_]:
        """(n,) bool: the returns that are clustered. The ROI is cut first and the ground
        segmenter sees only the returns in it, as in Apollo's pipeline (so nothing outside
        the ROI can change what is clustered)."""
        keep = np.ones(len(frame.cloud), dtype=bool)
        if self.within_roi:
            if frame.roi is None:
                raise InvalidArgument(f"within_roi=True, but frame {frame!r} has no ROI")
            keep &= np.asarray(frame.roi.contains(frame.cloud.xyz[:, :2]), dtype=bool)
        if self.ground is not None:
            rows = np.flatnonzero(keep)
            seen = frame.with_cloud(frame.cloud[rows]) if self.within_roi else frame
            labels = self.ground(seen)
            if not isinstance(labels, PointLabels) or len(labels) != len(rows):
                raise InvalidArgument(
                    f"ground={self.ground!r} must return PointLabels for all {len(rows)} "
                    "returns it is given"
                )
            keep[rows[labels.labels == GROUND]] = False
        return keep

    def describe(self) -> str:
        parts = [f"ground={self.ground!r}"] if self.ground is not None else []
        parts += ["within_roi=True"] if self.within_roi else []
        parts += ["features='xy'"] if self.features == "xy" else []
        return ", ".join(parts)


class _Clusterer:
    name = "clusterer"

    def __init__(self, feed: ClusterInput) -> None:
        self.feed = feed

    def cluster(self, points: NDArray[np.float64]) -> NDArray[np.int64]:
        raise NotImplementedError

    def __call__(self, frame: Any) -> Partition:
        if not isinstance(frame, Frame):
            raise InvalidArgument(
                f"{type(self).__name__} is called on a Frame, got {type(frame).__name__}"
            )
        keep = self.feed.mask(frame)
        labels = np.full(len(keep), NOISE, dtype=np.int64)
        columns = 3 if self.feed.features == "xyz" else 2
        points = frame.cloud.xyz[keep, :columns].astype(np.float64)
        if len(points):
            labels[keep] = self.cluster(points)
        return Partition(labels)


class SklearnClusters(_Clusterer):
    """A scikit-learn clusterer (``fit_predict``), cloned for every call.

    Parameters
    ----------
    estimator
        E.g. ``DBSCAN(eps=0.5, min_samples=5)``, ``HDBSCAN(min_cluster_size=10)``,
        ``OPTICS(min_samples=10)``.
    ground, within_roi, features
        What it is fed (:class:`ClusterInput`).
    """

    name = "sklearn"

    def __init__(
        self,
        estimator: Any,
        *,
        ground: Callable[[Frame], PointLabels] | None = None,
        within_roi: bool = False,
        features: Features = "xyz",
    ) -> None:
        base = require("sklearn.base", "scikit-learn", "SklearnClusters")
        if not callable(getattr(estimator, "fit_predict", None)):
            raise InvalidArgument(
                f"estimator={estimator!r} has no fit_predict (a scikit-learn clusterer)"
            )
        super().__init__(ClusterInput(ground=ground, within_roi=within_roi, features=features))
        self.estimator = estimator
        self._clone = base.clone

    def __repr__(self) -> str:
        rest = self.feed.describe()
        return f"SklearnClusters({self.estimator!r}{', ' if rest else ''}{rest})"

    def cluster(self, points: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.asarray(self._clone(self.estimator).fit_predict(points), dtype=np.int64)


class Open3DClusters(_Clusterer):
    """Open3D's DBSCAN (``PointCloud.cluster_dbscan(eps, min_points)``)."""

    name = "open3d-dbscan"

    def __init__(
        self,
        *,
        eps: float = 0.5,
        min_points: int = 5,
        ground: Callable[[Frame], PointLabels] | None = None,
        within_roi: bool = False,
    ) -> None:
        self._o3d = require("open3d", "open3d", "Open3DClusters")
        if not eps > 0:
            raise InvalidArgument(f"eps={eps!r} must be > 0 metres")
        if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 1:
            raise InvalidArgument(f"min_points={min_points!r} must be an int >= 1")
        super().__init__(ClusterInput(ground=ground, within_roi=within_roi))
        self.eps, self.min_points = float(eps), min_points

    def __repr__(self) -> str:
        rest = ", ".join(filter(None, [f"min_points={self.min_points}", self.feed.describe()]))
        return f"Open3DClusters(eps={self.eps}, {rest})"

    def cluster(self, points: NDArray[np.float64]) -> NDArray[np.int64]:
        cloud = self._o3d.geometry.PointCloud(self._o3d.utility.Vector3dVector(points))
        return np.asarray(cloud.cluster_dbscan(self.eps, self.min_points), dtype=np.int64)


class ReferenceClusters(_Clusterer):
    """The reference pipeline's segmentation: 8-connected occupied cells of a grid
    anchored at the sensor
    (:func:`~pytest_metamorphic.lidar.systems.perception.clustering.cluster_points`)."""

    name = "reference-clusters"

    def __init__(
        self,
        params: ClusterParams | None = None,
        *,
        ground: Callable[[Frame], PointLabels] | None = None,
        within_roi: bool = False,
    ) -> None:
        if params is not None and not isinstance(params, ClusterParams):
            raise InvalidArgument(f"params={params!r} must be a ClusterParams")
        super().__init__(ClusterInput(ground=ground, within_roi=within_roi, features="xy"))
        self.params = params or ClusterParams()

    def __repr__(self) -> str:
        rest = self.feed.describe()
        return f"ReferenceClusters({rest})"

    def cluster(self, points: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.asarray(cluster_points(points, self.params).labels, dtype=np.int64)
