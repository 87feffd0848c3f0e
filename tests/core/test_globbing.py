"""Glob patterns over folders with symbolic-link loops: each file once, and an end."""

from __future__ import annotations

import glob
import os
from pathlib import Path

import numpy as np
import pytest

from pytest_metamorphic.core.globbing import expand
from pytest_metamorphic.lidar.io import write_pcd
from pytest_metamorphic.lidar.io.catalog import FrameCatalog
from pytest_metamorphic.lidar.model.cloud import PointCloud

PATTERNS = [
    "*.pcd",
    "**/*.pcd",
    "**",
    "*/*",
    "sub/**/*.bin",
    "s?b/[ab]*.*",
    "**/.hidden*",
    ".*/*.pcd",
    "sub/deeper/*",
    "nothing*/*.pcd",
    "a.pcd",
]


def _tree(root: Path) -> None:
    for name in ("a.pcd", "b.bin", "sub/a.pcd", "sub/b.bin", "sub/deeper/c.bin", ".dot/d.pcd"):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(b"")
    (root / "sub" / ".hidden.pcd").write_bytes(b"")


@pytest.mark.parametrize("pattern", PATTERNS)
def test_without_links_it_matches_what_glob_matches(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, pattern: str
) -> None:
    _tree(tmp_path)
    monkeypatch.chdir(tmp_path)
    theirs = sorted(p.rstrip(os.sep) for p in glob.glob(pattern, recursive=True) if p)
    assert expand(pattern) == [p for p in theirs if p]
    absolute = str(tmp_path / pattern)
    theirs = sorted(p.rstrip(os.sep) for p in glob.glob(absolute, recursive=True))
    assert expand(absolute) == [p for p in theirs if p != str(tmp_path)]


def test_a_folder_linked_to_itself_lists_each_file_once(tmp_path: Path) -> None:
    # Before: glob listed loop/a.pcd 41 times (loop/self/self/.../a.pcd until ELOOP).
    _tree(tmp_path)
    (tmp_path / "self").symlink_to(".")
    (tmp_path / "sub" / "up").symlink_to("..")  # two loops: glob's walk never ended
    (tmp_path / "alias").symlink_to("sub")  # one folder by two names: listed once
    found = expand(str(tmp_path / "**" / "*.pcd"))
    assert found == [str(tmp_path / "a.pcd"), str(tmp_path / "alias" / "a.pcd")]


def test_a_catalog_over_a_looping_folder_indexes_each_sweep_once(tmp_path: Path) -> None:
    cloud = PointCloud(np.array([[1.0, 2.0, 0.0], [3.0, 4.0, 0.5]], dtype=np.float32))
    for name in ("000.pcd", "nested/001.pcd"):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        write_pcd(cloud, tmp_path / name)
    (tmp_path / "self").symlink_to(".")
    (tmp_path / "nested" / "back").symlink_to("..")
    catalog = FrameCatalog(str(tmp_path / "**" / "*.pcd"))
    assert len(catalog) == 2
