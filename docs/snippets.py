"""Every Python block of the guide runs, and every output shown is a real run's.

Each page's ``python`` blocks are written, in order, into one test module (after the
page's setup file ``docs/_snippets/<page>.py`` where there is one: the stand-ins a page
names but does not define, such as a user's model, and the paths of the shared data),
and pytest runs that module with the plugin, in a temporary folder. So a block is
checked as a user would use it: statements run at import, ``test_*`` functions run as
tests. A page expects every test to pass unless it says otherwise with an HTML comment
(invisible on the site) before a block::

    <!-- snippet: fails -->          the tests of this page fail (it shows a failure)
    <!-- snippet: skip (reason) -->  this block is not run (say why: a command for a GPU)

A block inside an HTML comment runs but is not shown: what a page's reader does between
two blocks elsewhere (a detector's run on another machine). The setup file's
``SUBSTITUTE`` maps strings of the page to what runs here (a user's ``recordings/*.pcd``
to a recording of the shared data).

An output block after ``<!-- output of: pytest examples/... -->`` shows what that command
prints (:func:`command_outputs`, run by a slow test: a whole campaign takes a minute).

An output block is a ``text`` block after the comment ``<!-- output -->``: each of its
lines, except ``...``, must appear in the run's output, in order (``...`` within a line
stands for any text), once numbers of seconds, the run's temporary folder and the width of
pytest's rules are set aside. The docs build (``conf.py``) runs all pages
and turns a failure into a warning, an error under ``-W``; ``python docs/snippets.py
[page.md ...]`` runs them from the command line and prints each run's output.
"""

from __future__ import annotations

import ast
import os
import re
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
SETUP = DOCS / "_snippets"
TIMEOUT = 600

_FENCE = re.compile(r"^(`{3,})(\S*)\s*$")
_MARK = re.compile(r"^<!--\s*(snippet|output)\b:?\s*(.*?)\s*-->\s*$")


@dataclass
class Block:
    """One fenced code block of a page."""

    page: Path
    line: int  # of the opening fence, 1-based
    language: str
    code: str
    mark: str = ""  # the <!-- ... --> comment just before it: "output", "fails", "skip ..."


@dataclass
class PageRun:
    """What running a page's snippets gave."""

    page: Path
    ran: int = 0
    output: str = ""
    problems: list[tuple[int, str]] = field(default_factory=list)  # (line, message)


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a Markdown page, with the comment that precedes each."""
    found: list[Block] = []
    lines = page.read_text(encoding="utf-8").splitlines()
    index, mark = 0, ""
    while index < len(lines):
        text = lines[index]
        comment = _MARK.match(text.strip())
        fence = _FENCE.match(text)
        if comment:
            kind, rest = comment.groups()
            if kind == "output":
                mark = f"output {rest}" if rest.startswith("of:") else "output"
            else:
                mark = rest
        elif fence:
            end = index + 1
            while end < len(lines) and lines[end].rstrip() != fence.group(1):
                end += 1
            code = "\n".join(lines[index + 1 : end])
            found.append(Block(page, index + 1, fence.group(2), code, mark))
            index, mark = end, ""
        elif text.strip():
            mark = ""
        index += 1
    return found


def substitutions(page: Path) -> dict[str, str]:
    """``SUBSTITUTE`` of the page's setup file: strings of the page replaced when run
    (``"recordings/*.pcd"`` -> a recording of the shared data), so a block reads as a user
    writes it and runs on real files."""
    setup = SETUP / f"{page.stem}.py"
    if not setup.exists():
        return {}
    tree = ast.parse(setup.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(target, ast.Name) and target.id == "SUBSTITUTE" for target in node.targets
        ):
            namespace: dict[str, Any] = {
                "DATA": str(data_folder()),
                "PYTHON": sys.executable,
                "ROOT": str(ROOT),
            }
            value = eval(compile(ast.Expression(node.value), str(setup), "eval"), namespace)
            return {str(key): str(item) for key, item in value.items()}
    return {}


def data_folder() -> Path:
    """The shared data, as the tests find it."""
    return Path(os.environ.get("PYTEST_METAMORPHIC_DATA", ROOT.parent / "shared" / "data"))


def module_source(page: Path, page_blocks: list[Block]) -> str:
    """The test module a page's Python blocks make (setup file first)."""
    # The names a setup file's SUBSTITUTE may use, defined for the setup itself too.
    parts = [f"DATA = {str(data_folder())!r}\nPYTHON = {sys.executable!r}\nROOT = {str(ROOT)!r}"]
    setup = SETUP / f"{page.stem}.py"
    if setup.exists():
        parts.append(f"# --- {_shown(setup)}\n" + setup.read_text(encoding="utf-8"))
    replace = substitutions(page)
    for block in page_blocks:
        if block.language == "python" and not block.mark.startswith("skip"):
            code = block.code
            for old, new in replace.items():
                code = code.replace(old, new)
            parts.append(f"# --- {_shown(page)}:{block.line}\n" + code)
    return "\n\n".join(parts) + "\n"


def _shown(path: Path) -> Path:
    """A path as printed: relative to the repository where it lies inside it."""
    return path.relative_to(ROOT) if path.is_relative_to(ROOT) else path


def normalized(text: str) -> str:
    """Output as compared: seconds, temporary folders and runs of spaces set aside."""
    text = re.sub(r"\b\d+(\.\d+)?s\b", "<s>", text)
    text = re.sub(r"(/tmp|/var/folders)/\S*?mt-snippets-[^/\s]*/", "", text)
    text = re.sub(r"={3,}", "===", text)  # rules as wide as the terminal
    return re.sub(r"[ \t]+", " ", text).strip()


def missing_lines(shown: str, output: str) -> list[str]:
    """Lines of a shown output block not found, in order, in the real output."""
    real = [normalized(line) for line in output.splitlines()]
    position, missing = 0, []
    for line in shown.splitlines():
        wanted = normalized(line)
        if not wanted or wanted in {"...", "…"}:
            continue
        pieces = [piece.strip() for piece in wanted.split("...") if piece.strip()]
        for index in range(position, len(real)):
            if _in_order(pieces, real[index]):
                position = index + 1
                break
        else:
            missing.append(line.strip())
    return missing


def _in_order(pieces: list[str], line: str) -> bool:
    """The pieces of a shown line (split at "...") occur in the real line, in order."""
    start = 0
    for piece in pieces:
        found = line.find(piece, start)
        if found < 0:
            return False
        start = found + len(piece)
    return True


def run_page(page: Path, *, python: str = sys.executable) -> PageRun:
    """Run a page's Python blocks as one pytest module; compare its output blocks."""
    result = PageRun(page)
    page_blocks = blocks(page)
    code = [b for b in page_blocks if b.language == "python" and not b.mark.startswith("skip")]
    if not code:
        return result
    result.ran = len(code)
    fails = any(b.mark == "fails" for b in page_blocks)
    with tempfile.TemporaryDirectory(prefix="mt-snippets-") as folder:
        module = Path(folder) / f"test_doc_{page.stem.replace('-', '_')}.py"
        module.write_text(module_source(page, page_blocks), encoding="utf-8")
        # A fixed seed: the build is reproducible (CI's profile is not loaded in the
        # temporary folder); a reader's own run searches afresh.
        command = [python, "-m", "pytest", str(module), "-p", "no:cacheprovider", "-q"]
        command += ["--hypothesis-seed=0"]
        command += ["--rootdir", folder, "--mt-artifacts", str(Path(folder) / "mt-artifacts")]
        environment = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "200"}
        try:
            run = subprocess.run(
                command, cwd=folder, capture_output=True, text=True, timeout=TIMEOUT,
                env=environment,
            )  # fmt: skip
        except subprocess.TimeoutExpired:
            result.problems.append((code[0].line, f"the page's snippets ran past {TIMEOUT} s"))
            return result
    result.output = run.stdout + run.stderr
    if fails and run.returncode != 1:
        result.problems.append((code[0].line, "the page shows a failing test, but none failed"))
    elif not fails and run.returncode not in (0, 5):
        tail = "\n".join(result.output.splitlines()[-40:])
        result.problems.append((code[0].line, f"the page's snippets failed:\n{tail}"))
    for block in page_blocks:
        if block.mark == "output":
            missing = missing_lines(block.code, result.output)
            if missing:
                result.problems.append(
                    (block.line, "output shown that the run did not print: " + missing[0])
                )
    return result


def command_outputs(page: Path) -> list[tuple[Block, list[str]]]:
    """Output blocks marked ``<!-- output of: pytest ... -->`` and what their command's
    run did not print (an empty list: all of it). The command runs from the repository's
    root with ``python -m``, its campaign logs and artifacts in a temporary folder. Slower
    than a page's snippets (a whole campaign), so run by a slow test, not by the build."""
    checked = []
    for block in blocks(page):
        if not block.mark.startswith("output of:"):
            continue
        words = shlex.split(block.mark.removeprefix("output of:"))
        with tempfile.TemporaryDirectory(prefix="mt-snippets-") as folder:
            command = [sys.executable, "-m", *words, "-p", "no:cacheprovider"]
            if words[0] == "pytest":
                command += ["--mt-campaign-dir", f"{folder}/c", "--mt-artifacts", f"{folder}/a"]
            environment = {**os.environ, "COLUMNS": "200"}
            run = subprocess.run(
                command, cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT,
                env=environment,
            )  # fmt: skip
        checked.append((block, missing_lines(block.code, run.stdout + run.stderr)))
    return checked


def pages() -> list[Path]:
    """The pages whose snippets run: the guide and the README."""
    return [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]


def main(argv: list[str]) -> int:
    chosen = [Path(arg).resolve() for arg in argv] or pages()
    failed = 0
    for page in chosen:
        run = run_page(page)
        if not run.ran:
            continue
        print(f"== {_shown(page)}: {run.ran} block(s)")
        print(run.output)
        for line, message in run.problems:
            failed += 1
            print(f"{_shown(page)}:{line}: {message}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
