"""A hardened reader for OpenStreetMap XML (``.osm`` and ``.osm.bz2``).

OSM files come from anywhere, so the parser is the standard library's expat with every
feature that lets a document reach beyond itself switched off: a DOCTYPE, an entity
declaration (internal or external, the "billion laughs" expansion bomb) or an external
entity reference is rejected with a :class:`~pytest_metamorphic.core.errors.DataError`
naming the file. Decompressed input is capped (``max_bytes``) against bz2 bombs."""

from __future__ import annotations

import bz2
import contextlib
import math
import xml.parsers.expat
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import IO, Any

import numpy as np

from pytest_metamorphic.core.errors import DataError, InvalidArgument
from pytest_metamorphic.core.files import open_regular
from pytest_metamorphic.driving.osm.projection import LocalProjection

__all__ = ["OsmData", "OsmNode", "OsmRelation", "OsmWay", "read_osm"]

_CHUNK = 1 << 20
_DEFAULT_MAX_BYTES = 512 << 20
# Parsed, a node takes about 370 bytes (its dataclass, tags and index entry) and a way's
# node reference about 30: a million elements is about 400 MB of memory.
_DEFAULT_MAX_ELEMENTS = 1_000_000


@dataclass(frozen=True)
class OsmNode:
    """An OSM node: id, WGS84 latitude/longitude in degrees, tags."""

    id: int
    lat: float
    lon: float
    tags: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class OsmWay:
    """An OSM way: id, the ordered node ids it references, tags."""

    id: int
    node_ids: tuple[int, ...]
    tags: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class OsmRelation:
    """An OSM relation: id, its members as ``(type, ref, role)``, tags (Lanelet2 maps keep
    each lane as a ``type=lanelet`` relation of a ``left`` and a ``right`` way)."""

    id: int
    members: tuple[tuple[str, int, str], ...]
    tags: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class OsmData:
    """Everything :func:`read_osm` keeps from a file.

    Attributes
    ----------
    path : str
    nodes : mapping of node id -> OsmNode
    ways : tuple of OsmWay, in file order
    bounds : (minlat, minlon, maxlat, maxlon) or None
        The file's ``<bounds>`` element, when present.
    relation_count : int
    relations : tuple of OsmRelation
        In file order (Lanelet2's lanelets and regulatory elements).
    """

    path: str
    nodes: Mapping[int, OsmNode]
    ways: tuple[OsmWay, ...]
    bounds: tuple[float, float, float, float] | None
    relation_count: int
    relations: tuple[OsmRelation, ...] = ()

    def projection(self) -> LocalProjection:
        """The local projection about the centre of the nodes' bounding box."""
        if not self.nodes:
            raise DataError("has no nodes to centre a projection on", path=self.path)
        lat = np.fromiter((n.lat for n in self.nodes.values()), float, len(self.nodes))
        lon = np.fromiter((n.lon for n in self.nodes.values()), float, len(self.nodes))
        return LocalProjection.about(lat, lon)


class _Handler:
    """expat callbacks building :class:`OsmData`; refuses anything entity-related."""

    def __init__(
        self, path: str, parser: xml.parsers.expat.XMLParserType, max_elements: int
    ) -> None:
        self.path = path
        self.parser = parser
        self.max_elements = max_elements
        self.elements = 0
        self.nodes: dict[int, OsmNode] = {}
        self.ways: list[OsmWay] = []
        self.bounds: tuple[float, float, float, float] | None = None
        self.relation_count = 0
        self.relations: list[OsmRelation] = []
        self.current_members: list[tuple[str, int, str]] = []
        self.depth = 0
        self.root_seen = False
        # The element whose <tag>/<nd> children are being collected.
        self.current: str | None = None
        self.current_attrs: dict[str, str] = {}
        self.current_tags: dict[str, str] = {}
        self.current_refs: list[int] = []

    # -- hostile constructs ------------------------------------------------------------
    def _refuse(self, what: str) -> None:
        raise DataError(
            f"{what} at line {self.parser.CurrentLineNumber}: OSM XML never needs one, and "
            "entity expansion or external entities are refused for safety",
            path=self.path,
        )

    def doctype(self, name: str, *_: Any) -> None:
        self._refuse(f"DOCTYPE declaration <!DOCTYPE {name}>")

    def entity_decl(self, name: str, *_: Any) -> None:
        self._refuse(f"entity declaration <!ENTITY {name}>")

    def external_entity(self, *_: Any) -> int:
        self._refuse("external entity reference")
        return 0

    # -- content -----------------------------------------------------------------------
    def _error(self, message: str) -> DataError:
        return DataError(f"line {self.parser.CurrentLineNumber}: {message}", path=self.path)

    def _int(self, attrs: Mapping[str, str], key: str, element: str) -> int:
        try:
            return int(attrs[key])
        except KeyError:
            raise self._error(f"<{element}> has no {key!r} attribute") from None
        except ValueError:
            raise self._error(f"<{element}> {key}={attrs[key]!r} is not an integer") from None

    def _float(self, attrs: Mapping[str, str], key: str, element: str) -> float:
        try:
            value = float(attrs[key])
        except KeyError:
            raise self._error(f"<{element}> has no {key!r} attribute") from None
        except ValueError:
            raise self._error(f"<{element}> {key}={attrs[key]!r} is not a number") from None
        if not math.isfinite(value):
            raise self._error(f"<{element}> {key}={attrs[key]!r} is not finite")
        return value

    def start(self, name: str, attrs: dict[str, str]) -> None:
        self.depth += 1
        if self.depth == 1:
            if name != "osm":
                raise self._error(f"root element is <{name}>, not <osm>: not an OSM XML file")
            self.root_seen = True
            return
        if name in ("node", "way", "relation") and self.depth == 2:
            self.current = name
            self.current_attrs = attrs
            self.current_tags = {}
            self.current_refs = []
            self.current_members = []
        elif name == "tag" and self.current is not None:
            if "k" not in attrs or "v" not in attrs:
                raise self._error(f"<tag> in a <{self.current}> needs both k and v")
            self.current_tags[attrs["k"]] = attrs["v"]
        elif name == "nd" and self.current == "way":
            self.current_refs.append(self._int(attrs, "ref", "nd"))
        elif name == "member" and self.current == "relation":
            member = (
                attrs.get("type", ""),
                self._int(attrs, "ref", "member"),
                attrs.get("role", ""),
            )
            self.current_members.append(member)
        elif name == "bounds" and self.depth == 2:
            self.bounds = tuple(  # type: ignore[assignment]
                self._float(attrs, key, "bounds")
                for key in ("minlat", "minlon", "maxlat", "maxlon")
            )

    def end(self, name: str) -> None:
        if self.depth == 2 and name == self.current:
            self._finish(name)
            self.current = None
        self.depth -= 1

    def _finish(self, name: str) -> None:
        attrs = self.current_attrs
        # Deleted or invisible objects appear in editor and history files; they are not map data.
        if attrs.get("action") == "delete" or attrs.get("visible") == "false":
            return
        element_id = self._int(attrs, "id", name)
        self.elements += 1 + (len(self.current_refs) + len(self.current_members)) // 10
        self.elements += len(self.current_tags)
        if self.elements > self.max_elements:
            raise DataError(
                f"holds more than max_elements={self.max_elements} map elements (nodes, ways, "
                "tags; about 400 bytes of memory each); cut the extract to the area the "
                "scenarios need, or pass a larger max_elements if it is trusted and fits",
                path=self.path,
            )
        tags = MappingProxyType(self.current_tags)
        if name == "relation":
            self.relation_count += 1
            self.relations.append(OsmRelation(element_id, tuple(self.current_members), tags))
            return
        if name == "node":
            lat = self._float(attrs, "lat", "node")
            lon = self._float(attrs, "lon", "node")
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                raise self._error(f"node {element_id} has lat={lat}, lon={lon} out of range")
            if element_id in self.nodes:
                raise self._error(f"node id {element_id} appears twice")
            self.nodes[element_id] = OsmNode(element_id, lat, lon, tags)
        else:
            self.ways.append(OsmWay(element_id, tuple(self.current_refs), tags))


@contextlib.contextmanager
def _open(path: Path) -> Iterator[IO[bytes]]:
    with open_regular(path, what="OSM file") as handle:  # unreadable, a FIFO: a DataError
        magic = handle.read(3)
        handle.seek(0)
        if path.suffix == ".bz2" or magic == b"BZh":
            with bz2.BZ2File(handle, "rb") as unpacked:  # closes only itself, not handle
                yield unpacked
        else:
            yield handle


def _chunks(stream: IO[bytes], path: Path, max_bytes: int) -> Iterator[bytes]:
    total = 0
    while True:
        try:
            chunk = stream.read(_CHUNK)
        except (OSError, EOFError, ValueError) as error:
            raise DataError(f"cannot decompress: {error}", path=path) from None
        if not chunk:
            return
        total += len(chunk)
        if total > max_bytes:
            raise DataError(
                f"is larger than max_bytes={max_bytes} once decompressed; pass a larger "
                "max_bytes if the file is trusted",
                path=path,
            )
        yield chunk


def read_osm(
    path: str | Path,
    *,
    max_bytes: int = _DEFAULT_MAX_BYTES,
    max_elements: int = _DEFAULT_MAX_ELEMENTS,
) -> OsmData:
    """Parse an OSM XML file (plain or bz2-compressed) with a hardened expat parser.

    Parameters
    ----------
    path : str or Path
        ``.osm`` or ``.osm.bz2`` (bz2 is also recognised by its magic bytes).
    max_bytes : int
        Refuse files larger than this once decompressed (default 512 MiB).
    max_elements : int
        Refuse extracts of more map elements than this (nodes, ways, tags, a tenth of
        each way's node references; default 1,000,000, about 400 MB parsed): an extract
        of a city district has tens of thousands.

    Raises
    ------
    DataError
        The file is missing, not OSM XML, malformed, or contains a DOCTYPE, an entity
        declaration or an external entity reference. The message names the file and line.
    """
    for name, value in (("max_bytes", max_bytes), ("max_elements", max_elements)):
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise InvalidArgument(f"{name}={value!r} must be a positive int")
    path = Path(path)
    parser = xml.parsers.expat.ParserCreate()
    handler = _Handler(str(path), parser, max_elements)
    parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
    parser.StartDoctypeDeclHandler = handler.doctype
    parser.EntityDeclHandler = handler.entity_decl
    parser.UnparsedEntityDeclHandler = handler.entity_decl
    parser.ExternalEntityRefHandler = handler.external_entity
    parser.StartElementHandler = handler.start
    parser.EndElementHandler = handler.end
    parser.buffer_text = True
    try:
        with _open(path) as stream:
            for chunk in _chunks(stream, path, max_bytes):
                parser.Parse(chunk, False)
            parser.Parse(b"", True)
    except xml.parsers.expat.ExpatError as error:
        raise DataError(
            f"malformed XML at line {error.lineno}, column {error.offset}: "
            f"{xml.parsers.expat.ErrorString(error.code)}",
            path=path,
        ) from None
    except LookupError as error:
        # An XML declaration naming an encoding Python does not know (encoding='UTF0'):
        # expat asks the codec registry, whose LookupError is not an ExpatError.
        raise DataError(f"declares an unknown text encoding: {error}", path=path) from None
    if not handler.root_seen:
        raise DataError("is empty: no <osm> root element", path=path)
    return OsmData(
        str(path),
        MappingProxyType(handler.nodes),
        tuple(handler.ways),
        handler.bounds,
        handler.relation_count,
        tuple(handler.relations),
    )
