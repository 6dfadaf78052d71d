"""The package's layers (tools/pyproject.toml, [tool.importlinter]): checked on the tree, and shown to catch a
backwards import and a cycle when one is added to a copy of the package."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[1]
LINT = Path(sys.executable).with_name("lint-imports")


def lint(where: Path) -> subprocess.CompletedProcess[str]:
    """lint-imports with `where` as the directory holding pyproject.toml and the dynid package."""
    env = {**os.environ, "PYTHONPATH": str(where), "NO_COLOR": "1"}
    return subprocess.run([str(LINT), "--no-cache"], cwd=where, env=env, capture_output=True, text=True, timeout=120)


def copy_package(tmp_path: Path) -> Path:
    shutil.copy(TOOLS / "pyproject.toml", tmp_path / "pyproject.toml")
    shutil.copytree(TOOLS / "dynid", tmp_path / "dynid", ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def test_layers_and_cycles_hold_on_the_tree() -> None:
    done = lint(TOOLS)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "3 kept, 0 broken" in done.stdout


@pytest.mark.parametrize(
    ("module", "added", "broken"),
    [
        # io reading the report: a lower layer importing a higher one.
        ("io/dataset.py", "from ..report import html as _backwards  # noqa: F401", "layers:"),
        # identify importing the detector it feeds.
        ("identify/fit.py", "from ..detect import t2 as _backwards  # noqa: F401", "layers:"),
        # the detector running the simulated plant.
        ("detect/t2.py", "from ..simulation import plant as _plant  # noqa: F401", "the simulated plant"),
        # dataset <-> csv_format: a cycle inside one layer.
        ("io/dataset.py", "from . import csv_format as _cycle  # noqa: F401", "no import cycles"),
    ],
)
def test_a_wrong_import_breaks_a_contract(tmp_path: Path, module: str, added: str, broken: str) -> None:
    root = copy_package(tmp_path)
    path = root / "dynid" / module
    path.write_text(path.read_text() + "\n" + added + "\n")
    done = lint(root)
    assert done.returncode != 0
    report = " ".join(done.stdout.split())
    assert f"{' '.join(broken.split())}" in report and "BROKEN" in report, report
