"""Failures reported at the user's test, not inside the plugin.

A metamorphic violation is found by the engine after the user's function has returned, so
its traceback would end in the engine's wrapper (``core/engine.py``), a file the user
never wrote. pytest and Hypothesis hide their own frames (``__tracebackhide__``); when
every frame of an error is hidden pytest shows them all again. So the error is raised
once more from a frame whose file and line are those of the user's ``def`` line: the
traceback then names the test that failed, with its decorators as context, as a failing
``assert`` in its body would.
"""

from __future__ import annotations

import linecache
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

__all__ = ["explain_the_users_code", "raise_at_definition", "start_at_the_users_test"]

_NAME = "__mt_error__"
_MARK = "__mt_definition__"  # a global of the raiser's frame: where the user's part starts
_PACKAGE = str(Path(__file__).resolve().parent.parent)


def raise_at_definition(fn: Callable[..., Any], error: BaseException) -> NoReturn:
    """Raise ``error`` from a frame at the ``def`` line of ``fn`` (the user's test).

    The library frames the error came through are dropped (its ``__cause__`` and
    ``__context__``, a crashed system's own traceback among them, are kept). Falls back to
    a plain ``raise`` where the source of ``fn`` cannot be read.
    """
    __tracebackhide__ = True
    raiser = _raiser_at(fn, error.with_traceback(None))
    if raiser is None:
        raise error
    raiser()
    raise AssertionError("unreachable")  # pragma: no cover - the raiser always raises


def _raiser_at(fn: Callable[..., Any], error: BaseException) -> Callable[[], NoReturn] | None:
    code = getattr(fn, "__code__", None)
    if code is None:
        return None
    filename = code.co_filename
    line = _def_line(filename, code.co_firstlineno)
    if line is None:
        return None
    text = linecache.getline(filename, line)
    indent = len(text) - len(text.lstrip())
    # The raise statement is at least as long as the user's line, so pytest draws no
    # carets under part of it (it omits a highlight that spans the whole line).
    statement = f"raise ({_NAME}"
    statement += " " * max(0, len(text.strip()) - len(statement) - 1) + ")"
    name = fn.__name__ if fn.__name__.isidentifier() else "test"
    source = "\n" * (line - 2) + f"def {name}():\n" + " " * max(indent, 1) + statement
    # The error is a global, not an argument: pytest prints a frame's arguments.
    namespace: dict[str, Any] = {_MARK: True, _NAME: error}
    try:
        exec(compile(source, filename, "exec"), namespace)  # our own two lines
    except SyntaxError:  # pragma: no cover - a name that is a keyword: the plain raise
        return None
    raiser: Callable[[], NoReturn] = namespace[name]
    return raiser


def _def_line(filename: str, first: int) -> int | None:
    """The line of the ``def`` statement at or after ``first`` (the first decorator)."""
    for line in range(first, first + 200):
        text = linecache.getline(filename, line).lstrip()
        if not text:
            if not linecache.getline(filename, line + 1):
                return None  # past the end of the file
            continue
        if text.startswith(("def ", "async def ")):
            return line if line >= 2 else None
    return None


def start_at_the_users_test(excinfo: Any) -> None:
    """Start a failure's traceback at the frame :func:`raise_at_definition` made.

    ``excinfo`` is pytest's ``ExceptionInfo``. Above that frame are only pytest's,
    Hypothesis's and the plugin's frames; one of them, Hypothesis's signature wrapper,
    poses as the plugin's wrapper function and is not hidden. Nothing changes when the
    error was not raised at a definition (a crash inside the user's own fixture, say).
    """
    entries = list(excinfo.traceback)
    for index, entry in enumerate(entries):
        if entry.frame.f_globals.get(_MARK):
            excinfo.traceback = excinfo.traceback[index:]
            return


def explain_the_users_code(error: BaseException) -> None:
    """Drop the plugin's own lines from Hypothesis's explanation ("These lines were always
    and only run by failing test cases"): the engine runs a comparison only when it fails,
    which says nothing about the user's code. The whole explanation goes when nothing of
    the user's is left in it."""
    notes = getattr(error, "__notes__", None)
    if not isinstance(notes, list) or "Explanation:" not in notes:
        return
    start = notes.index("Explanation:")
    end = start + 2
    while end < len(notes) and notes[end].startswith("        "):
        end += 1
    lines = notes[start + 2 : end]
    kept = [line for line in lines if not line.strip().startswith(_PACKAGE)]
    if len(kept) == len(lines):
        return
    located = [line for line in kept if not line.strip().startswith("(and ")]
    notes[start:end] = notes[start : start + 2] + kept if located else []
