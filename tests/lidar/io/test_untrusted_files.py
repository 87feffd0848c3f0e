"""Readers of outside files refuse what is not a regular file before opening it for
good (a FIFO named like a recording blocked every reader but OSM), and check a PCD's size
fields against its payload both ways (issue: inputs from outside)."""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pytest_metamorphic.core.errors import DataError
from pytest_metamorphic.driving.osm import read_osm
from pytest_metamorphic.lidar.io import (
    read_apollo_clusters,
    read_apollo_poly,
    read_apollo_pose,
    read_apollo_roi_points,
    read_bag,
    read_bin,
    read_cloud,
    read_kitti_calibration,
    read_kitti_labels,
    read_pcd,
    read_pcd_header,
    write_pcd,
)
from pytest_metamorphic.lidar.io.kitti import sensor_calibration
from pytest_metamorphic.lidar.model.cloud import PointCloud
from pytest_metamorphic.lidar.systems.process import read_json_predictions

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="FIFOs are POSIX")

READERS: dict[str, tuple[str, Callable[[Path], Any]]] = {
    "bin": ("sweep.bin", read_bin),
    "pcd": ("sweep.pcd", read_pcd),
    "pcd header": ("sweep.pcd", read_pcd_header),
    "cloud (unknown suffix)": ("sweep.xyz", read_cloud),
    "ROS 1 bag": ("drive.bag", read_bag),
    "ROS 2 db3": ("drive.db3", read_bag),
    "ROS 2 mcap": ("drive.mcap", read_bag),
    "Apollo polygons": ("roi.poly", read_apollo_poly),
    "Apollo ROI points": ("roi.pts", read_apollo_roi_points),
    "Apollo clusters": ("clusters.txt", read_apollo_clusters),
    "Apollo pose": ("pose.txt", read_apollo_pose),
    "KITTI calibration": ("calib.txt", read_kitti_calibration),
    "KITTI labels": ("label.txt", lambda p: read_kitti_labels(p, sensor_calibration())),
    "OSM": ("map.osm", read_osm),
    "JSON predictions": ("p.json", read_json_predictions),
}


def finishes(call: Callable[[], Any], seconds: float = 20.0) -> BaseException | None:
    """Run ``call`` in a thread; fail the test if it blocks (the old behaviour)."""
    outcome: list[BaseException | None] = []

    def run() -> None:
        try:
            call()
            outcome.append(None)
        except BaseException as error:
            outcome.append(error)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), "the reader blocked on a FIFO"
    return outcome[0]


@pytest.mark.parametrize("reader", sorted(READERS))
def test_a_fifo_named_like_the_file_is_refused_without_blocking(
    tmp_path: Path, reader: str
) -> None:
    name, read = READERS[reader]
    fifo = tmp_path / name
    os.mkfifo(fifo)
    error = finishes(lambda: read(fifo))
    assert isinstance(error, DataError), repr(error)
    assert "FIFO" in str(error) and str(fifo) in str(error)


@pytest.mark.parametrize("reader", ["bin", "pcd", "Apollo pose", "KITTI calibration", "OSM"])
def test_a_directory_is_refused_by_name(tmp_path: Path, reader: str) -> None:
    name, read = READERS[reader]
    folder = tmp_path / name
    folder.mkdir()
    with pytest.raises(DataError, match="directory"):
        read(folder)


def test_a_ros2_bag_folder_with_a_fifo_inside_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "bag"
    folder.mkdir()
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    os.mkfifo(folder / "bag_0.db3")
    error = finishes(lambda: read_bag(folder))
    assert isinstance(error, DataError) and "FIFO" in str(error)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
@pytest.mark.parametrize("reader", ["bin", "pcd", "OSM", "KITTI calibration"])
def test_an_unreadable_file_is_a_data_error(tmp_path: Path, reader: str) -> None:
    name, read = READERS[reader]
    path = tmp_path / name
    path.write_bytes(b"\0" * 64)
    path.chmod(0)
    with pytest.raises(DataError, match="ermission"):
        read(path)


def pcd_with(tmp_path: Path, **header: str) -> Path:
    """A binary PCD of 1000 points with header fields replaced."""
    path = tmp_path / "cloud.pcd"
    rng = np.random.default_rng(0)
    write_pcd(PointCloud(rng.random((1000, 4), dtype=np.float32)), path, overwrite=True)
    raw = path.read_bytes()
    head, _, payload = raw.partition(b"DATA binary\n")
    lines = head.decode().splitlines()
    for index, line in enumerate(lines):
        key = line.split(" ", 1)[0]
        if key in header:
            lines[index] = f"{key} {header[key]}"
    path.write_bytes(("\n".join(lines) + "\nDATA binary\n").encode() + payload)
    return path


@pytest.mark.parametrize(("width", "points"), [("0", "0"), ("100", "100"), ("999", "999")])
def test_a_header_that_understates_the_points_is_refused(
    tmp_path: Path, width: str, points: str
) -> None:
    # Before: read silently short (0 or 100 of the file's points), trailing bytes ignored.
    with pytest.raises(DataError, match="understates POINTS"):
        read_pcd(pcd_with(tmp_path, WIDTH=width, POINTS=points))


def test_a_header_that_overstates_the_points_is_refused(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="overstates"):
        read_pcd(pcd_with(tmp_path, WIDTH="1001", POINTS="1001"))


def test_trailing_bytes_after_a_binary_payload_are_refused(tmp_path: Path) -> None:
    path = pcd_with(tmp_path)
    assert len(read_pcd(path)) == 1000
    with path.open("ab") as handle:
        handle.write(b"\n")
    with pytest.raises(DataError, match="1 bytes follow"):
        read_pcd(path)


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
@pytest.mark.parametrize("reader", ["Apollo polygons", "Apollo ROI points", "pcd", "OSM"])
def test_a_device_is_refused_not_read_to_exhaustion(reader: str) -> None:
    # Before: /dev/zero read as text ended in a raw MemoryError.
    _, read = READERS[reader]
    error = finishes(lambda: read(Path("/dev/zero")))
    assert isinstance(error, DataError) and "device" in str(error)
