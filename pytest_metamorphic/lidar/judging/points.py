"""Judging a labelling or a partition point by point.

:class:`PointsKeepLabels` is the output relation of the component relations
(:mod:`pytest_metamorphic.relations.lidar.components`): every judged return keeps, in the
follow-up, the label (``kind="labels"``) or the cluster (``kind="clusters"``) the component
gave it in the source. Which follow-up return is which source return is decided by
:mod:`.correspondence`; a repeated return is judged against its original.

**Which returns are judged.** Returns the follow-up kept, farther than ``radius`` metres
from everything it changed (its new returns and the ones it removed), optionally only
those inside the source's ROI (``within="roi"``). With ``radius=0`` every kept return is
judged (reordering and repeating change no return, so all must keep their labels).

**Partitions** are compared by pair agreement: cluster ids are arbitrary, so each source
cluster is paired with the follow-up cluster holding most of its judged returns, and each
follow-up cluster with the source cluster most of its returns came from. A return
*changed cluster* when its follow-up cluster is not its source cluster's partner, or its
source cluster is not its follow-up cluster's partner (a split, a merge), or when it turned
from noise into a cluster member or back. DBSCAN's border points are the stated exception:
a point within ``eps`` of the core points of two clusters joins whichever the scan reaches
first, which depends on the order of the points (Ester et al. 1996, scikit-learn's
``DBSCAN`` documentation). With ``border=eps``, a return that moved to the partner of
another source cluster is allowed when that cluster held a source return within ``border``
metres of it; a whole cluster merged into its neighbour is still a change (its returns far
from the neighbour are not border points), and so is any change to or from noise (border
points are never noise).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.relations import CheckContext, Relation, Verdict
from pytest_metamorphic.lidar.judging.correspondence import (
    PointCorrespondence,
    corresponding_points,
)
from pytest_metamorphic.lidar.model.frame import Frame
from pytest_metamorphic.lidar.model.point_outputs import (
    NOISE,
    Partition,
    PointLabels,
    PointOutputKind,
    as_point_output,
)

__all__ = ["PointsKeepLabels", "changed_clusters"]

SHOWN_POINTS = 5
"""Changed returns an explanation names before "... n more"."""
KEPT_INDICES = 200
"""Changed returns (source indices) a verdict's details keep."""
# DBSCAN counts neighbours at distance <= eps; float32 coordinates put one exactly eps
# away a few micrometres either side.
_ROUNDING = 1e-5


def _non_negative(value: Any, name: str) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value < 0
    ):
        raise InvalidArgument(f"{name}={value!r} must be a finite number of metres >= 0")
    return float(value)


def _partners(keys: NDArray[np.intp], values: NDArray[np.intp], size: int) -> NDArray[np.intp]:
    """(size,) intp: for each key 0..size-1, the value it is paired with most often (ties:
    the smallest value; -1 for a key never seen)."""
    partner = np.full(size, -1, dtype=np.intp)
    if len(keys) == 0:
        return partner
    pairs, counts = np.unique(np.stack([keys, values]), axis=1, return_counts=True)
    order = np.lexsort((pairs[1], -counts, pairs[0]))
    pairs = pairs[:, order]
    first = np.ones(pairs.shape[1], dtype=bool)
    first[1:] = pairs[0, 1:] != pairs[0, :-1]
    partner[pairs[0, first]] = pairs[1, first]
    return partner


def changed_clusters(
    source: NDArray[np.int64], followup: NDArray[np.int64]
) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
    """Pair agreement of two partitions of the same returns (see the module docstring).

    Parameters
    ----------
    source, followup : (n,) int
        The cluster of each return on either side (``NOISE`` for none).

    Returns
    -------
    changed : (n,) bool
        Returns that changed cluster.
    moved_to : (n,) int
        For each return, the source cluster its follow-up cluster is the partner of
        (``NOISE`` when it has none), for telling merges from splits.
    """
    source = np.asarray(source, dtype=np.int64)
    followup = np.asarray(followup, dtype=np.int64)
    # Cluster ids are arbitrary ints: number them 0..k-1 on each side first.
    source_ids, a = np.unique(source, return_inverse=True)
    followup_ids, b = np.unique(followup, return_inverse=True)
    a, b = a.reshape(-1), b.reshape(-1)
    both = (source != NOISE) & (followup != NOISE)
    forward = _partners(a[both], b[both], len(source_ids))
    backward = _partners(b[both], a[both], len(followup_ids))
    moved = backward[b]
    moved_to = np.where(moved >= 0, source_ids[np.maximum(moved, 0)], NOISE)
    changed = (source == NOISE) != (followup == NOISE)
    changed |= both & ((b != forward[a]) | (a != moved))
    return changed, moved_to


class PointsKeepLabels(Relation):
    """Every judged return keeps its label or cluster (see the module docstring).

    Parameters
    ----------
    kind : {"labels", "clusters"}
        What the component outputs: a
        :class:`~pytest_metamorphic.lidar.model.point_outputs.PointLabels` or a
        :class:`~pytest_metamorphic.lidar.model.point_outputs.Partition` (or a bare (n,)
        int array read as one).
    radius : float
        Metres: returns nearer than this to a change of the follow-up are not judged.
    within : {"all", "roi"}
        ``"roi"``: only returns inside the source's ROI are judged.
    border : float
        Partitions only: DBSCAN's ``eps``, allowing border points to change sides.
    max_changed : int
        Changed returns tolerated (0: none).
    boundary_margin : float
        Metres: returns this near the source ROI's edge are not judged (a turned or
        mirrored ROI is rasterised afresh, so an ROI-first component's input differs there).
    """

    def __init__(
        self,
        kind: PointOutputKind,
        *,
        radius: float = 0.0,
        within: Literal["all", "roi"] = "all",
        border: float = 0.0,
        max_changed: int = 0,
        boundary_margin: float = 0.0,
    ) -> None:
        if kind not in ("labels", "clusters"):
            raise InvalidArgument(f"kind={kind!r} must be 'labels' or 'clusters'")
        if within not in ("all", "roi"):
            raise InvalidArgument(f"within={within!r} must be 'all' or 'roi'")
        if isinstance(max_changed, bool) or not isinstance(max_changed, int) or max_changed < 0:
            raise InvalidArgument(f"max_changed={max_changed!r} must be an int >= 0")
        self.kind: PointOutputKind = kind
        self.radius = _non_negative(radius, "radius")
        self.border = _non_negative(border, "border")
        self.boundary_margin = _non_negative(boundary_margin, "boundary_margin")
        if self.border and kind != "clusters":
            raise InvalidArgument("border= applies to partitions (kind='clusters') only")
        self.within = within
        self.max_changed = max_changed
        what = "label" if kind == "labels" else "cluster"
        where = f" farther than {self.radius:g} m from the change" if self.radius else ""
        self.name = (
            f"every return{where}{' in the ROI' if within == 'roi' else ''} keeps its {what}"
        )

    def check(self, source_output: Any, followup_output: Any, context: CheckContext) -> Verdict:
        source_frame, followup_frame = context.source_input, context.followup_input
        if not isinstance(source_frame, Frame) or not isinstance(followup_frame, Frame):
            raise InvalidArgument("a point-by-point relation needs Frame inputs on both sides")
        source = as_point_output(
            source_output, self.kind, points=len(source_frame.cloud), name="the source output"
        )
        followup = as_point_output(
            followup_output,
            self.kind,
            points=len(followup_frame.cloud),
            name="the follow-up output",
        )
        match = corresponding_points(source_frame, followup_frame, context.params)
        judged, counts = self._judged(source_frame, source.labels, match)
        rows = np.flatnonzero(match.origin >= 0)
        rows = rows[judged[match.origin[rows]]]
        before, after = source.labels[match.origin[rows]], followup.labels[rows]
        if self.kind == "labels":
            changed = before != after
            allowed = 0
        else:
            changed, moved_to = changed_clusters(before, after)
            changed, allowed = self._allow_border(
                changed, before, after, moved_to, source_frame, source.labels, match.origin[rows]
            )
        flipped = np.flatnonzero(changed)
        if self.kind == "labels":
            kinds = _label_changes(source, before[flipped], after[flipped])
        else:
            kinds = _cluster_changes(before[flipped], after[flipped], moved_to[flipped])
        details: dict[str, Any] = {
            "judged": len(rows),
            **counts,
            "changed": len(flipped),
            "border_allowed": allowed,
            "changed_points": match.origin[rows][flipped][:KEPT_INDICES].tolist(),
            "followup_points": rows[flipped][:KEPT_INDICES].tolist(),
        }
        if len(rows) == 0:
            return Verdict(True, self.name, "no return judged", details | {"judged_nothing": True})
        if len(flipped) <= self.max_changed:
            return Verdict(True, self.name, "", details)
        return Verdict(
            False,
            self.name,
            self._explain(flipped, kinds, source_frame, match, rows, len(rows)),
            details,
        )

    def _judged(
        self, frame: Frame, labels: NDArray[np.int64], match: PointCorrespondence
    ) -> tuple[NDArray[np.bool_], dict[str, int]]:
        xyz = frame.cloud.xyz
        far = match.far_from_change(xyz, self.radius)
        judged = match.kept & far
        counts = {"near_change": int(np.count_nonzero(match.kept & ~far))}
        if self.within == "roi":
            if frame.roi is None:
                raise InvalidArgument("within='roi' needs source frames with an ROI")
            inside = np.asarray(frame.roi.contains(xyz[:, :2]), dtype=bool)
            counts["outside_roi"] = int(np.count_nonzero(judged & ~inside))
            judged &= inside
        if self.boundary_margin and frame.roi is not None:
            inner = np.asarray(frame.roi.boundary_distance(xyz[:, :2])) > self.boundary_margin
            counts["near_roi_edge"] = int(np.count_nonzero(judged & ~inner))
            judged &= inner
        # Copies of one return labelled differently in the source: no label to keep.
        group = match.source_group
        if len(group):
            low = np.full(int(group.max()) + 1, np.iinfo(np.int64).max)
            high = np.full(int(group.max()) + 1, np.iinfo(np.int64).min)
            np.minimum.at(low, group, labels)
            np.maximum.at(high, group, labels)
            ambiguous = low[group] != high[group]
            counts["ambiguous_copies"] = int(np.count_nonzero(judged & ambiguous))
            judged &= ~ambiguous
        return judged, counts

    def _allow_border(
        self,
        changed: NDArray[np.bool_],
        before: NDArray[np.int64],
        after: NDArray[np.int64],
        moved_to: NDArray[np.int64],
        frame: Frame,
        labels: NDArray[np.int64],
        origins: NDArray[np.intp],
    ) -> tuple[NDArray[np.bool_], int]:
        candidates = np.flatnonzero(
            changed
            & (before != NOISE)
            & (after != NOISE)
            & (moved_to != NOISE)
            & (moved_to != before)
        )
        if not self.border or len(candidates) == 0:
            return changed, 0
        xyz = frame.cloud.xyz.astype(np.float64)
        tree = cKDTree(xyz)
        allowed = [
            index
            for index, near in zip(
                candidates,
                tree.query_ball_point(xyz[origins[candidates]], self.border + _ROUNDING),
                strict=True,
            )
            if np.any(labels[np.asarray(near, dtype=np.intp)] == moved_to[index])
        ]
        changed = changed.copy()
        changed[allowed] = False
        return changed, len(allowed)

    def _explain(
        self,
        flipped: NDArray[np.intp],
        kinds: tuple[NDArray[np.intp], list[str]],
        frame: Frame,
        match: PointCorrespondence,
        rows: NDArray[np.intp],
        judged: int,
    ) -> str:
        codes, names = kinds
        counts = np.bincount(codes, minlength=len(names))
        summary = ", ".join(
            f"{counts[code]} {names[code]}"
            for code in sorted(np.flatnonzero(counts).tolist(), key=lambda c: (-counts[c], c))
        )
        origins = match.origin[rows][flipped]
        xyz = frame.cloud.xyz[origins].astype(np.float64)
        if len(match.changed):
            nearest, _ = cKDTree(match.changed).query(xyz)
            distance = (
                f"; the nearest is {float(np.min(nearest)):.2f} m from the follow-up's change"
            )
        else:
            distance = "; the follow-up added and removed no return"
        seen: set[int] = set()
        named = []
        for origin, (x, y, z), code in zip(
            origins[:SHOWN_POINTS].tolist(),
            xyz[:SHOWN_POINTS],
            codes[:SHOWN_POINTS].tolist(),
            strict=True,
        ):
            what = names[code]
            # A repeated return and its original are one source return, changed twice.
            repeat = " (its repeat)" if origin in seen else ""
            seen.add(origin)
            named.append(f"#{origin}{repeat} at ({x:.2f}, {y:.2f}, {z:.2f}): {what}")
        shown = "; ".join(named)
        more = f"; ... {len(flipped) - SHOWN_POINTS} more" if len(flipped) > SHOWN_POINTS else ""
        allowed = f" (at most {self.max_changed} allowed)" if self.max_changed else ""
        head = f"{len(flipped)} of {judged} judged returns changed{allowed}"
        return f"{head}: {summary}{distance}. {shown}{more}"


def _label_changes(
    labels: PointLabels | Partition, before: NDArray[np.int64], after: NDArray[np.int64]
) -> tuple[NDArray[np.intp], list[str]]:
    """Each changed return's kind of change as a code into the names ("ground -> not
    ground"), vectorised: a violation may change tens of thousands of returns."""
    if len(before) == 0:
        return np.empty(0, dtype=np.intp), []
    low = min(int(before.min()), int(after.min()))
    span = max(int(before.max()), int(after.max())) - low + 1
    keys, codes = np.unique((before - low) * span + (after - low), return_inverse=True)
    names = [
        f"{_name(labels, key // span + low)} -> {_name(labels, key % span + low)}"
        for key in keys.tolist()
    ]
    return np.asarray(codes, dtype=np.intp).reshape(-1), names


_CLUSTER_CHANGES = [
    "noise -> a cluster",
    "cluster -> noise",
    "joined another cluster",
    "split off its cluster",
]


def _cluster_changes(
    before: NDArray[np.int64], after: NDArray[np.int64], moved_to: NDArray[np.int64]
) -> tuple[NDArray[np.intp], list[str]]:
    """Each changed return's kind of change, as a code into :data:`_CLUSTER_CHANGES`."""
    codes = np.full(len(before), 3, dtype=np.intp)
    codes[(moved_to != NOISE) & (moved_to != before)] = 2
    codes[after == NOISE] = 1
    codes[before == NOISE] = 0
    return codes, _CLUSTER_CHANGES


def _name(labels: PointLabels | Partition, value: Any) -> str:
    return labels.name(int(value)) if isinstance(labels, PointLabels) else str(int(value))
