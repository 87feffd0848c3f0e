"""The README and the user guide link to files and headings that exist (the Sphinx build in
``.ci/run`` checks the guide's own cross-references and the API reference; this also covers
the README, which Sphinx does not read, and runs with the default suite)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = sorted([ROOT / "README.md", ROOT / "CHANGELOG.md", *(ROOT / "docs").glob("*.md")])
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def _anchors(page: Path) -> set[str]:
    """GitHub's and MyST's heading anchors: lower case, punctuation dropped, spaces -> '-'."""
    anchors, in_code = set(), False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code = not in_code
        match = None if in_code else re.match(r"#+ (.*)", line)
        if match:
            text = re.sub(r"[^\w\- ]", "", match.group(1).strip().lower())
            anchors.add(text.replace(" ", "-"))
    return anchors


LINKS = [
    (page, target)
    for page in PAGES
    for target in LINK.findall(page.read_text(encoding="utf-8"))
    if not target.startswith(("http://", "https://", "mailto:"))
]


def test_the_pages_link_to_each_other() -> None:
    assert len(LINKS) > 15


@pytest.mark.parametrize(("page", "target"), LINKS, ids=[f"{p.name}->{t}" for p, t in LINKS])
def test_a_relative_link_points_at_a_file_and_heading_that_exist(page: Path, target: str) -> None:
    path, _, anchor = target.partition("#")
    linked = (page.parent / path).resolve() if path else page
    assert linked.exists(), f"{page.name} links to {target}: no such file"
    if anchor:
        assert anchor in _anchors(linked), f"{page.name} links to {target}: no such heading"


def test_the_readme_is_a_first_visit() -> None:
    # The guide lives in docs/; the README keeps the Quickstart's two commands and links.
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) < 200
    assert text.count("```bash") == 2
