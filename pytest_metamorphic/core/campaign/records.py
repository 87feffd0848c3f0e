"""A campaign log's records: their shape, checked field by field, and a checksum that
binds each record to its log's header.

A log is what CI caches and restores between runs, and what a resumed campaign trusts
instead of running the system again. So a record read back must be one this campaign
wrote: each record written since 0.7 carries ``"check"``, a SHA-256 over the log's
header line (campaign, relation, seed, sizes, system) and the record itself. A record
edited by hand (a ``holds`` flipped), copied from another campaign's or system's log, or
mangled by a cache is caught: its check does not match. The check is not a signature
(anyone can compute one); it guards against accidents and stale caches, not against
someone forging logs on purpose. Logs of 0.6 and earlier have no checks and are read
as before; a log whose header says ``"checked"`` must have a valid check on every record.

Every record is also checked for its shape (types and ranges of every field the tallies
read), parsed with a bounded line length and nesting, and reported by file and line.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from typing import Any

from pytest_metamorphic.core.errors import DataError

__all__ = ["CHECK", "CHECKED", "MAX_LINE", "parse_line", "record_check", "seal", "verify_record"]

CHECK = "check"  # the record's checksum field
CHECKED = "checked"  # in a header: every record of this log carries a check
MAX_LINE = 16 << 20  # bytes of one record line: a source with 50 follow-ups x 3 sizes is ~100 kB


def record_check(header: Mapping[str, Any], record: Mapping[str, Any]) -> str:
    """The checksum of ``record`` in a log whose header line is ``header``."""
    body = {key: value for key, value in record.items() if key != CHECK}
    text = json.dumps([header, body], sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:32]


def seal(header: Mapping[str, Any], record: Mapping[str, Any]) -> dict[str, Any]:
    """``record`` with its check, as written to the log."""
    return {**record, CHECK: record_check(header, record)}


def parse_line(line: str, where: str) -> Any:
    """One JSON line of a log, bounded in length and nesting (``where``: file:line)."""
    if len(line) > MAX_LINE:
        raise DataError(f"{where}: a record of {len(line)} bytes (at most {MAX_LINE})")
    try:
        return json.loads(line)
    except RecursionError:
        raise DataError(f"{where}: a record nested too deeply to parse") from None


def _int(value: Any, low: int, high: int | None, what: str, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise DataError(f"{where}: {what} is {type(value).__name__}, not an integer")
    if value < low or (high is not None and value > high):
        bound = f"[{low}, {high}]" if high is not None else f">= {low}"
        raise DataError(f"{where}: {what}={value} is outside {bound}")
    return value


def _pair(pair: Any, header: Mapping[str, Any], where: str) -> None:
    if not isinstance(pair, dict):
        raise DataError(f"{where}: a pair is {type(pair).__name__}, not an object")
    size = pair.get("size")
    if size not in header["sizes"] or isinstance(size, bool):
        raise DataError(
            f"{where}: pair size {size!r} is not one of the campaign's {header['sizes']}"
        )
    _int(pair.get("followup"), 0, int(header["followups"]) - 1, "a pair's follow-up", where)
    if "not_applicable" in pair or "crash" in pair:
        return
    _int(pair.get("o"), 0, None, "a pair's |O|", where)
    _int(pair.get("o2"), 0, None, "a pair's |O'|", where)
    if not isinstance(pair.get("holds"), bool):
        raise DataError(f"{where}: a pair's holds is {pair.get('holds')!r}, not true or false")
    categories = pair.get("categories", {})
    if not isinstance(categories, dict) or not all(
        isinstance(counts, list) and len(counts) == 2 for counts in categories.values()
    ):
        raise DataError(f"{where}: a pair's categories are not name -> [source, follow-up]")
    for counts in categories.values():
        for count in counts:
            _int(count, 0, None, "a category count", where)
    violated = pair.get("violated", [])
    if not isinstance(violated, list) or not all(isinstance(v, dict) for v in violated):
        raise DataError(f"{where}: a pair's violated elements are not a list of objects")


def verify_record(
    record: Any, header: Mapping[str, Any], logged_header: Mapping[str, Any], where: str
) -> str | None:
    """Check a record's shape against the campaign's ``header``, and its check against the
    log's own header line; the reason it does not verify, or None.

    Raises
    ------
    DataError
        The record is malformed (a shape no writer of this campaign makes).
    """
    if not isinstance(record, dict):
        raise DataError(f"{where}: a record is {type(record).__name__}, not an object")
    _int(record.get("source"), 0, int(header["sources"]) - 1, "source", where)
    _int(record.get("sut_calls"), 0, None, "sut_calls", where)
    pairs = record.get("pairs")
    if not isinstance(pairs, list):
        raise DataError(f"{where}: pairs is {type(pairs).__name__}, not a list")
    for pair in pairs:
        _pair(pair, header, where)
    for key in ("crash", "input", "digest"):
        if key in record and not isinstance(record[key], str):
            raise DataError(f"{where}: {key} is {type(record[key]).__name__}, not a string")
    if not logged_header.get(CHECKED):
        return None  # a log of 0.6 or earlier: no checks to verify
    found = record.get(CHECK)
    if found != record_check(logged_header, record):
        return (
            "its check does not match (edited after it was written, or copied from another "
            "campaign's or system's log)"
            if isinstance(found, str)
            else "it has no check, in a log whose every record has one"
        )
    return None
