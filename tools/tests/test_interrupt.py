"""Ctrl-C: every command ends promptly with one line, "dynid COMMAND: interrupted", exit code 130, never a
traceback, and leaves nothing behind (docs/design.md §7).

Each signal is sent at a set point of the command (a module starting to load, a file appearing, a function being
called), never after a sleep: a driver script runs the command with a hook at that point."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import dynid

TOOLS = Path(dynid.__file__).resolve().parents[1]
SCRIPT = Path(sys.executable).with_name("dynid")  # the console script pip generated (tools/pyproject.toml)


def driver(code: str, *args: str, cwd: Path | None = None, timeout: float = 120) -> subprocess.CompletedProcess:
    """`code` run by the interpreter with `args`, this tree's dynid first on the path, in a session of its own (a
    SIGINT it sends to its process group reaches nothing else)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TOOLS), os.environ.get("PYTHONPATH", "")]),
           "DYNID_NO_PROGRESS": "1"}
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, start_new_session=True)


# Ctrl-C as the first heavy module (numpy) starts to load: within the imports the entry point itself makes, before
# any handler of dynid's could be installed. Then the entry point as it is run: the console script, or `-m`.
INTERRUPT_IMPORTS = """
import os, runpy, signal, sys

class Interrupt:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, Interrupt())
how, what, *argv = sys.argv[1:]
sys.argv = [what, *argv]
if how == "script":
    runpy.run_path(what, run_name="__main__")
else:
    runpy.run_module(what, run_name="__main__", alter_sys=True)
"""


@pytest.mark.parametrize("how", ["script", "module"])
def test_ctrl_c_while_the_entry_point_imports_is_one_line(how: str, tmp_path: Path) -> None:
    if how == "script" and not SCRIPT.is_file():
        pytest.skip(f"no console script at {SCRIPT}")
    what = str(SCRIPT) if how == "script" else "dynid"
    done = driver(INTERRUPT_IMPORTS, how, what, "fit", "--data", "x.csv", "--out", "m.json", cwd=tmp_path)
    assert (done.returncode, done.stderr, done.stdout) == (130, "dynid fit: interrupted\n", ""), done.stderr
    assert list(tmp_path.iterdir()) == []


def test_the_entry_points_module_imports_the_standard_library_only() -> None:
    """What the console script imports before it calls main (`from dynid.cli import main`) is light: a Ctrl-C cannot
    land in numpy's import outside main's protection."""
    done = driver("import sys, dynid.cli; print(sorted(m for m in ('numpy', 'yaml', 'dynid.cli.app', 'dynid.config') "
                  "if m in sys.modules))")
    assert done.returncode == 0 and done.stdout == "[]\n", done.stderr
