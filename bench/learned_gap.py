"""How the learned detector's training sweeps differ from real ones, measured without labels.

The rows of the model card's "How it was chosen" table (``docs/learned-model.md``), on the
two unlabelled KITTI crops of the shared data (mmdetection3d's 000008, PointPillars'
testing 000002: no quality number counts them) against the HDL-64E sweeps of held-out
training scenes (``held_out_frame(i)``'s scenes), as the renderer gives them ("rendered")
and as training sees them after ``degrade`` ("degraded"). Everything in KITTI's camera
wedge (x > 0, azimuth within 40 degrees), the ground found by the detectors' own
estimator (``perception.ground.ground_heights``, a return within 0.25 m of it is ground),
the same estimator on every sweep; a road return is a ground return at least 1.4 m
under the sensor (KITTI's HDL-64E is 1.73 m above the road; near a camera crop's lower
edge, where the road is out of sight, the lowest return of a car would be its own ground):

* road intensity: median intensity of road returns 5-40 m away;
* zero share: the share of the returns above the ground, 5-40 m away, that read exactly 0;
* road density: road returns per m² of the wedge 20-30 m and 30-45 m away;
* nearest road: the nearest road return and its elevation angle;
* car return share: car-shaped clusters within 40 m (returns 0.25-2.5 m above the
  ground, 8-connected on 0.25 m cells, footprint 2.5-5.5 x at most 2.3 m along its
  principal axes, 1.1-2.0 m tall, at least 30 returns): the returns over the rays
  its outline spans (the HDL-64E's lasers between its lowest and highest elevation times
  its azimuth span over the sweep's azimuth step, the median gap between neighbouring
  returns of one laser);
* window band: the share of such a cluster's returns 60-90 % of its height above the
  ground, where a real car has its windows and the renderer's cabin is solid (glass lets
  a beam through to the seats or the far side, or reflects it away);
* surface return share: on surfaces above the ground (returns more than 0.3 m up),
  5-40 m and 40-70 m away, the share of a laser's rays that return between two returns
  of one surface (neighbours in azimuth on one laser, ranges within 2 % or 0.3 m, at most
  6 steps apart): whether far surfaces lose returns a render keeps (a laser is the
  sweep's ``ring`` field, or on a KITTI file, whose points run laser by laser, the run
  between two jumps in azimuth);
* the shipped model on the same sweeps (``--detector``, whole-sweep features, no ROI,
  without ``CNNSegParams.max_lift``, which drops what floats): the share of those car-shaped
  clusters with a reported car whose centre lies within 2 m of theirs, a label-free hint
  of recall; how far that car's heading is from the cluster's long axis (degrees, 0-90;
  a 3.9 x 1.6 m box turned 20 degrees about its centre keeps BEV IoU 0.66 with itself,
  30 degrees 0.56, so with any offset or size error it misses 0.5); and cars per sweep
  whose box floats more than 1 m above the ground under it (a symptom of wall tops and
  foliage read as cars, what ``max_lift`` was chosen on).

Ends with ``RESULT`` keys, each ``<measure>_real`` (both crops together) and
``<measure>_degraded`` (the held-out sweeps together).

    python bench/learned_gap.py [--scenes 60] [--detector] [--model cnnseg.onnx]
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pytest_metamorphic.lidar.io.bin import read_bin  # noqa: E402
from pytest_metamorphic.lidar.model.frame import Frame  # noqa: E402
from pytest_metamorphic.lidar.model.sensors import HDL64E  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.clustering import cluster_points  # noqa: E402
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import (  # noqa: E402
    CAMERA_HALF_WIDTH,
    HELD_OUT_SEED_OFFSET,
    HELD_OUT_STREETS,
    training_render,
)
from pytest_metamorphic.lidar.systems.perception.ground import ground_heights  # noqa: E402

sys.path.insert(0, str(ROOT / "bench"))
from learned import UNLABELLED  # noqa: E402

# The unlabelled crops bench/learned.py also runs MR1 on, by name (000002, 000008).
CROPS = {path.stem: path for path in sorted(UNLABELLED, key=lambda path: path.stem)}
WEDGE = math.radians(CAMERA_HALF_WIDTH)  # KITTI's camera wedge, as degrade cuts it
GROUND_TOLERANCE = 0.25  # metres: the ground estimator's own tolerance
ROAD_BELOW = 1.4  # metres under the sensor a road return lies (KITTI's: 1.73 m up)
LASERS = np.sort(HDL64E.elevations)


@dataclass
class Gap:
    """What one group of sweeps measures (lists hold one value per sweep or per car)."""

    road_intensity: list[float] = field(default_factory=list)
    zero_share: list[float] = field(default_factory=list)
    density_20_30: list[float] = field(default_factory=list)
    density_30_45: list[float] = field(default_factory=list)
    nearest_road: list[float] = field(default_factory=list)
    nearest_elevation: list[float] = field(default_factory=list)
    car_share: list[float] = field(default_factory=list)
    car_window_band: list[float] = field(default_factory=list)
    surface_near: list[float] = field(default_factory=list)
    surface_far: list[float] = field(default_factory=list)
    cars_found: list[bool] = field(default_factory=list)
    heading_error: list[float] = field(default_factory=list)
    floating_cars: list[int] = field(default_factory=list)


def _azimuth_step(points: np.ndarray, row: np.ndarray) -> float:
    """The sweep's azimuth step: the median gap between neighbouring returns of a laser."""
    azimuth = np.arctan2(points[:, 1], points[:, 0])
    order = np.lexsort((azimuth, row))
    gaps = np.diff(azimuth[order])
    same = np.diff(row[order]) == 0
    gaps = gaps[same & (gaps > 1e-6)]
    return float(np.median(gaps)) if len(gaps) else math.radians(0.18)


def _lasers(frame: Frame) -> np.ndarray:
    """Each return's laser: the ``ring`` field, or on a KITTI file (which holds its
    returns laser by laser, each in azimuth order) the run between two jumps in azimuth.
    Not ``derive_rings``: a camera crop cuts each laser's revolution, which its
    scan-order recovery (whole revolutions) does not recognise, and rings by elevation
    are off by a few on a real unit; a run here is a laser's part of the crop."""
    ring = frame.cloud.fields.get("ring")
    if ring is not None:
        return np.asarray(ring, dtype=np.int64)
    points = np.asarray(frame.cloud.points)
    azimuth = np.arctan2(points[:, 1], points[:, 0])
    starts = np.zeros(len(points), dtype=np.int64)
    starts[1:] = np.abs(np.diff(azimuth)) > math.radians(5.0)
    return np.cumsum(starts)


def _surface_share(points: np.ndarray, lasers: np.ndarray, above: np.ndarray, low: float,
                   high: float) -> float | None:  # fmt: skip
    """Rays that return over rays spanned between neighbouring returns of one surface."""
    distance = np.hypot(points[:, 0], points[:, 1])
    azimuth = np.arctan2(points[:, 1], points[:, 0])
    spanned = missing = 0
    for laser in np.unique(lasers):
        index = np.flatnonzero(lasers == laser)
        index = index[np.argsort(azimuth[index])]
        steps = np.diff(azimuth[index])
        if np.count_nonzero(steps > 1e-5) < 5:
            continue
        # The laser's azimuth step: most neighbouring returns are one step apart.
        rays = np.round(steps / np.percentile(steps[steps > 1e-5], 25)).astype(np.int64)
        a, b = index[:-1], index[1:]
        surface = (above[a] > 0.3) & (above[b] > 0.3) & (rays >= 1) & (rays <= 6)
        surface &= np.abs(distance[a] - distance[b]) < np.maximum(0.3, 0.02 * distance[a])
        surface &= (distance[a] >= low) & (distance[a] < high)
        spanned += int(rays[surface].sum())
        missing += int((rays[surface] - 1).sum())
    return 1.0 - missing / spanned if spanned >= 50 else None


def _car_clusters(points: np.ndarray, above: np.ndarray) -> list[np.ndarray]:
    """Indices of each car-shaped cluster within 40 m (see the module docstring)."""
    candidate = np.flatnonzero((above > 0.25) & (above < 2.5)
                               & (np.hypot(points[:, 0], points[:, 1]) < 40.0))  # fmt: skip
    clusters = cluster_points(points[candidate, :2])
    cars = []
    for label in range(clusters.count):
        members = candidate[clusters.labels == label]
        if len(members) < 30:
            continue
        xy = points[members, :2] - points[members, :2].mean(axis=0)
        _, _, axes = np.linalg.svd(xy, full_matrices=False)
        extent = np.ptp(xy @ axes.T, axis=0)
        tall = float(np.max(above[members]))
        if 2.5 <= extent[0] <= 5.5 and extent[1] <= 2.3 and 1.1 <= tall <= 2.0:
            cars.append(members)
    return cars


def _car_share(points: np.ndarray, members: np.ndarray, step: float) -> float:
    """Returns over the rays the cluster's outline spans."""
    xyz = points[members, :3]
    distance = np.hypot(xyz[:, 0], xyz[:, 1])
    elevation = np.arctan2(xyz[:, 2], distance)
    lasers = int(np.searchsorted(LASERS, elevation.max(), side="right")
                 - np.searchsorted(LASERS, elevation.min(), side="left"))  # fmt: skip
    azimuth = np.unwrap(np.sort(np.arctan2(xyz[:, 1], xyz[:, 0])))
    rays = max(lasers, 1) * (np.ptp(azimuth) / step + 1.0)
    return float(min(1.0, len(members) / rays))


def _window_band(above: np.ndarray) -> float:
    """The share of a cluster's returns 60-90 % of its height above the ground: its
    windows on a real car (the renderer's cabin is solid)."""
    height = above / np.max(above)
    return float(np.mean((height >= 0.6) & (height < 0.9)))


def measure(frame: Frame, gap: Gap, detector: object | None) -> None:
    """Add one sweep's measures to ``gap``."""
    points = np.asarray(frame.cloud.points, dtype=np.float64)
    wedge = (points[:, 0] > 0) & (np.abs(np.arctan2(points[:, 1], points[:, 0])) < WEDGE)
    lasers = _lasers(frame)[wedge]
    points = points[wedge]
    ground_z = ground_heights(points[:, :3].astype(np.float32)).astype(np.float64)
    above = points[:, 2] - ground_z
    ground = above < GROUND_TOLERANCE
    distance = np.hypot(points[:, 0], points[:, 1])
    near = (distance >= 5.0) & (distance <= 40.0)
    # Where the road is out of sight (a camera crop's near edge) the lowest return of a
    # car is its own ground: road returns must also lie 1.4 m under the sensor (KITTI's
    # is 1.73 m above the road).
    road = ground & (points[:, 2] < -ROAD_BELOW)
    intensity = points[:, 3]
    if np.any(road & near):
        gap.road_intensity.append(float(np.median(intensity[road & near])))
    if np.any(~ground & near):
        gap.zero_share.append(float(np.mean(intensity[~ground & near] == 0.0)))
    for low, high, into in ((20.0, 30.0, gap.density_20_30), (30.0, 45.0, gap.density_30_45)):
        area = WEDGE * (high**2 - low**2)  # the sector's 2 * WEDGE radians
        into.append(np.count_nonzero(road & (distance >= low) & (distance < high)) / area)
    if np.any(road):
        nearest = int(np.argmin(np.where(road, distance, np.inf)))
        gap.nearest_road.append(float(distance[nearest]))
        gap.nearest_elevation.append(
            math.degrees(math.atan2(points[nearest, 2], distance[nearest]))
        )
    elevation = np.arctan2(points[:, 2], np.maximum(distance, 0.1))
    row = np.abs(elevation[:, None] - LASERS[None, :]).argmin(axis=1)
    step = _azimuth_step(points, row)
    cars = _car_clusters(points, above)
    gap.car_share.extend(_car_share(points, members, step) for members in cars)
    gap.car_window_band.extend(_window_band(above[members]) for members in cars)
    for (low, high), into in (((5.0, 40.0), gap.surface_near), ((40.0, 70.0), gap.surface_far)):
        share = _surface_share(points, lasers, above, low, high)
        if share is not None:
            into.append(share)
    if detector is not None:
        _judge_detections(frame, points, cars, gap, detector)


def _judge_detections(
    frame: Frame, points: np.ndarray, cars: list[np.ndarray], gap: Gap, detector: object
) -> None:
    # No ROI on either side: the crops have none, and a rendered street's ROI (its road)
    # would hide what the network reports over walls and hedges beside it.
    boxes = [b for b in detector(frame.cloud, None) if b.label == "car"]  # type: ignore[operator]
    centres = np.array([b.center[:2] for b in boxes]).reshape(-1, 2)
    for members in cars:
        xy = points[members, :2]
        centre = xy.mean(axis=0)
        distance = np.hypot(*(centres - centre).T) if len(centres) else np.array([np.inf])
        gap.cars_found.append(float(np.min(distance)) < 2.0)
        if gap.cars_found[-1]:
            axis = np.linalg.svd(xy - centre, full_matrices=False)[2][0]
            off = boxes[int(np.argmin(distance))].yaw - math.atan2(axis[1], axis[0])
            gap.heading_error.append(abs(math.degrees(math.remainder(off, math.pi))))
    wedge_boxes = [b for b in boxes if b.center[0] > 0
                   and abs(math.atan2(b.center[1], b.center[0])) < WEDGE]  # fmt: skip
    if not wedge_boxes:
        gap.floating_cars.append(0)
        return
    all_points = np.asarray(frame.cloud.points[:, :3], dtype=np.float32)
    probes = np.array([[*b.center[:2], b.center[2] - b.size[2] / 2] for b in wedge_boxes])
    under = ground_heights(np.vstack([all_points, probes.astype(np.float32)]))[-len(probes) :]
    lift = probes[:, 2] - under
    gap.floating_cars.append(int(np.count_nonzero(np.isfinite(lift) & (lift > 1.0))))


def _summary(values: list[float], digits: int = 2) -> str:
    if not values:
        return "n/a"
    low, mid, high = np.percentile(values, [0, 50, 100])
    return f"{low:.{digits}f}-{high:.{digits}f} (median {mid:.{digits}f}, n={len(values)})"


ROWS = (
    ("road intensity, 5-40 m (median)", "road_intensity", 2),
    ("returns above the road reading exactly 0", "zero_share", 2),
    ("road returns per m², 20-30 m", "density_20_30", 1),
    ("road returns per m², 30-45 m", "density_30_45", 1),
    ("nearest road return, m", "nearest_road", 1),
    ("its elevation, degrees", "nearest_elevation", 1),
    ("share of a car's rays that return (car-shaped clusters, 40 m)", "car_share", 2),
    ("share of its returns 60-90 % of its height up (its windows)", "car_window_band", 2),
    ("share of rays that return on surfaces above the ground, 5-40 m", "surface_near", 3),
    ("the same, 40-70 m", "surface_far", 3),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=int, default=60, help="held-out scenes to draw")
    parser.add_argument("--detector", action="store_true", help="also run the shipped detector")
    parser.add_argument("--model", default=None, help="another ONNX model for --detector")
    args = parser.parse_args()
    detector = None
    if args.detector:
        from pytest_metamorphic.lidar.systems.perception.cnnseg import (
            CNNSegmentation,
            CNNSegParams,
        )

        # Without max_lift, which drops what floats: the symptom is what it was chosen on.
        detector = CNNSegmentation(True, network=args.model, params=CNNSegParams(max_lift=None))
    groups: dict[str, Gap] = {}
    for name, path in CROPS.items():
        if not path.is_file():
            sys.exit(f"{path} is missing: the gap is measured on the unlabelled KITTI crops")
        groups[f"crop {name}"] = gap = Gap()
        measure(Frame(read_bin(path), source=str(path)), gap, detector)
    rendered, degraded = Gap(), Gap()
    for index in range(args.scenes):
        raw, seen = training_render(HELD_OUT_SEED_OFFSET + index, streets=HELD_OUT_STREETS)
        if raw.sensor is not HDL64E:
            continue
        measure(raw, rendered, None)
        measure(seen, degraded, detector)
    groups["rendered"], groups["degraded"] = rendered, degraded
    sweeps = len(rendered.road_intensity)
    print(f"== the gap: 2 unlabelled KITTI crops against {sweeps} held-out HDL-64E sweeps ==")
    for label, key, digits in ROWS:
        print(f"\n{label}")
        for name, gap in groups.items():
            print(f"  {name:<12} {_summary(getattr(gap, key), digits)}")
    real = Gap()
    for name in CROPS:
        for key, values in vars(groups[f"crop {name}"]).items():
            getattr(real, key).extend(values)
    keys: dict[str, float] = {}
    for _, key, _ in ROWS:
        keys[f"{key}_real"] = float(np.median(getattr(real, key)))
        keys[f"{key}_degraded"] = float(np.median(getattr(degraded, key)))
    if detector is not None:
        for name, gap in (("real", real), ("degraded", degraded)):
            found, floating = gap.cars_found, gap.floating_cars
            print(f"\n{name}: {sum(found)} of {len(found)} car-shaped clusters with a car "
                  f"within 2 m; {sum(floating)} floating cars in {len(floating)} "
                  "sweeps")  # fmt: skip
            keys[f"cluster_cars_found_{name}"] = float(np.mean(found)) if found else 0.0
            errors = gap.heading_error
            print(f"  their heading against the cluster's long axis: {_summary(errors, 0)} "
                  f"degrees; {sum(e <= 10 for e in errors)} within 10")  # fmt: skip
            keys[f"heading_error_{name}"] = float(np.median(errors)) if errors else math.nan
            keys[f"floating_cars_per_sweep_{name}"] = float(np.mean(floating))
    print("RESULT " + " ".join(f"{key}={value:.4f}" for key, value in keys.items()))


if __name__ == "__main__":
    main()
