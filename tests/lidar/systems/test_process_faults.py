"""Detector programs that misbehave never hang a run, never outlive it, never fill the
memory, and are named for what they did (issue: inputs from outside)."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic.core.errors import ExternalSystemError, SystemTimeout
from pytest_metamorphic.lidar.systems.process import ProcessDetector

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX process groups")

SCRIPT = str(Path(__file__).with_name("misbehaving_detector.py"))
CLOUD = np.zeros((8, 4), np.float32)


def per_frame(mode: str, **options: object) -> ProcessDetector:
    return ProcessDetector([sys.executable, SCRIPT, mode, "{input}", "{output}"], **options)


def served(mode: str, *extra: str, **options: object) -> ProcessDetector:
    return ProcessDetector([sys.executable, SCRIPT, mode, *extra], persistent=True, **options)


def gone(pid: int) -> bool:
    """Not running: no such process, or a zombie waiting for its reaper."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return True
    return state in ("Z", "X")


def eventually(condition, seconds: float = 10.0) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


def test_the_timeout_is_the_limit_per_frame_without_a_startup_allowance() -> None:
    # Before: timeout + startup_timeout (60 s) per frame, so a 10 s sleep "passed".
    started = time.monotonic()
    with pytest.raises(SystemTimeout, match="within 1 s"):
        per_frame("sleep", timeout=1, startup_timeout=60)(CLOUD)
    assert time.monotonic() - started < 9  # killed long before its 10 s


def test_a_helper_holding_the_pipes_neither_blocks_the_frame_nor_outlives_it(
    tmp_path: Path,
) -> None:
    # Before: a false timeout on every frame (the wait read the pipes to their end), and
    # the helpers were left running.
    pid_file = tmp_path / "helper.pid"
    detector = per_frame("fork", timeout=20, env={"MT_HELPER_PID": str(pid_file)})
    started = time.monotonic()
    assert detector(CLOUD) == []
    assert time.monotonic() - started < 15
    helper = int(pid_file.read_text())
    assert eventually(lambda: gone(helper))


def test_stderr_is_read_back_only_as_its_tail() -> None:
    with pytest.raises(ExternalSystemError, match="status 1") as info:
        per_frame("chatty", timeout=30)(CLOUD)
    message = str(info.value)
    assert "the last words" in message and len(message) < 10_000


def test_a_partial_answer_line_cannot_hang_a_long_lived_process() -> None:
    # Before: readline() blocked after select() saw "do"; the run hung for ever.
    detector = served("partial", timeout=1, startup_timeout=1)
    started = time.monotonic()
    with pytest.raises(SystemTimeout, match="'do' without a newline"):
        detector(CLOUD)
    assert time.monotonic() - started < 9
    assert not detector.running


# A banner read as an answer names no frame of the request, which the protocol also warns
# about (timing decides whether it is read so); that warning is not these tests'.
IGNORE_FRAMELESS_ANSWER = pytest.mark.filterwarnings(
    "ignore::pytest_metamorphic.core.errors.ProtocolWarning"
)


@IGNORE_FRAMELESS_ANSWER
@pytest.mark.parametrize("mode", ["banner", "two-lines"])
def test_stray_output_on_stdout_is_named(mode: str) -> None:
    detector = served(mode, timeout=30)
    with pytest.raises(ExternalSystemError, match="stdout is reserved") as info:
        for _ in range(3):  # caught on the request where the stray line shows
            detector(CLOUD)
    assert ("Welcome" in str(info.value)) or ("another thing" in str(info.value))
    assert not detector.running


@IGNORE_FRAMELESS_ANSWER
def test_a_banner_taken_for_the_answer_is_named_even_if_the_file_is_half_written() -> None:
    """The banner is read as the first answer while the program is still writing its
    predictions: the file is empty then (or, on a loaded machine, not yet created). Its
    real answer follows; the error names the banner, not the file (before: "wrote
    garbage", depending on timing)."""
    detector = served("banner-slow-writer", timeout=30)
    with pytest.raises(ExternalSystemError, match="stdout is reserved") as info:
        detector(CLOUD)
    message = str(info.value)
    assert "Welcome to DetectorNet" in message and "garbage" not in message
    if "before writing" not in message:  # the file existed, half written
        assert "the first line was not its answer" in message and "'done" in message
    assert not detector.running


def test_a_long_lived_processs_stderr_stays_bounded() -> None:
    with served("noisy", timeout=30) as detector:
        for _ in range(4):  # 8 MB written in all
            detector(CLOUD)
        assert detector._channel is not None
        assert detector._channel.stderr_bytes < 3 << 20


def test_closing_kills_the_helpers_of_a_long_lived_process(tmp_path: Path) -> None:
    pid_file = tmp_path / "helper.pid"
    detector = served("forking-server", str(pid_file), timeout=30)
    detector(CLOUD)
    helper = int(pid_file.read_text())
    assert not gone(helper)
    detector.close()
    assert eventually(lambda: gone(helper))


def test_a_dead_process_is_replaced_and_its_helpers_do_not_outlive_it(tmp_path: Path) -> None:
    pid_file = tmp_path / "helper.pid"
    detector = served("forking-server", str(pid_file), timeout=30)
    detector(CLOUD)
    helper = int(pid_file.read_text())
    process = detector._channel.process  # type: ignore[union-attr]
    os.kill(process.pid, 9)  # dies between two frames
    process.wait(10)
    assert detector(CLOUD) == []  # started again for the next frame
    assert detector.starts == 2
    assert eventually(lambda: gone(helper))  # its group went with the dead process
    detector.close()


def test_a_program_that_ends_takes_its_helpers_with_it(tmp_path: Path) -> None:
    # The test process dying closes the program's stdin and the watchdog's pipe one after
    # the other, and the kernel may release them in either order. Before: when the stdin
    # went first, the program ended (end of input), the watchdog exited with its status
    # and nothing was left to kill the helper (7 of 500 parents killed under load leaked
    # it). Here the stdin closes alone, and the helper must still go, with no kill from
    # this process.
    pid_file = tmp_path / "helper.pid"
    detector = served("forking-server", str(pid_file), timeout=30)
    detector(CLOUD)
    channel = detector._channel
    assert channel is not None and channel.process.stdin is not None
    helper = int(pid_file.read_text())
    channel.process.stdin.close()
    assert channel.process.wait(10) == 0  # the program's own status still comes back
    assert eventually(lambda: gone(helper)), _describe([helper])


def test_a_process_that_dies_while_its_helper_holds_stdout_is_named(tmp_path: Path) -> None:
    # The helper keeps the pipe open: end-of-file never comes, the process's death must
    # still be noticed (not a time-out after the full limit).
    pid_file = tmp_path / "helper.pid"
    detector = served("forking-server", str(pid_file), timeout=30)
    detector(CLOUD)
    channel = detector._channel
    assert channel is not None
    threading_kill = __import__("threading").Timer(0.5, os.kill, (channel.process.pid, 9))
    threading_kill.start()
    started = time.monotonic()
    with pytest.raises(ExternalSystemError, match="died"):
        channel.request(f"STALL\t{tmp_path / 'out.json'}", timeout=30)
    assert time.monotonic() - started < 10


# -- no orphan: a detector dies with the process that started it ------------------------------

PARENT = """
import sys, time
import numpy as np
from pytest_metamorphic.lidar.systems.process import ProcessDetector
script, pid_file, group_file = sys.argv[1:4]
detector = ProcessDetector([sys.executable, script, "forking-server", pid_file],
                           persistent=True, timeout=30)
detector(np.zeros((8, 4), np.float32))
with open(group_file, "w") as handle:
    handle.write(str(detector._channel.process.pid))
time.sleep(600)  # a test runner busy elsewhere, until it is killed
"""


def _group(pgid: int) -> list[int]:
    """Live (not zombie) processes of process group ``pgid``."""
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError):
            continue
        if int(fields[2]) == pgid and fields[0] not in ("Z", "X"):
            members.append(int(entry.name))
    return members


def _describe(pids: list[int]) -> str:
    """Each process's state and command line, for a failure message."""
    lines = []
    for pid in pids:
        try:
            state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
            command = (Path("/proc") / str(pid) / "cmdline").read_bytes().replace(b"\0", b" ")
        except OSError:
            state, command = "gone", b""
        lines.append(f"{pid} [{state}] {command.decode(errors='replace')[:200]}")
    return "; ".join(lines)


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc to find the processes")
@pytest.mark.parametrize("signal_number", [15, 9], ids=["SIGTERM", "SIGKILL"])
def test_a_persistent_detector_dies_with_its_parent(tmp_path: Path, signal_number: int) -> None:
    # Before: the detector (its own session) outlived a parent killed by SIGTERM, which
    # is what a cancelled CI job and `timeout` send, and by SIGKILL.
    pid_file, group_file = tmp_path / "helper.pid", tmp_path / "group.pid"
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, SCRIPT, str(pid_file), str(group_file)],
        env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[3])},
    )
    try:
        assert eventually(group_file.exists, 60), "the parent never started its detector"
        assert eventually(lambda: group_file.read_text().strip() != "", 5)
        group = int(group_file.read_text())
        helper = int(pid_file.read_text())
        assert len(_group(group)) >= 3  # the watchdog, the detector, its helper
        os.kill(parent.pid, signal_number)
        parent.wait(10)
        # It used to leave the helper alive now and then (7 of 500 parents killed under
        # load): the program had ended first; see
        # test_a_program_that_ends_takes_its_helpers_with_it. The message says what
        # survived if anything does again.
        assert eventually(lambda: not _group(group), 30), _describe(_group(group))
        assert gone(helper)
    finally:
        parent.kill()
        text = group_file.read_text().strip() if group_file.exists() else ""
        if text:  # a failed run must not leave the group behind either
            with contextlib.suppress(ProcessLookupError):
                os.killpg(int(text), 9)


@pytest.mark.parametrize("literal", ["d = {}", "d = {'boxes': 1}", "x = '{0} {input!r}'"])
def test_braces_in_a_command_are_the_users_text(literal: str) -> None:
    # Before: IndexError / KeyError from str.format on the first frame.
    code = f"import json, sys; {literal}; json.dump({{'boxes': []}}, open(sys.argv[2], 'w'))"
    detector = ProcessDetector([sys.executable, "-c", code, "{input}", "{output}"])
    assert detector(CLOUD) == []


# -- frame identity: an answer names its input ------------------------------------------------

STALE = """
import json, sys
previous = None
for line in sys.stdin:
    parts = line.rstrip("\\n").split("\\t")
    for target in parts[1::2]:
        json.dump({"boxes": []}, open(target, "w"))
    print("done\\t" + (previous or parts[0]), flush=True)  # answers the request before
    previous = parts[0]
"""

SWAPPED = """
import json, sys
for line in sys.stdin:
    parts = line.rstrip("\\n").split("\\t")
    inputs, targets = parts[0::2], parts[1::2]
    for source, target in zip(reversed(inputs), targets):  # a batch's files mixed up
        json.dump({"input": source, "boxes": []}, open(target, "w"))
    print("\\t".join(inputs), flush=True)
"""

ANONYMOUS = """
import json, sys
for line in sys.stdin:
    for target in line.rstrip("\\n").split("\\t")[1::2]:
        json.dump({"boxes": []}, open(target, "w"))
    print("done", flush=True)
"""


def test_an_answer_to_an_earlier_request_is_refused() -> None:
    # Before: the protocol carried no frame identity; nothing noticed.
    detector = ProcessDetector([sys.executable, "-c", STALE], persistent=True)
    assert detector(CLOUD) == []  # the first answer names the first frame
    with pytest.raises(ExternalSystemError, match="names a frame of an earlier request"):
        detector(CLOUD)
    detector.close()


def test_a_batch_whose_files_name_the_wrong_frames_is_refused() -> None:
    detector = ProcessDetector([sys.executable, "-c", SWAPPED], persistent=True, batch_size=2)
    assert detector.run_batch([CLOUD]) == [[]]
    with pytest.raises(ExternalSystemError, match="the detector mixed up its frames"):
        detector.run_batch([CLOUD, CLOUD])
    detector.close()


def test_an_answer_that_names_no_frame_is_warned_once() -> None:
    from pytest_metamorphic import ProtocolWarning

    detector = ProcessDetector([sys.executable, "-c", ANONYMOUS], persistent=True)
    with pytest.warns(ProtocolWarning, match="names no frame of the request") as warned:
        detector(CLOUD)
        detector(CLOUD)
    assert len(warned) == 1
    detector.close()
