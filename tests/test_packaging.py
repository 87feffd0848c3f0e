"""What a user installs: the version from one place, the licence files and the shipped
model in the wheel (package data moved with ``lidar/``'s regrouping once already)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import pytest_metamorphic

ROOT = Path(__file__).resolve().parent.parent


def test_the_version_lives_in_one_place() -> None:
    tomllib = pytest.importorskip("tomllib", reason="Python 3.11 reads TOML")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert "version" not in project and "version" in project["dynamic"]
    assert pytest_metamorphic.__version__.count(".") == 2
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert f"## [{pytest_metamorphic.__version__}]" in changelog


def test_the_wheel_holds_the_licence_the_notice_and_the_model(tmp_path: Path) -> None:
    pytest.importorskip("setuptools")
    pytest.importorskip("wheel", reason="setuptools builds wheels with the wheel package")
    source = tmp_path / "src"
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE", "NOTICE"):
        shutil.copy(ROOT / name, source / name)
    shutil.copytree(
        ROOT / "pytest_metamorphic",
        source / "pytest_metamorphic",
        ignore=shutil.ignore_patterns("__pycache__"),
    )
    # The build backend itself, in this environment (no network): what pip runs.
    build = (
        "import sys; from setuptools import build_meta; print(build_meta.build_wheel(sys.argv[1]))"
    )
    done = subprocess.run(
        [sys.executable, "-c", build, str(tmp_path / "dist")],
        cwd=source,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    # setuptools stops building deprecated metadata (a licence table, licence classifiers)
    # on 2027-02-18: it must not warn about ours.
    assert "deprecated" not in done.stderr.lower(), done.stderr[-2000:]
    wheel = tmp_path / "dist" / done.stdout.strip().splitlines()[-1]
    names = zipfile.ZipFile(wheel).namelist()
    assert "pytest_metamorphic/lidar/systems/perception/cnnseg/cnnseg.onnx" in names
    assert "pytest_metamorphic/py.typed" in names
    licences = {Path(n).name for n in names if ".dist-info/" in n}
    assert {"LICENSE", "NOTICE"} <= licences
    metadata = next(n for n in names if n.endswith(".dist-info/METADATA"))
    assert "License-Expression: Apache-2.0" in zipfile.ZipFile(wheel).read(metadata).decode()
    version = pytest_metamorphic.__version__
    assert wheel.name.startswith(f"pytest_metamorphic-{version}-")
