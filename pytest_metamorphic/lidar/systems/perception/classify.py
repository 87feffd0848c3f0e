"""Rule-based object classification from box shape and height above the ground.

Apollo classifies with a CNN; without learned weights, the reference pipeline decides
from the MinBox footprint (length >= width), the vertical extent of the points, and the
object's top and bottom above the local ground, and nothing else, so the class is as
stable as the box is. The default ranges come from typical sizes (KITTI's label
statistics: cars about 3.9 x 1.6 x 1.5 m, pedestrians about 0.8 x 0.6 x 1.8 m, cyclists
about 1.8 x 0.6 x 1.7 m), widened for partial views: a LiDAR sees one or two sides of an
object, so a footprint is often shorter or narrower than the real one (a car seen from
behind is about 1.7 x 0.5 m). Classes are tried in the order car, cyclist, pedestrian;
a class matches when any of its rules does; anything else is ``"unknown"``. Footprints
narrower than 0.15 m are poles and posts, not people.

A car seen from behind and a cyclist seen from the side have the same footprint and
height (about 1.5 x 0.5 x 1.3 m); what tells them apart is the *crown*, how far the
returns within 0.35 m of the object's top reach along its length: a car's roof edge and
rear window 0.8-1.6 m, a rider's head and shoulders at most 0.5 m (measured on the KITTI
sweeps and rendered streets). Without it, a cyclist whose returns happened to span 1.30
instead of 1.31 m was a car (found by inserting a cyclist 22.5 m away).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.lidar.model.obstacles import Label

__all__ = ["CROWN_BAND", "ClassRule", "ClassifierParams", "ObjectShape", "classify"]

CROWN_BAND = 0.35
"""Metres below an object's top whose returns make its crown (see :class:`ObjectShape`)."""


@dataclass(frozen=True)
class ClassRule:
    """Closed ranges (metres) an object must fall in to get one class.

    ``length`` and ``width`` are the box footprint (length >= width), ``height`` the
    vertical extent of the points, ``top`` and ``bottom`` the heights above the local
    ground of the object's highest and lowest point, ``crown`` how far the returns near
    the top reach along the length (not checked for shapes without it).
    """

    length: tuple[float, float]
    width: tuple[float, float]
    top: tuple[float, float]
    height: tuple[float, float] = (0.0, 10.0)
    bottom: tuple[float, float] = (-1.0, 0.6)
    crown: tuple[float, float] = (0.0, 100.0)

    def __post_init__(self) -> None:
        for item in fields(self):
            low, high = getattr(self, item.name)
            if not low <= high:
                raise InvalidArgument(f"{item.name}=({low}, {high}) must have low <= high")

    def matches(self, shape: ObjectShape) -> NDArray[np.bool_]:
        """(k,) bool: which objects fall inside every range."""
        result = np.ones(len(shape.length), dtype=bool)
        for item in fields(self):
            low, high = getattr(self, item.name)
            value = getattr(shape, item.name)
            if value is not None:
                result &= (value >= low) & (value <= high)
        return result


@dataclass(frozen=True)
class ObjectShape:
    """Shape features of ``k`` objects, each a (k,) float64 array in metres.

    ``crown``: the extent along the box length of the returns within :data:`CROWN_BAND`
    of the top (None: not measured, and no rule checks it).
    """

    length: NDArray[np.float64]
    width: NDArray[np.float64]
    height: NDArray[np.float64]
    top: NDArray[np.float64]
    bottom: NDArray[np.float64]
    crown: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class ClassifierParams:
    """The rules of :func:`classify`: per class, a tuple of alternative rules."""

    car: tuple[ClassRule, ...] = (
        # Side or corner view. Thinner than 0.3 m is a wall or fence; vans reach 2.3 m.
        ClassRule(length=(2.2, 6.5), width=(0.3, 2.8), top=(0.9, 2.3)),
        # Seen from behind or in front: the car's width becomes the box length, the
        # box is shallow, and the points span less height than a standing person; its
        # roof edge spans most of that length (a cyclist's rider does not).
        ClassRule(
            length=(1.3, 2.2), width=(0.3, 2.2), top=(0.9, 2.0), height=(0.3, 1.3), crown=(0.6, 2.2)
        ),
    )
    cyclist: tuple[ClassRule, ...] = (
        ClassRule(length=(1.2, 2.2), width=(0.15, 0.8), top=(1.2, 2.1), height=(0.8, 2.1)),
    )
    pedestrian: tuple[ClassRule, ...] = (
        ClassRule(length=(0.2, 1.2), width=(0.15, 1.0), top=(1.1, 2.1), height=(0.8, 2.1)),
    )


def classify(shape: ObjectShape, params: ClassifierParams = ClassifierParams()) -> list[Label]:
    """Label objects from their shape.

    Parameters
    ----------
    shape : ObjectShape
        Footprint, extent and heights above ground of ``k`` objects.
    params : ClassifierParams

    Returns
    -------
    list of {"car", "pedestrian", "cyclist", "unknown"}, length k
    """
    labels = np.full(len(shape.length), "unknown", dtype=object)
    undecided = np.ones(len(shape.length), dtype=bool)
    for name in ("car", "cyclist", "pedestrian"):
        hit = np.zeros(len(shape.length), dtype=bool)
        for rule in getattr(params, name):
            hit |= rule.matches(shape)
        hit &= undecided
        labels[hit] = name
        undecided &= ~hit
    return labels.tolist()
