"""A campaign progress bar that lives at the end of pytest's own line of dots.

pytest writes one character per test after the file name. A campaign shard is one test
that can run for minutes, so while it runs the bar is written after those characters and
redrawn with backspaces; when the shard ends it is erased and pytest's ``.`` lands where
it belongs. The bar is drawn only on a terminal (``isatty``) and never wider than what is
left of the line; elsewhere (CI logs, pytest-xdist workers) nothing is drawn and the
final table says everything.
"""

from __future__ import annotations

import contextlib
import re
import time
from typing import Any, Protocol

__all__ = ["ProgressBar", "progress_text"]

_BAR_WIDTH = 20
_MIN_ROOM = 12
_ESCAPES = re.compile(r"\x1b\[[0-9;]*m")


class _Writer(Protocol):
    def write(self, content: str, *, flush: bool = False) -> None: ...


def progress_text(
    name: str,
    done: int,
    total: int,
    elapsed: float,
    *,
    shard: str = "",
    in_flight: int = 0,
    failed: int = 0,
    rate: float | None = None,
) -> str:
    """`` name 2/8: 10/20 sources, 4 in flight, 1 failed, 2.5/s, 4 s, ~4 s left [###---]``.

    In flight and failed show only when non-zero, the rate only when given; the bar comes
    last, so a narrow line loses it first.
    """
    filled = _BAR_WIDTH * done // total if total else _BAR_WIDTH
    bar = "#" * filled + "-" * (_BAR_WIDTH - filled)
    if rate:
        left = f", ~{(total - done) / rate:.0f} s left" if done < total else ""
    else:
        left = f", ~{elapsed / done * (total - done):.0f} s left" if 0 < done < total else ""
    where = f" {shard}" if shard else ""
    details = "".join(
        [
            f", {in_flight} in flight" if in_flight else "",
            f", {failed} failed" if failed else "",
            f", {rate:.1f}/s" if rate else "",
        ]
    )
    return f" {name}{where}: {done}/{total} sources{details}, {elapsed:.0f} s{left} [{bar}]"


class ProgressBar:
    """Draws :func:`progress_text` in the room left on the current terminal line.

    Parameters
    ----------
    writer : object with ``write(text, flush=)``
        pytest's terminal writer.
    room : int
        Columns left on the current line; below a dozen nothing is drawn.
    """

    def __init__(self, writer: _Writer, room: int, name: str, *, shard: str = "") -> None:
        self.writer = writer
        self.room = room
        self.name = name
        self.shard = shard
        self.shown = 0
        self.started = time.monotonic()

    @classmethod
    def for_terminal(
        cls, reporter: Any, name: str, *, shard: str = "", capture: Any = None
    ) -> ProgressBar | None:
        """A bar for pytest's terminal reporter, or None where none can be drawn.

        ``capture`` is pytest's capture manager: the bar is drawn while a test runs, when
        pytest captures the output, so every write suspends capturing.
        """
        writer = getattr(reporter, "_tw", None)
        if writer is None or not getattr(reporter, "isatty", False):
            return None
        # The terminal writer's own estimate counts colour escapes as -1 columns.
        line = getattr(writer, "_current_line", None)
        width = getattr(writer, "fullwidth", None)
        if not isinstance(line, str) or not isinstance(width, int):
            return None
        used = len(_ESCAPES.sub("", line))
        return cls(_Uncaptured(writer, capture), width - used - 1, name, shard=shard)

    def update(self, status: Any) -> None:
        """Redraw for a :class:`~pytest_metamorphic.core.campaign.CampaignProgress`."""
        if self.room < _MIN_ROOM:
            return
        text = progress_text(
            self.name,
            status.done,
            status.total,
            time.monotonic() - self.started,
            shard=self.shard,
            in_flight=status.in_flight,
            failed=status.failed,
            rate=status.rate,
        )
        if len(text) > self.room:
            text = text[: self.room - 1] + "…"
        self._replace(text)

    def close(self) -> None:
        """Erase the bar, leaving the cursor where pytest left it."""
        self._replace("")

    def _replace(self, text: str) -> None:
        back = "\b" * self.shown
        # Blank out what the new text does not cover, then step back to its end.
        extra = max(self.shown - len(text), 0)
        self.writer.write(back + text + " " * extra + "\b" * extra, flush=True)
        self.shown = len(text)


class _Uncaptured:
    """Writes to the terminal even while pytest captures the test's output."""

    def __init__(self, writer: _Writer, capture: Any) -> None:
        self.writer = writer
        self.capture = capture

    def write(self, content: str, *, flush: bool = False) -> None:
        suspended = (
            self.capture.global_and_fixture_disabled()
            if self.capture is not None
            else contextlib.nullcontext()
        )
        with suspended:
            self.writer.write(content, flush=flush)
