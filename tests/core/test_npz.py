"""NumPy archives from outside: a member is checked (dtype, declared shape, inflated size)
before numpy allocates it, and every refusal names the file and the member."""

from __future__ import annotations

import io
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.core.npz import MAX_MEMBER_BYTES, NpzArchive
from pytest_metamorphic.lidar.followups.insert import load_templates, save_templates
from pytest_metamorphic.lidar.followups.insert.catalogue import solid_road_users


def _npy(header: dict[str, object], body: bytes = b"") -> bytes:
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, header)
    return out.getvalue() + body


def _library_with(tmp_path: Path, name: str, member: bytes) -> Path:
    """A real template library whose first vertex array is replaced by ``member``."""
    good = save_templates(tmp_path / "good.npz", solid_road_users()[:1])
    path = tmp_path / name
    with zipfile.ZipFile(good) as source, zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as out:
        for info in source.infolist():
            data = member if info.filename == "v0.npy" else source.read(info)
            out.writestr(info.filename, data)
    return path


def test_arrays_round_trip_in_either_order(tmp_path: Path) -> None:
    path = tmp_path / "a.npz"
    c_order = np.arange(12, dtype=np.float32).reshape(3, 4)
    np.savez_compressed(path, c=c_order, f=np.asfortranarray(c_order), empty=np.zeros((0, 3)))
    with NpzArchive(path) as archive:
        assert sorted(archive.names()) == ["c", "empty", "f"]
        np.testing.assert_array_equal(archive["c"], c_order)
        np.testing.assert_array_equal(archive["f"], c_order)
        assert archive["empty"].shape == (0, 3)
        with pytest.raises(KeyError):
            archive["missing"]


def test_an_object_array_is_refused_by_name(tmp_path: Path) -> None:
    # Before: numpy's bare "Object arrays cannot be loaded when allow_pickle=False".
    path = tmp_path / "objects.npz"
    bad = np.empty(2, dtype=object)
    bad[:] = [{"a": 1}, "x"]
    good = save_templates(tmp_path / "good.npz", solid_road_users()[:1])
    with np.load(good) as archive:
        arrays = dict(archive)
    arrays["v0"] = bad
    np.savez(path, **arrays)
    with pytest.raises(DataError, match=r"objects\.npz: .*member 'v0' holds Python objects"):
        load_templates(path)


def test_a_member_that_inflates_past_the_bound_is_not_read(tmp_path: Path) -> None:
    # Before: a raw MemoryError (a 4 MB file inflating to 4 GiB was read whole).
    count = (MAX_MEMBER_BYTES // 8 + 3 * 1024) // 3 * 3
    zeros = np.zeros(count, dtype="<f8").tobytes()
    member = _npy({"descr": "<f8", "fortran_order": False, "shape": (count // 3, 3)}, zeros)
    path = _library_with(tmp_path, "bomb.npz", member)
    del zeros, member
    assert path.stat().st_size < 2 * 2**20  # zeros deflate a thousandfold
    began = time.perf_counter()
    with pytest.raises(DataError, match=r"bomb\.npz: .*member 'v0' inflates to \d+ bytes"):
        load_templates(path)
    assert time.perf_counter() - began < 5  # refused on the zip's record, not by reading


def test_a_declared_shape_past_the_bound_is_refused_before_allocating(tmp_path: Path) -> None:
    # Before: "Unable to allocate 21.8 TiB for an array with shape (1000000000000, 3)".
    member = _npy({"descr": "<f8", "fortran_order": False, "shape": (10**12, 3)}, b"\0" * 64)
    path = _library_with(tmp_path, "huge.npz", member)
    with pytest.raises(DataError, match=r"huge\.npz: .*'v0' declares shape \(1000000000000, 3\)"):
        load_templates(path)


def test_a_shape_larger_than_the_member_is_refused(tmp_path: Path) -> None:
    member = _npy({"descr": "<f8", "fortran_order": False, "shape": (1000, 3)}, b"\0" * 96)
    path = _library_with(tmp_path, "short.npz", member)
    with pytest.raises(DataError, match=r"short\.npz: .*declares shape \(1000, 3\).*holds"):
        load_templates(path)


def test_the_total_read_is_bounded(tmp_path: Path) -> None:
    path = tmp_path / "many.npz"
    np.savez(path, **{f"a{i}": np.zeros(1000) for i in range(5)})
    with NpzArchive(path, total_limit=3 * 8000) as archive:
        for name in ("a0", "a1", "a2"):
            archive[name]
        with pytest.raises(DataError, match=r"many\.npz: .*its members take more"):
            archive["a3"]


@pytest.mark.parametrize(
    "member",
    [
        b"\x93NUMPY\x09\x00garbage",
        b"not an npy file at all",
        _npy({"descr": "<f8", "fortran_order": False, "shape": (2,)})[:20],
    ],
    ids=["unknown version", "no magic", "cut header"],
)
def test_a_broken_member_is_named(tmp_path: Path, member: bytes) -> None:
    path = _library_with(tmp_path, "broken.npz", member)
    with pytest.raises(DataError, match=r"broken\.npz: .*member 'v0' cannot be read"):
        load_templates(path)


def test_a_corrupted_member_fails_its_checksum_by_name(tmp_path: Path) -> None:
    path = tmp_path / "crc.npz"
    np.savez(path, a=np.arange(1000, dtype=np.float64))  # stored, not deflated
    data = bytearray(path.read_bytes())
    data[data.index(b"\x00\x00\x00\x00\x00\x00\xf0?") + 3] ^= 0xFF  # inside 1.0's bytes
    path.write_bytes(bytes(data))
    with NpzArchive(path) as archive, pytest.raises(DataError, match=r"crc\.npz: .*'a'"):
        archive["a"]
