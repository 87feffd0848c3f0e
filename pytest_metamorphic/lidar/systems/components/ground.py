"""Ground segmenters as systems under test: a frame in, a ground label for every return out.

* :class:`PatchworkGround` - Patchwork++ (Lee et al., RA-L 2022; ``pip install
  pypatchworkpp``): region-wise plane fits on a concentric zone model, with adaptive
  thresholds learnt from earlier sweeps.
* :class:`Open3DPlaneGround` - one RANSAC plane (``open3d``'s ``segment_plane``), the
  prototype every tutorial starts with.
* :class:`ReferenceGround` - the reference pipeline's ground stage (a local-minimum grid).

Each returns :class:`~pytest_metamorphic.lidar.model.point_outputs.PointLabels`
(``GROUND`` = 1, ``NOT_GROUND`` = 0), in the cloud's order.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import GROUND, NOT_GROUND, PointLabels
from pytest_metamorphic.lidar.systems.perception.ground import GroundParams, ground_heights

__all__ = ["Open3DPlaneGround", "PatchworkGround", "ReferenceGround", "require"]


def require(module: str, package: str, component: str) -> Any:
    """Import an optional library, or say which package the component needs."""
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise InvalidArgument(
            f"{component} needs {package} ({error}); install it with "
            f"pip install {package} (or pytest-metamorphic[components])"
        ) from None


def _frame(value: Any, component: str) -> Frame:
    if not isinstance(value, Frame):
        raise InvalidArgument(f"{component} is called on a Frame, got {type(value).__name__}")
    return value


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence a C++ library's own prints (Patchwork++ announces every construction)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _labels(count: int, ground: Any) -> PointLabels:
    labels = np.full(count, NOT_GROUND, dtype=np.int64)
    labels[np.asarray(ground, dtype=np.intp)] = GROUND
    return PointLabels(labels)


class PatchworkGround:
    """Patchwork++ on a frame's points (x, y, z, intensity).

    Parameters
    ----------
    params : mapping, optional
        Attributes of ``pypatchworkpp.Parameters`` to set (``sensor_height``,
        ``num_sectors_each_zone``, ...); the library's defaults are KITTI's HDL-64E
        mounted 1.723 m up.
    reuse : bool
        Keep one estimator across calls, as a running stack does. Patchwork++ adapts its
        thresholds to what it has seen: on KITTI sweep 000001 a reused estimator labels 23
        returns differently on its first call than on its second (later calls agree with
        the second, whatever sweeps came between). The default (False) makes a fresh one
        per call, so that a per-sweep relation judges the sweep alone.
    """

    name = "patchwork++"

    def __init__(self, params: Mapping[str, Any] | None = None, *, reuse: bool = False) -> None:
        self._library = require("pypatchworkpp", "pypatchworkpp", "PatchworkGround")
        self.settings = dict(params or {})
        probe = self._library.Parameters()
        for key, value in self.settings.items():
            if not hasattr(probe, key):
                raise InvalidArgument(f"pypatchworkpp.Parameters has no field {key!r}")
            setattr(probe, key, value)
        probe.verbose = False
        self._params = probe
        self.reuse = bool(reuse)
        self._estimator: Any = None

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v!r}" for k, v in self.settings.items())
        return f"PatchworkGround({shown}{', ' if shown else ''}reuse={self.reuse})"

    def _made(self) -> Any:
        if self._estimator is not None and self.reuse:
            return self._estimator
        with _quiet_stdout():
            estimator = self._library.patchworkpp(self._params)
        self._estimator = estimator
        return estimator

    def __call__(self, frame: Any) -> PointLabels:
        frame = _frame(frame, "PatchworkGround")
        points = np.ascontiguousarray(frame.cloud.points[:, :4], dtype=np.float32)
        estimator = self._made()
        if len(points) == 0:
            return PointLabels(np.empty(0, dtype=np.int64))
        estimator.estimateGround(points)
        return _labels(len(points), estimator.getGroundIndices())


class Open3DPlaneGround:
    """The largest plane found by Open3D's RANSAC (``PointCloud.segment_plane``) as ground.

    Parameters
    ----------
    distance : float
        Inlier distance to the plane, metres (Open3D's ``distance_threshold``).
    ransac_n, iterations : int
        Points per hypothesis and hypotheses tried.
    seed : int or None
        Seeds Open3D's random generator before each call (``open3d.utility.random.seed``);
        None leaves it alone, as most prototypes do: then two calls on one sweep may
        disagree.
    """

    name = "open3d-plane"

    def __init__(
        self,
        *,
        distance: float = 0.2,
        ransac_n: int = 3,
        iterations: int = 200,
        seed: int | None = 0,
    ) -> None:
        self._o3d = require("open3d", "open3d", "Open3DPlaneGround")
        if not distance > 0:
            raise InvalidArgument(f"distance={distance!r} must be > 0 metres")
        for value, label in ((ransac_n, "ransac_n"), (iterations, "iterations")):
            if (
                isinstance(value, bool)
                or not isinstance(value, int)
                or value < (3 if label == "ransac_n" else 1)
            ):
                raise InvalidArgument(
                    f"{label}={value!r} must be an int (ransac_n >= 3, iterations >= 1)"
                )
        self.distance, self.ransac_n, self.iterations, self.seed = (
            distance,
            ransac_n,
            iterations,
            seed,
        )

    def __repr__(self) -> str:
        return (
            f"Open3DPlaneGround(distance={self.distance}, ransac_n={self.ransac_n}, "
            f"iterations={self.iterations}, seed={self.seed})"
        )

    def __call__(self, frame: Any) -> PointLabels:
        frame = _frame(frame, "Open3DPlaneGround")
        xyz = frame.cloud.xyz.astype(np.float64)
        if len(xyz) < self.ransac_n:
            return PointLabels(np.full(len(xyz), NOT_GROUND, dtype=np.int64))
        if self.seed is not None:
            self._o3d.utility.random.seed(int(self.seed))
        cloud = self._o3d.geometry.PointCloud(self._o3d.utility.Vector3dVector(xyz))
        _, inliers = cloud.segment_plane(self.distance, self.ransac_n, self.iterations)
        return _labels(len(xyz), inliers)


class ReferenceGround:
    """The reference pipeline's ground stage: a return within ``tolerance`` of the local
    ground height (:func:`~pytest_metamorphic.lidar.systems.perception.ground.ground_heights`)
    is ground."""

    name = "reference-ground"

    def __init__(self, params: GroundParams | None = None) -> None:
        if params is not None and not isinstance(params, GroundParams):
            raise InvalidArgument(f"params={params!r} must be a GroundParams")
        self.params = params or GroundParams()

    def __repr__(self) -> str:
        return "ReferenceGround()"

    def __call__(self, frame: Any) -> PointLabels:
        frame = _frame(frame, "ReferenceGround")
        xyz = frame.cloud.xyz
        height = ground_heights(xyz, self.params)
        return PointLabels((xyz[:, 2] < height + self.params.tolerance).astype(np.int64) * GROUND)
