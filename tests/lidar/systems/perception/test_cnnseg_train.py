"""The training script's augmentation: a quarter turn or mirror of a window's targets is
the targets of the turned or mirrored scene (needs PyTorch: ``pip install '.[train]'``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.systems.perception.cnnseg.data import training_frame
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import SHIPPED_GRID
from pytest_metamorphic.lidar.systems.perception.cnnseg.targets import cell_targets

torch = pytest.importorskip("torch", reason="PyTorch is not installed: pip install '.[train]'")
from pytest_metamorphic.lidar.systems.perception.cnnseg.train import _augment  # noqa: E402


class _Draws:
    """Stands in for the generator: the turns, then the mirror, as given."""

    def __init__(self, *values: int) -> None:
        self.values = list(values)

    def integers(self, _high: int) -> int:
        return self.values.pop(0)


def _moved(frame: Frame, turns: int, mirror: bool) -> Frame:
    """The scene mirrored (y -> -y), then turned by quarter turns about the sensor."""

    def move(x: float, y: float, yaw: float) -> tuple[float, float, float]:
        if mirror:
            y, yaw = -y, -yaw
        for _ in range(turns):
            x, y, yaw = -y, x, yaw + math.pi / 2
        return x, y, yaw

    points = frame.cloud.points.copy()
    if mirror:
        points[:, 1] = -points[:, 1]
    for _ in range(turns):  # (x, y) -> (-y, x)
        points[:, :2] = np.column_stack([-points[:, 1], points[:, 0]])
    boxes = []
    for box in frame.boxes:
        x, y, yaw = move(box.center[0], box.center[1], box.yaw)
        boxes.append(dataclasses.replace(box, center=(x, y, box.center[2]), yaw=yaw))
    return dataclasses.replace(frame, cloud=frame.cloud.with_points(points), boxes=tuple(boxes))


@pytest.mark.parametrize(("turns", "mirror"), [(1, False), (2, False), (3, True), (0, True)])
def test_augmenting_targets_is_moving_the_scene(turns: int, mirror: bool) -> None:
    frame = training_frame(3)
    targets = cell_targets(frame, SHIPPED_GRID)
    batch = {
        name: torch.from_numpy(np.asarray(getattr(targets, name), np.float32)[None])
        for name in ("objectness", "offset", "heading")
    }
    augmented = _augment(batch, _Draws(turns, int(mirror)))  # type: ignore[arg-type]
    expected = cell_targets(_moved(frame, turns, mirror), SHIPPED_GRID)
    cells = expected.objectness > 0
    assert np.array_equal(augmented["objectness"][0].numpy() > 0, cells)
    for name in ("offset", "heading"):
        got = augmented[name][0].numpy()[:, cells]
        assert got == pytest.approx(getattr(expected, name)[:, cells], abs=1e-4), name
    assert np.abs(expected.heading[:, cells]).sum() > 0  # the scene has oriented objects
