"""NumPy archives (``.npz``) from outside, each member checked before numpy allocates it.

``numpy.load`` trusts an archive: a member holding Python objects raises a bare
``ValueError``, a header declaring shape (10^12, 3) asks for terabytes, and a 4 MB member
that inflates to 4 GiB is read whole before anything looks at it. :class:`NpzArchive`
reads the same files (it is what :func:`numpy.savez` and :func:`numpy.savez_compressed`
write) and refuses, with a :class:`~pytest_metamorphic.core.errors.DataError` naming the
file and the member, any member that

* is not a ``.npy`` array, or holds Python objects (``dtype=object``, or a structured
  dtype with an object field): numpy could only read it by unpickling;
* declares more bytes (shape x item size) than ``member_limit``, or than the archive's
  own record of the member's inflated size;
* would take the archive's reads past ``total_limit``.

:func:`read_npy` reads a lone ``.npy`` file under the same checks.

Only the declared bytes are ever inflated (zipfile stops at the size the archive
records, and checks the CRC at the end), so memory stays bounded by the limits whatever
the file holds.
"""

from __future__ import annotations

import os
import zipfile
import zlib
from pathlib import Path
from types import TracebackType
from typing import IO

import numpy as np

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.core.files import open_regular

__all__ = ["MAX_MEMBER_BYTES", "MAX_TOTAL_BYTES", "NpzArchive", "read_npy"]

MAX_MEMBER_BYTES = 256 * 2**20
"""The largest array read from an archive by default (256 MiB: a mesh of ten million
vertices)."""
MAX_TOTAL_BYTES = 1024 * 2**20
"""The most bytes read from one archive by default (1 GiB)."""
_MAX_MEMBERS = 100_000
_BROKEN = (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, NotImplementedError)


class NpzArchive:
    """An ``.npz`` file opened for checked reading: ``archive[name]`` is the member
    ``name.npy`` as an array (:class:`KeyError` when absent), like ``numpy.load``'s.

    Parameters
    ----------
    path : path-like
        The archive, a regular file (a FIFO or a folder is refused by name).
    what : str
        What the file should be ("object-template library"), for the errors.
    member_limit, total_limit : int
        Bytes one member and all members read may declare.

    Raises
    ------
    DataError
        Not a readable zip archive, too many members, or (on reading a member) a member
        refused as listed in the module's docstring; each names the file and the member.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        what: str = "NumPy archive",
        member_limit: int = MAX_MEMBER_BYTES,
        total_limit: int = MAX_TOTAL_BYTES,
    ) -> None:
        self.path, self.what = Path(path), what
        self.member_limit, self.total_limit = member_limit, total_limit
        self._read = 0
        self._handle: IO[bytes] = open_regular(self.path, what=what)
        try:
            self._zip = zipfile.ZipFile(self._handle)
            infos = self._zip.infolist()
        except _BROKEN as error:
            self._handle.close()
            raise DataError(
                f"cannot read the {what}: not a zip archive ({error})", path=self.path
            ) from None
        if len(infos) > _MAX_MEMBERS:
            self.close()
            raise DataError(
                f"{what} has {len(infos)} members (at most {_MAX_MEMBERS})", path=self.path
            )
        self._members = {
            info.filename[: -len(".npy")]: info for info in infos if info.filename.endswith(".npy")
        }

    def names(self) -> list[str]:
        """The arrays the archive holds (member names without ``.npy``)."""
        return list(self._members)

    def __contains__(self, name: object) -> bool:
        return name in self._members

    def __getitem__(self, name: str) -> np.ndarray:
        info = self._members[name]  # KeyError, as numpy's NpzFile
        where = f"member {name!r}"
        if info.file_size > self.member_limit:
            raise self._refused(where, f"inflates to {info.file_size} bytes", self.member_limit)
        try:
            with self._zip.open(info) as member:
                dtype, shape, fortran = _header(member)
                count, nbytes = _declared(dtype, shape, f"{self.what}: {where}", self.path)
                if nbytes > self.member_limit:
                    raise self._refused(where, f"declares shape {shape} ({nbytes} bytes)")
                if nbytes > info.file_size:
                    raise DataError(
                        f"{self.what}: {where} declares shape {shape} ({nbytes} bytes) but "
                        f"holds {info.file_size} bytes in all",
                        path=self.path,
                    )
                if self._read + nbytes > self.total_limit:
                    raise self._refused("its members", "take more", self.total_limit)
                self._read += nbytes
                data = member.read(nbytes)
        except DataError:
            raise
        except _BROKEN as error:
            raise DataError(
                f"{self.what}: {where} cannot be read ({error})", path=self.path
            ) from None
        if len(data) != nbytes:
            raise DataError(f"{self.what}: {where} is cut short", path=self.path)
        return _array(data, dtype, count, shape, fortran)

    def _refused(self, where: str, reason: str, limit: int | None = None) -> DataError:
        bound = self.member_limit if limit is None else limit
        return DataError(
            f"{self.what}: {where} {reason}, more than the {bound} bytes read from one "
            "archive; refused",
            path=self.path,
        )

    def close(self) -> None:
        self._zip.close()
        self._handle.close()

    def __enter__(self) -> NpzArchive:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()


def read_npy(
    path: str | os.PathLike[str], *, what: str = "NumPy array", limit: int = MAX_MEMBER_BYTES
) -> np.ndarray:
    """The array a ``.npy`` file holds, checked as an archive's member is (no Python
    objects, a declared size within ``limit`` and within the file).

    Raises
    ------
    DataError
        Not a readable ``.npy`` file, or refused; the message names the file.
    """
    with open_regular(path, what=what) as handle:
        size = os.fstat(handle.fileno()).st_size
        try:
            dtype, shape, fortran = _header(handle)
        except _BROKEN as error:
            raise DataError(f"{what} cannot be read ({error})", path=path) from None
        count, nbytes = _declared(dtype, shape, what, path)
        if nbytes > limit or nbytes > size - handle.tell():
            raise DataError(
                f"{what} declares shape {shape} ({nbytes} bytes): more than the file holds "
                f"or the {limit} bytes read",
                path=path,
            )
        data = handle.read(nbytes)
    return _array(data, dtype, count, shape, fortran)


def _declared(
    dtype: np.dtype, shape: tuple[int, ...], label: str, path: str | os.PathLike[str]
) -> tuple[int, int]:
    """(elements, bytes) a header declares, refusing Python objects (read only by
    unpickling)."""
    if dtype.hasobject:
        raise DataError(
            f"{label} holds Python objects (dtype {dtype}); only plain numeric arrays are "
            "read (no pickles)",
            path=path,
        )
    count = int(np.prod(shape, dtype=object))  # Python ints: no overflow at 10^12 x 3
    return count, count * dtype.itemsize


def _array(
    data: bytes, dtype: np.dtype, count: int, shape: tuple[int, ...], fortran: bool
) -> np.ndarray:
    return np.frombuffer(data, dtype=dtype, count=count).reshape(
        shape, order="F" if fortran else "C"
    )


def _header(member: IO[bytes]) -> tuple[np.dtype, tuple[int, ...], bool]:
    """The ``.npy`` header of ``member``: dtype, shape, Fortran order (numpy's own parser,
    which reads the header's dictionary with ``ast.literal_eval``, never ``eval``)."""
    version = np.lib.format.read_magic(member)
    if version == (1, 0):
        read = np.lib.format.read_array_header_1_0
    elif version in ((2, 0), (3, 0)):
        # 3.0 differs from 2.0 only in reading the header as UTF-8, for non-ASCII field
        # names; a Latin-1 reading refuses nothing an ASCII header holds.
        read = np.lib.format.read_array_header_2_0
    else:
        raise ValueError(f"npy format version {version} is not known")
    shape, fortran, dtype = read(member)
    return np.dtype(dtype), tuple(int(n) for n in shape), bool(fortran)
