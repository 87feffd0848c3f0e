"""OSM tags: drivable ``highway`` classes, ``width``, ``lanes``, ``oneway``, cycle and
parking lanes on the carriageway, per-class defaults."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

__all__ = [
    "CYCLE_LANE_WIDTH",
    "DRIVABLE_HIGHWAYS",
    "HIGHWAY_DEFAULTS",
    "PARKING_LANE_WIDTHS",
    "SIDEWALK_WIDTH",
    "HighwayDefaults",
    "parse_lanes",
    "parse_margins",
    "parse_oneway",
    "parse_parking",
    "parse_sidewalks",
    "parse_width",
]

#: ``highway=*`` values a car may drive on.
DRIVABLE_HIGHWAYS = frozenset(
    {
        "motorway", "motorway_link", "trunk", "trunk_link", "primary", "primary_link",
        "secondary", "secondary_link", "tertiary", "tertiary_link", "unclassified",
        "residential", "living_street", "service", "road", "busway",
    }
)  # fmt: skip


@dataclass(frozen=True)
class HighwayDefaults:
    """Per-class assumptions used when a way has no ``width`` tag.

    ``lane_width`` in metres; ``lanes`` for a two-way way and ``oneway_lanes`` for a one-way
    way (OSM's ``lanes`` counts both directions, so one-way roads default to fewer lanes).
    """

    lane_width: float
    lanes: int
    oneway_lanes: int


_ROAD = HighwayDefaults(3.0, 2, 1)
_PATH = HighwayDefaults(2.0, 1, 1)

#: Default lane width and lane counts per ``highway`` class (``*_link`` uses its base class).
#: Typical European/US design values; anything unlisted uses the ``residential`` entry.
HIGHWAY_DEFAULTS: Mapping[str, HighwayDefaults] = MappingProxyType(
    {
        "motorway": HighwayDefaults(3.75, 4, 2),
        "trunk": HighwayDefaults(3.5, 4, 2),
        "primary": HighwayDefaults(3.5, 2, 1),
        "secondary": HighwayDefaults(3.25, 2, 1),
        "tertiary": HighwayDefaults(3.0, 2, 1),
        "unclassified": _ROAD,
        "residential": _ROAD,
        "road": _ROAD,
        "living_street": HighwayDefaults(3.0, 1, 1),
        "service": HighwayDefaults(3.0, 1, 1),
        "busway": HighwayDefaults(3.5, 1, 1),
        "track": HighwayDefaults(2.5, 1, 1),
        "pedestrian": HighwayDefaults(3.0, 1, 1),
        "footway": _PATH,
        "path": _PATH,
        "bridleway": _PATH,
        "steps": _PATH,
        "corridor": _PATH,
        "cycleway": HighwayDefaults(1.5, 1, 1),
    }
)


_NUMBER = r"(\d+(?:\.\d+)?|\.\d+)"
_METRES = re.compile(rf"^{_NUMBER}\s*(m|meters?|metres?)?$")
_FEET = re.compile(rf"^{_NUMBER}\s*(ft|feet|foot|')$")
_FEET_INCHES = re.compile(rf"^{_NUMBER}\s*(?:'|ft)\s*{_NUMBER}\s*(?:\"|in|'')$")
_FOOT_M = 0.3048
_INCH_M = 0.0254


def parse_width(value: str | None) -> float | None:
    """A ``width=*`` tag in metres, or None when it is absent or not understood.

    Handles the forms mappers use: ``5``, ``5.5``, ``5,5`` (decimal comma), ``5 m``,
    ``5.5 metres``, ``16'``, ``16 ft``, ``12'6"``. Values outside (0, 100] m are
    treated as mistakes (None), so the per-class default applies instead.
    """
    if value is None:
        return None
    text = value.strip().lower().lstrip("~").strip()
    # A single comma between digits is a decimal comma ("5,5"); "5,500" is ambiguous: refuse.
    if re.fullmatch(r"\d+,\d{1,2}(\s*\D.*)?", text):
        text = text.replace(",", ".", 1)
    metres: float | None = None
    if match := _METRES.match(text):
        metres = float(match.group(1))
    elif match := _FEET.match(text):
        metres = float(match.group(1)) * _FOOT_M
    elif match := _FEET_INCHES.match(text):
        metres = float(match.group(1)) * _FOOT_M + float(match.group(2)) * _INCH_M
    if metres is None or not 0.0 < metres <= 100.0:
        return None
    return metres


def parse_lanes(value: str | None) -> int | None:
    """A ``lanes=*`` tag as a positive int, or None when absent or not understood."""
    if value is None:
        return None
    text = value.strip()
    if not text.isdigit():
        return None
    lanes = int(text)
    return lanes if 1 <= lanes <= 20 else None


def parse_oneway(tags: Mapping[str, str]) -> tuple[bool, bool]:
    """``(oneway, reversed)`` from a way's tags.

    ``oneway=yes/true/1`` is one-way along the node order, ``-1``/``reverse`` against it;
    ``no/false/0`` is two-way; without a tag, motorways and roundabouts are one-way
    (OSM's implied values) and everything else is two-way.
    """
    value = tags.get("oneway", "").strip().lower()
    if value in ("yes", "true", "1", "reversible", "alternating"):
        return True, False
    if value in ("-1", "reverse"):
        return True, True
    if value in ("no", "false", "0"):
        return False, False
    implied = tags.get("highway") in ("motorway", "motorway_link") or tags.get("junction") in (
        "roundabout",
        "circular",
    )
    return implied, False


def _defaults(highway: str) -> HighwayDefaults:
    base = highway[: -len("_link")] if highway.endswith("_link") else highway
    return HIGHWAY_DEFAULTS.get(base, HIGHWAY_DEFAULTS["residential"])


#: Width of a painted cycle lane (m): the common design value (1.5 m in the German ERA and
#: the US NACTO guide; OSM has no width tag for it on most ways).
CYCLE_LANE_WIDTH = 1.5
#: Width of an on-street parking lane by orientation (m; typical design values).
PARKING_LANE_WIDTHS: Mapping[str, float] = MappingProxyType(
    {"parallel": 2.0, "diagonal": 4.5, "perpendicular": 5.0}
)
_SIDES = ("right", "left")


def _side_value(tags: Mapping[str, str], key: str, side: str) -> str:
    """``key:side``, else ``key:both``, else "" (normalised)."""
    for name in (f"{key}:{side}", f"{key}:both"):
        if name in tags:
            return tags[name].strip().lower()
    return ""


def _cycle_lane(tags: Mapping[str, str], side: str, oneway: bool) -> float:
    value = _side_value(tags, "cycleway", side)
    if not value:
        # Plain ``cycleway=lane``: both sides of a two-way road, the right of a one-way one.
        value = tags.get("cycleway", "").strip().lower()
        if oneway and side == "left":
            value = ""
    return CYCLE_LANE_WIDTH if value in ("lane", "opposite_lane") else 0.0


def _parking_lane(tags: Mapping[str, str], side: str) -> float:
    # Older scheme: parking:lane:<side>=parallel|diagonal|perpendicular.
    if width := PARKING_LANE_WIDTHS.get(_side_value(tags, "parking:lane", side)):
        return width
    # Newer scheme: parking:<side>=lane with parking:<side>:orientation (default parallel);
    # street_side / on_kerb parking is off the carriageway.
    if _side_value(tags, "parking", side) != "lane":
        return 0.0
    orientation = tags.get(f"parking:{side}:orientation") or tags.get("parking:both:orientation")
    return PARKING_LANE_WIDTHS.get((orientation or "parallel").strip().lower(), 0.0)


def parse_margins(
    tags: Mapping[str, str], *, oneway: bool = False, reverse: bool = False
) -> tuple[float, float]:
    """Widths (m) of the non-traffic strips on the carriageway, ``(right, left)``.

    Counted: painted cycle lanes (``cycleway[:side]=lane``, :data:`CYCLE_LANE_WIDTH`) and
    parking lanes on the carriageway (``parking:lane:<side>=parallel|diagonal|perpendicular``
    or ``parking:<side>=lane`` with its orientation, :data:`PARKING_LANE_WIDTHS`). Tracks,
    shared lanes and kerbside parking are not on the carriageway and count 0. Sides are
    those of the way's node order; ``reverse`` (``oneway=-1``, driven against it) swaps them.
    """
    right, left = (_cycle_lane(tags, side, oneway) + _parking_lane(tags, side) for side in _SIDES)
    return (left, right) if reverse else (right, left)


def parse_parking(tags: Mapping[str, str], *, reverse: bool = False) -> tuple[float, float]:
    """Widths (m) of the parking lanes on the carriageway, ``(right, left)``.

    The part of :func:`parse_margins` that is parking; a parking lane lies at the kerb,
    outside any cycle lane (the usual "door zone" layout). Sides as in
    :func:`parse_margins`.
    """
    right, left = (_parking_lane(tags, side) for side in _SIDES)
    return (left, right) if reverse else (right, left)


#: Width of a footway beside the carriageway when ``sidewalk:*:width`` is not tagged (m;
#: the common minimum clear width, 1.8 m in the German EFA and 5 ft = 1.5 m plus buffer in
#: the US; we take 2.0 m).
SIDEWALK_WIDTH = 2.0


def _sidewalk(tags: Mapping[str, str], side: str) -> float:
    value = _side_value(tags, "sidewalk", side)
    if not value:
        plain = tags.get("sidewalk", "").strip().lower()
        value = "yes" if plain in ("both", side, "yes") else ""
    if value not in ("yes", "both", side):
        return 0.0  # no, separate (mapped as its own way), none
    width = parse_width(tags.get(f"sidewalk:{side}:width") or tags.get("sidewalk:both:width"))
    return SIDEWALK_WIDTH if width is None else width


def parse_sidewalks(tags: Mapping[str, str], *, reverse: bool = False) -> tuple[float, float]:
    """Widths (m) of the footways beyond the right and left kerb (0: none mapped, a verge).

    ``sidewalk=both|right|left|yes``, ``sidewalk:<side>=yes``, ``sidewalk:both=yes``;
    widths from ``sidewalk:<side>:width``, else :data:`SIDEWALK_WIDTH`. ``separate`` (a
    footway mapped as its own way) and ``no`` count 0. Sides as in :func:`parse_margins`.
    """
    right, left = (_sidewalk(tags, side) for side in _SIDES)
    return (left, right) if reverse else (right, left)
