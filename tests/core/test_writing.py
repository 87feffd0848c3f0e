"""Writing where a user asked: temporary names that fit the file system, and failures
(a read-only mount, a file where a folder must be, a name too long) said as the library's
WriteError, naming the user's path with advice that fits the cause."""

from __future__ import annotations

import errno
import os
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic.core.errors import WriteError
from pytest_metamorphic.core.files import staging_sibling, write_atomically, write_error
from pytest_metamorphic.core.locks import exclusive
from pytest_metamorphic.lidar.followups.insert import load_templates, save_templates
from pytest_metamorphic.lidar.followups.insert.catalogue import solid_road_users
from pytest_metamorphic.lidar.io import read_cloud, write_bin, write_pcd
from pytest_metamorphic.lidar.model.cloud import PointCloud
from tests.read_only import run_on_a_read_only_mount

CLOUD = PointCloud(np.array([[1.0, 2.0, 0.0], [3.0, 4.0, 0.5]], dtype=np.float32))
LONGEST = 255  # bytes in a name on ext4, xfs, btrfs, tmpfs


def _name_limit(folder: Path) -> int:
    return int(os.pathconf(folder, "PC_NAME_MAX"))


def test_a_temporary_sibling_fits_the_name_limit_however_long_the_name(tmp_path: Path) -> None:
    limit = _name_limit(tmp_path)
    for name in ("a.pcd", "x" * (limit - 4) + ".pcd", "é" * ((limit - 4) // 2) + ".pcd"):
        sibling = staging_sibling(tmp_path / name)
        assert sibling.parent == tmp_path and sibling.name.startswith(".")
        assert len(os.fsencode(sibling.name)) <= limit
        sibling.write_bytes(b"")  # the file system takes it
    assert staging_sibling(tmp_path / "a.pcd") != staging_sibling(tmp_path / "a.pcd")


@pytest.mark.parametrize("writer", ["pcd", "bin", "templates", "atomically"])
def test_a_legal_long_name_is_written(tmp_path: Path, writer: str) -> None:
    # Before: OSError "File name too long" naming the hidden ".<name>.<hex>.tmp" (264 bytes).
    name = "n" * (_name_limit(tmp_path) - 5)
    if writer == "pcd":
        path = write_pcd(CLOUD, tmp_path / f"{name}.pcd")
        assert len(read_cloud(path)) == 2
    elif writer == "bin":
        path = write_bin(CLOUD, tmp_path / f"{name}.bin")
        assert len(read_cloud(path)) == 2
    elif writer == "templates":
        path = save_templates(tmp_path / f"{name}.npz", solid_road_users()[:1])
        assert len(load_templates(path)) == 1
    else:
        path = tmp_path / f"{name}.txt"
        write_atomically(path, lambda tmp: tmp.write_text("ok"))
        assert path.read_text() == "ok"
    assert os.listdir(tmp_path) == [path.name]  # no temporary left behind


@pytest.mark.parametrize("writer", ["pcd", "bin", "templates", "atomically"])
def test_a_name_past_the_limit_is_named_as_the_users(tmp_path: Path, writer: str) -> None:
    name = "n" * (_name_limit(tmp_path) + 20)
    write = {
        "pcd": lambda: write_pcd(CLOUD, tmp_path / f"{name}.pcd"),
        "bin": lambda: write_bin(CLOUD, tmp_path / f"{name}.bin"),
        "templates": lambda: save_templates(tmp_path / f"{name}.npz", solid_road_users()[:1]),
        "atomically": lambda: write_atomically(tmp_path / name, lambda t: t.write_text("x")),
    }[writer]
    with pytest.raises(WriteError, match=r"File name too long.*too long.*shorter") as raised:
        write()
    assert raised.value.errno == errno.ENAMETOOLONG
    assert raised.value.path is not None and Path(raised.value.path).name.startswith(name)
    assert ".tmp" not in str(raised.value)
    assert os.listdir(tmp_path) == []


def test_a_file_where_the_folder_must_be_is_said_so(tmp_path: Path) -> None:
    (tmp_path / "runs").write_text("not a folder")
    lock = exclusive(tmp_path / "runs" / "campaign" / ".lock", what="campaign log x")
    with pytest.raises(WriteError, match=r"runs/campaign: could not write campaign log x"):
        lock.__enter__()
    with pytest.raises(WriteError, match=r"runs/report\.json: .*a file stands where a folder"):
        write_atomically(tmp_path / "runs" / "report.json", lambda p: p.write_text("{}"))


def test_the_advice_fits_the_cause() -> None:
    said = {
        code: str(write_error(OSError(code, os.strerror(code)), "/x/r.json", what="the report"))
        for code in (errno.EROFS, errno.ENOSPC, errno.EACCES, errno.EIO)
    }
    assert "read-only file system: choose a folder on a writable one" in said[errno.EROFS]
    assert "free some space" in said[errno.ENOSPC]
    assert "free" not in said[errno.EROFS] and "free" not in said[errno.EACCES]
    assert "may not write there" in said[errno.EACCES]
    assert said[errno.EIO].startswith("/x/r.json: could not write the report (")


def test_every_writer_on_a_read_only_mount_says_read_only(tmp_path: Path) -> None:
    folder = tmp_path / "ro"
    folder.mkdir()
    program = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).resolve().parents[2])!r})
        import numpy as np
        from pytest_metamorphic.core.errors import WriteError
        from pytest_metamorphic.core.files import write_atomically
        from pytest_metamorphic.core.locks import exclusive
        from pytest_metamorphic.lidar.io import write_pcd
        from pytest_metamorphic.lidar.model.cloud import PointCloud
        cloud = PointCloud(np.zeros((2, 3), dtype=np.float32))
        for write in (
            lambda: write_pcd(cloud, "ro/a.pcd"),
            lambda: write_atomically("ro/r.json", lambda p: p.write_text("{{}}")),
            lambda: exclusive("ro/camp/.lock", what="campaign log x").__enter__(),
        ):
            try:
                write()
            except WriteError as error:
                print("WriteError:", error)
        """
    )
    said = run_on_a_read_only_mount(folder, [sys.executable, "-c", program], cwd=tmp_path)
    lines = [line for line in said.splitlines() if line.startswith("WriteError:")]
    assert len(lines) == 3, said
    assert all("(Read-only file system): it is on a read-only file system" in x for x in lines)
    assert "ro/a.pcd:" in lines[0] and "ro/r.json:" in lines[1] and "ro/camp:" in lines[2]
