"""Ground removal on a coarse grid: the ground is the lowest point nearby, allowing a slope.

The ground height of a cell is the lowest of ``z_min(c') + max_slope * d(c, c')`` over
the cells ``c'`` of the ``window`` x ``window`` block around it, where ``z_min`` is a
cell's lowest point and ``d`` the distance between cell centres (a grey erosion with a
cone-shaped structuring element). A point is ground when it lies less than
``tolerance`` above its cell's ground height.

Looking at neighbours keeps the roof of a car from becoming "ground" in cells where the
car hides the road: the road next to it, plus the slope allowance, is lower. Allowing
``max_slope`` keeps sloped road (up to that gradient) ground all the way instead of
only near its lowest point; steeper terrain (embankments, walls) is left as obstacles.
The price: an object on flat ground loses its lowest ``max_slope * cell_size +
tolerance`` (0.4 m by default) to the ground, where the road one cell away sets the height.

Points below ``floor_z`` (multipath reflections that appear under the road) are ignored
when estimating the ground, so one bad return cannot lower the ground of a whole block.
With ``rank=k > 1`` a cell's height is its k-th lowest *distinct* height instead of its
lowest, and cells with fewer distinct heights define none: k - 1 stray returns in a cell
(a speck of noise, a point a driver sent twice) cannot lower the ground around it. A
whole-scene detector, which sees every point of the sweep, needs that; a detector that
sees only ROI points (the reference) can use the plain minimum.

The grid is anchored at the sensor origin (cell ``i`` covers ``[i, i + 1) * cell_size``),
so a point's cell never depends on which other points are in the frame.
Everything is a function of the *set* of points: order and repeats do not matter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import grey_erosion

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.systems.perception.grid import grid_cells

__all__ = ["GroundParams", "ground_heights"]


@dataclass(frozen=True)
class GroundParams:
    """Parameters of :func:`ground_heights` (defaults suit a Velodyne HDL-64E on a car).

    Attributes
    ----------
    cell_size : float
        Grid cell edge in metres.
    window : int
        Odd number of cells per side of the neighbourhood that can lower a cell's
        ground height (7 cells of 1 m: road within 3 m of a car is enough).
    max_slope : float
        Steepest ground gradient (rise over run) followed without leaving obstacles;
        0.15 covers steep roads and ramps.
    tolerance : float
        Points less than this many metres above the ground height are ground.
    floor_z : float
        Points lower than this (sensor frame, metres) never define the ground. KITTI's
        sensor is 1.73 m above the road, so -3.5 m leaves room for a 1.7 m dip.
    rank : int
        A cell's height is its ``rank``-th lowest distinct point height (1: the lowest);
        cells with fewer distinct heights define none.
    """

    cell_size: float = 1.0
    window: int = 7
    max_slope: float = 0.15
    tolerance: float = 0.25
    floor_z: float = -3.5
    rank: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.rank, bool) or not isinstance(self.rank, int) or self.rank < 1:
            raise InvalidArgument(f"rank={self.rank!r} must be an int >= 1")
        if not self.cell_size > 0:
            raise InvalidArgument(f"cell_size={self.cell_size!r} must be > 0")
        if not isinstance(self.window, int) or self.window < 1 or self.window % 2 == 0:
            raise InvalidArgument(f"window={self.window!r} must be an odd int >= 1")
        if not self.max_slope >= 0:
            raise InvalidArgument(f"max_slope={self.max_slope!r} must be >= 0")
        if not self.tolerance >= 0:
            raise InvalidArgument(f"tolerance={self.tolerance!r} must be >= 0")


def ground_heights(
    xyz: NDArray[np.float32], params: GroundParams = GroundParams()
) -> NDArray[np.float32]:
    """The local ground height under every point.

    Parameters
    ----------
    xyz : (n, >=3) float32
        Points in the sensor frame (x forward, y left, z up), metres.
    params : GroundParams

    Returns
    -------
    (n,) float32
        Ground z below each point; ``+inf`` where no point at or above ``floor_z`` lies
        within the window (then nothing there counts as ground). A point is ground when
        ``z < height + params.tolerance``.
    """
    n = len(xyz)
    if n == 0:
        return np.empty(0, dtype=np.float32)
    flat, shape = grid_cells(xyz, params.cell_size)
    z = xyz[:, 2]
    usable = z >= params.floor_z
    lowest = _cell_heights(flat[usable], z[usable], shape[0] * shape[1], params.rank)
    # Outside the grid there are no points: padding with +inf changes no minimum.
    ground = grey_erosion(
        lowest.reshape(shape),
        structure=_cone(params),
        mode="constant",
        cval=np.inf,
    )
    return ground.reshape(-1)[flat]


def _cell_heights(
    flat: NDArray[np.int64], z: NDArray[np.float32], cells: int, rank: int
) -> NDArray[np.float32]:
    """(cells,) float32: each cell's ``rank``-th lowest distinct z; +inf where there is none."""
    heights = np.full(cells, np.inf, dtype=np.float32)
    if rank == 1:
        np.minimum.at(heights, flat, z)
        return heights
    order = np.lexsort((z, flat))
    flat, z = flat[order], z[order]
    fresh = np.ones(len(z), dtype=bool)
    fresh[1:] = (flat[1:] != flat[:-1]) | (z[1:] != z[:-1])
    flat, z = flat[fresh], z[fresh]
    starts = np.ones(len(z), dtype=bool)
    starts[1:] = flat[1:] != flat[:-1]
    first = np.maximum.accumulate(np.where(starts, np.arange(len(z)), 0))
    pick = np.arange(len(z)) - first == rank - 1
    heights[flat[pick]] = z[pick]
    return heights


def _cone(params: GroundParams) -> NDArray[np.float32]:
    """Structuring element: minus the allowed rise from each neighbour to the centre."""
    offsets = np.arange(params.window) - params.window // 2
    distance = np.hypot(offsets[:, None], offsets[None, :]) * params.cell_size
    return (-params.max_slope * distance).astype(np.float32)
