"""Every reader against Hypothesis-made corruptions of real files.

Truncations, overwritten bytes, garbage inserted, binary integers overwritten with huge
values, and header numbers rewritten. The contract: a reader returns a valid cloud or
raises DataError naming the file; nothing else escapes; it never hangs (an alarm fails
the test after a few seconds); and a header lying about sizes never makes it allocate
much more than the file (tracemalloc's peak is bounded).
"""

from __future__ import annotations

import contextlib
import re
import shutil
import signal
import tracemalloc
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.lidar.io import (
    index_bag,
    read_apollo_clusters,
    read_apollo_poly,
    read_apollo_pose,
    read_apollo_roi_points,
    read_bag,
    read_bin,
    read_kitti_labels,
    read_pcd,
    write_bag,
    write_pcd,
)
from pytest_metamorphic.lidar.model.cloud import PointCloud

FUZZ = settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
SECONDS = 20  # far above any honest read of these small files
INTEGERS = st.sampled_from(
    [0, 1, 2, 3, 7, 255, 256, 65535, 2**31 - 1, 2**31, 2**32 - 1, 2**40, 2**63 - 1, 2**64 - 1]
)


class Hang(BaseException):
    """Raised by the alarm; a BaseException so no reader's error handling can swallow it."""


@contextlib.contextmanager
def guarded(limit: float) -> Iterator[list[int]]:
    """Fail on a hang; report tracemalloc's peak (bytes) in the yielded list."""

    def alarm(signum, frame):
        raise Hang(f"reader still running after {SECONDS} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, SECONDS)
    tracemalloc.start()
    peak: list[int] = []
    try:
        yield peak
    finally:
        peak.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert peak[0] < limit, f"peak allocation {peak[0]} bytes, limit {limit:.0f}"


@st.composite
def corrupted(draw, data: bytes, *, header: int = 512) -> bytes:
    """1-3 edits of ``data``, offsets biased toward the first ``header`` bytes."""
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 3))):
        size = len(out)
        offset = draw(st.integers(0, min(size, header)) | st.integers(0, size))
        kind = draw(st.sampled_from(["truncate", "overwrite", "insert", "u32", "u64", "number"]))
        if kind == "truncate":
            del out[offset:]
        elif kind == "overwrite":
            patch = draw(st.binary(min_size=1, max_size=8))
            out[offset : offset + len(patch)] = patch
        elif kind == "insert":
            out[offset:offset] = draw(st.binary(min_size=1, max_size=16))
        elif kind in ("u32", "u64"):
            width = 4 if kind == "u32" else 8
            value = draw(INTEGERS) % 2 ** (8 * width)
            out[offset : offset + width] = value.to_bytes(width, "little")
        else:  # rewrite one decimal number of a text header (or text file)
            numbers = list(re.finditer(rb"-?\d+(\.\d+)?", bytes(out[: max(header, 1)])))
            if numbers:
                match = draw(st.sampled_from(numbers))
                value = str(draw(INTEGERS | st.integers(-5, 5))).encode()
                out[match.start() : match.end()] = value
    return bytes(out)


def check(read: Callable[[Path], object], path: Path, named: Path, limit: float) -> None:
    """``read(path)`` returns a cloud (or other result) or a DataError naming ``named``."""
    with guarded(limit):
        try:
            result = read(path)
        except DataError as error:
            event(f"DataError: {str(error)[len(str(named)) + 2 :][:40]}")
            assert str(named) in str(error), error
            assert len(str(error)) > len(str(named)) + 5  # says what is wrong, too
            return
    event("read")
    if isinstance(result, PointCloud):
        assert result.points.dtype == np.float32 and np.isfinite(result.points).all()


def _limit(size: int) -> float:
    return 24e6 + 12 * size


# -- PCD, .bin --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def pcd_files(tmp_path_factory):
    """The real VLP-16 PCD, and a 2000-point slice of it in the other two DATA kinds."""
    from conftest import shared_data_path

    real = shared_data_path("nebula_velodyne/vlp16/1673400472138016708.pcd")
    folder = tmp_path_factory.mktemp("pcd")
    part = read_pcd(real)[:2000]
    return {
        "binary": real.read_bytes(),
        "binary_compressed": write_pcd(
            part, folder / "c.pcd", data="binary_compressed"
        ).read_bytes(),
        "ascii": write_pcd(part, folder / "a.pcd", data="ascii").read_bytes(),
    }


@pytest.mark.parametrize("kind", ["binary", "binary_compressed", "ascii"])
def test_pcd_reader(pcd_files, tmp_path, kind):
    data = pcd_files[kind]
    path = tmp_path / "fuzz.pcd"

    @FUZZ
    @given(corrupted(data))
    def run(content):
        path.write_bytes(content)
        check(read_pcd, path, path, _limit(len(data)))

    run()


@pytest.mark.parametrize(
    "name",
    [
        "mmdet3d_demo/kitti/000008.bin",
        "mmdet3d_demo/nuscenes/n015-2018-07-24-11-22-45+0800__LIDAR_TOP__1532402927647951.pcd.bin",
    ],
)
def test_bin_reader(shared_data, tmp_path, name):
    data = (shared_data / name).read_bytes()
    path = tmp_path / Path(name).name

    @settings(FUZZ, max_examples=20)
    @given(corrupted(data, header=len(data)))
    def run(content):
        path.write_bytes(content)
        check(read_bin, path, path, _limit(len(data)))

    run()


# -- bags -------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_bags(tmp_path_factory):
    """Two 300-point slices of the real Ouster frames (all 9 fields) in each bag format."""
    from conftest import shared_data_path

    index = index_bag(shared_data_path("pointcloudset_ouster/test_converted.bag"))
    clouds = [index.read(i)[::150][:300] for i in range(len(index))]
    folder = tmp_path_factory.mktemp("bags")
    return {
        "rosbag1": write_bag(clouds, folder / "small.bag"),
        "sqlite3": write_bag(clouds, folder / "small", storage="sqlite3"),
        "mcap": write_bag(clouds, folder / "smallm", storage="mcap"),
    }


def _read_every_message(path: Path) -> None:
    index = index_bag(path)
    for position in range(len(index)):
        index.read(position)


@pytest.mark.parametrize("storage", ["rosbag1", "sqlite3", "mcap"])
def test_bag_readers(small_bags, tmp_path, storage):
    source = small_bags[storage]
    if source.is_dir():
        target = tmp_path / source.name
        shutil.copytree(source, target)
        storage_file = next(p for p in target.iterdir() if p.suffix in (".db3", ".mcap"))
    else:
        target = storage_file = tmp_path / source.name
        shutil.copy(source, target)
    data = storage_file.read_bytes()

    @settings(FUZZ, max_examples=30)
    @given(corrupted(data, header=4096))
    def run(content):
        storage_file.write_bytes(content)
        check(_read_every_message, target, target, _limit(len(data)))

    run()


def test_ros2_metadata_corruption(small_bags, tmp_path):
    target = tmp_path / "meta"
    shutil.copytree(small_bags["sqlite3"], target)
    metadata = target / "metadata.yaml"
    data = metadata.read_bytes()

    @settings(FUZZ, max_examples=30)
    @given(corrupted(data, header=len(data)))
    def run(content):
        metadata.write_bytes(content)
        check(_read_every_message, target, target, _limit(1e6))

    run()


def test_real_ouster_bag(shared_data, tmp_path):
    # The real bag is BZ2-chunked and 3 MB: a few corruptions, mostly of its header and
    # index; the slow suite runs more.
    data = (shared_data / "pointcloudset_ouster/test_converted.bag").read_bytes()
    path = tmp_path / "ouster.bag"

    @settings(FUZZ, max_examples=6)
    @given(corrupted(data, header=8192))
    def run(content):
        path.write_bytes(content)
        check(lambda p: read_bag(p, index=1), path, path, 64e6 + 4 * len(data))

    run()


@pytest.mark.slow
def test_real_ouster_bag_many(shared_data, tmp_path):
    data = (shared_data / "pointcloudset_ouster/test_converted.bag").read_bytes()
    path = tmp_path / "ouster.bag"

    @settings(FUZZ, max_examples=150)
    @given(corrupted(data, header=len(data)))
    def run(content):
        path.write_bytes(content)
        check(_read_every_message, path, path, 64e6 + 4 * len(data))

    run()


# -- text formats -----------------------------------------------------------------------------

TEXT_READERS = [
    ("kitti_openpcdet/training/label_2/000001.txt", None),
    ("kitti_openpcdet/training/calib/000001.txt", None),
    ("apollo/hdmap_roi_filter/poly_mask_ut.poly", read_apollo_poly),
    ("apollo/hdmap_roi_filter/poly_mask_ut_pcd_first676.txt",
     lambda p: read_apollo_roi_points(p, allow_truncated=True)),
    ("apollo/min_box_object_builder/QB9178_3_1461381834_1461382134_30651.pcd",
     read_apollo_clusters),
    ("apollo/poses/000012.pose", read_apollo_pose),
]  # fmt: skip


@pytest.mark.parametrize(("name", "reader"), TEXT_READERS)
def test_text_readers(shared_data, tmp_path, name, reader):
    data = (shared_data / name).read_bytes()
    path = tmp_path / Path(name).name
    label = shared_data / "kitti_openpcdet/training/label_2/000001.txt"
    calib = shared_data / "kitti_openpcdet/training/calib/000001.txt"
    if reader is None:  # KITTI: corrupt one of the pair, keep the other real
        reader = (
            (lambda p: read_kitti_labels(p, calib))
            if "label_2" in name
            else (lambda p: read_kitti_labels(label, p))
        )

    @settings(FUZZ, max_examples=25)
    @given(corrupted(data, header=len(data)))
    def run(content):
        path.write_bytes(content)
        check(reader, path, path, _limit(len(data)))

    run()
