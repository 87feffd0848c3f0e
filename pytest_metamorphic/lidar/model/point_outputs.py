"""Outputs that say something about every point: a labelling and a partition.

A ground segmenter answers, for each return, "ground or not" (a semantic segmenter: which
class); a clusterer answers which object each return belongs to. Neither is a list of
boxes, and neither can be judged by matching boxes: relations compare them point by point
(:mod:`pytest_metamorphic.lidar.judging.points`).

* :class:`PointLabels` - one label per point (ints: ground = 1, non-ground = 0 for a
  ground segmenter, or class ids with their ``names``);
* :class:`Partition` - one cluster id per point, ``-1`` for noise (scikit-learn's and
  Open3D's convention); cluster ids are arbitrary, only which points share one matters.

Both are indexed like the cloud they were computed from: entry ``i`` is about point ``i``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = [
    "GROUND",
    "NOISE",
    "NOT_GROUND",
    "Partition",
    "PointLabels",
    "PointOutputKind",
    "as_point_output",
]

GROUND = 1
"""The label of a ground return in a ground segmenter's :class:`PointLabels`."""
NOT_GROUND = 0
"""The label of any other return."""
NOISE = -1
"""The cluster id of a point no cluster holds (:class:`Partition`)."""

PointOutputKind = Literal["labels", "clusters"]


def _ids(values: Any, name: str) -> NDArray[np.int64]:
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"{name} cannot be converted to an array: {error}") from None
    if array.ndim != 1:
        raise InvalidArgument(f"{name} must be 1-D (one entry per point), got shape {array.shape}")
    if array.dtype == bool:
        array = array.astype(np.int64)
    integral = np.issubdtype(array.dtype, np.integer) or (
        np.issubdtype(array.dtype, np.floating) and bool(np.all(array == np.round(array)))
    )
    if array.size and not integral:
        raise InvalidArgument(f"{name} must hold ints, got dtype {array.dtype}")
    return array.astype(np.int64)


@dataclass(frozen=True, eq=False)
class PointLabels:
    """One label per point of a cloud.

    Parameters
    ----------
    labels : (n,) int
        Label of each point (bools are read as 0/1: a ground mask gives ``GROUND`` = 1).
    names : mapping of int to str, optional
        What each label means, for reports (default for two labels: ground / not ground).
    """

    kind: ClassVar[PointOutputKind] = "labels"
    labels: NDArray[np.int64]
    names: Mapping[int, str] = field(
        default_factory=lambda: {GROUND: "ground", NOT_GROUND: "not ground"}
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "labels", _ids(self.labels, "PointLabels.labels"))
        if not isinstance(self.names, Mapping):
            raise InvalidArgument(
                f"PointLabels.names must be a mapping of int to str, got {self.names!r}"
            )

    def __len__(self) -> int:
        return len(self.labels)

    def name(self, label: int) -> str:
        """What ``label`` means (its number when ``names`` does not say)."""
        return self.names.get(int(label), str(int(label)))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PointLabels) and np.array_equal(self.labels, other.labels)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        values, counts = np.unique(self.labels, return_counts=True)
        shown = ", ".join(
            f"{self.name(v)}: {c}" for v, c in zip(values.tolist(), counts.tolist(), strict=True)
        )
        return f"PointLabels({len(self)} points; {shown})"


@dataclass(frozen=True, eq=False)
class Partition:
    """Clusters of a cloud's points: one id per point, :data:`NOISE` (-1) for none.

    Parameters
    ----------
    labels : (n,) int
        Cluster id of each point; ids are arbitrary (only which points share one matters),
        negative ids are noise.
    """

    kind: ClassVar[PointOutputKind] = "clusters"
    labels: NDArray[np.int64]

    def __post_init__(self) -> None:
        labels = _ids(self.labels, "Partition.labels")
        object.__setattr__(self, "labels", np.where(labels < 0, NOISE, labels))

    def __len__(self) -> int:
        return len(self.labels)

    @property
    def count(self) -> int:
        """The number of clusters (noise not counted)."""
        return len(np.unique(self.labels[self.labels != NOISE]))

    def __eq__(self, other: object) -> bool:
        # The same partition, whatever the ids are called.
        if not isinstance(other, Partition) or len(other) != len(self):
            return False
        if not np.array_equal(self.labels == NOISE, other.labels == NOISE):
            return False
        pairs = np.unique(np.stack([self.labels, other.labels]), axis=1)
        return len(np.unique(pairs[0])) == len(np.unique(pairs[1])) == pairs.shape[1]

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        noise = int(np.count_nonzero(self.labels == NOISE))
        return f"Partition({len(self)} points; {self.count} clusters, {noise} noise)"


def as_point_output(
    value: Any, kind: PointOutputKind, *, points: int, name: str
) -> PointLabels | Partition:
    """``value`` as the point output ``kind`` says, checked against the cloud's size.

    Accepts a :class:`PointLabels` / :class:`Partition` or a bare (n,) int or bool array
    (read as ``kind``). ``name`` says which output it is in errors ("the source output").
    """
    if kind not in ("labels", "clusters"):
        raise InvalidArgument(f"kind={kind!r} must be 'labels' or 'clusters'")
    wanted = PointLabels if kind == "labels" else Partition
    if isinstance(value, (PointLabels, Partition)) and not isinstance(value, wanted):
        raise InvalidArgument(f"{name} is a {type(value).__name__}, but the relation judges {kind}")
    if not isinstance(value, wanted):
        if (
            isinstance(value, (list, tuple))
            and value
            and not isinstance(value[0], (int, np.integer, bool))
        ):
            raise InvalidArgument(
                f"{name} is a list of {type(value[0]).__name__}: a component relation needs one "
                f"{'label' if kind == 'labels' else 'cluster id'} per point"
            )
        value = wanted(value)
    if len(value) != points:
        raise InvalidArgument(
            f"{name} has {len(value)} entries but its input cloud has {points} points: a "
            f"{'labelling' if kind == 'labels' else 'partition'} needs one per point, in the "
            "cloud's order"
        )
    return value
