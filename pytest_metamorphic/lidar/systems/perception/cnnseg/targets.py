"""What the network is trained to predict, from a rendered frame's ground truth.

Rendered frames (:func:`pytest_metamorphic.lidar.synthetic.render`) label every return with
the obstacle it hit (the ``instance`` field: the index into ``frame.boxes``; ground and
background objects are negative). A cell is an object cell when it holds a return of an
obstacle; when several obstacles share a cell, the one with most returns there wins.
Each object cell is trained on its obstacle's centre offset, class, top height and heading,
like Apollo's ``instance_pt``, ``class_score``, ``height_pt`` and ``heading_pt`` blobs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.systems.perception.cnnseg.features import GridSpec, point_cells
from pytest_metamorphic.lidar.systems.perception.cnnseg.network import CLASSES

__all__ = ["Targets", "cell_targets", "instance_field"]


@dataclass(frozen=True)
class Targets:
    """Per-cell training targets of one frame.

    Attributes
    ----------
    objectness : (size, size) float32
        1 for object cells, else 0.
    offset : (2, size, size) float32
        Obstacle centre minus cell centre (x, y metres); 0 outside object cells.
    label : (size, size) int64
        Index into :data:`~.network.CLASSES`; -1 outside object cells.
    height : (size, size) float32
        Obstacle top (z, metres); 0 outside object cells.
    heading : (2, size, size) float32
        cos and sin of twice the obstacle's yaw (a box is the same turned by 180 degrees,
        so the doubled angle is what is defined) for cars and cyclists; 0 elsewhere,
        pedestrians included (their boxes' yaw says little).
    """

    objectness: NDArray[np.float32]
    offset: NDArray[np.float32]
    label: NDArray[np.int64]
    height: NDArray[np.float32]
    heading: NDArray[np.float32]


def instance_field(frame: Frame, use: str) -> NDArray[np.integer]:
    """The renderer's per-return ``instance`` field of ``frame`` (obstacle index,
    ground or background), or :class:`InvalidArgument` naming it and ``use``: a
    recorded sweep has none."""
    if "instance" not in frame.cloud.fields:
        raise InvalidArgument(
            f"{use}: {frame!r} has no 'instance' field (which return belongs to which "
            "obstacle, the road or the background), so it is not a rendered frame"
        )
    return np.asarray(frame.cloud.fields["instance"])


def cell_targets(frame: Frame, grid: GridSpec | None = None, *, min_points: int = 1) -> Targets:
    """Targets for a rendered frame (one with an ``instance`` field and its boxes).

    Obstacles labelled ``"unknown"`` are left out (the network learns the three road-user
    classes; anything else is background to it), and so are obstacles with fewer than
    ``min_points`` returns in the frame's cloud (a car seen by two returns is nothing a
    network can tell from a post).
    """
    instance = instance_field(frame, "training targets").astype(np.int64)
    grid = grid or GridSpec()
    boxes = list(frame.boxes)
    if len(boxes) and instance.size and instance.max() >= len(boxes):
        raise InvalidArgument(f"{frame!r}: instance ids exceed its {len(boxes)} boxes")
    n = grid.size
    flat, inside = point_cells(frame.cloud.points, grid)
    hit = inside & (instance >= 0)
    objectness = np.zeros(n * n, dtype=np.float32)
    offset = np.zeros((2, n * n), dtype=np.float32)
    label = np.full(n * n, -1, dtype=np.int64)
    height = np.zeros(n * n, dtype=np.float32)
    heading = np.zeros((2, n * n), dtype=np.float32)
    if hit.any():
        cells, owners = flat[hit], instance[hit]
        # Most returns per (cell, obstacle) wins the cell.
        pairs, votes = np.unique(np.stack([cells, owners]), axis=1, return_counts=True)
        order = np.lexsort((-votes, pairs[0]))
        pairs = pairs[:, order]
        first = np.ones(pairs.shape[1], dtype=bool)
        first[1:] = pairs[0, 1:] != pairs[0, :-1]
        cell, owner = pairs[0, first], pairs[1, first]
        classes = np.array([CLASSES.index(b.label) if b.label in CLASSES else -1 for b in boxes])
        returns = np.bincount(instance[instance >= 0], minlength=len(boxes))
        classes[returns < min_points] = -1
        known = classes[owner] >= 0
        cell, owner = cell[known], owner[known]
        centers = np.array([b.center for b in boxes], dtype=np.float64)
        tops = np.array([b.center[2] + b.size[2] / 2.0 for b in boxes], dtype=np.float64)
        cx, cy = grid.cell_centers()
        objectness[cell] = 1.0
        offset[0, cell] = centers[owner, 0] - cx.ravel()[cell]
        offset[1, cell] = centers[owner, 1] - cy.ravel()[cell]
        label[cell] = classes[owner]
        height[cell] = tops[owner]
        oriented = classes[owner] != CLASSES.index("pedestrian")
        doubled = 2.0 * np.array([b.yaw for b in boxes], dtype=np.float64)[owner[oriented]]
        heading[0, cell[oriented]] = np.cos(doubled)
        heading[1, cell[oriented]] = np.sin(doubled)
    return Targets(
        objectness.reshape(n, n),
        offset.reshape(2, n, n),
        label.reshape(n, n),
        height.reshape(n, n),
        heading.reshape(2, n, n),
    )
