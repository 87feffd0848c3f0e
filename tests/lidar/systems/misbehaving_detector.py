"""Detector programs that misbehave the ways real ones do, for the process tests (not a
test module). Stdlib only, so each starts in milliseconds.

    python misbehaving_detector.py MODE [INPUT OUTPUT]

Per frame (INPUT OUTPUT given): ``sleep`` (10 s, then answers), ``fork`` (starts a helper
that keeps stdout and stderr open for 60 s and writes its pid to ``$MT_HELPER_PID``,
answers at once), ``chatty`` (writes 5 MB on stderr, then exits 1).
Long-lived (requests on stdin): ``partial`` (prints half a line, then stalls), ``banner``
(prints a banner before any request), ``banner-slow-writer`` (a banner, and each
predictions file left empty for half a second before it is written), ``two-lines`` (two
lines per request), ``noisy`` (2 MB on stderr per request), ``forking-server`` (a helper
per process that outlives it).
A request whose input is ``STALL`` is answered after a minute.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

EMPTY = {"boxes": []}


def answer(target: str) -> None:
    with open(target, "w") as handle:
        json.dump(EMPTY, handle)


def helper(pid_file: str) -> None:
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    with open(pid_file, "w") as handle:
        handle.write(str(child.pid))


def per_frame(mode: str, source: str, target: str) -> None:
    if mode == "sleep":
        time.sleep(10)
    elif mode == "fork":
        helper(os.environ["MT_HELPER_PID"])  # the helper inherits our stdout and stderr
    elif mode == "chatty":
        sys.stderr.write("x" * (5 << 20) + "\nthe last words\n")
        sys.exit(1)
    answer(target)


def slow_answer(target: str) -> None:
    """The predictions file exists, empty, for a while before it is written."""
    with open(target, "w") as handle:
        handle.flush()
        time.sleep(0.5)
        json.dump(EMPTY, handle)


def serve(mode: str) -> None:
    if mode in ("banner", "banner-slow-writer"):
        print("Welcome to DetectorNet 3.1 (c) ACME", flush=True)
    if mode == "forking-server":
        helper(sys.argv[2])
    for line in sys.stdin:
        parts = line.rstrip("\n").split("\t")
        if parts[0] == "STALL":
            time.sleep(60)
        for target in parts[1::2]:
            (slow_answer if mode == "banner-slow-writer" else answer)(target)
        if mode == "partial":
            sys.stdout.write("do")
            sys.stdout.flush()
            time.sleep(60)
        if mode == "noisy":
            sys.stderr.write("y" * (2 << 20) + "\n")
            sys.stderr.flush()
        print("done\t" + "\t".join(parts[::2]), flush=True)
        if mode == "two-lines":
            print("and another thing", flush=True)


if __name__ == "__main__":
    if len(sys.argv) == 4:
        per_frame(*sys.argv[1:])
    else:
        serve(sys.argv[1])
