"""Files the project did not write: opened without blocking, parsed without escaping.

Recordings, artifacts from another machine, manifests a detector farm filled in and a
detector's prediction files are outside data. Reading them must never hang (a FIFO named
like a recording blocks ``open()`` until a writer appears), never read outside the folder
that holds them (a record naming ``../../etc/passwd``), never echo what it read into an
error, and never end in a raw traceback from deep inside a parser. Every reader of
outside data goes through these helpers:

* :func:`open_regular` / :func:`read_regular`: a regular file or a :class:`DataError`
  saying what it is instead (a FIFO, a device, a directory), checked on the open file
  descriptor (no race with a swap between check and open);
* :func:`read_json`: UTF-8 JSON of bounded size and nesting;
* :func:`inside`: a path from a record resolved inside its folder (no absolute paths, no
  ``..``, no symlink out);
* :func:`field`: a typed field of a parsed record, or a DataError naming it.

Writing under a folder a user named goes through :func:`staging_sibling` (a hidden
temporary name that fits the file system's name limit, however long the user's name) and
:func:`write_error` (the operating system's failure as a
:class:`~pytest_metamorphic.core.errors.WriteError` naming the user's path, with advice
that fits the cause: a read-only mount is not a full disk).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import stat
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

from pytest_metamorphic.core.errors import DataError, WriteError

__all__ = [
    "MAX_JSON_BYTES",
    "check_regular",
    "field",
    "inside",
    "open_regular",
    "open_regular_fd",
    "read_json",
    "read_regular",
    "staging_sibling",
    "write_advice",
    "write_atomically",
    "write_error",
]

MAX_JSON_BYTES = 64 * 1024 * 1024
"""The largest JSON file read (records, manifests, prediction files are far smaller)."""


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a regular file"


def open_regular_fd(path: str | os.PathLike[str], *, what: str = "file") -> int:
    """A raw descriptor of ``path`` opened for reading if it is a regular file (for readers
    that read into arrays straight from the descriptor); see :func:`open_regular`."""
    name = os.fspath(path)
    # Non-blocking, so that opening a FIFO returns at once.
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(name, flags)
    except IsADirectoryError:
        raise DataError(f"cannot read {what}: it is a directory", path=name) from None
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise DataError(f"cannot read {what}: {reason}", path=name) from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise DataError(f"cannot read {what}: it is {_kind(mode)}", path=name)
        # O_NONBLOCK stays: it means nothing for a regular file (reads never wait), and
        # clearing it would cost two more system calls per file.
    except BaseException:
        os.close(fd)
        raise
    return fd


def check_regular(path: str | os.PathLike[str], *, what: str = "file") -> None:
    """Refuse ``path`` unless it is a regular file, without opening it (for files a
    third-party library opens itself: a bag's storage files).

    Raises
    ------
    DataError
        Missing, or not a regular file (named: a FIFO, a device, a directory).
    """
    name = os.fspath(path)
    try:
        mode = os.stat(name).st_mode
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise DataError(f"cannot read {what}: {reason}", path=name) from None
    if not stat.S_ISREG(mode):
        raise DataError(f"cannot read {what}: it is {_kind(mode)}", path=name)


def open_regular(path: str | os.PathLike[str], *, what: str = "file") -> IO[bytes]:
    """Open ``path`` for binary reading if it is a regular file.

    Parameters
    ----------
    path : path-like
    what : str
        What the file should be ("PCD file", "artifact record"), for the error.

    Raises
    ------
    DataError
        Missing, unreadable, or not a regular file (named: a FIFO, a device, a directory);
        never blocks on a FIFO.
    """
    return os.fdopen(open_regular_fd(path, what=what), "rb")


def read_regular(
    path: str | os.PathLike[str], *, what: str = "file", limit: int | None = None
) -> bytes:
    """The bytes of a regular file (see :func:`open_regular`), at most ``limit`` of them.

    Raises
    ------
    DataError
        As :func:`open_regular`, or the file is larger than ``limit`` bytes.
    """
    with open_regular(path, what=what) as handle:
        # The size first: read(limit + 1) would allocate the whole limit up front.
        size = os.fstat(handle.fileno()).st_size
        if limit is not None and size > limit:
            raise DataError(f"{what} is larger than {limit} bytes", path=os.fspath(path))
        data = handle.read(size + 1)
    if limit is not None and len(data) > limit:  # it grew while being read
        raise DataError(f"{what} is larger than {limit} bytes", path=os.fspath(path))
    return data


def read_json(
    path: str | os.PathLike[str], *, what: str = "JSON file", limit: int = MAX_JSON_BYTES
) -> Any:
    """Parse a JSON file from outside.

    Raises
    ------
    DataError
        Not a readable regular file, larger than ``limit``, not UTF-8, not JSON, or nested
        deeper than the parser's recursion limit; the message names the file and the
        place, never its text.
    """
    name = os.fspath(path)
    data = read_regular(path, what=what, limit=limit)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise DataError(f"{what} is not UTF-8 (byte {error.start})", path=name) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise DataError(
            f"{what} is not valid JSON (line {error.lineno}, column {error.colno}: {error.msg})",
            path=name,
        ) from None
    except RecursionError:
        # The C parser stops at the interpreter's recursion limit (about 1000 levels).
        raise DataError(f"{what} is nested too deeply to parse", path=name) from None


def inside(
    folder: str | os.PathLike[str],
    relative: object,
    *,
    field: str,
    path: str | os.PathLike[str] | None = None,
) -> Path:
    """``folder / relative`` for a path read from a record, refused unless it stays inside
    ``folder``.

    Parameters
    ----------
    folder : path-like
        The folder the record describes (an artifact, a dataset).
    relative : object
        The value read from the record.
    field : str
        Where it was read (``"source.cloud"``), for the error.
    path : path-like, optional
        The record's own file, named in the error.

    Raises
    ------
    DataError
        Not a non-empty string; an absolute path; a ``..`` component; or a path that a
        symbolic link takes out of ``folder``. The value itself is not echoed beyond its
        first 80 characters.
    """
    where = os.fspath(path) if path is not None else os.fspath(folder)
    if not isinstance(relative, str) or not relative or "\x00" in relative:
        raise DataError(f"{field} must be a file name inside the folder", path=where)
    shown = relative if len(relative) <= 80 else relative[:77] + "..."
    candidate = Path(relative)
    if candidate.is_absolute() or candidate.drive or ".." in candidate.parts:
        raise DataError(
            f"{field} = {shown!r} leaves the folder (absolute or '..'); refused", path=where
        )
    base = Path(folder).resolve()
    resolved = (base / candidate).resolve()
    if not resolved.is_relative_to(base):
        raise DataError(
            f"{field} = {shown!r} leaves the folder through a symbolic link; refused",
            path=where,
        )
    return base / candidate


def field(
    record: object,
    key: str,
    types: type | tuple[type, ...],
    *,
    where: str,
    path: str | os.PathLike[str] | None = None,
    default: Any = ...,
) -> Any:
    """``record[key]`` checked to be of ``types``.

    Parameters
    ----------
    record : object
        A parsed JSON object (anything else is reported as such).
    key : str
    types : type or tuple of type
        Accepted types; ``bool`` is never accepted for ``int`` or ``float``.
    where : str
        The record's name for the error (``"the manifest's entry 3"``).
    path : path-like, optional
        The file, named in the error.
    default : object, optional
        Returned when the key is missing; without it a missing key is an error.

    Raises
    ------
    DataError
        ``record`` is not an object, the key is missing, or the value has another type.
    """
    name = None if path is None else os.fspath(path)
    if not isinstance(record, Mapping):
        raise DataError(f"{where} must be a JSON object, not {_json_type(record)}", path=name)
    if key not in record:
        if default is not ...:
            return default
        raise DataError(f"{where} has no {key!r}", path=name)
    value = record[key]
    accepted = types if isinstance(types, tuple) else (types,)
    numeric = any(t in (int, float) for t in accepted) and bool not in accepted
    if not isinstance(value, accepted) or (numeric and isinstance(value, bool)):
        wanted = " or ".join(_json_type_name(t) for t in accepted)
        raise DataError(f"{where}: {key!r} must be {wanted}, not {_json_type(value)}", path=name)
    return value


_JSON_NAMES = {
    dict: "an object",
    list: "an array",
    str: "a string",
    int: "an integer",
    float: "a number",
    bool: "true or false",
    type(None): "null",
}


def _json_type_name(kind: type) -> str:
    return _JSON_NAMES.get(kind, kind.__name__)


def _json_type(value: object) -> str:
    for kind, name in _JSON_NAMES.items():
        if type(value) is kind:
            return name
    return type(value).__name__


def write_atomically(path: Path, write: Callable[[Path], object], *, what: str = "file") -> None:
    """Create or replace ``path`` with what ``write(tmp)`` writes to a temporary sibling,
    renamed into place: an interruption never leaves half a file.

    Raises
    ------
    WriteError
        The folder or the file cannot be written (named: ``path``, not the sibling).
    """
    path = Path(path)
    tmp = staging_sibling(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write(tmp)
        os.replace(tmp, path)
    except OSError as error:
        _discard(tmp)
        if isinstance(error, WriteError):
            raise
        raise write_error(error, path, what=what) from None
    except BaseException:
        _discard(tmp)
        raise


def _discard(tmp: Path) -> None:
    # On a read-only mount even unlinking a file that is not there fails (EROFS).
    with contextlib.suppress(OSError):
        tmp.unlink(missing_ok=True)


NAME_MAX = 255
"""The longest file name (in bytes) assumed where the file system does not say."""


def _name_max(folder: Path) -> int:
    for candidate in (folder, *folder.parents):
        try:
            return int(os.pathconf(candidate, "PC_NAME_MAX"))
        except (OSError, ValueError, AttributeError):  # not there yet, or no pathconf
            continue
    return NAME_MAX


def staging_sibling(target: str | os.PathLike[str], kind: str = "tmp") -> Path:
    """A fresh hidden name beside ``target`` to write before renaming into place:
    ``.<name>.<8 hex>.<kind>``, the name cut so that the whole fits the file system's
    limit (a legal 250-byte name would otherwise make a 264-byte temporary one)."""
    target = Path(target)
    tag = f".{uuid.uuid4().hex[:8]}.{kind}"
    room = _name_max(target.parent) - 1 - len(tag)
    name = os.fsencode(target.name)
    if len(name) > room:
        name = name[: max(room, 1)]
    return target.parent / f".{os.fsdecode(name)}{tag}"


_ADVICE = {
    errno.EROFS: "it is on a read-only file system: choose a folder on a writable one",
    errno.EACCES: "you may not write there: choose a folder you may write to",
    errno.EPERM: "you may not write there: choose a folder you may write to",
    errno.ENOSPC: "the disk is full: free some space",
    errno.EDQUOT: "the disk quota is used up: free some space",
    errno.EFBIG: "the file reached the largest size allowed (the file system's, or ulimit -f)",
    errno.ENAMETOOLONG: "a name is too long for the file system: choose a shorter one",
    errno.ENOTDIR: "a file stands where a folder must be: move it or choose another path",
    errno.EISDIR: "a folder stands where the file must be: move it or choose another path",
    # mkdir(exist_ok=True) on a file says EEXIST
    errno.EEXIST: "a file stands where a folder must be: move it or choose another path",
    errno.EMFILE: "the process has too many files open",
    errno.ENFILE: "the system has too many files open",
}


def write_advice(error: OSError) -> str:
    """What to do about ``error``, an operating-system failure to write."""
    return _ADVICE.get(error.errno or 0, "check that the folder exists and can be written")


def write_error(error: OSError, path: str | os.PathLike[str], *, what: str) -> WriteError:
    """``error`` as a :class:`~pytest_metamorphic.core.errors.WriteError` naming ``path``
    (the user's, whatever file the operating system named) and what to do."""
    reason = error.strerror or type(error).__name__
    return WriteError(
        f"could not write {what} ({reason}): {write_advice(error)}", path=path, cause=error
    )
