"""Confidence intervals for violation rates."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["Rate", "wilson"]

Z95 = 1.959963984540054


@dataclass(frozen=True)
class Rate:
    """``k`` events in ``n`` trials, with a Wilson score interval.

    ``n == 0`` has no rate: :attr:`value`, :attr:`low` and :attr:`high` are None and it
    prints as ``n/a`` (kept distinct from a measured 0%).
    """

    k: int
    n: int
    value: float | None
    low: float | None
    high: float | None

    def __str__(self) -> str:
        if self.value is None:
            return "n/a"
        return f"{self.value:.1%} [{self.low:.1%}, {self.high:.1%}]"

    def to_json(self) -> dict[str, object]:
        return {"k": self.k, "n": self.n, "rate": self.value, "low": self.low, "high": self.high}


def wilson(k: int, n: int, *, z: float = Z95) -> Rate:
    """Wilson score interval for ``k`` successes in ``n`` trials (95% by default).

    Unlike the normal approximation it stays inside [0, 1] and is sensible at k = 0 or
    k = n, which is where violation rates often sit.
    """
    if n < 0 or k < 0 or k > n:
        raise InvalidArgument(f"need 0 <= k <= n, got k={k}, n={n}")
    if n == 0:
        return Rate(0, 0, None, None, None)
    p = k / n
    z2 = z * z
    denominator = 1 + z2 / n
    center = (p + z2 / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / denominator
    # Clamp only rounding noise: at k = 0 the exact lower bound is 0.
    return Rate(k, n, p, max(0.0, center - half), min(1.0, center + half))
