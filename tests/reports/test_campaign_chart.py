"""The campaign chart shows what the gate judges: violation rates with intervals, split by
fate, beside the paper's count metric (reports/campaign_chart.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic.core.campaign import CampaignResult, SizeCounts
from pytest_metamorphic.reports.campaign_chart import FATE_COLORS, violation_bars, write_chart


def _merging() -> CampaignResult:
    """Obstacles merge in every pair at n=100 (counts held: all "same" by the paper's
    metric), and are lost or merged in a fifth of the pairs at n=10."""
    header = {"campaign": "merges", "relation": "subset", "sources": 100, "sizes": [10, 100]}
    sizes = {
        10: SizeCounts(
            pairs=100,
            equal=100,
            violations=20,
            fates={"lost": 10, "merged": 10},
            categories={"car": [0, 100, 0]},
            category_violations={"car": 20},
        ),
        100: SizeCounts(
            pairs=100,
            equal=100,
            violations=100,
            fates={"merged": 100},
            categories={"car": [0, 100, 0]},
            category_violations={"car": 100},
        ),
    }
    return CampaignResult(header, sizes, sources_done=set(range(100)))


def test_bars_show_rates_intervals_and_fates() -> None:
    bars = violation_bars(_merging())
    overall = [bar for bar in bars if bar.category is None]
    assert [(bar.size, bar.k, bar.n, round(bar.rate)) for bar in overall] == [
        (10, 20, 100, 20),
        (100, 100, 100, 100),
    ]
    assert overall[0].low < 20 < overall[0].high
    assert overall[0].fates == (("lost", 10.0), ("merged", 10.0))
    per_category = [bar for bar in bars if bar.category == "car"]
    assert [round(bar.rate) for bar in per_category] == [20, 100]


def _pixels(path: Path, colour: str) -> int:
    image = pytest.importorskip("matplotlib.image")
    pixels = image.imread(path)[..., :3]
    rgb = np.array([int(colour[i : i + 2], 16) / 255 for i in (1, 3, 5)])
    return int(np.all(np.abs(pixels - rgb) < 0.02, axis=-1).sum())


def test_a_merge_that_keeps_the_counts_shows_as_violations(tmp_path: Path) -> None:
    """The issue's case: the paper's count chart is all grey, the violations are not."""
    pytest.importorskip("matplotlib")
    write_chart(_merging(), tmp_path / "c.png")
    merged = _pixels(tmp_path / "c.png", FATE_COLORS["merged"])
    lost = _pixels(tmp_path / "c.png", FATE_COLORS["lost"])
    assert merged > 0 and lost > 0
    # merged: 10% + 100% of a bar's height, lost: 10% (legend swatches add the same to both)
    assert 4 < merged / lost < 11
