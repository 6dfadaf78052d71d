"""`dynid` as a user runs it, for the real-data tests: a process of its own, its exit code and its `--json -` result.

The process is forked from the hostile sweep's preloaded server (tests/hostile/run.py `run_dynid`), as
tools/tests/conftest.py's `dynid()` does: the executable's exit code, output and files (test_gaps holds a forked
command to the executable), without an interpreter start and dynid's imports per command."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from ..hostile.run import run_dynid


def run(*args: object, keep_urdf_path: bool = True) -> subprocess.CompletedProcess:
    """`dynid ARGS` (each as its str); keep_urdf_path=False drops DYNID_URDF_PATH, so the test's own --urdf is the only
    one found."""
    done = run_dynid([str(a) for a in args], Path.cwd(), timeout=900,
                     unset=() if keep_urdf_path else ("DYNID_URDF_PATH",))
    return subprocess.CompletedProcess(["dynid", *args], done.code, done.stdout, done.stderr)


def dynid(*args: str, keep_urdf_path: bool = True) -> dict:
    """`dynid ARGS --json -`, which must succeed: its JSON result."""
    done = run(*args, "--json", "-", keep_urdf_path=keep_urdf_path)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)
