"""Deep equality and difference descriptions that understand numpy arrays.

Used by the ``equal`` relation, by :class:`~pytest_metamorphic.core.matching.EqualityMatcher`
and by the engine's determinism re-check, so all three agree on what "the same output" is;
:func:`value_digest` condenses a value to a short digest (campaign logs, the engine's
memory of a case that timed out).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
from collections import Counter
from collections.abc import Mapping
from dataclasses import fields, is_dataclass
from typing import Any

__all__ = [
    "deep_equal",
    "describe_outputs",
    "describe_params",
    "describe_value",
    "first_difference",
    "value_digest",
]

_MAX_REPR = 120


_MAX_ELEMENTS = 6  # elements a list's description names before "... and N more"


def describe_value(value: Any) -> str:
    """A one-line, length-capped description, for failure messages.

    A value with a ``describe()`` (a box: ``car at (12.1, -3.4)``) is described by it; a
    list or tuple of such values by its count and the first few, so an output of boxes
    reads ``3 element(s): car at (10.1, -6.8); pedestrian at (4.0, 2.2); ...`` instead
    of one box's repr with 16-digit floats cut off mid-number.
    """
    own = _own_description(value)
    if own is not None:
        return own
    if isinstance(value, (list, tuple)) and value:
        parts = [_own_description(item) for item in value[:_MAX_ELEMENTS]]
        if all(part is not None for part in parts):
            more = len(value) - len(parts)
            tail = f"; ... and {more} more" if more else ""
            return f"{len(value)} element(s): " + "; ".join(map(str, parts)) + tail
    text = repr(value)
    return text if len(text) <= _MAX_REPR else text[: _MAX_REPR - 3] + "..."


def describe_params(params: Mapping[str, Any]) -> str:
    """Transform parameters as messages and failing cases show them: ``{n=1, angle=90.0}``."""
    return "{" + ", ".join(f"{key}={describe_value(value)}" for key, value in params.items()) + "}"


def describe_outputs(source: Any, followup: Any) -> list[str]:
    """Lines comparing a source output with a follow-up output, for failure messages.

    Lists of values that describe themselves (boxes) are compared by their descriptions,
    rounded as they print: the lines name what only one side has, not the many elements
    both share. Other values are described side by side.
    """
    left, right = _descriptions(source), _descriptions(followup)
    if left is None or right is None:
        return [
            f"source output:    {describe_value(source)}",
            f"follow-up output: {describe_value(followup)}",
        ]
    only_source = Counter(left) - Counter(right)
    only_followup = Counter(right) - Counter(left)
    shared = len(left) - only_source.total()
    lines = [
        f"outputs: {len(left)} element(s) in the source, {len(right)} in the follow-up, "
        f"{shared} described alike"
    ]
    for side, only in (("source", only_source), ("follow-up", only_followup)):
        if only:
            lines.append(f"  only in the {side} ({only.total()}): {_listed(only)}")
    if not only_source and not only_followup:
        difference = first_difference(source, followup)
        if difference is not None:
            lines.append(f"  alike as described; the first difference: {difference}")
    return lines


def _descriptions(value: Any) -> list[str] | None:
    if not isinstance(value, (list, tuple)):
        return None
    described = [_own_description(item) for item in value]
    if any(item is None for item in described):
        return None
    return [str(item) for item in described]


def _listed(items: Counter[str]) -> str:
    names = [f"{name} (x{count})" if count > 1 else name for name, count in items.items()]
    more = len(names) - _MAX_ELEMENTS
    return "; ".join(names[:_MAX_ELEMENTS]) + (f"; ... and {more} more" if more > 0 else "")


def _own_description(value: Any) -> str | None:
    describe = getattr(value, "describe", None)
    if callable(describe) and not isinstance(value, type):
        try:
            return str(describe())
        except Exception:
            return None
    return None


def deep_equal(a: Any, b: Any) -> bool:
    """True when ``a`` and ``b`` are equal; NaN equals NaN, arrays compare element-wise."""
    return first_difference(a, b) is None


def first_difference(a: Any, b: Any, path: str = "output") -> str | None:
    """Describe the first place where ``a`` and ``b`` differ, or None when they are equal."""
    where = path
    if type(a) is type(b) and isinstance(a, (list, tuple, dict)):
        # Fast path: C-level equality. Only when it says "different" (or cannot decide,
        # e.g. arrays inside) do we walk the structure to explain, NaN-aware.
        try:
            if a == b:
                return None
        except Exception:
            pass
    if _is_array(a) or _is_array(b):
        return _array_difference(a, b, where)
    equals = getattr(a, "equals", None)
    if callable(equals) and type(a) is type(b) and not isinstance(a, (str, bytes)):
        # Domain types (PointCloud, ...) define exact equality themselves.
        try:
            return None if equals(b) else f"{where}: {describe_value(a)} != {describe_value(b)}"
        except TypeError:
            pass
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        if a.keys() != b.keys():
            missing = sorted(map(repr, a.keys() - b.keys()))
            extra = sorted(map(repr, b.keys() - a.keys()))
            return f"{where}: keys differ (only in first: {missing}, only in second: {extra})"
        for key in a:
            found = first_difference(a[key], b[key], f"{path}[{key!r}]")
            if found:
                return found
        return None
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if type(a) is not type(b):
            return f"{where}: {type(a).__name__} != {type(b).__name__}"
        if len(a) != len(b):
            return f"{where}: length {len(a)} != {len(b)}"
        for index, (x, y) in enumerate(zip(a, b, strict=True)):
            found = first_difference(x, y, f"{path}[{index}]")
            if found:
                return found
        return None
    if is_dataclass(a) and type(a) is type(b) and not isinstance(a, type):
        for item in fields(a):
            if not item.compare:
                continue
            found = first_difference(
                getattr(a, item.name), getattr(b, item.name), f"{path}.{item.name}"
            )
            if found:
                return found
        return None
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return None
    try:
        same = bool(a == b)
    except Exception:
        same = False
    return None if same else f"{where}: {describe_value(a)} != {describe_value(b)}"


def _is_array(value: Any) -> bool:
    return type(value).__module__ == "numpy" and hasattr(value, "shape")


def _array_difference(a: Any, b: Any, where: str) -> str | None:
    import numpy as np

    x, y = np.asarray(a), np.asarray(b)
    if x.shape != y.shape:
        return f"{where}: shape {x.shape} != {y.shape}"
    if x.dtype.kind in "fc" or y.dtype.kind in "fc":
        same = (x == y) | (np.isnan(x) & np.isnan(y))
    else:
        same = x == y
    same = np.asarray(same)
    if same.all():
        return None
    index = tuple(int(i) for i in np.argwhere(~same)[0])
    count = int((~same).sum())
    return f"{where}{list(index)}: {x[index]!r} != {y[index]!r} ({count} element(s) differ)"


# Deeper structures are cut: a fingerprint, not a serialisation.
_MAX_DEPTH = 40
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def value_digest(value: Any) -> str:
    """A short digest of a value, equal for equal values across processes (arrays by
    their bytes, containers element by element, dataclasses field by field, anything
    else by its ``repr`` without memory addresses)."""
    digest = hashlib.sha1()
    _feed(digest, value, 0)
    return digest.hexdigest()[:16]


def _feed(digest: Any, value: Any, depth: int) -> None:
    if depth > _MAX_DEPTH:
        digest.update(b"...")
        return
    array = hasattr(value, "tobytes") and hasattr(value, "dtype") and hasattr(value, "shape")
    if array and getattr(value.dtype, "kind", "O") != "O":
        digest.update(f"array {value.dtype} {value.shape}:".encode())
        digest.update(value.tobytes())
    elif isinstance(value, (list, tuple)):
        digest.update(b"[")
        for item in value:
            _feed(digest, item, depth + 1)
            digest.update(b",")
        digest.update(b"]")
    elif isinstance(value, dict):
        digest.update(b"{")
        for key in sorted(value, key=repr):
            _feed(digest, key, depth + 1)
            digest.update(b":")
            _feed(digest, value[key], depth + 1)
        digest.update(b"}")
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        digest.update(type(value).__qualname__.encode() + b"(")
        for field in dataclasses.fields(value):
            _feed(digest, getattr(value, field.name), depth + 1)
            digest.update(b",")
        digest.update(b")")
    else:
        digest.update(_ADDRESS.sub("", repr(value)).encode())
