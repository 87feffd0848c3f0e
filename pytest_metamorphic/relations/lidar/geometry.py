"""Relations under rigid changes of the scene: the obstacles move with it."""

from __future__ import annotations

import math
from typing import Any, Literal

from hypothesis import strategies as st

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.perturb import RotateAboutSensor
from pytest_metamorphic.lidar.followups.symmetry import MirrorAcrossX, ShiftAlongX, ShiftScene
from pytest_metamorphic.lidar.judging.equivariance import (
    SAME_OBSTACLE,
    MirroredObstacles,
    MovedObstacles,
    RotatedObstacles,
    ShiftedObstacles,
    moved_obstacles,
)
from pytest_metamorphic.lidar.judging.scope import ScopeLike
from pytest_metamorphic.relations.lidar._common import _check_size, _frame, lidar_relation

__all__ = [
    "MirroredObstacles",
    "MovedObstacles",
    "RotatedObstacles",
    "ShiftedObstacles",
    "mirror_symmetry",
    "rotation_equivariance",
    "translation_equivariance",
]


def rotation_equivariance(
    *,
    angles: Literal["quarter_turns", "any"] = "quarter_turns",
    center_tolerance: float | None = None,
    size_tolerance: float | None = None,
    yaw_tolerance: float | None = None,
    min_points: int | None = None,
    boundary_margin: float | None = None,
    same_label: bool | None = None,
    exclusive: bool = True,
    scope: ScopeLike = "roi",
    name: str | None = None,
) -> MetamorphicRelation:
    """Turning the cloud and the ROI about the sensor by θ turns the obstacles by θ.

    Parameters
    ----------
    angles : {"quarter_turns", "any"}
        ``"quarter_turns"`` (default): θ in {90°, 180°, 270°}. Bird's-eye grids
        anchored at the sensor map onto themselves, so a grid-based detector sees the
        same points in the same cells; the tolerances say "the same obstacle"
        (:data:`~pytest_metamorphic.lidar.judging.equivariance.SAME_OBSTACLE`: centre
        10 cm, length and width 15 cm, heading 5°; objects of any size, 0.5 m from the
        ROI edge, same label): a grid-based pipeline moves its boxes exactly, DBSCAN's
        ties (border points between touching clusters) by centimetres, a real fault by
        decimetres to metres. ``"any"``: θ in tenths of a
        degree in (-180°, 180°]. Grid cells then cut objects differently: a few points
        change between ground and obstacle, MinBox (whose facing-edge choice jumps when
        the hull gains or loses a vertex) moves a box side by tens of centimetres, and
        small or borderline objects split, merge or change class (a cyclist whose
        points span 1.3 m, the car rule's limit for a car seen from behind, flips
        between the two). The defaults (0.8 m, 0.8 m, 20°, objects of >= 30 points,
        1 m from the ROI edge, labels not compared) hold for the reference pipeline on
        clean synthetic scenes, and still catch boxes that do not turn (axis-aligned
        boxes are off by metres). On cluttered real sweeps (KITTI) the reference
        pipeline violates the "any" variant in most frames, and so does a whole-scene
        detector on rendered streets, where an on-road car a cell or two from off-road
        clutter merges with it at some angles and not at others.
    center_tolerance, size_tolerance, yaw_tolerance, min_points, boundary_margin
        Override the defaults (metres, metres, degrees, points, metres); see
        :class:`RotatedObstacles`.
    same_label : bool, optional
        Whether a turned obstacle must keep its class (default: for quarter turns).
    exclusive : bool
        Each obstacle needs its *own* partner (default); False lets pieces of one object
        share one (a network that splits an object in one output and not the other).
    scope : "roi", "all" or ObstacleScope
        Which obstacles are compared (default: those wholly inside the ROI).
    """
    if angles not in ("quarter_turns", "any"):
        raise InvalidArgument(f"angles={angles!r} must be 'quarter_turns' or 'any'")
    quarter = angles == "quarter_turns"
    relation = moved_obstacles(
        "rotation",
        quarter_turns=quarter,
        center_tolerance=center_tolerance,
        size_tolerance=size_tolerance,
        yaw_tolerance=yaw_tolerance,
        min_points=min_points,
        boundary_margin=boundary_margin,
        same_label=same_label,
        exclusive=exclusive,
        scope=scope,
    )
    turns: st.SearchStrategy[float]
    if quarter:
        turns = st.sampled_from((90, 180, 270))
    else:
        turns = st.integers(-1799, 1800).map(lambda tenths: tenths / 10.0)

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)

        def turn(degrees: float) -> Followup:
            rotation = RotateAboutSensor(math.radians(degrees))
            return Followup(rotation.apply(frame), params=rotation.params())

        return turns.map(turn)

    label = name or f"cloud and ROI turned ({angles}) => O turned"
    return lidar_relation(label, followup, relation)


def mirror_symmetry(
    *,
    center_tolerance: float = SAME_OBSTACLE[0],
    size_tolerance: float = SAME_OBSTACLE[1],
    yaw_tolerance: float = SAME_OBSTACLE[2],
    min_points: int = 0,
    boundary_margin: float = 0.5,
    same_label: bool = True,
    exclusive: bool = True,
    scope: ScopeLike = "roi",
    name: str = "cloud and ROI mirrored (y -> -y) => O mirrored",
) -> MetamorphicRelation:
    """Reflecting the cloud and the ROI in the car's x axis reflects the obstacles.

    The follow-up is the source's mirror image
    (:class:`~pytest_metamorphic.lidar.followups.symmetry.MirrorAcrossX`): a
    left-hand-traffic scene from a right-hand one. Precondition: a detector whose
    bird's-eye grids are anchored at the sensor (a reflection maps them onto themselves)
    and which prefers no side. Tolerances as for quarter turns (10 cm, 15 cm, 5 degrees,
    labels equal: the same obstacle, whatever DBSCAN's ties do), obstacles at least
    ``boundary_margin`` from the ROI's edge (the mirrored ROI is rasterised afresh). It
    catches what rotations cannot: a detector that reports its boxes in a frame turned
    about the sensor (a wrong yaw extrinsic) commutes with every rotation, but not with a
    reflection. ``same_label=False``: classes are not
    compared; ``exclusive`` as for :func:`rotation_equivariance`.
    """
    relation = moved_obstacles(
        "mirror",
        center_tolerance=center_tolerance,
        size_tolerance=size_tolerance,
        yaw_tolerance=yaw_tolerance,
        min_points=min_points,
        boundary_margin=boundary_margin,
        same_label=same_label,
        exclusive=exclusive,
        scope=scope,
    )

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        mirror = MirrorAcrossX()
        return st.just(mirror).map(lambda m: Followup(m.apply(frame), params=m.params()))

    return lidar_relation(name, followup, relation)


def translation_equivariance(
    *,
    shifts: Literal["cells", "any"] = "cells",
    cell_size: float = 1.0,
    max_cells: int = 10,
    max_shift: float = 10.0,
    center_tolerance: float | None = None,
    size_tolerance: float | None = None,
    yaw_tolerance: float | None = None,
    min_points: int | None = None,
    boundary_margin: float | None = None,
    same_label: bool | None = None,
    scope: ScopeLike = "roi",
    name: str | None = None,
) -> MetamorphicRelation:
    """Shifting the cloud, the ROI and the boxes shifts the obstacles.

    Optional, and not in :func:`lidar_relations`: no sensor sees a shifted scene. A real
    sweep is centred on its sensor: density falls with range, beams fan out from the
    origin, what is behind an object is in its shadow. Shifted, the near side of the
    sweep has the density of a far side and the shadows point away from a place where no
    sensor stands, and a detector that uses any of that (range gates and range-dependent
    thresholds, polar or sensor-anchored grids, MinBox's choice of the edges facing the
    sensor, a network trained on sensor-centred sweeps) does not claim the relation, for
    good reason. Detectors that treat the sweep as a set of points in the plane (a
    clusterer and box fitter with no range in them) do; for them it is the cheapest test
    that nothing depends on absolute coordinates. Measured (docs/soundness.md): the
    reference, its whole-scene variant and the scikit-learn example hold shifts by any
    amount on rendered streets and fail them on the KITTI sweeps, and the reference fails
    whole-cell shifts there too (4 of 56 follow-ups: an obstacle whose box moves by 10-20
    cm). Hence opt-in, for a detector that claims it.

    Parameters
    ----------
    shifts : {"cells", "any"}
        ``"cells"`` (default): along x by whole grid cells
        (:class:`~pytest_metamorphic.lidar.followups.symmetry.ShiftAlongX`; 1 to
        ``max_cells`` cells of ``cell_size`` metres either way, shrinking toward one cell
        forward), compared as the same obstacle (centre and size 2 cm, heading 1 degree,
        labels compared): a detector whose grids are anchored at the sensor sees the same
        cells. ``"any"``: by any ``(dx, dy)`` up to ``max_shift`` metres each, in
        centimetres (:class:`~pytest_metamorphic.lidar.followups.symmetry.ShiftScene`,
        shrinking toward 1 cm), compared with the loose tolerances of turns by any angle
        (centre and size 0.8 m, heading 20 degrees, objects of >= 30 points 1 m inside the
        ROI, labels not compared): every cell border cuts the scene elsewhere.
    center_tolerance, size_tolerance, yaw_tolerance, min_points, boundary_margin, same_label
        Override those defaults (metres, metres, degrees, points, metres, bool).
    """
    if shifts not in ("cells", "any"):
        raise InvalidArgument(f"shifts={shifts!r} must be 'cells' or 'any'")
    if isinstance(cell_size, bool) or not isinstance(cell_size, (int, float)):
        raise InvalidArgument(f"cell_size={cell_size!r} must be a number of metres > 0")
    if not (math.isfinite(cell_size) and cell_size > 0):
        raise InvalidArgument(f"cell_size={cell_size!r} must be a number of metres > 0")
    if isinstance(max_shift, bool) or not isinstance(max_shift, (int, float)):
        raise InvalidArgument(f"max_shift={max_shift!r} must be a number of metres >= 0.01")
    if not (math.isfinite(max_shift) and max_shift >= 0.01):
        raise InvalidArgument(f"max_shift={max_shift!r} must be a number of metres >= 0.01")
    _check_size(max_cells, "max_cells")
    cells = shifts == "cells"
    relation = moved_obstacles(
        "translation",
        quarter_turns=cells,
        center_tolerance=0.02 if cells and center_tolerance is None else center_tolerance,
        size_tolerance=0.02 if cells and size_tolerance is None else size_tolerance,
        yaw_tolerance=1.0 if cells and yaw_tolerance is None else yaw_tolerance,
        min_points=0 if cells and min_points is None else min_points,
        boundary_margin=0.5 if cells and boundary_margin is None else boundary_margin,
        same_label=same_label,
        scope=scope,
    )
    if cells:
        # 1, -1, 2, -2, ... cells: shrinks toward one cell forward.
        steps = st.integers(0, 2 * max_cells - 1).map(lambda k: (k // 2 + 1) * (1 - 2 * (k % 2)))
        moves: st.SearchStrategy[ShiftAlongX | ShiftScene] = steps.map(
            lambda count: ShiftAlongX(count * cell_size)
        )
        label = name or "cloud and ROI shifted along x by whole cells => O shifted"
    else:
        # Centimetres, not both zero: shrinks toward 1 cm along y, then x.
        reach = round(max_shift * 100)
        pairs = st.tuples(st.integers(-reach, reach), st.integers(-reach, reach)).filter(
            lambda pair: pair != (0, 0)
        )
        moves = pairs.map(lambda pair: ShiftScene(pair[0] / 100, pair[1] / 100))
        label = name or "cloud and ROI shifted by any amount => O shifted"

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        return moves.map(lambda move: Followup(move.apply(frame), params=move.params()))

    return lidar_relation(label, followup, relation)
