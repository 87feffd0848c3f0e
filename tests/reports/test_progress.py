"""The campaign progress bar: drawn after pytest's dots, erased without a trace."""

from __future__ import annotations

import io

import pytest

from pytest_metamorphic.core.campaign import CampaignProgress
from pytest_metamorphic.reports.progress import ProgressBar, progress_text


class Screen:
    """A one-line terminal: interprets backspaces, overwrites characters in place."""

    def __init__(self, prefix: str) -> None:
        self.cells = list(prefix)
        self.cursor = len(prefix)

    def write(self, content: str, *, flush: bool = False) -> None:
        for char in content:
            if char == "\b":
                self.cursor = max(self.cursor - 1, 0)
                continue
            if self.cursor == len(self.cells):
                self.cells.append(char)
            else:
                self.cells[self.cursor] = char
            self.cursor += 1

    @property
    def text(self) -> str:
        return "".join(self.cells).rstrip()


def test_progress_text_shows_bar_counts_and_time_left() -> None:
    text = progress_text("MR1", 5, 20, 10.0, shard="2/8")
    assert text == " MR1 2/8: 5/20 sources, 10 s, ~30 s left [#####---------------]"
    assert progress_text("MR1", 20, 20, 12.0) == " MR1: 20/20 sources, 12 s [####################]"


def test_bar_redraws_in_place_and_erases_itself() -> None:
    screen = Screen("examples/test_campaign.py ..")
    bar = ProgressBar(screen, room=80, name="MR1")
    for done in (1, 10, 100):
        bar.update(CampaignProgress(done, 100))
        assert screen.text.startswith("examples/test_campaign.py .. MR1: ")
        assert f"{done}/100 sources" in screen.text
    bar.close()
    assert screen.text == "examples/test_campaign.py .."
    assert screen.cursor == len("examples/test_campaign.py ..")  # pytest's next dot goes here


def test_bar_never_wraps_and_skips_a_full_line() -> None:
    screen = Screen("x" * 70)
    ProgressBar(screen, room=30, name="a long campaign name").update(CampaignProgress(3, 10))
    assert len(screen.text) <= 70 + 30 and screen.text.endswith("…")
    full = Screen("x" * 79)
    ProgressBar(full, room=5, name="MR1").update(CampaignProgress(3, 10))
    assert full.text == "x" * 79


@pytest.mark.parametrize("tty", [False, True])
def test_bar_only_on_a_terminal(tty: bool) -> None:
    class Writer:
        fullwidth = 80
        _current_line = "x" * 30

        def write(self, content: str, *, flush: bool = False) -> None:
            raise AssertionError

    class Reporter:
        isatty = tty
        _tw = Writer()

    bar = ProgressBar.for_terminal(Reporter(), "MR1")
    assert (bar is not None) is tty
    if bar:
        assert bar.room == 49


def test_reporter_without_a_writer_gets_no_bar() -> None:
    assert ProgressBar.for_terminal(io.StringIO(), "MR1") is None


def test_writes_suspend_pytest_capture_and_width_ignores_colour() -> None:
    events: list[str] = []

    class Capture:
        def global_and_fixture_disabled(self):
            import contextlib

            @contextlib.contextmanager
            def suspended():
                events.append("suspend")
                yield
                events.append("resume")

            return suspended()

    class Writer:
        fullwidth = 80
        _current_line = "examples/t.py \x1b[32m.\x1b[0m\x1b[32m.\x1b[0m"

        def write(self, content: str, *, flush: bool = False) -> None:
            events.append("write")

    class Reporter:
        isatty = True
        _tw = Writer()

    bar = ProgressBar.for_terminal(Reporter(), "MR1", capture=Capture())
    assert bar is not None and bar.room == 80 - len("examples/t.py ..") - 1
    bar.update(CampaignProgress(1, 2))
    assert events == ["suspend", "write", "resume"]


def test_progress_text_shows_what_a_cluster_run_has_in_flight_failed_and_its_rate() -> None:
    text = progress_text("MR1", 40, 100, 20.0, shard="local:2", in_flight=6, failed=1, rate=2.0)
    assert text.startswith(" MR1 local:2: 40/100 sources, 6 in flight, 1 failed, 2.0/s, 20 s")
    assert "~30 s left" in text  # the 60 sources left at this run's 2 per second
