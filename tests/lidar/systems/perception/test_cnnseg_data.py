"""The learned model's training data: degraded as real sweeps are, targets that match
what the network sees, windows on the grid's own cell lattice."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.synthetic import render
from pytest_metamorphic.lidar.synthetic.streetscape import street_scene
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import (
    CROP,
    degrade,
    example,
    training_frame,
)
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import SHIPPED_GRID
from pytest_metamorphic.lidar.systems.perception.cnnseg.targets import cell_targets


@pytest.fixture(scope="module")
def street() -> Frame:
    return render(street_scene(np.random.default_rng(11)), seed=11)


def test_degrading_is_reproducible_and_keeps_box_counts_true(street: Frame) -> None:
    first = degrade(street, np.random.default_rng(5))
    again = degrade(street, np.random.default_rng(5))
    assert np.array_equal(first.cloud.points, again.cloud.points)
    assert len(first.cloud) < len(street.cloud)
    instance = np.asarray(first.cloud.fields["instance"])
    for index, box in enumerate(first.boxes):
        assert box.points == int((instance == index).sum())
    assert first.cloud.points[:, 3].min() >= 0.0 and first.cloud.points[:, 3].max() <= 1.0


def test_dead_lasers_take_whole_rings_away(street: Frame) -> None:
    rings = np.asarray(street.cloud.fields["ring"])
    seen = set()
    for seed in range(40):
        degraded = degrade(street, np.random.default_rng(seed))
        left = np.unique(np.asarray(degraded.cloud.fields["ring"]))
        missing = set(np.unique(rings)) - set(left)
        seen.update(missing)
        if missing:  # a ring is gone entirely or not at all
            assert not np.isin(np.asarray(degraded.cloud.fields["ring"]), list(missing)).any()
    assert seen, "40 seeds never killed a laser (a quarter of sweeps should have one)"


def test_targets_leave_out_obstacles_with_too_few_returns(street: Frame) -> None:
    all_targets = cell_targets(street, SHIPPED_GRID)
    strict = cell_targets(street, SHIPPED_GRID, min_points=10_000)
    assert all_targets.objectness.sum() > 0 and strict.objectness.sum() == 0


def test_an_example_is_a_window_of_the_grid_with_targets_per_view() -> None:
    seed = 7
    data = example(seed, SHIPPED_GRID)
    for view in ("full", "roi"):
        assert data[view].shape == (6, CROP, CROP)
        assert data[f"{view}_offset"].shape == (2, CROP, CROP)
        # Object cells hold returns of the view (ROI-only features have no object
        # outside the ROI to find: its targets must not ask for one).
        nonempty = data[view][5] > 0
        assert np.all(nonempty[data[f"{view}_objectness"] > 0])
    assert data["roi"][5].sum() <= data["full"][5].sum()
    frame = training_frame(seed)
    assert frame.roi is not None and len(frame.cloud) > 10_000
