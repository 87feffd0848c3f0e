"""Noise seeds: one integer per injected point, hashed into uniform floats.

A seed is a complete, replayable description of a point: :func:`seeded_uniforms` maps
(seed, counter) pairs through SplitMix64 to floats in [0, 1), so the same seeds always give
the same points, whether Hypothesis drew them (and shrinks them by deleting seeds) or a
campaign drew them from a numpy generator.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["SEED_BITS", "seeded_uniforms"]

SEED_BITS = 32
"""Noise seeds are integers in ``[0, 2**SEED_BITS)``."""

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


# -- seeded uniforms ---------------------------------------------------------------------------


def _mix(z: NDArray[np.uint64]) -> NDArray[np.uint64]:
    """SplitMix64's finaliser, in place (uint64 arithmetic wraps, as the hash wants)."""
    shifted = z >> np.uint64(30)
    z ^= shifted
    z *= _MIX1
    np.right_shift(z, np.uint64(27), out=shifted)
    z ^= shifted
    z *= _MIX2
    np.right_shift(z, np.uint64(31), out=shifted)
    z ^= shifted
    return z


def seeded_uniforms(seeds: ArrayLike, counters: ArrayLike) -> NDArray[np.float64]:
    """Uniform floats in [0, 1) from (seed, counter) pairs, SplitMix64-hashed.

    Parameters
    ----------
    seeds : (n,) array_like of int
    counters : (k,) array_like of int
      Which values of each seed's stream to return.

    Returns
    -------
    (n, k) float64
      ``out[i, j]`` depends only on ``seeds[i]`` and ``counters[j]``.
    """
    seed = np.array(seeds, dtype=np.uint64).reshape(-1, 1)
    counter = np.asarray(counters, dtype=np.uint64).reshape(1, -1)
    # Hash the seed first so that neighbouring seeds give unrelated streams. The steps
    # work in place: for the 1000 points of a follow-up, fresh temporaries were half the
    # time.
    seed += _GOLDEN
    state = _mix(seed) + (counter + np.uint64(1)) * _GOLDEN
    _mix(state)
    state >>= np.uint64(11)
    uniforms = state.astype(np.float64)
    uniforms *= 1.0 / (1 << 53)
    return uniforms


def _as_seeds(seeds: ArrayLike) -> NDArray[np.int64]:
    try:
        array = np.asarray(seeds)
    except (TypeError, ValueError) as error:
        raise InvalidArgument(f"seeds cannot be converted to an array: {error}") from None
    if array.size == 0:
        return np.empty(0, dtype=np.int64)
    if array.ndim != 1 or not np.issubdtype(array.dtype, np.integer):
        raise InvalidArgument(
            f"seeds must be a 1-D list of ints, got shape {array.shape} {array.dtype}"
        )
    if array.min() < 0 or array.max() >= 2**SEED_BITS:
        raise InvalidArgument(f"seeds must lie in [0, 2**{SEED_BITS})")
    return array.astype(np.int64)


def _draw_seeds(n: Any, rng: Any) -> NDArray[np.int64]:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise InvalidArgument(f"n={n!r} must be a non-negative int")
    if not isinstance(rng, np.random.Generator):
        raise InvalidArgument(f"rng must be a numpy Generator, got {type(rng).__name__}")
    return rng.integers(0, 2**SEED_BITS, size=int(n), dtype=np.int64)
