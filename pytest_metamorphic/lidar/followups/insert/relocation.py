"""Moving a real object within its own sweep: taken out where it stood, re-cast elsewhere.

:class:`RelocateObject` is a removal followed by an insertion of the same object: its
returns go and their beams run on to the ground behind it
(:class:`~pytest_metamorphic.lidar.followups.edit.RemoveObject`), then its template (its
own returns, meshed, :class:`~pytest_metamorphic.lidar.followups.insert.ObjectTemplate`)
is re-cast by the frame's sensor at the new place
(:class:`~pytest_metamorphic.lidar.followups.insert.InsertObject`): density follows the
new range, it hides what lies behind it there, and what lies before it hides it.

A :class:`Move` is one of three rigid motions (LiRTest's object translation and rotation):

* ``"range"``: along its bearing, up to half as far or up to three times as far (the
  far field; the sensor sees the same face). Never into the near field: from a metre or
  two the sensor would look down onto a roof the template (the faces seen from where it
  stood) lacks; :func:`~pytest_metamorphic.relations.lidar.near_field_insertion` puts
  whole meshes there;
* ``"bearing"``: around the sensor at the same range (the same face, another direction);
* ``"turn"``: turned in place about its own centre. The template holds only the faces the
  sensor saw, so turns stay within :data:`MAX_TURN` degrees: farther, the faces it would
  show were never seen.

:class:`Movable` lists the moves that leave an object on free ground, in clear view and
in scope, smallest first.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.followups.edit import RemoveObject
from pytest_metamorphic.lidar.followups.insert.insertion import InsertObject
from pytest_metamorphic.lidar.followups.insert.placement import _TargetGround
from pytest_metamorphic.lidar.followups.insert.template import ObjectTemplate, Placement
from pytest_metamorphic.lidar.judging.scope import ObstacleScope
from pytest_metamorphic.lidar.model.domain import DEFAULT_DOMAIN, OperatingDomain
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.hdl64 import BeamLayout
from pytest_metamorphic.lidar.model.obstacles import Box

__all__ = ["MAX_TURN", "MOVE_KINDS", "Movable", "Move", "MoveKind", "RelocateObject"]

MoveKind = Literal["range", "bearing", "turn"]
MOVE_KINDS: tuple[MoveKind, ...] = ("range", "bearing", "turn")
MAX_TURN = 30
"""Degrees an object may be turned in place (its template shows only the faces seen)."""
# Candidate amounts per kind: percent of the range, degrees about the sensor, degrees in place.
_AMOUNTS: dict[MoveKind, tuple[int, ...]] = {
    # Farther up to three times the range: the far field (a template's faces stay the
    # ones seen, from farther away; nearer than half the range they would not).
    "range": (5, 10, 15, 20, 25, 30, 40, 50, 75, 100, 150, 200),
    "bearing": tuple(range(2, 181, 2)),
    "turn": (5, 10, 15, 20, 25, MAX_TURN),
}


@dataclass(frozen=True)
class Move:
    """One rigid motion of an object: ``kind`` by ``amount`` (percent of its range for
    ``"range"``, negative nearer; degrees for ``"bearing"`` and ``"turn"``, positive
    counter-clockwise)."""

    kind: MoveKind
    amount: float

    def __post_init__(self) -> None:
        if self.kind not in MOVE_KINDS:
            raise InvalidArgument(f"kind={self.kind!r} must be one of {MOVE_KINDS}")
        amount = self.amount
        if isinstance(amount, bool) or not isinstance(amount, (int, float)):
            raise InvalidArgument(f"amount={amount!r} must be a number")
        if not math.isfinite(amount) or (self.kind == "range" and amount <= -100):
            raise InvalidArgument(f"amount={amount!r} is not a possible {self.kind} move")

    def placement(self, template: ObjectTemplate, ground_z: float) -> Placement:
        """Where ``template`` (seen where it stands) goes after the move."""
        bearing, distance, turn = template.bearing, template.range, 0.0
        if self.kind == "range":
            distance *= 1 + self.amount / 100
        elif self.kind == "bearing":
            bearing = math.remainder(bearing + math.radians(self.amount), 2 * math.pi)
        else:
            turn = math.radians(self.amount)
        return Placement(bearing, distance, ground_z, turn)

    def motion(self, template: ObjectTemplate) -> tuple[float, float, float]:
        """The move as ``(angle, tx, ty)``: a point ``p`` goes to ``R(angle) p + t``."""
        if self.kind == "range":
            shift = template.range * self.amount / 100
            return 0.0, shift * math.cos(template.bearing), shift * math.sin(template.bearing)
        if self.kind == "bearing":
            return math.radians(self.amount), 0.0, 0.0
        angle = math.radians(self.amount)
        px, py = (
            template.range * math.cos(template.bearing),
            template.range * math.sin(template.bearing),
        )
        c, s = math.cos(angle), math.sin(angle)
        return angle, px - (c * px - s * py), py - (s * px + c * py)

    def size(self) -> float:
        """How big the move is, comparable across kinds (Hypothesis shrinks toward small):
        a degree counts as a percent."""
        return abs(self.amount)

    def describe(self) -> str:
        if self.kind == "range":
            way = "nearer" if self.amount < 0 else "farther"
            return f"{abs(self.amount):g} % {way} along its bearing"
        if self.kind == "bearing":
            return f"{self.amount:+g} degrees around the sensor"
        return f"turned {self.amount:+g} degrees in place"


def moved_box(box: Box, motion: tuple[float, float, float]) -> Box:
    """``box`` moved by ``motion`` (:meth:`Move.motion`)."""
    angle, tx, ty = motion
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = box.center
    center = (c * x - s * y + tx, s * x + c * y + ty, z)
    return dataclasses.replace(box, center=center, yaw=math.remainder(box.yaw + angle, 2 * math.pi))


@dataclass(frozen=True, eq=False)
class RelocateObject:
    """One object of a frame moved: removed where it stood, re-cast after ``move``.

    Build it with :meth:`of`; :meth:`apply` takes the frame it was built for.

    Attributes
    ----------
    removal : RemoveObject
        The object taken out (its box: ground truth or a proposal).
    insertion : InsertObject
        The object put back after the move (built onto the frame without it).
    move : Move
    motion : (3,) float
        ``move`` as a rigid motion ``(angle, tx, ty)`` of the plane.
    original : (k, 3) float32
        The object's returns where it stood (what the system saw of it in the source).
    """

    removal: RemoveObject
    insertion: InsertObject
    move: Move
    motion: tuple[float, float, float]
    original: NDArray[np.float32] = field(repr=False)

    @classmethod
    def of(
        cls,
        frame: Frame,
        box: Box,
        move: Move,
        *,
        layout: BeamLayout,
        margin: float = 0.15,
        template: ObjectTemplate | None = None,
        without: Frame | None = None,
        ground: _TargetGround | None = None,
    ) -> RelocateObject | None:
        """``box``'s object in ``frame`` moved by ``move``, or None when the new place is
        not free ground in clear view (``template``, ``without``: the object's template
        and the frame without it, ``ground``: that frame's ground, when already built)."""
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        if not isinstance(move, Move):
            raise InvalidArgument(f"move={move!r} must be a Move")
        removal = RemoveObject(box, margin)
        chosen = template if template is not None else ObjectTemplate.from_frame(frame, box)
        without = without if without is not None else removal.apply(frame)
        target = ground if ground is not None else _TargetGround(without)
        ground_z = _free_ground(chosen, move, target, box)
        if ground_z is None:
            return None
        insertion = InsertObject.onto(
            without, chosen, move.placement(chosen, ground_z), layout=layout
        )
        original = frame.cloud.xyz[removal.removed(frame)].astype(np.float32)
        return cls(removal, insertion, move, move.motion(chosen), original)

    def __len__(self) -> int:
        return len(self.insertion)

    @property
    def box(self) -> Box:
        """The object's box after the move (the template's, placed)."""
        return self.insertion.box

    @property
    def injected_points(self) -> NDArray[np.float32]:
        """(k, 4) float32: the moved returns where the object went (what a picture draws)."""
        return self.insertion.points

    def expected(self, box: Box) -> Box:
        """Where a source obstacle that was this object should be after the move."""
        return moved_box(box, self.motion)

    def apply(self, frame: Frame) -> Frame:
        if not isinstance(frame, Frame):
            raise InvalidArgument(f"frame must be a Frame, got {type(frame).__name__}")
        return self.insertion.apply(self.removal.apply(frame))

    def region(self) -> Box:
        """Where the object stood (what :class:`OthersKept` measures distances from)."""
        return self.removal.region()

    def affects(self, box: Box, clearance: float) -> bool:
        """Whether the move may fairly change what is detected at ``box``: near where the
        object stood or now stands, or in either place's shadow."""
        return self.removal.affects(box, clearance) or self.insertion.affects(box, clearance)

    def params(self) -> dict[str, Any]:
        return {
            "relocated_object": self.removal.box.describe(),
            "move": self.move.describe(),
            "moved_to": self.box.describe(),
            "moved_returns": len(self.insertion),
            "relocate_object": self,
        }

    def describe_edit(self) -> str:
        return f"{self.removal.box.describe()} moved {self.move.describe()}"

    # Not reducible by returns (no ``restrict``): a moved object cut to a few returns is
    # another object. What a violation reduces to is the smallest move, which Hypothesis
    # shrinks to (the moves are listed smallest first).

    def to_json(self) -> dict[str, Any]:
        return {
            "type": "RelocateObject",
            "removal": self.removal.to_json(),
            "insertion": self.insertion.to_json(),
            "move": {"kind": self.move.kind, "amount": self.move.amount},
            "motion": list(self.motion),
            "original": self.original.tolist(),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RelocateObject:
        """The relocation :meth:`to_json` describes (artifacts replay with it)."""
        move = data["move"]
        angle, tx, ty = (float(v) for v in data["motion"])
        return cls(
            RemoveObject.from_json(data["removal"]),
            InsertObject.from_json(data["insertion"]),
            Move(move["kind"], float(move["amount"])),
            (angle, tx, ty),
            np.asarray(data["original"], dtype=np.float32).reshape(-1, 3),
        )

    def __repr__(self) -> str:
        return f"RelocateObject({self.describe_edit()}, {len(self)} returns)"


@dataclass(frozen=True, eq=False)
class Movable:
    """An object of a frame ready to move: its template, the frame without it and that
    frame's ground (built once, for many moves). Build it with :meth:`of`."""

    frame: Frame
    box: Box
    template: ObjectTemplate
    without: Frame
    ground: _TargetGround
    margin: float = 0.15

    @classmethod
    def of(
        cls, frame: Frame, box: Box, *, margin: float = 0.15, min_returns: int = 30
    ) -> Movable | None:
        """``box``'s object of ``frame``, or None when its returns make no template of
        ``min_returns`` returns."""
        try:
            template = ObjectTemplate.from_frame(frame, box, margin=margin)
        except InvalidArgument:  # too few returns, or no surface (a thin pole)
            return None
        if len(template.vertices) < min_returns:
            return None
        without = RemoveObject(box, margin).apply(frame)
        return cls(frame, box, template, without, _TargetGround(without), margin)

    def moves(
        self,
        *,
        layout: BeamLayout,
        scope: ObstacleScope,
        kinds: Sequence[MoveKind] = MOVE_KINDS,
        limit: int = 24,
        domain: OperatingDomain = DEFAULT_DOMAIN,
    ) -> dict[MoveKind, list[Move]]:
        """For each of ``kinds``, up to ``limit`` moves that leave the object on free
        ground (no return above the local ground in its footprint grown by 0.5 m), in
        clear view, judged by ``scope`` and within 90 % of ``domain``'s far limit
        (:meth:`~pytest_metamorphic.lidar.model.domain.OperatingDomain.far_limit`),
        smallest first."""
        far = domain.far_limit(layout.max_range)
        found: dict[MoveKind, list[Move]] = {}
        for kind in kinds:
            moves = [move for move in _candidates(kind) if self._free(move, layout, scope, far)]
            if moves:
                found[kind] = moves[:limit]
        return found

    def _free(self, move: Move, layout: BeamLayout, scope: ObstacleScope, far: float) -> bool:
        placement = move.placement(self.template, 0.0)
        if not layout.min_range + 2.0 < placement.range < 0.9 * far:
            return False
        if _free_ground(self.template, move, self.ground, self.box) is None:
            return False
        return bool(scope.judged([self.template.box_at(placement)], self.frame)[0])

    def relocate(self, move: Move, *, layout: BeamLayout) -> RelocateObject | None:
        """The object moved by ``move`` (None: the place is not free)."""
        return RelocateObject.of(
            self.frame, self.box, move, layout=layout, margin=self.margin,
            template=self.template, without=self.without, ground=self.ground,
        )  # fmt: skip


def _free_ground(
    template: ObjectTemplate, move: Move, ground: _TargetGround, vacated: Box
) -> float | None:
    """The ground height where ``move`` puts ``template``, when that is free seen ground
    in clear view (``vacated``: where it stood, its stray returns not counted), else None."""
    probe = template.box_at(move.placement(template, 0.0))
    height = ground.ground_under(probe, vacated=vacated)
    if height is None or not ground.in_clear_view(probe):
        return None
    return height


def _candidates(kind: MoveKind) -> list[Move]:
    """Moves of ``kind``, smallest first (each amount both ways)."""
    moves = []
    for amount in _AMOUNTS[kind]:
        for sign in (1, -1):
            if kind == "range" and sign < 0 and amount >= 50:
                continue  # half the range at most: the template's returns stay dense enough
            moves.append(Move(kind, sign * amount))
    return moves
