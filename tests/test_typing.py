"""The package type-checks for its users: ``py.typed`` is shipped, so a user's mypy reads
our annotations. ``tests/typing/public_api.py`` uses the public API as a test module would
(``@metamorphic``, strategies, relations, ``Box``, systems, campaigns) and marks misuses
the annotations must reject; mypy must accept it exactly."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
USAGE = ROOT / "tests" / "typing" / "public_api.py"


def _mypy(*arguments: str) -> tuple[str, int]:
    api = pytest.importorskip("mypy.api", reason="mypy is in the dev extra")
    stdout, stderr, status = api.run(
        [
            "--config-file",
            str(ROOT / "pyproject.toml"),
            "--python-version",
            "3.11",  # assert_type and the user's syntax; the package itself targets 3.10
            "--no-warn-unused-configs",  # the usage file imports a part of the package
            "--no-incremental",
            *arguments,
        ]
    )
    return stdout + stderr, status


def test_the_public_api_type_checks_as_a_user_uses_it() -> None:
    output, status = _mypy(str(USAGE))
    assert status == 0, output


def test_a_misuse_of_the_api_is_a_type_error(tmp_path: Path) -> None:
    # The check is not vacuous: the same file with one misuse left unmarked fails.
    broken = tmp_path / "broken.py"
    broken.write_text(
        "from pytest_metamorphic.lidar.model.obstacles import Box\n"
        "Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.0, 'truck')\n",
        encoding="utf-8",
    )
    output, status = _mypy(str(broken))
    assert status == 1 and "arg-type" in output, output
