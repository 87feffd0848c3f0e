"""The guide's code blocks are run by the docs build (docs/snippets.py, from docs/conf.py);
these tests check the runner itself: what it runs, and that it reports what fails."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "docs"))

import snippets  # noqa: E402

PAGE = """# A page

```python
from hypothesis import strategies as st
from pytest_metamorphic import metamorphic, relations

@metamorphic(source=st.lists(st.integers()), followup=lambda xs: st.permutations(xs),
             relation=relations.equal())
def test_sort(xs):
    return {body}
```

<!-- snippet: skip (a command for another machine) -->
```python
raise SystemExit("never run")
```

<!-- output -->
```text
test_doc_page.py::test_sort  equal  100 ...
```
"""


def _page(tmp_path: Path, body: str) -> Path:
    page = tmp_path / "page.md"
    page.write_text(PAGE.replace("{body}", body), encoding="utf-8")
    return page


def test_blocks_carry_their_marks_and_lines(tmp_path: Path) -> None:
    blocks = snippets.blocks(_page(tmp_path, "sorted(xs)"))
    assert [(b.language, b.mark, b.line) for b in blocks] == [
        ("python", "", 3),
        ("python", "skip (a command for another machine)", 14),
        ("text", "output", 19),
    ]


def test_a_shown_output_is_found_in_order_with_ellipses() -> None:
    real = "=== metamorphic relations ===\nt.py::test_sort   equal   100   200\n1 passed in 0.52s"
    shown = "==== metamorphic relations ====\n...\nt.py::test_sort equal ... 200\n1 passed in 3.1s"
    assert snippets.missing_lines(shown, real) == []
    assert snippets.missing_lines("1 passed in 3.1s\nt.py::test_sort", real) == ["t.py::test_sort"]


@pytest.mark.parametrize(
    ("body", "problem"),
    [("sorted(xs)", None), ("xs", "the page's snippets failed")],
    ids=["correct", "a bug the page's test finds"],
)
def test_a_page_runs_as_a_test_module(tmp_path: Path, body: str, problem: str | None) -> None:
    page = _page(tmp_path, body)
    run = snippets.run_page(page)
    assert run.ran == 1  # the skipped block is not run
    messages = [message for _, message in run.problems]
    if problem is None:
        assert messages == []
    else:
        assert messages[0].startswith(problem) and "MetamorphicViolation" in messages[0]
        assert any(m.startswith("output shown that the run did not print") for m in messages)


def test_a_page_that_shows_a_failure_must_fail(tmp_path: Path) -> None:
    page = _page(tmp_path, "sorted(xs)")
    page.write_text(
        page.read_text().replace("```python\nfrom", "<!-- snippet: fails -->\n```python\nfrom", 1)
    )
    messages = [message for _, message in snippets.run_page(page).problems]
    assert messages == ["the page shows a failing test, but none failed"]


@pytest.mark.slow
def test_the_readmes_campaign_output_is_a_real_runs() -> None:
    # The Quickstart's main job, run as the README says (about a minute): its table and
    # gate are printed as shown.
    checked = snippets.command_outputs(ROOT / "README.md")
    assert len(checked) == 1
    ((block, missing),) = checked
    assert block.mark == "output of: pytest examples/test_paper_campaign.py --mt-campaign"
    assert missing == []
