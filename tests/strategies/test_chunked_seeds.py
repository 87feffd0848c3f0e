"""Exact-size noise is drawn as chunk seeds (strategies/_noise.py): whatever Hypothesis
draws or shrinks to, the n point seeds are distinct, so a minimal set of noise points
never holds one point twice."""

from __future__ import annotations

import numpy as np
from hypothesis import find, given
from hypothesis import strategies as st

from pytest_metamorphic.strategies._noise import chunked_seeds


@given(st.data(), st.sampled_from([1, 2, 7, 10, 100, 1000]), st.booleans())
def test_the_seeds_are_distinct_whatever_is_drawn(
    data: st.DataObject, n: int, unique: bool
) -> None:
    seeds, chunks = data.draw(chunked_seeds(n, unique=unique))
    assert len(seeds) == n == len(set(seeds))
    assert len(chunks) == min(n, 10)


def test_shrunk_chunk_seeds_still_give_distinct_points() -> None:
    # Before: shrinking sent the relation library's chunk seeds to [0, 0], and its
    # "proven 1-minimal" set of 2 points was one point twice.
    seeds, chunks = find(chunked_seeds(2, unique=False), lambda drawn: True)
    assert chunks == [0, 0] and len(set(seeds)) == 2
    from pytest_metamorphic.lidar.followups.perturb import NoiseOutsideROI
    from pytest_metamorphic.lidar.model.cloud import PointCloud
    from pytest_metamorphic.lidar.model.frame import Frame
    from pytest_metamorphic.lidar.roi import ROI

    cloud = PointCloud(np.random.default_rng(0).uniform(-20, 20, (500, 4)).astype(np.float32))
    frame = Frame(cloud, roi=ROI.from_polygons([[(-10, -5), (30, -5), (30, 5), (-10, 5)]]))
    points = NoiseOutsideROI.from_seeds(frame, seeds).points
    assert len(np.unique(points, axis=0)) == 2
