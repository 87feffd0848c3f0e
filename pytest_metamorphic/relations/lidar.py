"""Ready metamorphic relations for LiDAR obstacle perception (systems ``frame -> list[Box]``).

Each function returns a :class:`~pytest_metamorphic.core.engine.MetamorphicRelation`
(an input transform of a :class:`~pytest_metamorphic.lidar.frame.Frame` plus an output
relation) to pass to ``@metamorphic(relations=[...])``; :func:`lidar_relations` returns
them all. The source input must be a ``Frame`` with an ROI (``frame.roi``).

===============================  ===================================  ======================
relation                         follow-up                            expected output
===============================  ===================================  ======================
:func:`mr1_subset`               noise outside the ROI (paper's MR1)  O ⊆ O' (one-to-one)
:func:`mr1_cardinality`          the same                             abs O <= abs O'
:func:`outside_noise_invariance` the same                             O == O'
:func:`outside_removal`          outside-ROI points removed           O == O'
:func:`permutation_invariance`   points reordered                     O == O'
:func:`duplication_invariance`   some points repeated                 O == O'
:func:`rotation_equivariance`    cloud and ROI turned by θ            O turned by θ
===============================  ===================================  ======================

MR1 follows Zhou & Sun (CACM 2019): 1000 points by default (the largest of their 10,
100 and 1000) scattered outside the ROI, z and intensity uniform over the frame's ranges, "outside"
holding for the exact polygons and for Apollo's 0.25 m bitmap with a free cell in
between. The paper checked only the cardinality; :func:`mr1_subset` checks what MR1
says, every source obstacle keeping its own match
(:func:`~pytest_metamorphic.core.matching.one_to_one`) in the follow-up.

The equalities are exact: a perception stack that filters by ROI first and treats the
cloud as a set of points (as :class:`~pytest_metamorphic.lidar.perception.ReferencePerception`
does) cannot tell the inputs apart. Rotation is the exception; see
:func:`rotation_equivariance` for its tolerances and why they are needed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray

from pytest_metamorphic.core.engine import Followup, MetamorphicRelation
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.matching import Matcher, one_to_one
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.frame import Frame
from pytest_metamorphic.lidar.obstacles import Box
from pytest_metamorphic.lidar.perturb import (
    PAPER_NOISE_SIZES,
    SEED_BITS,
    DropPoints,
    DuplicatePoints,
    NoiseOutsideROI,
    RotateAboutSensor,
)
from pytest_metamorphic.lidar.scope import (
    ObstacleScope,
    ScopeLike,
    as_scope,
    judged_count,
    judged_equal,
    obstacles_kept,
)
from pytest_metamorphic.strategies import (
    duplicated_points,
    noise_outside_roi,
    permuted_points,
)

__all__ = [
    "DEFAULT_NOISE",
    "PACKET_POINTS",
    "PAPER_NOISE_SIZES",
    "ObstacleScope",
    "RotatedObstacles",
    "duplication_invariance",
    "lidar_relations",
    "mr1_cardinality",
    "mr1_subset",
    "outside_noise_invariance",
    "outside_removal",
    "permutation_invariance",
    "rotation_equivariance",
]


DEFAULT_CLEARANCE = 5.0
"""Metres outside the ROI within which :func:`outside_removal` keeps points (ROI scope)."""

DEFAULT_NOISE = 1000
"""The paper's largest setting; shrinking then finds how few of them matter."""
_CHUNKS = 10

NoiseSize = int | Sequence[int] | None


def _noise(n: NoiseSize, max_size: int) -> Any:
    """Follow-up strategy: noise outside the ROI, as many points as ``n`` says."""
    if n is None:
        return lambda frame: noise_outside_roi(_frame(frame), min_size=1, max_size=max_size)
    sizes = (n,) if isinstance(n, int) else tuple(n)

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        NoiseOutsideROI.from_seeds(frame, [0])  # no ROI, empty frame: fail now
        return st.sampled_from(sizes).flatmap(lambda size: _chunked_noise(frame, size))

    return followup


def _chunked_noise(frame: Frame, n: int) -> st.SearchStrategy[Followup]:
    """Exactly ``n`` noise points, drawn as ``_CHUNKS`` seeds of ``n / _CHUNKS`` points each.

    Hypothesis' choice budget holds about a thousand integers per test case, so one seed
    per point cannot give two follow-ups of 1000 points. Shrinking simplifies the chunk
    seeds; the engine's own reduction then finds the few points that matter.
    """
    chunks = min(n, _CHUNKS)
    size = -(-n // chunks)
    top = 2**SEED_BITS // size - 1

    def make(values: list[int]) -> Followup:
        seeds = [v * size + j for v in values for j in range(size)][:n]
        noise = NoiseOutsideROI.from_seeds(frame, seeds)
        return Followup(noise.apply(frame), params={**noise.params(), "chunks": values})

    return st.lists(st.integers(0, top), min_size=chunks, max_size=chunks).map(make)


def _check_noise(n: NoiseSize, max_size: int) -> None:
    _check_size(max_size, "max_size")
    if n is None or isinstance(n, int):
        _check_size(n, "n", allow_none=True)
        return
    if isinstance(n, (str, bytes)) or not isinstance(n, Sequence) or not n:
        raise InvalidArgument(f"n={n!r} must be an int, a non-empty sequence of ints, or None")
    for size in n:
        _check_size(size, "n")


def _frame(value: Any) -> Frame:
    if not isinstance(value, Frame):
        raise InvalidArgument(
            f"LiDAR relations need Frame source inputs (with .roi), got {type(value).__name__}"
        )
    return value


def _check_size(value: Any, name: str, *, allow_none: bool = False) -> None:
    if value is None and allow_none:
        return
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InvalidArgument(f"{name}={value!r} must be a positive int")


def mr1_subset(
    *,
    n: NoiseSize = DEFAULT_NOISE,
    max_size: int = 1000,
    matcher: Matcher | None = None,
    scope: ScopeLike = "roi",
    name: str = "MR1: noise outside ROI => O subset of O'",
) -> MetamorphicRelation:
    """The paper's MR1: points added outside the ROI must not remove any obstacle.

    Parameters
    ----------
    n : int, sequence of int, or None
        Noise points per follow-up: ``n`` (default 1000, the paper's largest setting);
        or one of several sizes (e.g. :data:`PAPER_NOISE_SIZES`, shrinking toward the
        first); the engine's reduction then finds the few points that matter. With
        None, between 1 and ``max_size`` points (Hypothesis then mostly draws a
        handful, which rarely land next to the ROI).
    max_size : int
        The largest count when ``n`` is None.
    matcher : Matcher, optional
        When a follow-up obstacle counts as the same as a source one. Default: same
        label and bird's-eye IoU >= 0.5 (KITTI's threshold for people), so an obstacle
        that moves a little is kept but one that vanishes or changes class is not.
    scope : "roi", "all" or ObstacleScope
        Which source obstacles must be kept: by default those with at least half their
        footprint inside the ROI (:mod:`pytest_metamorphic.lidar.scope`), so a detector
        that reports the whole sweep is not blamed for noise changing obstacles off the
        road; those changes are counted as information. ``"all"`` judges every obstacle.
    """
    _check_noise(n, max_size)
    relation = obstacles_kept(matcher=matcher, scope=scope)
    return MetamorphicRelation(name, _noise(n, max_size), relation)


def mr1_cardinality(
    *,
    n: NoiseSize = DEFAULT_NOISE,
    max_size: int = 1000,
    scope: ScopeLike = "roi",
    name: str = "MR1 (paper's check): noise outside ROI => |O| <= |O'|",
) -> MetamorphicRelation:
    """MR1 as Zhou & Sun checked it: the follow-up has at least as many obstacles.

    ``n``, ``max_size`` and ``scope`` as for :func:`mr1_subset`; the judged obstacles of
    each side are counted.
    """
    _check_noise(n, max_size)
    return MetamorphicRelation(name, _noise(n, max_size), judged_count("<=", scope=scope))


def outside_noise_invariance(
    *,
    n: NoiseSize = DEFAULT_NOISE,
    max_size: int = 1000,
    scope: ScopeLike = "roi",
    name: str = "noise outside ROI => O == O'",
) -> MetamorphicRelation:
    """Points outside the ROI change nothing judged: the judged obstacles are equal.

    ``n``, ``max_size`` and ``scope`` as for :func:`mr1_subset`. Every judged obstacle of
    either output needs an identical one in the other (order aside); with
    ``scope="all"`` the two outputs must be equal exactly, order included.
    """
    _check_noise(n, max_size)
    return MetamorphicRelation(name, _noise(n, max_size), judged_equal(scope=scope))


def outside_removal(
    *,
    method: Literal["raster", "exact"] = "raster",
    max_size: int = 1000,
    scope: ScopeLike = "roi",
    clearance: float | None = None,
    name: str = "outside-ROI points removed => O == O'",
) -> MetamorphicRelation:
    """Removing points outside the ROI changes nothing judged.

    The follow-up drops either every point outside the ROI or up to ``max_size`` of them
    (a drawn subset, shrinking toward one point). ``method`` decides "outside" the way
    the system under test does (Apollo: the rasterised bitmap). ``scope`` as for
    :func:`outside_noise_invariance`.

    ``clearance`` (metres): only points at least this far outside the ROI are dropped.
    A detector that sees the whole sweep legitimately uses the points next to the ROI:
    its ground estimate under an obstacle at the road's edge looks a few metres around
    it, and an object straddling the edge is one cluster. Removing that context changes
    judged obstacles without any fault, unlike adding sparse noise there. The default is
    5 m with the ROI scope (beyond the reference ground window's 3.5 m) and 0 with
    ``scope="all"``, for ROI-first stacks, where no outside point may matter.
    """
    chosen = as_scope(scope)
    relation = judged_equal(scope=chosen)
    if method not in ("raster", "exact"):
        raise InvalidArgument(f"method={method!r} must be 'raster' or 'exact'")
    _check_size(max_size, "max_size")
    if clearance is None:
        clearance = 0.0 if chosen.everything else DEFAULT_CLEARANCE
    if isinstance(clearance, bool) or not isinstance(clearance, (int, float)):
        raise InvalidArgument(f"clearance={clearance!r} must be a number of metres >= 0")
    if not (math.isfinite(clearance) and clearance >= 0):
        raise InvalidArgument(f"clearance={clearance!r} must be a number of metres >= 0")

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        if frame.roi is None:
            raise InvalidArgument(f"{frame!r} has no ROI; outside_removal needs frame.roi")
        outside = np.flatnonzero(~frame.roi.contains(frame.cloud.points, method=method))
        if clearance > 0 and len(outside):
            far = frame.roi.boundary_distance(frame.cloud.points[outside, :2]) >= clearance
            outside = outside[far]
        if len(outside) == 0:
            return st.just(Followup(frame, params={"dropped": 0}))

        def drop(choice: tuple[bool, list[int]]) -> Followup:
            everything, picks = choice
            rows = outside if everything else outside[np.asarray(picks, dtype=np.intp)]
            removal = DropPoints(rows)
            params = {
                **removal.params(),
                "all_outside": everything,
                "method": method,
                "clearance": clearance,
            }
            return Followup(removal.apply(frame), params=params)

        picks = st.lists(
            st.integers(0, len(outside) - 1),
            min_size=1,
            max_size=min(max_size, len(outside)),
            unique=True,
        )
        return st.tuples(st.booleans(), picks).map(drop)

    return MetamorphicRelation(name, followup, relation)


def permutation_invariance(*, name: str = "points reordered => O == O'") -> MetamorphicRelation:
    """The order of the points in the cloud does not matter, for any obstacle.

    Not scoped: reordering touches every point alike, so a detector must give exactly
    the same output everywhere (this and :func:`duplication_invariance` hold for
    whole-scene detectors as they do for ROI-first ones).
    """
    return MetamorphicRelation(
        name, lambda frame: permuted_points(_frame(frame)), judged_equal(scope="all")
    )


PACKET_POINTS = 384
"""Points in one HDL-64E data packet (12 firings x 32 lasers)."""


def duplication_invariance(
    *, max_size: int = 100, name: str = "points repeated => O == O'"
) -> MetamorphicRelation:
    """Repeating points does not matter.

    Follow-ups repeat, in order of shrinking preference: up to ``max_size`` scattered
    points; one packet's worth of consecutive points (:data:`PACKET_POINTS`, a driver
    that sends a packet twice); or the whole sweep (two drivers publishing one topic).
    """
    _check_size(max_size, "max_size")

    def followup(frame: Any) -> st.SearchStrategy[Followup]:
        frame = _frame(frame)
        count = len(frame.cloud)

        def repeat(rows: NDArray[np.intp], what: str) -> Followup:
            perturbation = DuplicatePoints(rows)
            return Followup(
                perturbation.apply(frame), params={**perturbation.params(), "what": what}
            )

        def packet(start: int) -> Followup:
            rows = np.arange(start, min(start + PACKET_POINTS, count), dtype=np.intp)
            return repeat(rows, f"points {start}..{start + len(rows) - 1} (one packet)")

        whole = st.just(None).map(lambda _: repeat(np.arange(count, dtype=np.intp), "every point"))
        return st.one_of(
            duplicated_points(frame, max_size=max_size),
            st.integers(0, max(count - 1, 0)).map(packet),
            whole,
        )

    return MetamorphicRelation(name, followup, judged_equal(scope="all"))


class RotatedObstacles(Relation):
    """``O'`` is ``O`` turned by the follow-up's ``theta_deg`` about the sensor, within tolerances.

    Compared are the *clear* obstacles of either side: labelled car, pedestrian or
    cyclist, with at least ``min_points`` points, and whose footprint circle stays more
    than ``boundary_margin`` metres from the ROI's edges (the rotated ROI is rasterised
    afresh, as Apollo does every frame, so cells along its edges differ). Each clear
    source obstacle, turned, needs its own follow-up obstacle (of the same label when
    ``same_label``) with the centre within ``center_tolerance``, length and width each
    within ``size_tolerance`` and, for elongated boxes (length - width > 0.3 m), the heading within
    ``yaw_tolerance`` degrees modulo 180 (a box's front is not defined); and each clear
    follow-up obstacle needs its own such source obstacle. With a ``scope``
    (:mod:`pytest_metamorphic.lidar.scope`, default the ROI) only obstacles it judges are
    clear; others are counted in ``unjudged`` details, as information.
    """

    def __init__(
        self,
        *,
        center_tolerance: float,
        size_tolerance: float,
        yaw_tolerance: float,
        min_points: int,
        boundary_margin: float,
        same_label: bool = True,
        scope: ScopeLike = "roi",
    ) -> None:
        self.scope: ObstacleScope = as_scope(scope)
        if not isinstance(same_label, bool):
            raise InvalidArgument(f"same_label={same_label!r} must be True or False")
        for label, value in (
            ("center_tolerance", center_tolerance),
            ("size_tolerance", size_tolerance),
            ("yaw_tolerance", yaw_tolerance),
            ("boundary_margin", boundary_margin),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                raise InvalidArgument(f"{label}={value!r} must be a number >= 0")
        if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 0:
            raise InvalidArgument(f"min_points={min_points!r} must be an int >= 0")
        self.center_tolerance = float(center_tolerance)
        self.size_tolerance = float(size_tolerance)
        self.yaw_tolerance = math.radians(yaw_tolerance)
        self.min_points = min_points
        self.boundary_margin = float(boundary_margin)
        self.same_label = same_label
        self.name = (
            f"rotated(centre<={center_tolerance:g} m, size<={size_tolerance:g} m, "
            f"yaw<={yaw_tolerance:g} deg{', same label' if same_label else ''}; "
            f"{self.scope.describe()})"
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        if "theta_deg" not in context.params:
            raise InvalidArgument(
                f"{self.name} needs the follow-up's rotation in params['theta_deg'] "
                "(use rotation_equivariance() or RotateAboutSensor.params())"
            )
        theta = math.radians(float(context.params["theta_deg"]))
        expected = [_as_box(box, "source").rotated(theta) for box in source_output]
        found = [_as_box(box, "follow-up") for box in followup_output]
        roi = getattr(context.followup_input, "roi", None)
        # Judged in the follow-up's frame: the turned source boxes and the found ones.
        judged_expected = self.scope.judged(expected, context.followup_input)
        judged_found = self.scope.judged(found, context.followup_input)
        missing = self._unmatched(expected, self._clear(expected, roi, judged_expected), found)
        extra = self._unmatched(found, self._clear(found, roi, judged_found), expected)
        details = {
            "theta_deg": context.params["theta_deg"],
            "missing": [],
            "extra": [],
            "scope": self.scope.describe(),
            "unjudged_changes": self._unjudged_changes(
                expected, found, judged_expected, judged_found
            ),
        }
        if not missing and not extra:
            return Verdict(True, self.name, details=details)
        lines = [f"source {expected[i].describe()} (turned) has no match" for i in missing]
        lines += [f"follow-up {found[j].describe()} has no source counterpart" for j in extra]
        details["missing"] = [expected[i].describe() for i in missing]
        details["extra"] = [found[j].describe() for j in extra]
        return Verdict(False, self.name, "; ".join(lines[:10]), details)

    def _unjudged_changes(
        self,
        expected: list[Box],
        found: list[Box],
        judged_expected: NDArray[np.bool_],
        judged_found: NDArray[np.bool_],
    ) -> int:
        """Unjudged obstacles, on either side, without a partner within the tolerances."""
        outside = [i for i, judged in enumerate(judged_expected) if not judged]
        outside2 = [j for j, judged in enumerate(judged_found) if not judged]
        return len(self._unmatched(expected, outside, found)) + len(
            self._unmatched(found, outside2, expected)
        )

    def _clear(self, boxes: Sequence[Box], roi: Any, judged: NDArray[np.bool_]) -> list[int]:
        chosen = []
        for index, box in enumerate(boxes):
            if not judged[index]:
                continue
            if box.label == "unknown" or (box.points or 0) < self.min_points:
                continue
            if roi is not None and self.boundary_margin > 0:
                reach = math.hypot(box.size[0], box.size[1]) / 2.0 + self.boundary_margin
                if roi.boundary_distance([box.center[:2]])[0] <= reach:
                    continue
            chosen.append(index)
        return chosen

    def _unmatched(
        self, boxes: Sequence[Box], chosen: list[int], others: Sequence[Box]
    ) -> list[int]:
        """Indices in ``chosen`` (into ``boxes``) left without a partner among ``others``."""
        if not chosen:
            return []
        compatible = np.zeros((len(chosen), len(others)), dtype=bool)
        cost = np.zeros(compatible.shape)
        for row, index in enumerate(chosen):
            for col, other in enumerate(others):
                distance, ok = self._compatible(boxes[index], other)
                compatible[row, col], cost[row, col] = ok, distance
        pairs = one_to_one(compatible, cost)
        matched = {chosen[row] for row, _ in pairs}
        return [index for index in chosen if index not in matched]

    def _compatible(self, a: Box, b: Box) -> tuple[float, bool]:
        distance = a.center_distance(b)
        if (self.same_label and a.label != b.label) or distance > self.center_tolerance:
            return distance, False
        if abs(a.size[0] - b.size[0]) > self.size_tolerance:
            return distance, False
        if abs(a.size[1] - b.size[1]) > self.size_tolerance:
            return distance, False
        elongated = a.size[0] - a.size[1] > 0.3 and b.size[0] - b.size[1] > 0.3
        turned = abs(math.remainder(a.yaw - b.yaw, math.pi))
        return distance, not (elongated and turned > self.yaw_tolerance)


def _as_box(value: Any, which: str) -> Box:
    if not isinstance(value, Box):
        raise InvalidArgument(f"rotation relations need Box outputs; a {which} item is {value!r}")
    return value


def rotation_equivariance(
    *,
    angles: Literal["quarter_turns", "any"] = "quarter_turns",
    center_tolerance: float | None = None,
    size_tolerance: float | None = None,
    yaw_tolerance: float | None = None,
    min_points: int | None = None,
    boundary_margin: float | None = None,
    scope: ScopeLike = "roi",
    name: str | None = None,
) -> MetamorphicRelation:
    """Turning the cloud and the ROI about the sensor by θ turns the obstacles by θ.

    Parameters
    ----------
    angles : {"quarter_turns", "any"}
        ``"quarter_turns"`` (default): θ in {90°, 180°, 270°}. Bird's-eye grids
        anchored at the sensor map onto themselves, so a grid-based detector sees the
        same points in the same cells; tolerances are tight (2 cm, 2 cm, 1°, objects
        of any size, 0.5 m from the ROI edge, same label). ``"any"``: θ in tenths of a
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
    scope : "roi", "all" or ObstacleScope
        Which obstacles are compared (default: those mostly inside the ROI).
    """
    if angles not in ("quarter_turns", "any"):
        raise InvalidArgument(f"angles={angles!r} must be 'quarter_turns' or 'any'")
    quarter = angles == "quarter_turns"
    defaults = (0.02, 0.02, 1.0, 0, 0.5) if quarter else (0.8, 0.8, 20.0, 30, 1.0)
    given = (center_tolerance, size_tolerance, yaw_tolerance, min_points, boundary_margin)
    values = [d if g is None else g for g, d in zip(given, defaults, strict=True)]
    relation = RotatedObstacles(
        center_tolerance=values[0],
        size_tolerance=values[1],
        yaw_tolerance=values[2],
        min_points=values[3],
        boundary_margin=values[4],
        same_label=quarter,
        scope=scope,
    )
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
    return MetamorphicRelation(label, followup, relation)


def lidar_relations(
    *,
    noise: NoiseSize = DEFAULT_NOISE,
    rotation: Literal["quarter_turns", "any"] = "quarter_turns",
    scope: ScopeLike = "roi",
) -> list[MetamorphicRelation]:
    """The whole library, for ``@metamorphic(relations=lidar_relations())``.

    ``noise`` is the ``n`` of the three noise relations; ``rotation`` the ``angles`` of
    :func:`rotation_equivariance`; ``scope`` which obstacles the ROI-related relations
    judge (default: those mostly inside the ROI; ``"all"`` for every obstacle).
    """
    as_scope(scope)
    return [
        mr1_subset(n=noise, scope=scope),
        mr1_cardinality(n=noise, scope=scope),
        outside_noise_invariance(n=noise, scope=scope),
        outside_removal(scope=scope),
        permutation_invariance(),
        duplication_invariance(),
        rotation_equivariance(angles=rotation, scope=scope),
    ]
