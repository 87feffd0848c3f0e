"""Confidence intervals for violation rates, and for the difference of two rates.

:func:`wilson` is the score interval of one rate (Wilson 1927); :func:`newcombe` the
hybrid score interval of a difference of two independent rates built from two Wilson
intervals (Newcombe 1998, method 10), which campaign baselines use to tell a worse rate
from noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

from pytest_metamorphic.core.errors import InvalidArgument

__all__ = ["Difference", "Rate", "newcombe", "wilson", "z_for"]

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


def z_for(confidence: float) -> float:
    """The two-sided normal quantile of ``confidence`` (0.95 -> 1.96)."""
    if isinstance(confidence, bool) or not isinstance(confidence, (int, float)):
        raise InvalidArgument(f"confidence={confidence!r} must be a number in (0, 1)")
    if not 0.0 < confidence < 1.0:
        raise InvalidArgument(f"confidence={confidence!r} must be in (0, 1), e.g. 0.95")
    return NormalDist().inv_cdf(0.5 + confidence / 2.0)


@dataclass(frozen=True)
class Difference:
    """``a - b`` of two independent rates, with Newcombe's hybrid score interval.

    None where either rate has no trials.
    """

    a: Rate
    b: Rate
    value: float | None
    low: float | None
    high: float | None

    def __str__(self) -> str:
        if self.value is None:
            return "n/a"
        return f"{self.value:+.1%} [{self.low:+.1%}, {self.high:+.1%}]"

    def to_json(self) -> dict[str, object]:
        return {"difference": self.value, "low": self.low, "high": self.high}


def newcombe(k_a: int, n_a: int, k_b: int, n_b: int, *, z: float = Z95) -> Difference:
    """Newcombe's hybrid score interval for ``k_a/n_a - k_b/n_b`` (independent samples).

    Each bound adds the two Wilson intervals' distances in quadrature (method 10 of
    Newcombe, Statistics in Medicine 17, 1998), so it keeps Wilson's good behaviour at
    0 and n, where violation rates sit; its coverage is close to nominal and errs on the
    conservative side there.
    """
    a, b = wilson(k_a, n_a, z=z), wilson(k_b, n_b, z=z)
    if a.value is None or b.value is None:
        return Difference(a, b, None, None, None)
    assert a.low is not None and a.high is not None and b.low is not None and b.high is not None
    difference = a.value - b.value
    low = difference - math.sqrt((a.value - a.low) ** 2 + (b.high - b.value) ** 2)
    high = difference + math.sqrt((a.high - a.value) ** 2 + (b.value - b.low) ** 2)
    return Difference(a, b, difference, max(-1.0, low), min(1.0, high))
