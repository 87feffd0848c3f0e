"""Strategy building blocks: ROI containment, MR1 noise injection, HDL-64E scene rendering.

* containment of a ~120k-point HDL-64E sweep in Apollo's real ROI-filter polygons
  (``../shared/data/apollo/hdmap_roi_filter/poly_mask_ut.poly``; a generated crossroads
  when the data is absent): the 0.25 m bitmap lookup (what Apollo does), the exact test,
  and matplotlib's ``Path.contains_points`` as the baseline, all measured in this run;
* MR1 noise, n = 1000 points outside the ROI, built from seeds and appended to the frame
  (per follow-up of a prepared frame; preparing it and a one-off follow-up are shown
  too); the same through Hypothesis (drawing the seeds) is shown per example, for scale;
* rendering a ~120k-point street scene (4 obstacles, 3 background objects) with Embree,
  and with the numpy fallback for comparison.

Times are medians of repeated runs (the machine may be shared; the minimum is shown too).

Where the time goes (cProfile and step timers on the idle 2-core machine, 2026-11-26):

* raster lookup, 0.7 ms per 116k points (2026-11-27; 1.0 ms before): x and y converted to
  float64, the range test and the cell arithmetic in place, then one flat bitmap lookup,
  all in blocks of 16k points whose temporaries are reused. With whole-sweep float64
  temporaries, fresh memory on every call, their page faults were half of the lookup
  (with glibc's heap kept, ``MALLOC_TOP_PAD_``, the old code took 0.8 ms of its 1.7 in
  the perception pipeline).
* noise n = 1000 (2026-11-27): 0.22-0.25 ms per follow-up, 0.35-0.38 ms for a one-off
  one (0.41-0.44 before). The frame's z and intensity ranges (one folded pass over the sweep,
  ``column_bounds``, 0.11 ms) are the frame's, not the follow-up's: ``prepare`` computes
  them once per source, as the strategies and relations now do (they computed them three
  times for a strategy and its first draw). Per follow-up: hashing the seeds into
  positions, 0.12 ms (0.15: the hash now works in place, and only the ~1 % of positions
  beyond the range are redrawn and scattered, not all of them), and the copy of the
  sweep and its fields into the follow-up, 0.08 ms (a follow-up must not alias its
  source, which the engine keeps; a preallocated buffer shared by follow-ups would let
  one overwrite another that a report or artifact still holds). Through Hypothesis a
  follow-up costs more than our work: ~2.4 ms per example for an exact n = 1000 (10
  chunk seeds), ~34 ms when each of the 1000 points is a drawn seed (what a shrinkable
  range draws; an exact n did so before 2026-11-27, and two such follow-ups per source
  failed Hypothesis' large_base_example health check).
* render, 27 ms: Embree's ray cast of 133k rays is 9 ms (scene build 0.6 ms); the rest
  was numpy on ~116k hits: trimesh's ``intersects_id`` bookkeeping, fancy indexing of
  (n, 3) arrays (``np.take`` is 4-6x faster), strided row sums, unitising the same rays
  every time and re-sorting already sorted hits. Now: plane-line ranges with trimesh's
  own arithmetic (bit-identical points), rows gathered with ``np.take``, sums column by
  column in numpy's order, the sweep's rays and their unit vectors built once per layout.

    python bench/strategies.py [--repeat N]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from hypothesis import Phase, given, settings
from hypothesis.strategies import SearchStrategy
from matplotlib.path import Path as MplPath

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pytest_metamorphic.lidar.followups.perturb import NoiseOutsideROI  # noqa: E402
from pytest_metamorphic.lidar.model.obstacles import SIZE_PRIORS, Box, Label  # noqa: E402
from pytest_metamorphic.lidar.roi import ROI  # noqa: E402
from pytest_metamorphic.lidar.synthetic import (  # noqa: E402
    BackgroundObject,
    Obstacle,
    Scene,
    default_engine,
    render,
)
from pytest_metamorphic.strategies import noise_outside_roi  # noqa: E402

DATA = Path(os.environ.get("PYTEST_METAMORPHIC_DATA", ROOT.parent / "shared" / "data"))
APOLLO_POLY = DATA / "apollo" / "hdmap_roi_filter" / "poly_mask_ut.poly"


def timed(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """(median, min) wall time in milliseconds over ``repeat`` calls, after one warm-up."""
    fn()
    samples = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        samples.append((time.perf_counter() - start) * 1e3)
    return statistics.median(samples), min(samples)


def per_example_ms(strategy: SearchStrategy[object], examples: int = 30) -> float:
    """Milliseconds per example of a @given test that only draws from ``strategy``."""
    count = 0

    @settings(database=None, max_examples=examples, phases=[Phase.generate], deadline=None)
    @given(strategy)
    def draw(_: object) -> None:
        nonlocal count
        count += 1

    start = time.perf_counter()
    draw()
    return (time.perf_counter() - start) * 1e3 / max(count, 1)


def street(roi: ROI) -> Scene:
    h = 1.73

    def on_ground(x: float, y: float, label: Label, yaw: float = 0.0) -> Obstacle:
        size = SIZE_PRIORS[label].mean
        return Obstacle(Box((x, y, -h + size[2] / 2), size, yaw, label))

    return Scene(
        sensor_height=h,
        roi=roi,
        obstacles=(
            on_ground(12, 2, "car", 0.2),
            on_ground(9, -3, "pedestrian"),
            on_ground(20, -1, "cyclist", 1.0),
            on_ground(30, 3, "car"),
        ),
        background=(
            BackgroundObject("building", (25, 22), (14, 10, 8), yaw=0.3),
            BackgroundObject("pole", (15, -9), (0.3, 0.3, 6)),
            BackgroundObject("tree", (30, -14), (4, 4, 7)),
        ),
        name="bench street",
    )


def load_roi() -> tuple[ROI, str]:
    if APOLLO_POLY.exists():
        return ROI.from_apollo_poly(
            APOLLO_POLY
        ), "Apollo poly_mask_ut.poly (2 polygons, 161 vertices)"
    arms = [
        [[-120, -6], [120, -6], [120, 6], [-120, 6]],
        [[-6, -120], [6, -120], [6, 120], [-6, 120]],
    ]
    return ROI.from_polygons(arms), "generated crossroads (shared data absent)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args()
    repeat = max(3, args.repeat)

    roi, roi_name = load_roi()
    road = ROI.from_polygons([[[-120, -7], [120, -7], [120, 7], [-120, 7]]])
    frame = render(street(road))
    xy = frame.cloud.points[:, :2]
    n_points = len(xy)

    # -- containment ------------------------------------------------------------------------
    roi.contains(xy)  # build and cache the bitmaps (Apollo builds its bitmap once per frame)
    roi.contains(xy, method="exact")
    paths = [MplPath(polygon) for polygon in roi.polygons]
    xy64 = xy.astype(np.float64)

    def matplotlib_baseline() -> np.ndarray:
        inside = np.zeros(len(xy64), dtype=bool)
        for path in paths:
            inside |= path.contains_points(xy64)
        return inside

    exact = roi.contains(xy, method="exact")
    assert np.array_equal(exact, matplotlib_baseline()), "exact and matplotlib disagree"
    raster_agree = float(np.mean(roi.contains(xy) == exact))
    raster_ms = timed(lambda: roi.contains(xy), repeat)
    exact_ms = timed(lambda: roi.contains(xy, method="exact"), repeat)
    mpl_ms = timed(matplotlib_baseline, repeat)
    build_ms = timed(lambda: ROI.from_polygons(roi.polygons).bitmap, max(3, repeat // 3))

    # -- noise injection -----------------------------------------------------------------------
    seeds = np.random.default_rng(0).integers(0, 2**32, 1000)
    NoiseOutsideROI.from_seeds(frame, seeds)  # free-cell list is cached on the ROI
    # A strategy or relation prepares each source frame once (its z and intensity
    # ranges), then builds every follow-up of it from seeds: the per-follow-up cost.
    prepared = NoiseOutsideROI.prepare(frame)
    noise_ms = timed(lambda: prepared.from_seeds(seeds).apply(frame), repeat)
    prepare_ms = timed(lambda: NoiseOutsideROI.prepare(frame), repeat)
    cold_ms = timed(lambda: NoiseOutsideROI.from_seeds(frame, seeds).apply(frame), repeat)
    # The whole follow-up through Hypothesis (draw, inject, wrap), per example of a running
    # @given test, for scale: an exact n is drawn as 10 chunk seeds, a range as one seed
    # per point (so that shrinking can delete points).
    chunked_ms = per_example_ms(noise_outside_roi(frame, n=1000))
    per_point_ms = per_example_ms(noise_outside_roi(frame, min_size=1000, max_size=1000))

    # -- rendering -------------------------------------------------------------------------------
    scene = street(road)
    engine = default_engine()
    render_ms = timed(lambda: render(scene), max(3, repeat // 2))
    numpy_ms = timed(lambda: render(scene, engine="numpy"), 3)

    speedup = mpl_ms[0] / raster_ms[0]
    rows = [
        ("ROI", "", roi_name),
        ("points (HDL-64E render)", f"{n_points:>11}", ""),
        (
            "raster lookup (Apollo 0.25 m bitmap)",
            f"{raster_ms[0]:8.2f} ms",
            f"min {raster_ms[1]:.2f}",
        ),
        ("exact even-odd (grid-accelerated)", f"{exact_ms[0]:8.2f} ms", f"min {exact_ms[1]:.2f}"),
        ("matplotlib Path.contains_points", f"{mpl_ms[0]:8.2f} ms", f"min {mpl_ms[1]:.2f}"),
        (
            "raster speed-up vs matplotlib",
            f"{speedup:8.1f} x",
            f"target >= 20x (ratio of minima: {mpl_ms[1] / raster_ms[1]:.1f} x)",
        ),
        ("raster == exact on these points", f"{100 * raster_agree:8.3f} %", ""),
        ("bitmap scan conversion (once per ROI)", f"{build_ms[0]:8.2f} ms", ""),
        (
            "MR1 noise n=1000: seeds -> points -> frame",
            f"{noise_ms[0]:8.2f} ms",
            "target <= 0.3 ms (per follow-up)",
        ),
        ("  preparing a frame, once per source", f"{prepare_ms[0]:8.2f} ms", "z/intensity ranges"),
        ("  both: from_seeds(frame, seeds).apply", f"{cold_ms[0]:8.2f} ms", "one-off follow-up"),
        ("  through Hypothesis, n=1000 (chunk seeds)", f"{chunked_ms:8.2f} ms", "per example"),
        ("  through Hypothesis, 1000 shrinkable seeds", f"{per_point_ms:8.2f} ms", "per example"),
        (f"render ~120k-point scene ({engine})", f"{render_ms[0]:8.2f} ms", "target <= 30 ms"),
        ("render same scene (numpy fallback)", f"{numpy_ms[0]:8.2f} ms", f"{len(frame.cloud)} pts"),
    ]
    width = max(len(name) for name, _, _ in rows)
    print(f"{'measurement':<{width}}  {'value':>14}  note")
    print("-" * (width + 32))
    for name, value, note in rows:
        print(f"{name:<{width}}  {value:>14}  {note}")
    print(
        f"RESULT roi_speedup_vs_mpl={speedup:.2f} noise1000_ms={noise_ms[0]:.3f} "
        f"noise_prepare_ms={prepare_ms[0]:.3f} noise1000_unprepared_ms={cold_ms[0]:.3f} "
        f"render_ms={render_ms[0]:.1f}"
    )


if __name__ == "__main__":
    main()
