"""`boards --help` and `rt_monitor --help`: the usage on stdout, every option of the synopsis explained, exit 0.

Driven through the built programs only (no dynid import).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = {
    "boards": ROOT / "build" / "firmware_like" / "boards",
    "rt_monitor": ROOT / "build" / "rt_monitor" / "rt_monitor",
}
# Every option each program takes (its argument parser), so that a help text cannot silently drop one.
OPTIONS = {
    "boards": {"--config", "--data", "--sink", "--realtime", "--rt-priority", "--t0", "--sensor", "--strain-sat",
               "--restart", "--repeat", "--encoder", "--bitrate", "--help"},
    "rt_monitor": {"--model", "--config", "--replay", "--realtime", "--loopback", "--lcm-url", "--residual", "--mlockall",
                   "--priority", "--cpu", "--latency-out", "--stats-out", "--help"},
}


def run(program: str, *args: str) -> subprocess.CompletedProcess:
    path = PROGRAMS[program]
    assert path.is_file(), f"{path} is not built (scripts/setup)"
    return subprocess.run([str(path), *args], capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("program", sorted(PROGRAMS))
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_prints_the_usage_on_stdout_and_exits_0(program: str, flag: str) -> None:
    done = run(program, flag)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    lines = done.stdout.splitlines()
    assert lines[0].startswith(f"usage: {program} ")
    assert set(re.findall(r"--[a-z][a-z0-9-]*", lines[0])) == OPTIONS[program]  # the synopsis names them all
    # ... and the body explains each: an indented line starting with the option, then text after it.
    for opt in OPTIONS[program]:
        explained = [l for l in lines[1:] if re.match(rf"\s+(-h, )?{opt}\b\S*( \S+)?\s{{2,}}\S", l)]
        assert len(explained) == 1, (opt, done.stdout)
    assert "exit codes:" in done.stdout


@pytest.mark.parametrize("program", sorted(PROGRAMS))
def test_help_wins_over_missing_required_options(program: str) -> None:
    # --help alone: no "--config ... required" error; with other valid options before it, the same.
    done = run(program, "--config", "x.conf", "--help")
    assert done.returncode == 0 and done.stdout.startswith(f"usage: {program} "), done.stderr


@pytest.mark.parametrize("program", sorted(PROGRAMS))
def test_a_bad_flag_is_still_one_error_line_and_the_synopsis(program: str) -> None:
    done = run(program, "--fast")
    assert done.returncode == 2 and done.stdout == ""
    err = done.stderr.splitlines()
    assert err[0] == f"{program}: error: unknown argument '--fast'"
    assert len(err) == 2 and err[1].startswith(f"usage: {program} ") and "--help" in err[1]
