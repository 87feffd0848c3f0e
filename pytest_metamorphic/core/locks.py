"""One writer at a time: an OS lock on what a run writes (a campaign's logs, an export).

Two runs writing one campaign directory blend two systems' results (and one run sets
aside logs the other is still writing); two exports into one folder mix their files.
:func:`exclusive` holds an advisory ``flock`` on a lock file next to what it guards. The
lock dies with the process (a killed run never leaves a stale lock behind), and a second
writer gets :class:`~pytest_metamorphic.core.errors.FolderInUse` naming the holder
(process id, host, command line) at once instead of waiting.

Locks are POSIX ``flock`` locks: on Windows nothing is locked (documented), and on some
network file systems the lock is only as good as the server's support for it.
"""

from __future__ import annotations

import contextlib
import os
import socket
import sys
from collections.abc import Iterator
from pathlib import Path

from pytest_metamorphic.core.errors import FolderInUse
from pytest_metamorphic.core.files import write_error

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

__all__ = ["exclusive"]


def _holder() -> str:
    command = " ".join(sys.argv)[:200]
    return f"process {os.getpid()} on {socket.gethostname()} ({command})"


@contextlib.contextmanager
def exclusive(lock: str | os.PathLike[str], *, what: str) -> Iterator[None]:
    """Hold the lock file ``lock`` (created if needed) for the block.

    Parameters
    ----------
    lock : path-like
        The lock file, e.g. ``folder/.lock``; its folder is created if needed.
    what : str
        What the lock guards, for the error ("campaign log ...", "export folder ...").

    Raises
    ------
    FolderInUse
        Another process holds the lock; the message names it.
    WriteError
        The lock file's folder cannot be written (a read-only mount, no permission).
    """
    path = Path(lock)
    if fcntl is None:  # pragma: no cover - Windows
        yield
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as error:  # a read-only mount, a file where the folder should be
        raise write_error(error, path.parent, what=what) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 400, 0).decode("utf-8", errors="replace").strip()
            raise FolderInUse(
                f"{what} is in use by {holder or 'another process'}; wait for it to finish "
                "or use another folder",
                path=path.parent,
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, _holder().encode("utf-8"), 0)
        yield
    finally:
        # Closing the descriptor releases the lock; the file stays (removing it would
        # race with a process that just opened it).
        os.close(fd)
