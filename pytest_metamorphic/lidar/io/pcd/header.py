"""PCD headers: parsing (a one-regex fast path for canonical headers), checking, writing."""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.lidar.model.cloud import PointCloud

__all__ = ["PcdHeader"]

PcdData = Literal["ascii", "binary", "binary_compressed"]

#: Headers are a few hundred bytes; anything longer without a DATA line is not a PCD.
MAX_HEADER_BYTES = 64 * 1024
#: Bytes read for the header first; more are read only when its DATA line is not in them.
_FIRST_READ = 4096
#: O_BINARY: no newline translation on Windows (0 elsewhere).
#: Real PCD records are at most a few kB (a 308-float VFH descriptor is 1232 bytes).
MAX_POINT_STEP = 1 << 20
_SIZES = {"F": (4, 8), "U": (1, 2, 4, 8), "I": (1, 2, 4, 8)}
_KEYWORDS = frozenset(
    ("VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA")
)
_DEFAULT_VIEWPOINT = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
_WRITABLE = "f4 f8 u1 u2 u4 u8 i1 i2 i4 i8"
#: The canonical header: comment lines, then the spec's ten lines in the spec's order with
#: one space after each keyword, as PCL, Open3D and this library write them.
_CANONICAL = re.compile(
    rb"(?P<comments>(?:#[^\n]*\n)*)"
    rb"(?P<layout>VERSION [^\n]*\nFIELDS [^\n]*\nSIZE [^\n]*\nTYPE [^\n]*\nCOUNT [^\n]*\n)"
    rb"WIDTH (?P<width>[0-9]+)\nHEIGHT (?P<height>[0-9]+)\n"
    rb"(?P<viewpoint>VIEWPOINT [^\n]*\n)"
    rb"POINTS (?P<points>[0-9]+)\nDATA (?P<data>ascii|binary_compressed|binary)\n"
)
#: Canonical layout lines (VERSION to COUNT, VIEWPOINT) that parsed as a valid header:
#: their fields, sizes, types, counts and viewpoint. The frames of one sensor share them,
#: and parsing them is most of the cost of reading a small file.
_KNOWN_LAYOUTS: dict[
    tuple[bytes, bytes],
    tuple[tuple[str, ...], tuple[int, ...], tuple[str, ...], tuple[int, ...], tuple[float, ...]],
] = {}
_MAX_KNOWN_LAYOUTS = 64
_FRAME_ID = re.compile(r"#\s*frame_id (.*)")
_TIMESTAMP = re.compile(r"#\s*timestamp (\S+)\s*")


@dataclass(frozen=True)
class PcdHeader:
    """What a PCD header declares.

    Attributes
    ----------
    fields : tuple of str
      Field names in file order, ``_`` padding included.
    sizes, types, counts : tuple of int / str / int
      Bytes per value, ``F``/``U``/``I``, values per point, one per field.
    width, height, points : int
      ``points == width * height``; ``height > 1`` means an organised cloud.
    data : {"ascii", "binary", "binary_compressed"}
    data_offset : int
      Byte offset of the payload.
    viewpoint : (7,) tuple of float
      Sensor pose tx ty tz qw qx qy qz (kept, not applied, as PCL does).
    frame_id, timestamp : str, float or None
      Restored from this library's comment lines, when present.
    """

    fields: tuple[str, ...]
    sizes: tuple[int, ...]
    types: tuple[str, ...]
    counts: tuple[int, ...]
    width: int
    height: int
    points: int
    data: PcdData
    data_offset: int
    viewpoint: tuple[float, ...] = _DEFAULT_VIEWPOINT
    frame_id: str = ""
    timestamp: float | None = None

    @property
    def point_step(self) -> int:
        """Bytes per point in the ``binary`` layout."""
        return sum(size * count for size, count in zip(self.sizes, self.counts, strict=True))

    def dtype(self) -> np.dtype:
        """Structured little-endian dtype of one ``binary`` record (padding skipped)."""
        return _record_dtype(self.fields, self.sizes, self.types, self.counts)


@functools.lru_cache(maxsize=64)
def _record_dtype(
    fields: tuple[str, ...], sizes: tuple[int, ...], types: tuple[str, ...], counts: tuple[int, ...]
) -> np.dtype:
    # Cached: the frames of one sensor share a layout, and building a structured dtype
    # costs as much as parsing the rest of the header.
    names, formats, offsets, offset = [], [], [], 0
    for field, size, kind, count in zip(fields, sizes, types, counts, strict=True):
        if field != "_":
            code = f"<{kind.lower()}{size}"
            names.append(field)
            formats.append(code if count == 1 else (code, (count,)))
            offsets.append(offset)
        offset += size * count
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": offset})


def _parse(head: bytes, path: Path, *, complete: bool) -> PcdHeader | None:
    """The header at the start of ``head``, as :func:`_parse_header` (which see for None).

    A header in the canonical form whose layout was seen before is taken from one regex
    match; any other is parsed line by line, and a canonical one's layout is then
    remembered. Both ways give the same header (tests/lidar/io/test_io_pcd.py).
    """
    match = _CANONICAL.match(head)
    if match is not None:
        header = _parse_canonical(match, path)
        if header is not None:
            return header
    header = _parse_header(head, path, complete=complete)
    if match is not None and header is not None:
        if len(_KNOWN_LAYOUTS) >= _MAX_KNOWN_LAYOUTS:
            _KNOWN_LAYOUTS.clear()
        layout = (header.fields, header.sizes, header.types, header.counts, header.viewpoint)
        _KNOWN_LAYOUTS[match["layout"], match["viewpoint"]] = layout
    return header


def _parse_canonical(match: re.Match[bytes], path: Path) -> PcdHeader | None:
    """The header of a canonical match whose layout is known to be valid.

    None to parse it line by line instead: an unknown layout, or anything to report (the
    line-by-line parse words the error).
    """
    known = _KNOWN_LAYOUTS.get((match["layout"], match["viewpoint"]))
    if known is None:
        return None
    width, height = int(match["width"]), int(match["height"])
    if int(match["points"]) != width * height:
        return None
    frame_id, timestamp = "", None
    if match["comments"]:
        try:
            comments = match["comments"].decode("utf-8")
        except UnicodeDecodeError:
            return None
        for line in comments.split("\n"):  # not splitlines(): lines end at \n only
            frame_id, timestamp = _comment(line.strip(), frame_id, timestamp, path)
    fields, sizes, types, counts, viewpoint = known
    data = match["data"].decode("ascii")
    return PcdHeader(
        fields,
        sizes,
        types,
        counts,
        width,
        height,
        width * height,
        data,  # type: ignore[arg-type]
        match.end(),
        viewpoint,
        frame_id,
        timestamp,
    )


def _comment(
    line: str, frame_id: str, timestamp: float | None, path: Path
) -> tuple[str, float | None]:
    """Frame id and timestamp after a (stripped) comment line: this library's two."""
    if match := _FRAME_ID.fullmatch(line):
        return match.group(1), timestamp
    if match := _TIMESTAMP.fullmatch(line):
        return frame_id, _floats([match.group(1)], "timestamp comment", path)[0]
    return frame_id, timestamp


def _parse_header(head: bytes, path: Path, *, complete: bool) -> PcdHeader | None:
    """The header at the start of ``head``.

    None when ``head`` ends before the DATA line and is not ``complete`` (more of the
    file follows: read more and parse again).
    """
    values: dict[str, list[str]] = {}
    frame_id, timestamp = "", None
    offset = 0
    while True:
        end = head.find(b"\n", offset)
        if end < 0:
            if not complete:
                return None
            if len(head) >= MAX_HEADER_BYTES:
                raise DataError(f"no DATA line in the first {MAX_HEADER_BYTES} bytes", path=path)
            if offset >= len(head):
                what = "an empty file" if not head else "no DATA line (truncated header?)"
                raise DataError(f"not a PCD file: {what}", path=path)
            end = len(head)  # a last line without its newline
        try:
            line = head[offset:end].decode("utf-8")
        except UnicodeDecodeError:
            raise DataError(
                f"not a PCD file: header line at byte {offset} is not text", path=path
            ) from None
        offset = end + 1
        words = line.split()
        if not words:
            continue
        if words[0][0] == "#":
            frame_id, timestamp = _comment(line.strip(), frame_id, timestamp, path)
            continue
        keyword = words[0].upper()
        if keyword not in _KEYWORDS:
            raise DataError(f"not a PCD file: unknown header line {line.strip()[:60]!r}", path=path)
        if keyword in values:
            raise DataError(f"header has two {keyword} lines", path=path)
        values[keyword] = words[1:]
        if keyword == "DATA":
            break
    return _header_from_values(values, min(offset, len(head)), frame_id, timestamp, path)


def _header_from_values(
    values: dict[str, list[str]], offset: int, frame_id: str, timestamp: float | None, path: Path
) -> PcdHeader:
    for required in ("FIELDS", "SIZE", "TYPE", "WIDTH", "HEIGHT"):
        if required not in values:
            raise DataError(f"header has no {required} line", path=path)
    fields, sizes, types, counts = _check_layout(values, path)
    width = _single_int(values["WIDTH"], "WIDTH", path)
    height = _single_int(values["HEIGHT"], "HEIGHT", path)
    points = width * height
    if "POINTS" in values and _single_int(values["POINTS"], "POINTS", path) != points:
        raise DataError(
            f"POINTS {values['POINTS'][0]} differs from WIDTH x HEIGHT = {points}", path=path
        )
    viewpoint: tuple[float, ...] = _DEFAULT_VIEWPOINT
    if "VIEWPOINT" in values:
        viewpoint = _floats(values["VIEWPOINT"], "VIEWPOINT", path)
        if len(viewpoint) != 7 or not all(map(math.isfinite, viewpoint)):
            raise DataError("VIEWPOINT needs 7 finite numbers", path=path)
    data = " ".join(values["DATA"]).lower()
    if data not in ("ascii", "binary", "binary_compressed"):
        raise DataError(f"DATA {data!r} is not ascii, binary or binary_compressed", path=path)
    return PcdHeader(
        fields,
        sizes,
        types,
        counts,
        width,
        height,
        points,
        data,  # type: ignore[arg-type]
        offset,
        viewpoint,
        frame_id,
        timestamp,
    )


_Layout = tuple[tuple[str, ...], tuple[int, ...], tuple[str, ...], tuple[int, ...]]


def _check_layout(values: dict[str, list[str]], path: Path) -> _Layout:
    fields = tuple(values["FIELDS"])
    if not fields:
        raise DataError("FIELDS line names no fields", path=path)
    named = [field for field in fields if field != "_"]
    if len(set(named)) != len(named):
        raise DataError(f"FIELDS repeats a name: {' '.join(fields)}", path=path)
    sizes = _ints(values["SIZE"], "SIZE", path)
    types = tuple([v.upper() for v in values["TYPE"]])
    counts = _ints(values.get("COUNT", ["1"] * len(fields)), "COUNT", path)
    for keyword, items in (("SIZE", sizes), ("TYPE", types), ("COUNT", counts)):
        if len(items) != len(fields):
            raise DataError(
                f"{keyword} has {len(items)} entries for {len(fields)} FIELDS", path=path
            )
    step = 0
    for field, size, kind, count in zip(fields, sizes, types, counts, strict=True):
        if kind not in _SIZES:
            raise DataError(f"field {field!r} has TYPE {kind!r}; expected F, U or I", path=path)
        if size not in _SIZES[kind]:
            raise DataError(f"field {field!r} has TYPE {kind} with SIZE {size}", path=path)
        if count < 1:
            raise DataError(f"field {field!r} has COUNT {count}", path=path)
        step += size * count
    if step > MAX_POINT_STEP:
        raise DataError(
            f"fields declare {step} bytes per point (limit {MAX_POINT_STEP})", path=path
        )
    return fields, sizes, types, counts


def _ints(items: list[str], keyword: str, path: Path) -> tuple[int, ...]:
    """Non-negative decimal integers, or a DataError naming the first item that is not."""
    # One test of the joined text instead of one per item: headers are parsed per file.
    joined = "".join(items)
    if items and not (joined.isascii() and joined.isdigit()):
        bad = next(text for text in items if not (text.isascii() and text.isdigit()))
        raise DataError(f"{keyword} value {bad[:40]!r} is not a non-negative integer", path=path)
    return tuple(map(int, items))


def _single_int(items: list[str], keyword: str, path: Path) -> int:
    if len(items) != 1:
        raise DataError(f"{keyword} needs one integer, got {' '.join(items)[:60]!r}", path=path)
    return _ints(items, keyword, path)[0]


def _floats(items: list[str], keyword: str, path: Path) -> tuple[float, ...]:
    values = []
    for text in items:
        try:
            values.append(float(text))
        except ValueError:
            raise DataError(f"{keyword} value {text[:40]!r} is not a number", path=path) from None
    return tuple(values)


def _header_text(cloud: PointCloud, dtype: np.dtype, data: str) -> str:
    names, sizes, types, counts = [], [], [], []
    for key in dtype.names or ():
        base, shape = dtype[key].base, dtype[key].shape
        names.append(key)
        sizes.append(str(base.itemsize))
        types.append(base.kind.upper())
        counts.append(str(shape[0] if shape else 1))
    lines = ["# .PCD v0.7 - Point Cloud Data file format"]
    if cloud.frame_id:
        lines.append(f"# frame_id {cloud.frame_id}")
    if cloud.timestamp is not None:
        lines.append(f"# timestamp {cloud.timestamp!r}")
    lines += [
        "VERSION 0.7",
        f"FIELDS {' '.join(names)}",
        f"SIZE {' '.join(sizes)}",
        f"TYPE {' '.join(types)}",
        f"COUNT {' '.join(counts)}",
        f"WIDTH {len(cloud)}",
        "HEIGHT 1",
        "VIEWPOINT 0 0 0 1 0 0 0",
        f"POINTS {len(cloud)}",
        f"DATA {data}",
    ]
    return "\n".join(lines) + "\n"
