"""Every Python block of README.md runs as written, in a directory whose out/ holds scripts/main's default runs."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DYNID = Path(sys.executable).with_name("dynid")


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_the_readme_has_a_python_example() -> None:
    blocks = python_blocks((ROOT / "README.md").read_text(encoding="utf-8"))
    assert blocks and "import dynid" in blocks[0]
    assert len(blocks[0].strip().splitlines()) <= 8  # the five-line fit, and its imports


@pytest.fixture(scope="module")
def workdir(default_experiments: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """out/identification, out/validation, out/contact: the session's default runs (conftest), as scripts/main
    makes them."""
    work = tmp_path_factory.mktemp("readme")
    (work / "out").mkdir()
    for kind, path in default_experiments.items():
        (work / "out" / kind).symlink_to(path, target_is_directory=True)
    return work


@pytest.mark.parametrize("index", range(len(python_blocks((ROOT / "README.md").read_text(encoding="utf-8")))))
def test_python_block_runs(workdir: Path, index: int) -> None:
    code = python_blocks((ROOT / "README.md").read_text(encoding="utf-8"))[index]
    done = subprocess.run([sys.executable, "-c", code], cwd=workdir, capture_output=True, text=True, timeout=900,
                          env={**os.environ, "DYNID_NO_PROGRESS": "1"})
    assert done.returncode == 0, done.stderr[-3000:]
    # What the example prints: Table II's two rows, then the detector's rates.
    assert "'force'" in done.stdout and "'torque'" in done.stdout and "'tpr'" in done.stdout, done.stdout
    assert (workdir / "out" / "model.json").is_file() and (workdir / "out" / "model.dcoef").is_file()
    check = subprocess.run([str(DYNID), "export", "--print", str(workdir / "out" / "model.dcoef")],
                           capture_output=True, text=True, timeout=120)
    assert check.returncode == 0 and "icub_right_arm" in check.stdout, check.stderr
