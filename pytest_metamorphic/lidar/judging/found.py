"""Whether an object put into a sweep (inserted, moved) was found, and as what.

A follow-up that places a known object knows its returns and its class; the detector's
output holds it when its boxes hold enough of those returns, and holds it *as that
class* when the boxes holding them carry the class. :func:`found_as` measures both;
:data:`CLASS_RULES` names what counts as the object's class.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import Box
from pytest_metamorphic.lidar.model.obstacles.box import _as_xyz

__all__ = ["CLASS_RULES", "ClassRule", "Found", "accepted_labels", "check_class_rule", "found_as"]

ClassRule = Literal["own", "own_or_unknown", "any"]
CLASS_RULES: tuple[ClassRule, ...] = ("own", "own_or_unknown", "any")
"""How an object's class is judged: ``"own"`` (boxes of its class only),
``"own_or_unknown"`` (its class, or ``"unknown"``: a detector that cannot tell what a far
or sparse object is has still not missed it, and has not called it something else),
``"any"`` (any class: only whether it was found)."""


def accepted_labels(label: str, rule: ClassRule) -> frozenset[str] | None:
    """The labels that count as finding an object of class ``label`` (None: any)."""
    if rule == "any":
        return None
    if rule == "own":
        return frozenset({label})
    if rule == "own_or_unknown":
        return frozenset({label, "unknown"})
    raise InvalidArgument(f"classes={rule!r} must be one of {CLASS_RULES}")


def check_class_rule(rule: object) -> ClassRule:
    """``rule`` validated (an :class:`InvalidArgument` names the accepted values)."""
    if rule not in CLASS_RULES:
        raise InvalidArgument(f"classes={rule!r} must be one of {CLASS_RULES}")
    return rule


@dataclass(frozen=True)
class Found:
    """What a detector's boxes hold of one object's returns.

    Attributes
    ----------
    share : float
        Share of the returns inside any box (grown by 10 cm).
    share_as : float
        Share inside boxes whose label is accepted for the object's class.
    labels : Counter
        How many of the returns each label's boxes hold (a return in two boxes counts
        for both labels).
    """

    share: float
    share_as: float
    labels: Counter[str]

    def main_label(self) -> str | None:
        """The label holding most of the returns (None: none is held)."""
        return self.labels.most_common(1)[0][0] if self.labels else None


def found_as(
    points: ArrayLike, boxes: Sequence[Box], accepted: frozenset[str] | None, *, grow: float = 0.1
) -> Found:
    """How much of the object whose returns are ``points`` (n, 3) ``boxes`` hold, and how
    much of it boxes of an ``accepted`` label hold (None: any label)."""
    xyz = _as_xyz(points)
    if len(xyz) == 0:
        return Found(0.0, 0.0, Counter())
    inside = np.zeros(len(xyz), dtype=bool)
    inside_as = np.zeros(len(xyz), dtype=bool)
    labels: Counter[str] = Counter()
    for box in boxes:
        held = box.grown(grow).contains(xyz)
        if not held.any():
            continue
        inside |= held
        labels[box.label] += int(held.sum())
        if accepted is None or box.label in accepted:
            inside_as |= held
    return Found(float(inside.mean()), float(inside_as.mean()), labels)
