"""The site looks maintained at 1280 px: docs/check_layout.py opens the built pages in
headless Chromium (Debian's, driven by Playwright) and fails on what reaches past the
article or is clipped. Skipped where Chromium or Playwright is not installed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "docs"))

import check_layout  # noqa: E402

pytest.importorskip("playwright", reason="playwright is not installed (pip install playwright)")
pytestmark = pytest.mark.skipif(
    check_layout.chromium() is None, reason="no chromium (apt install chromium)"
)


def test_the_probe_sees_an_overflowing_table_and_clipped_code(tmp_path: Path) -> None:
    (tmp_path / "index.html").write_text(
        "<html><body><div role='main' style='width:500px'>"
        "<table style='width:900px'><tr><td>wide</td></tr></table>"
        "<pre style='overflow-x:hidden;width:200px'>" + "x" * 200 + "</pre>"
        "<pre style='overflow-x:auto;width:200px'>" + "y" * 200 + "</pre>"
        "</div></body></html>",
        encoding="utf-8",
    )
    (result,) = check_layout.check_site(tmp_path, tmp_path / "shots", pages=["index.html"])
    assert not result.clean
    assert result.overflowing == ["table: wide"]
    assert result.clipped == ["pre: " + "x" * 60]
    assert result.scrolling == ["pre: " + "y" * 60]
    assert (tmp_path / "shots" / "index.png").stat().st_size > 0


@pytest.mark.slow
def test_the_built_site_has_no_overflow_at_1280_px(tmp_path: Path) -> None:
    site = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "sphinx", "-q", "-b", "html", "-D", "mt_run_snippets=0",
         str(ROOT / "docs"), str(site)],
        check=True,
    )  # fmt: skip
    results = check_layout.check_site(site, tmp_path / "shots")
    assert [r.page for r in results if not r.clean] == [], results
    assert len(list((tmp_path / "shots").glob("*.png"))) == len(check_layout.PAGES)
