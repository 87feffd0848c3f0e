"""The Velodyne HDL-64E beam layout, from a real calibration, for synthetic scans.

The 64 lasers are not evenly spaced: an upper block of 32 spans about +2.0° to -8.6°
(~0.34° apart) and a lower block of 32 about -8.8° to -24.6° (~0.5° apart). Each laser also
has its own azimuth offset of up to ±10° (``rot_correction``). The numbers below are the
``vert_correction`` and ``rot_correction`` of every laser in ros-drivers/velodyne's
``velodyne_pointcloud/params/64e_s3-xiesc.yaml`` (an HDL-64E S3 factory calibration,
radians, listed by ``laser_id``).

The sensor spins at 5-20 Hz firing about 1.3 M points/s; at 10 Hz each laser fires 2083
times per revolution, an azimuth step of 0.1728° (KITTI records ~120k points per sweep).
Range is up to 120 m with about 2 cm accuracy.

Simplifications (documented, deliberate): every beam starts at the sensor origin (the real
lasers sit up to ~2.6 cm sideways and ~21 cm vertically apart), all lasers fire at the same
instant per azimuth step, and the vehicle does not move during a sweep.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["HDL64E", "HDL64E_AZIMUTH_OFFSETS", "HDL64E_ELEVATIONS", "BeamLayout", "Rays"]

# (vert_correction, rot_correction) in radians for laser_id 0..63, from 64e_s3-xiesc.yaml.
_CALIBRATION = (
    (-0.1261818455292898, -0.07648247457737148),
    (-0.11953745909742221, -0.03932070772308096),
    (0.00356118725906175, 0.06005350008746038),
    (0.010306535403103584, 0.09919490315516696),
    (-0.1144967440141401, -0.00095355016485159),
    (-0.10803612329921503, 0.03824387099052699),
    (-0.14944538101702426, -0.015297255529962315),
    (-0.14344353231329066, 0.024255809272700053),
    (-0.10278016723125998, 0.07354442571180776),
    (-0.09569590023202451, 0.11317857886058363),
    (-0.1386345201601863, 0.05954228616823424),
    (-0.13181073657049397, 0.09906092120980835),
    (-0.054438932963427306, -0.07574798243226695),
    (-0.048730533448148504, -0.037047761947550245),
    (-0.08961595328025192, -0.0895955468906376),
    (-0.0839353306800186, -0.05072966149865084),
    (-0.043427018903405855, -0.001864320564407547),
    (-0.03648801216715539, 0.03747852840556422),
    (-0.07906187922560139, -0.015194972429011364),
    (-0.07255814015150577, 0.02391977928648433),
    (-0.031587736747464255, 0.07264374331532833),
    (-0.025460288914769372, 0.11143265968730214),
    (-0.06665878416276627, 0.05942554283989759),
    (-0.06055112836378901, 0.09797042203986979),
    (0.015620435355027301, -0.07658879305408597),
    (0.022567997346205196, -0.0379098725675606),
    (-0.019943931467746017, -0.0904730670226138),
    (-0.013200099491225388, -0.051308328902808065),
    (0.027266617424120905, -0.0019143155208309244),
    (0.03421014630846329, 0.03681404490741569),
    (-0.007885903531460533, -0.015542064486559148),
    (-0.0015491891506552067, 0.023284423588222334),
    (-0.39021216204755743, -0.1278634161583795),
    (-0.38355018793281753, -0.066528586091226),
    (-0.197138848550284, 0.08854290740283328),
    (-0.18768579625563228, 0.14547956884148489),
    (-0.3750836655445631, -0.005071588212420635),
    (-0.36762882325722723, 0.05427589303135225),
    (-0.4285668719175616, -0.028143856558087547),
    (-0.4214410765541042, 0.03172272051181349),
    (-0.3565455112681652, 0.11411698480351568),
    (-0.34717860842539194, 0.1735498527902839),
    (-0.4110102035460227, 0.09564756333839054),
    (-0.40083030888437793, 0.15538288292189534),
    (-0.2840315837972709, -0.12413605610123538),
    (-0.27761533458791926, -0.06413447432303407),
    (-0.3359268721635124, -0.14872602785785152),
    (-0.33026751989087316, -0.08707280959256145),
    (-0.26851710773019805, -0.006799911150716457),
    (-0.26051854302098837, 0.05242808851765633),
    (-0.3216451745070007, -0.028383715411859876),
    (-0.3135280670349956, 0.031843273893907245),
    (-0.24941678290173272, 0.10955275158734502),
    (-0.2409525119882134, 0.16876716543828738),
    (-0.30313513748485243, 0.09037283276367176),
    (-0.29323634555253386, 0.14871534295217081),
    (-0.17760463486977288, -0.12100867217308608),
    (-0.17006926832673774, -0.06431965899265843),
    (-0.22974121500510264, -0.14486168214370612),
    (-0.22391891879349718, -0.0852480451703211),
    (-0.16231529056824404, -0.005967226432828876),
    (-0.15314424682880032, 0.050600613599087636),
    (-0.21457119711920336, -0.027436902217920986),
    (-0.2079266762969834, 0.0290479702718764),
)

HDL64E_ELEVATIONS: NDArray[np.float64] = np.array([v for v, _ in _CALIBRATION])
"""(64,) float64: elevation of each laser in radians, by laser id (positive is up)."""
HDL64E_ELEVATIONS.setflags(write=False)

HDL64E_AZIMUTH_OFFSETS: NDArray[np.float64] = np.array([r for _, r in _CALIBRATION])
"""(64,) float64: per-laser azimuth correction in radians, by laser id."""
HDL64E_AZIMUTH_OFFSETS.setflags(write=False)


@dataclass(frozen=True)
class Rays:
    """One sweep's rays from the sensor origin.

    Attributes
    ----------
    directions : (r, 3) float64
      Unit vectors, laser-major within each azimuth step.
    ring : (r,) uint8
      Laser index of each ray (sorted by elevation, 0 = lowest, as ROS ``ring``).
    azimuth : (r,) float64
      Azimuth of each ray in radians, counter-clockwise from +x.
    """

    directions: NDArray[np.float64]
    ring: NDArray[np.uint8]
    azimuth: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.directions)


@dataclass(frozen=True)
class BeamLayout:
    """A spinning multi-beam LiDAR: per-laser elevations and azimuth offsets, step, range.

    Parameters
    ----------
    name : str
    elevations : (L,) float64
      Radians, positive up.
    azimuth_offsets : (L,) float64
      Radians added to the firing azimuth of each laser (for the HDL-64E, the
      calibration's ``rot_correction``; its sign convention does not matter for a
      synthetic sweep, which covers all azimuths).
    firings_per_revolution : int
      Azimuth steps per sweep.
    max_range, min_range : float
      Returns outside ``[min_range, max_range]`` metres are dropped (HDL-64E: 120 m; the
      0.9 m minimum is our assumption for returns blocked by the housing and vehicle).
    range_noise : float
      Standard deviation of the Gaussian range error in metres.
    """

    name: str
    elevations: NDArray[np.float64] = field(repr=False)
    azimuth_offsets: NDArray[np.float64] = field(repr=False)
    firings_per_revolution: int = 2083
    max_range: float = 120.0
    min_range: float = 0.9
    range_noise: float = 0.02

    def __post_init__(self) -> None:
        elevations = np.array(self.elevations, dtype=np.float64)
        offsets = np.array(self.azimuth_offsets, dtype=np.float64)
        if elevations.ndim != 1 or len(elevations) == 0:
            raise InvalidArgument(
                f"elevations must be a non-empty 1-D array, got {elevations.shape}"
            )
        if offsets.shape != elevations.shape:
            raise InvalidArgument(
                f"azimuth_offsets has shape {offsets.shape}, elevations {elevations.shape}"
            )
        if not (np.isfinite(elevations).all() and (np.abs(elevations) < math.pi / 2).all()):
            raise InvalidArgument("elevations must be finite and within ±90 degrees (radians)")
        if not np.isfinite(offsets).all():
            raise InvalidArgument("azimuth_offsets must be finite")
        steps = self.firings_per_revolution
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise InvalidArgument(f"firings_per_revolution={steps!r} must be a positive int")
        if not (0 <= self.min_range < self.max_range and math.isfinite(self.max_range)):
            raise InvalidArgument(
                f"need 0 <= min_range < max_range < inf, got {self.min_range}, {self.max_range}"
            )
        if not (math.isfinite(self.range_noise) and self.range_noise >= 0):
            raise InvalidArgument(f"range_noise={self.range_noise} must be >= 0")
        elevations.setflags(write=False)
        offsets.setflags(write=False)
        object.__setattr__(self, "elevations", elevations)
        object.__setattr__(self, "azimuth_offsets", offsets)

    @property
    def lasers(self) -> int:
        return len(self.elevations)

    @property
    def azimuth_step(self) -> float:
        """Radians between consecutive firings of one laser."""
        return 2.0 * math.pi / self.firings_per_revolution

    def rays(self, *, azimuth_range: tuple[float, float] | None = None) -> Rays:
        """All rays of one sweep, or of the firings whose azimuth lies in a range.

        Parameters
        ----------
        azimuth_range : (float, float), optional
          ``(start, stop)`` radians; only firing azimuths ``start <= a < stop`` are kept
          (before per-laser offsets). Use it for partial sweeps in fast tests.
        """
        if azimuth_range is None:
            return self._full_sweep
        return self._sweep(azimuth_range)

    @functools.cached_property
    def _full_sweep(self) -> Rays:
        # Every render of a whole sweep casts the same 133k rays: build them once per
        # layout (read-only, since every render shares them).
        rays = self._sweep(None)
        for array in (rays.directions, rays.ring, rays.azimuth):
            array.setflags(write=False)
        return rays

    def __getstate__(self) -> dict[str, Any]:
        # The cached sweep is rebuilt where it is needed, not shipped to workers.
        state = dict(self.__dict__)
        state.pop("_full_sweep", None)
        return state

    def _sweep(self, azimuth_range: tuple[float, float] | None) -> Rays:
        firing = np.arange(self.firings_per_revolution) * self.azimuth_step
        if azimuth_range is not None:
            start, stop = (float(v) for v in azimuth_range)
            if not (math.isfinite(start) and math.isfinite(stop) and start < stop):
                raise InvalidArgument(f"azimuth_range={azimuth_range!r} needs start < stop")
            wrapped = np.mod(firing - start, 2 * math.pi)
            firing = firing[wrapped < stop - start]
        # Rings number lasers from the lowest beam up, as drivers publish them.
        ring_of_laser = np.empty(self.lasers, dtype=np.uint8)
        ring_of_laser[np.argsort(self.elevations, kind="stable")] = np.arange(self.lasers)
        azimuth = (firing[:, None] + self.azimuth_offsets[None, :]).ravel()
        elevation = np.broadcast_to(self.elevations, (len(firing), self.lasers)).ravel()
        ring = np.broadcast_to(ring_of_laser, (len(firing), self.lasers)).ravel()
        cos_e = np.cos(elevation)
        directions = np.stack(
            [cos_e * np.cos(azimuth), cos_e * np.sin(azimuth), np.sin(elevation)], axis=1
        )
        return Rays(directions, np.ascontiguousarray(ring), azimuth)


HDL64E = BeamLayout(
    name="Velodyne HDL-64E S3 (64e_s3-xiesc calibration), 10 Hz",
    elevations=HDL64E_ELEVATIONS,
    azimuth_offsets=HDL64E_AZIMUTH_OFFSETS,
)
"""The HDL-64E at 10 Hz: 64 x 2083 = 133,312 rays per sweep, 120 m range, 2 cm noise."""
