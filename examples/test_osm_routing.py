"""Metamorphic testing of a router on real OpenStreetMap streets.

Which route from A to B is shortest has no easy oracle on a real street network. A relation
does (Zhou & Sun's routing relation): **forbidding a street never makes the best route
shorter.** And forbidding a street the best route does not use leaves its length unchanged.

The system under test is scipy's Dijkstra over the street graph read from the OSM files in
``../shared/data/osm_osmnx/`` (a Bavarian village and West Oakland), one-way streets
respected. Copy this file and replace ``route_length`` with a call to your router.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cache

import numpy as np
import pytest
from hypothesis import settings
from hypothesis import strategies as st
from scipy.sparse import csr_array
from scipy.sparse.csgraph import dijkstra

from conftest import shared_data_path
from pytest_metamorphic import (
    DataError,
    Followup,
    MetamorphicRelation,
    MetamorphicViolation,
    metamorphic,
    relations,
)
from pytest_metamorphic.driving.osm import StreetGraph, street_graph

MAPS = {
    "bavaria": ("osm_osmnx", "planet_10.068,48.135_10.071,48.137.osm"),
    "west-oakland": ("osm_osmnx", "West-Oakland.osm.bz2"),
}


@cache
def graph(name: str) -> StreetGraph:
    return street_graph(shared_data_path(*MAPS[name]))


@dataclass(frozen=True)
class Trip:
    """A route from node ``origin`` to ``target`` in ``city``, avoiding ``forbidden`` ways."""

    city: str
    origin: int
    target: int
    forbidden: frozenset[int] = frozenset()


def without_forbidden(trip: Trip) -> StreetGraph:
    """The trip's street graph with the forbidden ways' edges removed."""
    streets = graph(trip.city)
    keep = ~np.isin(streets.way_ids, list(trip.forbidden))
    return replace(
        streets, edges=streets.edges[keep], lengths=streets.lengths[keep],
        way_ids=streets.way_ids[keep],
    )  # fmt: skip


def route_length(trip: Trip) -> float:
    """The system under test: shortest route length in metres (inf when unreachable)."""
    matrix = without_forbidden(trip).csgraph()
    return float(dijkstra(matrix, directed=True, indices=trip.origin)[trip.target])


def zeroing_route_length(trip: Trip) -> float:
    """A realistic bug: "removing" forbidden streets by zeroing their weights. In a scipy
    sparse graph an explicitly stored 0 is a *free* edge, not a missing one."""
    streets = graph(trip.city)
    n = len(streets)
    lengths = np.where(np.isin(streets.way_ids, list(trip.forbidden)), 0.0, streets.lengths)
    matrix = csr_array((lengths, (streets.edges[:, 0], streets.edges[:, 1])), shape=(n, n))
    return float(dijkstra(matrix, directed=True, indices=trip.origin)[trip.target])


@st.composite
def trips(draw: st.DrawFn) -> Trip:
    city = draw(st.sampled_from(sorted(MAPS)))
    n = len(graph(city))
    return Trip(city, draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1)))


def forbid_a_street(trip: Trip) -> st.SearchStrategy[Followup]:
    ways = sorted(set(graph(trip.city).way_ids.tolist()))
    return st.sampled_from(ways).map(
        lambda way: Followup(
            Trip(trip.city, trip.origin, trip.target, trip.forbidden | {way}),
            params={"forbidden_way": way},
        )
    )


def never_shorter(before: float, after: float, context: object) -> bool:
    # Tolerance: floating sums of the same edges in another order.
    return after >= before - 1e-6


def forbid_an_unused_street(trip: Trip) -> st.SearchStrategy[Followup]:
    streets = graph(trip.city)
    try:
        route, _ = streets.shortest_path(trip.origin, trip.target)
    except DataError:  # unreachable: no street is used
        route = [trip.origin]
    used_nodes = set(route)
    on_route = {
        int(way)
        for (a, b), way in zip(streets.edges.tolist(), streets.way_ids.tolist(), strict=True)
        if a in used_nodes and b in used_nodes
    }
    unused = sorted(set(streets.way_ids.tolist()) - on_route)
    if not unused:
        return st.just(Followup(trip, params={"forbidden_way": None}))
    return st.sampled_from(unused).map(
        lambda way: Followup(
            Trip(trip.city, trip.origin, trip.target, trip.forbidden | {way}),
            params={"forbidden_way": way},
        )
    )


ROUTING_RELATIONS = [
    MetamorphicRelation(
        "forbidding a street never shortens the route",
        forbid_a_street,
        relations.predicate(never_shorter, name="length' >= length"),
    ),
    MetamorphicRelation(
        "forbidding an unused street keeps the length",
        forbid_an_unused_street,
        relations.approx(abs=1e-6),
    ),
]


def routing_test(
    router: Callable[[Trip], float], *, derandomize: bool = False
) -> Callable[[], None]:
    @settings(max_examples=60, database=None, derandomize=derandomize)
    @metamorphic(source=trips(), relations=ROUTING_RELATIONS, followups=3)
    def check(trip: Trip) -> float:
        return router(trip)

    return check


test_routing_relations = routing_test(route_length)


def test_relations_catch_zeroed_instead_of_removed_edges() -> None:
    with pytest.raises(MetamorphicViolation, match="forbidding a street never shortens"):
        # Derandomized: a test that asserts the bug is found must not depend on the seed.
        routing_test(zeroing_route_length, derandomize=True)()
