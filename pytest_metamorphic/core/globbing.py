"""Glob patterns over a user's folders, safe against symbolic-link loops.

:func:`glob.glob` with ``recursive=True`` follows every symbolic link to a folder: a
``self -> .`` link makes ``loop/**/*.pcd`` list one file 41 times (until the kernel's
``ELOOP``), and two such links make the walk exponential (it never ends). :func:`expand`
gives the same matches as :func:`glob.glob` for the patterns users write (``*``, ``?``,
``[...]``, ``**`` for any depth, names starting with ``.`` only for a pattern that starts
with ``.``), but walks each folder once (by device and inode, links followed) and lists
each file once, under the first path the walk reaches it by.
"""

from __future__ import annotations

import fnmatch
import glob
import os
from collections import deque
from collections.abc import Iterator, Sequence

__all__ = ["expand"]


def expand(pattern: str) -> list[str]:
    """The paths ``pattern`` matches, sorted, each file and folder once.

    Parameters
    ----------
    pattern : str
        A glob pattern; ``**`` as a whole component matches any number of folders.

    Returns
    -------
    list of str
        Matching files and folders, joined to the pattern's fixed leading part as
        :func:`glob.glob` joins them.
    """
    parts = pattern.split(os.sep)
    fixed = next((i for i, part in enumerate(parts) if glob.has_magic(part)), len(parts))
    if fixed == len(parts):  # no wildcard: the path itself, when it exists
        return [pattern] if os.path.lexists(pattern) else []
    root = os.sep.join(parts[:fixed])
    start = root if root else os.curdir
    if not os.path.isdir(start):
        return []
    wanted = [part for part in parts[fixed:] if part]  # "a//b" is "a/b"
    found = {}
    for relative, identity in _walk(start, deep="**" in wanted, depth=len(wanted)):
        if identity not in found and _match(wanted, relative):
            found[identity] = os.path.join(root, *relative) if root else os.path.join(*relative)
    return sorted(found.values())


def _walk(start: str, *, deep: bool, depth: int) -> Iterator[tuple[Sequence[str], tuple[int, int]]]:
    """Every entry below ``start`` (as its parts relative to it, and its identity), each
    folder entered once; without ``**`` no deeper than the pattern's ``depth``."""
    visited: set[tuple[int, int]] = set()
    # Breadth first: a file reached by two paths is listed under the shorter.
    queue: deque[tuple[str, tuple[str, ...]]] = deque([(start, ())])
    while queue:
        folder, prefix = queue.popleft()
        try:
            info = os.stat(folder)
            entries = sorted(os.scandir(folder), key=lambda entry: entry.name)
        except OSError:  # unreadable or gone: glob skips it too
            continue
        if (info.st_dev, info.st_ino) in visited:
            continue
        visited.add((info.st_dev, info.st_ino))
        for entry in entries:
            relative = (*prefix, entry.name)
            try:
                stat = entry.stat()  # follows links, as glob does
            except OSError:  # a dangling link
                continue
            yield relative, (stat.st_dev, stat.st_ino)
            if entry.is_dir() and (deep or len(relative) < depth):
                queue.append((entry.path, relative))


def _match(pattern: Sequence[str], parts: Sequence[str]) -> bool:
    if not pattern:
        return not parts
    head, rest = pattern[0], pattern[1:]
    if head == "**":
        # Zero or more folders, none hidden (as glob's "**").
        return any(
            _match(rest, parts[i:])
            for i in range(len(parts) + 1)
            if not any(part.startswith(".") for part in parts[:i])
        )
    if not parts or (parts[0].startswith(".") and not head.startswith(".")):
        return False
    return fnmatch.fnmatchcase(parts[0], head) and _match(rest, parts[1:])
