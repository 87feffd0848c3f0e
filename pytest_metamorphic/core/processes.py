"""Programs the project runs but did not write: bounded in time, memory and lifetime.

A detector in another process may hang, print a partial line and stall, fork helpers that
keep its output pipes open, print a banner on the channel reserved for answers, or write
gigabytes of logs. None of that may hang a test run, leave processes behind, or fill the
memory:

* every program runs in a **process group of its own**; on a time-out, at exit and when
  it is stopped, the whole group is killed (its helpers too);
* it **dies with the process that started it**, however that process ends (SIGTERM from a
  cancelled CI job or ``timeout``, SIGKILL, a crash, a Dask worker's death): the program
  is started by a small watchdog (a Python process without site imports) that holds the
  read end of a pipe whose write end only this process holds; when this process is gone
  the pipe reads end-of-file and the watchdog kills the whole group. The watchdog passes
  stdin, stdout and stderr straight to the program and exits with its status. (A child
  this process *forks* while the program runs inherits the write end and keeps the
  watchdog waiting until it exits too. POSIX only; on Windows programs run directly.);
* when the program ends, **whatever it started ends with it**: the watchdog steps out of
  the group and kills it before it reports the program's exit status. Leaving that to
  this process is not enough: when this process dies, the kernel may release the
  program's stdin a moment before the watchdog's pipe, so the program ends (end of
  input) before the watchdog learns that this process is gone;
* its **stderr goes to a file**, never a pipe, and only the last ``tail`` bytes are ever
  read back (the file is cut back to its tail while a long-lived program runs);
* :func:`run_command` waits for the program itself, not for pipes its helpers inherited;
* :class:`LineChannel` talks to a long-lived program one line at a time, reading **bytes**
  under a deadline (a partial line cannot block the read), and names output nobody asked
  for (stray stdout) instead of taking it for an answer.
"""

from __future__ import annotations

import contextlib
import errno
import os
import selectors
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from typing import IO, Any

from pytest_metamorphic.core.errors import ExternalSystemError, SystemTimeout

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

__all__ = ["STDERR_TAIL", "LineChannel", "kill_group", "run_command"]

STDERR_TAIL = 4096
"""Bytes of a program's stderr kept for error messages."""

# A long-lived program's stderr file is cut back to its tail beyond this size.
_STDERR_KEEP = 1 << 20
# An answer line longer than this is not an answer.
_MAX_LINE = 1 << 16


def kill_group(process: subprocess.Popen[bytes]) -> None:
    """Kill ``process`` and every process of its group, and reap it."""
    with contextlib.suppress(ProcessLookupError, PermissionError, OSError):
        if hasattr(os, "killpg"):
            os.killpg(process.pid, signal.SIGKILL)
        else:  # pragma: no cover - Windows: no process groups of this kind
            process.kill()
    with contextlib.suppress(Exception):
        process.wait(timeout=10)
    _release(process)


def _stderr_file() -> IO[bytes]:
    handle = tempfile.TemporaryFile(mode="w+b")  # noqa: SIM115 - its owner closes it
    # O_APPEND on the (shared) file description: the program always writes at the end,
    # also after the file is cut back ("a" in the mode would only seek to the end once).
    if fcntl is not None:
        flags = fcntl.fcntl(handle.fileno(), fcntl.F_GETFL)
        fcntl.fcntl(handle.fileno(), fcntl.F_SETFL, flags | os.O_APPEND)
    return handle


def _tail(handle: IO[bytes], size: int = STDERR_TAIL) -> str:
    """The last ``size`` bytes of a stderr file as indented text ("(nothing)" if empty)."""
    handle.flush()
    end = handle.seek(0, os.SEEK_END)
    handle.seek(max(end - size, 0))
    text = handle.read().decode("utf-8", errors="replace").strip()
    if not text:
        return "    (nothing)"
    if end > size:
        text = "..." + text
    return "\n".join(f"    {line}" for line in text.splitlines())


# The watchdog: runs the program as its child (same process group), and kills the group
# when the pipe from the test process reads end-of-file (that process is gone). When the
# program ends, it moves into the test process's group (a process may join a group of its
# own session), kills its old group (the program's leftovers) and exits with the
# program's status; if the test process is already gone (the group is in another session,
# or there is none), the status has no reader and the whole group is killed. Only os,
# sys, select and signal: it starts in a few milliseconds with -S -E.
_WATCHDOG = """
import os, select, signal, sys
watch = int(sys.argv[1])
args = sys.argv[2:]
wake_read, wake_write = os.pipe()
os.set_blocking(wake_write, False)
signal.set_wakeup_fd(wake_write)
signal.signal(signal.SIGCHLD, lambda *_: None)
signal.signal(signal.SIGTERM, lambda *_: os.killpg(0, signal.SIGKILL))
child = os.fork()
if child == 0:
    for fd in (watch, wake_read, wake_write):
        os.close(fd)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    try:
        os.execvp(args[0], args)
    except OSError as error:
        os.write(2, ("%s: %s\\n" % (args[0], error)).encode())
    os._exit(127)
while True:
    done, status = os.waitpid(child, os.WNOHANG)
    if done:
        break
    try:
        ready = select.select([watch, wake_read], [], [])[0]
    except InterruptedError:
        continue
    if wake_read in ready:
        os.read(wake_read, 512)
    if watch in ready and not os.read(watch, 1):
        os.killpg(0, signal.SIGKILL)
group = os.getpgid(0)
try:
    os.setpgid(0, os.getpgid(os.getppid()))
except OSError:
    os.killpg(0, signal.SIGKILL)
try:
    os.killpg(group, signal.SIGKILL)
except OSError:
    pass
if os.WIFSIGNALED(status):
    number = os.WTERMSIG(status)
    if number not in (signal.SIGKILL, signal.SIGSTOP):
        signal.signal(number, signal.SIG_DFL)
    os.kill(os.getpid(), number)
os._exit(os.waitstatus_to_exitcode(status))
"""


def _found(program: str, env: Mapping[str, str] | None, cwd: str | None) -> bool:
    """Whether ``program`` can be started (the watchdog would only find out after it
    forked, as exit status 127)."""
    if os.sep in program:
        path = program if os.path.isabs(program) else os.path.join(cwd or ".", program)
        return os.access(path, os.X_OK) and os.path.isfile(path)
    search = (env if env is not None else os.environ).get("PATH", os.defpath)
    return shutil.which(program, path=search) is not None


# Its own process group, killed as a whole. Not its own session: the watchdog must be able
# to move into the test process's group when the program ends (a session leader cannot
# change its group). Popen's process_group is new in Python 3.11.
_OWN_GROUP: dict[str, Any]
if not hasattr(os, "setpgid"):  # pragma: no cover - Windows: no process groups of this kind
    _OWN_GROUP = {"start_new_session": True}
elif sys.version_info >= (3, 11):
    _OWN_GROUP = {"process_group": 0}
else:  # pragma: no cover - Python 3.10
    _OWN_GROUP = {"preexec_fn": os.setpgrp}


def _popen(
    args: Sequence[str],
    *,
    stdin: int | IO[bytes],
    stdout: int | IO[bytes],
    stderr: IO[bytes],
    env: Mapping[str, str] | None,
    cwd: str | None,
) -> subprocess.Popen[bytes]:
    if not args:
        raise OSError(errno.EINVAL, "empty command")
    if not _found(args[0], env, cwd):
        raise OSError(errno.ENOENT, f"No such file or directory: {args[0]!r}")
    command: list[str] = list(args)
    keep: tuple[int, ...] = ()
    watch = None
    if hasattr(os, "fork") and hasattr(os, "killpg"):
        read_end, watch = os.pipe()  # the write end stays here, non-inheritable
        command = [sys.executable, "-S", "-E", "-c", _WATCHDOG, str(read_end), *args]
        keep = (read_end,)
    try:
        process = subprocess.Popen(
            command,
            stdin=stdin,
            stdout=stdout,
            stderr=stderr,
            env=None if env is None else dict(env),
            cwd=cwd,
            close_fds=True,
            pass_fds=keep,
            **_OWN_GROUP,
        )
    except BaseException:
        if watch is not None:
            os.close(watch)
        raise
    finally:
        for fd in keep:
            os.close(fd)
    if watch is not None:
        _WATCHES[process.pid] = watch
    return process


# pid of a watchdog -> the write end of its pipe, closed when its group is killed (or when
# this process ends, which is the point).
_WATCHES: dict[int, int] = {}


def _release(process: subprocess.Popen[bytes]) -> None:
    fd = _WATCHES.pop(process.pid, None)
    if fd is not None:
        with contextlib.suppress(OSError):
            os.close(fd)


def run_command(
    args: Sequence[str],
    *,
    name: str,
    timeout: float | None,
    env: Mapping[str, str] | None = None,
    cwd: str | None = None,
) -> None:
    """Run a program to completion within ``timeout`` seconds.

    Its stdout and stderr go to files (a helper it leaves running cannot block the wait);
    afterwards its whole process group is killed, so nothing it started outlives it.

    Raises
    ------
    SystemTimeout
        Still running after ``timeout`` seconds (the group is killed).
    ExternalSystemError
        It could not start, or exited with a non-zero status (with the end of its stderr).
    """
    with _stderr_file() as stderr:
        try:
            process = _popen(
                args, stdin=subprocess.DEVNULL, stdout=stderr, stderr=stderr, env=env, cwd=cwd
            )
        except OSError as error:
            raise ExternalSystemError(f"{name} could not start: {error}") from None
        try:
            status = process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise SystemTimeout(
                f"{name} did not finish within {timeout:g} s; killed with its process group",
                seconds=float(timeout or 0),
            ) from None
        finally:
            kill_group(process)  # the program's leftovers too, whatever happened
        if status != 0:
            raise ExternalSystemError(
                f"{name} exited with status {status}; its output ends:\n{_tail(stderr)}"
            )


class LineChannel:
    """A long-lived program that answers one line on stdout per line it reads on stdin.

    Parameters
    ----------
    args : sequence of str
        The command line.
    name : str
        How errors name the program.
    env, cwd
        Its environment and working directory.
    """

    def __init__(
        self,
        args: Sequence[str],
        *,
        name: str,
        env: Mapping[str, str] | None = None,
        cwd: str | None = None,
    ) -> None:
        self.name = name
        self._buffer = b""
        self._last: str | None = None
        self._stderr = _stderr_file()
        try:
            self.process = _popen(
                args,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=self._stderr,
                env=env,
                cwd=cwd,
            )
        except OSError as error:
            self._stderr.close()
            raise ExternalSystemError(f"{name} could not start: {error}") from None
        assert self.process.stdout is not None and self.process.stdin is not None
        self._stdout = self.process.stdout.fileno()
        os.set_blocking(self._stdout, False)

    def alive(self) -> bool:
        return self.process.poll() is None

    def close(self, grace: float = 5.0) -> None:
        """Close its stdin (the end of requests), give it ``grace`` seconds to exit, then
        kill its process group."""
        with contextlib.suppress(Exception):
            self.process.stdin.close()  # type: ignore[union-attr]
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(timeout=grace)
        kill_group(self.process)
        for stream in (self.process.stdout, self._stderr):
            with contextlib.suppress(Exception):
                stream.close()  # type: ignore[union-attr]

    def request(self, line: str, *, timeout: float | None) -> str:
        """Send ``line`` and return the program's one-line answer.

        Raises
        ------
        SystemTimeout
            No complete answer line within ``timeout`` seconds (a partial line included);
            the program's group is killed.
        ExternalSystemError
            It died, or printed something on stdout that is not the answer to this request
            (stdout is reserved for one answer line per request; logs go to stderr).
        """
        stray = self._pending()
        if stray:
            self.close(grace=0)
            # A banner printed at start-up is read as the first answer, and that answer
            # then shows up here: name both lines.
            before = f" after answering {self._last[:120]!r}" if self._last is not None else ""
            raise ExternalSystemError(
                f"{self.name} printed {stray[:200]!r} on stdout outside an answer{before}. "
                "stdout is reserved for one answer line per request (a library banner or a "
                "print there breaks the protocol); log to stderr"
            )
        try:
            self.process.stdin.write(line.encode("utf-8") + b"\n")  # type: ignore[union-attr]
            self.process.stdin.flush()  # type: ignore[union-attr]
        except OSError:
            self._died()
        answer = self._read_line(timeout)
        extra = self._pending()
        if extra:
            self.close(grace=0)
            raise ExternalSystemError(
                f"{self.name} printed more than one line for one request (the answer "
                f"{answer[:80]!r}, then {extra[:200]!r}). stdout is reserved for one answer "
                "line per request; log to stderr"
            )
        self._trim_stderr()
        self._last = answer
        return answer

    @property
    def last_answer(self) -> str | None:
        """The line taken as the answer to the latest request."""
        return self._last

    def output_within(self, seconds: float) -> str:
        """Whatever the program prints on stdout within ``seconds`` (empty if nothing);
        the program keeps running. Used to tell a stray line taken for an answer (a
        banner) from a real answer, when the files it announced turn out incomplete."""
        deadline = time.monotonic() + seconds
        while True:
            pending = self._pending()
            if pending or time.monotonic() >= deadline:
                return pending
            time.sleep(0.02)

    def stderr_tail(self) -> str:
        """The end of what the program wrote on stderr, indented, for error messages."""
        return _tail(self._stderr)

    @property
    def stderr_bytes(self) -> int:
        """Size of the kept stderr (cut back to its tail past a megabyte)."""
        return self._stderr.seek(0, os.SEEK_END)

    def _pending(self) -> str:
        """Output waiting on stdout now (without blocking), as text."""
        with contextlib.suppress(BlockingIOError, OSError):
            while True:
                chunk = os.read(self._stdout, 65536)
                if not chunk:
                    break
                self._buffer += chunk
        pending, self._buffer = self._buffer, b""
        return pending.decode("utf-8", errors="replace")

    def _read_line(self, timeout: float | None) -> str:
        deadline = None if timeout is None else time.monotonic() + timeout
        with selectors.DefaultSelector() as selector:
            selector.register(self._stdout, selectors.EVENT_READ)
            while b"\n" not in self._buffer:
                if len(self._buffer) > _MAX_LINE:
                    self.close(grace=0)
                    raise ExternalSystemError(
                        f"{self.name} printed {len(self._buffer)} bytes without a newline "
                        "where one answer line was expected"
                    )
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    partial = self._buffer[:80]
                    self.close(grace=0)
                    raise SystemTimeout(
                        f"{self.name} gave no answer within {timeout:g} s"
                        + (f" (it printed {partial!r} without a newline)" if partial else "")
                        + "; killed with its process group",
                        seconds=float(timeout or 0),
                    )
                # Checked between short waits: a helper that inherited stdout keeps the
                # pipe open after the program itself died.
                if not selector.select(0.2 if left is None else min(left, 0.2)):
                    if self.process.poll() is not None:
                        self._died()
                    continue
                try:
                    chunk = os.read(self._stdout, 65536)
                except BlockingIOError:
                    continue
                if not chunk:
                    self._died()
                self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line.decode("utf-8", errors="replace").rstrip("\r")

    def _died(self) -> None:
        try:
            status = self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            status = None
        tail = self.stderr_tail()
        self.close(grace=0)
        raise ExternalSystemError(
            f"{self.name} died (exit status {status}) before answering; its stderr ends:\n{tail}"
        )

    def _trim_stderr(self) -> None:
        """Cut the stderr file back to its tail once it is past a megabyte (the program
        appends, so it keeps writing at the new end)."""
        size = self._stderr.seek(0, os.SEEK_END)
        if size <= _STDERR_KEEP:
            return
        self._stderr.seek(size - STDERR_TAIL)
        keep = self._stderr.read()
        self._stderr.truncate(0)
        self._stderr.write(keep)  # appended: at the start of the emptied file
        self._stderr.flush()
