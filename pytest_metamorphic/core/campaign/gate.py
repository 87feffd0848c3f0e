"""When a campaign fails a build: its gate.

A campaign measures a rate; a CI job needs a verdict. :class:`Gate` says which, and
:func:`judge_campaign` gives it on a finished result:

* **no violations** (the default, ``max_rate=0``): one violating pair fails the campaign,
  as one violation fails a ``@metamorphic`` test;
* **a threshold** (``max_rate=0.05``, or one rate per size): fails where the evidence says
  the rate is above it: the lower bound of the Wilson interval, at ``confidence`` shared
  over the sizes (Bonferroni), exceeds the threshold. A rate that merely *looks* above it
  in a small sample passes, and says so;
* **expected violations** (``expect_violations=True``, a campaign on a known fault such
  as a mutant): fails when the relation found *no* violation, because then the relation
  did not detect the fault it is there to detect;
* **a baseline** (a report of the same campaign from another run, e.g. main's): fails
  where this run's rate is significantly worse than the baseline's: the lower bound of
  Newcombe's interval for the difference, at ``confidence`` shared over the sizes,
  exceeds ``margin`` (for expected violations, worse is *fewer*: the upper bound falls
  below ``-margin``).

Whatever the mode, a campaign that did not test what it claims cannot pass: a partial
run, a size at which no pair could be made, or (unless ``allow_crashes``) a pair or
source on which the system crashed.

The confidence is family-wise over one campaign's sizes, 0.99 by default: a gate that
fails a pull request falsely is worse than one that misses a small regression (a
campaign whose rate does not change passes against its own baseline in 20 of 20
reruns with other seeds; ``tests/core/campaign/test_gate.py``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from pytest_metamorphic.core.campaign.results import CampaignResult, SizeCounts
from pytest_metamorphic.core.errors import InvalidArgument
from pytest_metamorphic.core.intervals import newcombe, wilson, z_for

__all__ = ["DEFAULT_CONFIDENCE", "Gate", "GateCheck", "GateVerdict", "judge_campaign"]

DEFAULT_CONFIDENCE = 0.99


def _check_rate(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < 1:
        raise InvalidArgument(f"{what}={value!r} must be a rate in [0, 1), e.g. 0.05")
    return float(value)


@dataclass(frozen=True)
class Gate:
    """When a campaign test fails (see the module's docstring).

    Parameters
    ----------
    max_rate : float, mapping of size -> float, or None
        The violation rate above which the campaign fails; 0 (the default) fails on one
        violation; a mapping gives each size its own (sizes it leaves out: 0); None: no
        threshold (only a baseline, crashes and untested sizes fail).
    expect_violations : bool
        The system has a fault the relation must detect: fail when no pair violates.
    confidence : float
        Family-wise confidence of the threshold and baseline tests over the sizes.
    allow_crashes : bool
        Do not fail on pairs or sources that crashed the system (they are reported).
    margin : float
        How much worse than the baseline a rate may be before it counts (absolute).
    """

    max_rate: float | Mapping[int, float] | None = 0.0
    expect_violations: bool = False
    confidence: float = DEFAULT_CONFIDENCE
    allow_crashes: bool = False
    margin: float = 0.0

    def __post_init__(self) -> None:
        if isinstance(self.max_rate, Mapping):
            rates = {}
            for size, rate in self.max_rate.items():
                if isinstance(size, bool) or not isinstance(size, int):
                    raise InvalidArgument(f"max_rate's keys must be sizes (ints), got {size!r}")
                rates[size] = _check_rate(rate, f"max_rate[{size}]")
            object.__setattr__(self, "max_rate", dict(sorted(rates.items())))
        elif self.max_rate is not None:
            object.__setattr__(self, "max_rate", _check_rate(self.max_rate, "max_rate"))
        for name in ("expect_violations", "allow_crashes"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidArgument(f"{name}={getattr(self, name)!r} must be True or False")
        if self.expect_violations and self.max_rate not in (None, 0.0):
            raise InvalidArgument(
                "expect_violations=True with a max_rate: a campaign either expects its "
                "system to violate the relation or bounds how often it may"
            )
        z_for(self.confidence)  # validates
        _check_rate(self.margin, "margin")

    def threshold(self, size: int) -> float | None:
        """The maximum rate at ``size`` (None: no threshold)."""
        if self.max_rate is None or self.expect_violations:
            return None
        if isinstance(self.max_rate, Mapping):
            return float(self.max_rate.get(size, 0.0))
        return float(self.max_rate)

    def describe(self) -> str:
        if self.expect_violations:
            return "expects violations: a fault the relation must detect"
        if self.max_rate is None:
            return "no threshold on the violation rate"
        if isinstance(self.max_rate, Mapping):
            rates = ", ".join(f"{size}: {rate:.1%}" for size, rate in self.max_rate.items())
            return f"violation rate at most {{{rates}}} (others 0)"
        if self.max_rate == 0:
            return "no violations"
        return f"violation rate at most {self.max_rate:.1%}"

    def to_json(self) -> dict[str, Any]:
        rate = self.max_rate
        return {
            "max_rate": {str(k): v for k, v in rate.items()} if isinstance(rate, Mapping) else rate,
            "expect_violations": self.expect_violations,
            "confidence": self.confidence,
            "allow_crashes": self.allow_crashes,
            "margin": self.margin,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Gate:
        rate = data.get("max_rate", 0.0)
        if isinstance(rate, Mapping):
            rate = {int(k): v for k, v in rate.items()}
        return cls(
            max_rate=rate,
            expect_violations=bool(data.get("expect_violations", False)),
            confidence=data.get("confidence", DEFAULT_CONFIDENCE),
            allow_crashes=bool(data.get("allow_crashes", False)),
            margin=data.get("margin", 0.0),
        )


@dataclass(frozen=True)
class GateCheck:
    """One part of a gate's verdict: what was checked, whether it passed, and why."""

    name: str
    passed: bool
    lines: tuple[str, ...]

    def to_json(self) -> dict[str, Any]:
        return {"check": self.name, "passed": self.passed, "lines": list(self.lines)}


@dataclass(frozen=True)
class GateVerdict:
    """A campaign's verdict: passed only if every check passed."""

    campaign: str
    gate: Gate
    checks: tuple[GateCheck, ...] = field(default_factory=tuple)

    @property
    def passed(self) -> bool:
        return all(check.passed for check in self.checks)

    def lines(self) -> list[str]:
        state = "PASSED" if self.passed else "FAILED"
        out = [f"gate {state}: campaign {self.campaign!r} ({self.gate.describe()})"]
        for check in self.checks:
            mark = "ok  " if check.passed else "FAIL"
            out.extend(f"  {mark} {line}" for line in check.lines[:1])
            out.extend(f"       {line}" for line in check.lines[1:])
        return out

    def failure_message(self) -> str:
        failed = [check for check in self.checks if not check.passed]
        head = f"campaign {self.campaign!r} failed its gate ({self.gate.describe()})"
        return "\n".join([head, *(line for check in failed for line in check.lines)])

    def to_json(self) -> dict[str, Any]:
        return {
            "passed": self.passed,
            "gate": self.gate.to_json(),
            "checks": [check.to_json() for check in self.checks],
        }


def _label(result: CampaignResult) -> str:
    return str(result.header.get("size_label", "n"))


def _z(gate: Gate, tests: int) -> tuple[float, float]:
    """The z of each of ``tests`` two-sided intervals sharing ``gate.confidence``, and the
    confidence each has (Bonferroni)."""
    each = 1.0 - (1.0 - gate.confidence) / max(tests, 1)
    return z_for(each), each


def _tested(result: CampaignResult) -> GateCheck:
    lines = []
    if not result.complete:
        done, total = len(result.sources_done), result.header["sources"]
        lines.append(f"PARTIAL: {done} of {total} sources finished; a partial run cannot pass")
    for size, counts in sorted(result.sizes.items()):
        if counts.pairs == 0:
            reason = (
                f"none of its {counts.not_applicable} follow-ups could be made"
                if counts.not_applicable
                else "no pair was run"
            )
            lines.append(f"NOTHING TESTED at {_label(result)}={size}: {reason}")
        elif counts.judged == 0 and counts.crashes < counts.pairs:
            lines.append(
                f"NOTHING JUDGED at {_label(result)}={size}: in none of its {counts.pairs} "
                "pairs did the relation judge an element (no obstacle in scope: check the "
                "ROI, the scope and what the system reports)"
            )
    if lines:
        return GateCheck("tested", False, tuple(lines))
    pairs = sum(counts.pairs for counts in result.sizes.values())
    return GateCheck("tested", True, (f"every size tested ({pairs} pairs in all)",))


def _crashes(result: CampaignResult, gate: Gate) -> GateCheck:
    pairs = sum(counts.crashes for counts in result.sizes.values())
    sources = result.source_crashes
    if not pairs and not sources:
        return GateCheck("crashes", True, ("no crash",))
    what = f"{pairs} pair(s) and {sources} source(s) crashed the system"
    if gate.allow_crashes:
        return GateCheck("crashes", True, (f"{what} (allowed: allow_crashes=True)",))
    return GateCheck(
        "crashes",
        False,
        (f"{what}: a crash is not a pass (allow_crashes=True tolerates them)",),
    )


def _threshold(result: CampaignResult, gate: Gate) -> GateCheck | None:
    sizes = [(s, c, gate.threshold(s)) for s, c in sorted(result.sizes.items()) if c.pairs]
    limited = [(s, c, t) for s, c, t in sizes if t is not None]
    if not limited:
        return None
    if all(limit == 0 for _, _, limit in limited):
        return _none_allowed(result, [(size, counts) for size, counts, _ in limited])
    z, each = _z(gate, len(limited))
    lines, passed = [], True
    for size, counts, limit in limited:
        rate = wilson(counts.violations, counts.pairs, z=z)
        assert rate.low is not None
        above = rate.low > limit
        passed &= not above
        verdict = "above" if above else "not above"
        lines.append(
            f"{_label(result)}={size}: {counts.violations} of {counts.pairs} pairs violate "
            f"({rate.value:.1%}); {each:.2%} lower bound {rate.low:.1%} is {verdict} the "
            f"maximum {limit:.1%}"
        )
    head = (
        f"violation rate within its maximum at every {_label(result)} "
        f"(Wilson lower bounds, {gate.confidence:.0%} over {len(limited)} size(s))"
    )
    if not passed:
        head = (
            f"violation rate above its maximum (Wilson lower bounds, {gate.confidence:.0%} "
            f"over {len(limited)} size(s))"
        )
    return GateCheck("threshold", passed, (head, *lines))


def _none_allowed(result: CampaignResult, sizes: list[tuple[int, SizeCounts]]) -> GateCheck:
    """The default gate: one violating pair fails (any lower bound of k >= 1 is above 0)."""
    pairs = sum(counts.pairs for _, counts in sizes)
    found = [(size, counts) for size, counts in sizes if counts.violations]
    if not found:
        return GateCheck("threshold", True, (f"no violation in {pairs} pairs",))
    lines = [
        f"{_label(result)}={size}: {counts.violations} of {counts.pairs} pairs violate "
        f"({counts.violations / counts.pairs:.1%})"
        for size, counts in found
    ]
    total = sum(counts.violations for _, counts in found)
    return GateCheck(
        "threshold",
        False,
        (
            f"{total} violating pair(s) where none is allowed (campaign_test(max_rate=...) "
            "bounds a rate instead; expect_violations=True for a known fault)",
            *lines,
        ),
    )


def _not_gated(result: CampaignResult) -> GateCheck:
    """``max_rate=None``: the violations are reported, not judged."""
    pairs = sum(counts.pairs for counts in result.sizes.values())
    found = sum(counts.violations for counts in result.sizes.values())
    return GateCheck(
        "threshold",
        True,
        (f"{found} violating pair(s) in {pairs}: reported, not gated (max_rate=None)",),
    )


def _expected(result: CampaignResult) -> GateCheck:
    found = {size: counts.violations for size, counts in sorted(result.sizes.items())}
    pairs = sum(counts.pairs for counts in result.sizes.values())
    total = sum(found.values())
    per_size = ", ".join(f"{_label(result)}={size}: {k}" for size, k in found.items())
    if total:
        return GateCheck(
            "expected violations",
            True,
            (f"found the expected violations: {total} of {pairs} pairs ({per_size})",),
        )
    return GateCheck(
        "expected violations",
        False,
        (
            f"expected violations, found none in {pairs} pairs: the relation did not "
            "detect this system's fault",
        ),
    )


def _baseline(
    result: CampaignResult, gate: Gate, baseline: CampaignResult, where: str
) -> GateCheck:
    if baseline.header.get("relation") != result.header.get("relation"):
        return GateCheck(
            "baseline",
            False,
            (
                f"the baseline ({where}) judged relation {baseline.header.get('relation')!r}, "
                f"this run {result.header.get('relation')!r}: rates of different relations "
                "are not comparable; refresh the baseline",
            ),
        )
    common = [
        (size, counts, baseline.sizes[size])
        for size, counts in sorted(result.sizes.items())
        if size in baseline.sizes and counts.pairs and baseline.sizes[size].pairs
    ]
    if not common:
        return GateCheck(
            "baseline",
            False,
            (f"the baseline ({where}) shares no tested size with this run: nothing compared",),
        )
    z, each = _z(gate, len(common))
    lines, passed = [], True
    worse_word = "fewer violations" if gate.expect_violations else "worse"
    for size, now, then in common:
        difference = newcombe(now.violations, now.pairs, then.violations, then.pairs, z=z)
        assert difference.low is not None and difference.high is not None
        if gate.expect_violations:
            worse = difference.high < -gate.margin
        else:
            worse = difference.low > gate.margin
        passed &= not worse
        lines.append(
            f"{_label(result)}={size}: {now.violations}/{now.pairs} ({_rate(now)}) vs baseline "
            f"{then.violations}/{then.pairs} ({_rate(then)}): difference {difference.value:+.1%}, "
            f"{each:.2%} interval [{difference.low:+.1%}, {difference.high:+.1%}]"
            + (f" -> {worse_word}" if worse else "")
        )
    margin = f", margin {gate.margin:.1%}" if gate.margin else ""
    head = (
        f"{'not ' if passed else ''}significantly {worse_word} than the baseline {where} "
        f"(Newcombe intervals for the difference, {gate.confidence:.0%} over "
        f"{len(common)} size(s){margin})"
    )
    if not baseline.complete:
        lines.append(
            f"(the baseline is partial: {len(baseline.sources_done)} of "
            f"{baseline.header.get('sources')} sources)"
        )
    return GateCheck("baseline", passed, (head, *lines))


def _rate(counts: SizeCounts) -> str:
    return f"{counts.violations / counts.pairs:.1%}" if counts.pairs else "n/a"


def judge_campaign(
    result: CampaignResult,
    gate: Gate | None = None,
    *,
    baseline: CampaignResult | None = None,
    baseline_where: str = "",
    baseline_note: str = "",
) -> GateVerdict:
    """The gate's verdict on a finished (merged) campaign result.

    Parameters
    ----------
    result : CampaignResult
    gate : Gate, optional
        Default ``Gate()``: no violations, no crashes, every size tested.
    baseline : CampaignResult, optional
        The same campaign's result from another run (:func:`load_baseline`).
    baseline_where : str
        Where the baseline came from, for the messages.
    baseline_note : str
        Why there is no baseline although one was asked for (printed, not a failure).
    """
    gate = gate or Gate()
    if not isinstance(gate, Gate):
        raise InvalidArgument(f"gate={gate!r} must be a Gate")
    checks = [_tested(result), _crashes(result, gate)]
    if gate.expect_violations:
        checks.append(_expected(result))
    else:
        checks.append(_threshold(result, gate) or _not_gated(result))
    if baseline is not None:
        checks.append(_baseline(result, gate, baseline, baseline_where))
    elif baseline_note:
        checks.append(GateCheck("baseline", True, (f"not compared: {baseline_note}",)))
    return GateVerdict(str(result.header.get("campaign", "")), gate, tuple(checks))
