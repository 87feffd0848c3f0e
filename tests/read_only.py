"""A folder mounted read-only for one command, without privileges (a user and mount
namespace of its own), for tests of what a run does on a read-only mount."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest


def _unshare() -> str:
    tool = shutil.which("unshare")
    if tool is None:
        pytest.skip("unshare (util-linux) is not installed: no read-only mount to test on")
    probe = subprocess.run([tool, "-rm", "true"], capture_output=True, check=False)
    if probe.returncode:
        pytest.skip("user namespaces are not allowed here: no read-only mount to test on")
    return tool


def run_on_a_read_only_mount(folder: Path, command: list[str], cwd: Path) -> str:
    """Run ``command`` with ``folder`` bind-mounted read-only (a user and mount namespace
    of its own: no privileges needed, nothing outside the command sees the mount)."""
    script = (
        f'mount --bind "{folder}" "{folder}" && mount -o remount,bind,ro "{folder}" && exec "$@"'
    )
    done = subprocess.run(
        [_unshare(), "-rm", "sh", "-c", script, "sh", *command],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    return done.stdout + done.stderr
