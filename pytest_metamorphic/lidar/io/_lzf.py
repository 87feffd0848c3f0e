"""LZF for PCD ``binary_compressed``: python-lzf when installed, a tested fallback otherwise.

python-lzf (PyPI ``python-lzf``, the optional ``lzf`` extra) wraps Marc Lehmann's liblzf,
the library PCL itself uses. Without it, :func:`decompress` runs a pure-Python decoder
(correct, ~100x slower) and :func:`compress` emits literal runs only: a valid LZF stream
every reader accepts, but not smaller than the input.
"""

from __future__ import annotations

__all__ = ["MAX_RATIO", "compress", "decompress"]

#: LZF cannot expand data by more than this factor (a 3-byte back reference copies at
#: most 264 bytes), so a declared size above ``MAX_RATIO * compressed + 64`` is a lie.
MAX_RATIO = 90


def _native() -> object | None:
    try:
        import lzf
    except ImportError:
        return None
    return lzf


def compress(data: bytes, *, native: bool = True) -> bytes:
    """LZF-compress ``data``; never fails, even on incompressible input."""
    module = _native() if native else None
    if module is not None and data:
        # Incompressible input grows by at most one byte per 32 (literal run headers).
        packed = module.compress(data, len(data) + len(data) // 32 + 16)  # type: ignore[attr-defined]
        if packed is not None:
            return packed
    return _literal_runs(data)


def decompress(data: bytes, size: int, *, native: bool = True) -> bytes:
    """Decompress an LZF stream that must expand to exactly ``size`` bytes.

    Raises ValueError for corrupt data or a size mismatch. The caller bounds ``size``
    (see :data:`MAX_RATIO`) before calling, since the output buffer is allocated up front.
    """
    if size == 0:
        if data:
            raise ValueError(f"{len(data)} compressed bytes for an empty payload")
        return b""
    module = _native() if native else None
    if module is None:
        return _decompress_python(data, size)
    out = module.decompress(data, size)  # type: ignore[attr-defined]
    if out is None:
        raise ValueError(f"LZF data expands to more than the declared {size} bytes")
    if len(out) != size:
        raise ValueError(f"LZF data expands to {len(out)} bytes, not the declared {size}")
    return out


def _literal_runs(data: bytes) -> bytes:
    out = bytearray()
    for start in range(0, len(data), 32):
        chunk = data[start : start + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def _decompress_python(data: bytes, size: int) -> bytes:
    out = bytearray()
    position, end = 0, len(data)
    while position < end:
        control = data[position]
        position += 1
        if control < 32:
            length = control + 1
            if position + length > end:
                raise ValueError(f"LZF literal run at byte {position - 1} passes the end")
            out += data[position : position + length]
            position += length
        else:
            length = control >> 5
            if length == 7:
                if position >= end:
                    raise ValueError("LZF back reference cut off at the end")
                length += data[position]
                position += 1
            if position >= end:
                raise ValueError("LZF back reference cut off at the end")
            source = len(out) - ((control & 0x1F) << 8) - data[position] - 1
            position += 1
            length += 2
            if source < 0:
                raise ValueError(
                    f"LZF back reference at byte {position - 2} points before the start"
                )
            if source + length <= len(out):
                out += out[source : source + length]
            else:  # overlapping copy repeats the pattern byte by byte
                for offset in range(length):
                    out.append(out[source + offset])
        if len(out) > size:
            raise ValueError(f"LZF data expands to more than the declared {size} bytes")
    if len(out) != size:
        raise ValueError(f"LZF data expands to {len(out)} bytes, not the declared {size}")
    return bytes(out)
