"""`dynid` as a user runs it, for the real-data tests: a subprocess, its exit code and its `--json -` result."""

from __future__ import annotations

import json
import os
import subprocess
import sys


def run(*args: str, keep_urdf_path: bool = True) -> subprocess.CompletedProcess:
    """`dynid ARGS`; keep_urdf_path=False drops DYNID_URDF_PATH, so the test's own --urdf is the only one found."""
    env = None if keep_urdf_path else {k: v for k, v in os.environ.items() if k != "DYNID_URDF_PATH"}
    return subprocess.run([sys.executable, "-m", "dynid.cli", *args], capture_output=True, text=True, timeout=900,
                          env=env)


def dynid(*args: str, keep_urdf_path: bool = True) -> dict:
    """`dynid ARGS --json -`, which must succeed: its JSON result."""
    done = run(*args, "--json", "-", keep_urdf_path=keep_urdf_path)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)
