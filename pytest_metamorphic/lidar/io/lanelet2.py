"""Lanelet2 maps (the OSM-XML HD-map format Autoware uses): each lane as its left and right
bounds, in local metres.

A Lanelet2 file is OSM XML: nodes (with ``local_x``/``local_y`` tags in Autoware's maps,
otherwise latitude and longitude), ways (line strings: kerbs, lane markings) and
relations; a ``type=lanelet`` relation names its ``left`` and ``right`` ways. The file is
parsed by the hardened OSM reader (:func:`pytest_metamorphic.driving.osm.read_osm`: no
DOCTYPE, no entities, size limits). A lane's area is its left bound followed by its right
bound reversed (both run in the driving direction; a way stored the other way round is
turned, as Lanelet2 itself does).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.driving.osm import OsmData, read_osm
from pytest_metamorphic.driving.osm.projection import LocalProjection

__all__ = ["Lanelet", "read_lanelet2"]


@dataclass(frozen=True, eq=False)
class Lanelet:
    """One lane of a Lanelet2 map.

    Attributes
    ----------
    id : int
    subtype : str
        ``road``, ``highway``, ``crosswalk``, ``walkway``, ... ("" when untagged).
    left, right : (k, 2) float64
        Its bounds in the map's local metres (x east, y north), in the driving direction.
    """

    id: int
    subtype: str
    left: NDArray[np.float64] = field(repr=False)
    right: NDArray[np.float64] = field(repr=False)

    def polygon(self) -> NDArray[np.float64]:
        """(k, 2) float64: the lane's area, left bound then right bound reversed."""
        return np.concatenate([self.left, self.right[::-1]])


MAX_LOCAL_M = 1e6
"""The farthest a node's ``local_x`` / ``local_y`` may lie from the map's origin (1000 km:
a map's local frame covers a city; beyond, polygon areas lose their precision)."""


def read_lanelet2(
    path: str | os.PathLike[str], *, origin: tuple[float, float] | None = None
) -> tuple[Lanelet, ...]:
    """Every lanelet of a Lanelet2 OSM file, in file order.

    Parameters
    ----------
    path : path-like
    origin : (lat, lon), optional
        Where local metres start, for maps without ``local_x``/``local_y`` node tags
        (default: the centre of the map's nodes). Ignored when every node has them.

    Raises
    ------
    DataError
        Not OSM XML, no lanelet, or a lanelet whose ``left``/``right`` way or their
        nodes are missing (the message names the file and the lanelet).
    """
    data = read_osm(Path(path))
    xy = _node_positions(data, origin)
    ways = {way.id: way for way in data.ways}
    lanelets = []
    for relation in data.relations:
        if relation.tags.get("type") != "lanelet":
            continue
        bounds = {}
        for kind, ref, role in relation.members:
            if kind == "way" and role in ("left", "right"):
                way = ways.get(ref)
                if way is None:
                    raise DataError(
                        f"lanelet {relation.id}: its {role} way {ref} is not in the file", path=path
                    )
                missing = [n for n in way.node_ids if n not in xy]
                if missing or len(way.node_ids) < 2:
                    what = f"missing nodes {missing[:3]}" if missing else "fewer than 2 nodes"
                    raise DataError(
                        f"lanelet {relation.id}: its {role} way {ref} has {what}", path=path
                    )
                bounds[role] = np.array([xy[n] for n in way.node_ids], dtype=np.float64)
        if set(bounds) != {"left", "right"}:
            raise DataError(f"lanelet {relation.id} needs a left and a right way", path=path)
        left, right = bounds["left"], bounds["right"]
        if np.linalg.norm(left[0] - right[0]) > np.linalg.norm(left[0] - right[-1]):
            right = right[::-1]  # stored against the driving direction
        lanelets.append(Lanelet(relation.id, relation.tags.get("subtype", ""), left, right))
    if not lanelets:
        raise DataError("holds no lanelet (no relation tagged type=lanelet)", path=path)
    return tuple(lanelets)


def _node_positions(
    data: OsmData, origin: tuple[float, float] | None
) -> dict[int, NDArray[np.float64]]:
    nodes = data.nodes
    if nodes and all("local_x" in n.tags and "local_y" in n.tags for n in nodes.values()):
        positions = {}
        for node in nodes.values():
            try:
                x, y = float(node.tags["local_x"]), float(node.tags["local_y"])
            except ValueError:
                raise DataError(
                    f"node {node.id}: local_x/local_y are not numbers", path=data.path
                ) from None
            if not (math.isfinite(x) and math.isfinite(y)):
                raise DataError(f"node {node.id}: local_x/local_y are not finite", path=data.path)
            if max(abs(x), abs(y)) > MAX_LOCAL_M:
                # A point at 1e308 m made every polygon's area overflow: refused as
                # "collinear", naming neither the map nor the point.
                raise DataError(
                    f"node {node.id}: local_x/local_y = ({x:.6g}, {y:.6g}) lies more than "
                    f"{MAX_LOCAL_M:.0f} m from the map's origin",
                    path=data.path,
                )
            positions[node.id] = np.array([x, y])
        return positions
    if not nodes:
        return {}
    if origin is None:
        projection = LocalProjection.about(
            [n.lat for n in nodes.values()], [n.lon for n in nodes.values()]
        )
    else:
        try:
            projection = LocalProjection(float(origin[0]), float(origin[1]))
        except (TypeError, ValueError, IndexError):
            raise InvalidArgument(f"origin={origin!r} must be (lat, lon) in degrees") from None
    ids = list(nodes)
    local = projection.to_local([nodes[i].lat for i in ids], [nodes[i].lon for i in ids])
    return dict(zip(ids, local, strict=True))
