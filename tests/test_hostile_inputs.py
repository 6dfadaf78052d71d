"""The hostile-input sweep (issue 22): every dynid command, rt_monitor and boards on bad input.

Each case (tests/hostile/dynid_cases.py, c_cases.py) runs one program on one bad file, frame, flag, configuration
or path and must end as the project's rule says: the documented exit code (2 for dynid's bad input), exactly one
line on stderr naming the problem (a C program's usage error: that line, then its synopsis), no traceback, no
death by signal, no sanitizer report (the C programs run from build-asan/ where scripts/setup built them), and
nothing written: the case's input and output directories are byte for byte as they were, so no output, partial
file or temporary file is left behind. A few controls (`accepted`) run the same harness on input that is fine, or
only partly skipped, and must write their output: they show the sweep would see one.

The good files are built once per session (tests/hostile/fixtures.py); each case has its own directories.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from .hostile.c_cases import BOARDS, CANDUMP_LINES, COEFFICIENTS, MONITOR_CONF, MONITOR_FLAGS
from .hostile.case import Case
from .hostile.dynid_cases import CANDUMP, CSV, DATASETS, FLAGS, MODELS
from .hostile.fixtures import Fixtures, build
from .hostile.run import SANITIZER_MARKS, Outcome, program, run_dynid, run_program

CASES: list[Case] = [*CSV, *DATASETS, *CANDUMP, *MODELS, *FLAGS, *MONITOR_CONF, *COEFFICIENTS, *CANDUMP_LINES,
                     *MONITOR_FLAGS, *BOARDS]


@pytest.fixture(scope="session")
def fixtures(tmp_path_factory: pytest.TempPathFactory) -> Fixtures:
    return build(tmp_path_factory.mktemp("hostile"))


def snapshot(*roots: Path) -> dict[str, str]:
    """Every entry under the roots: a file by its sha256, a directory or link by its kind."""
    out = {}
    for root in roots:
        for path in sorted(root.rglob("*")):
            if path.is_symlink():
                out[str(path)] = "link"
            elif path.is_dir():
                out[str(path)] = "dir"
            else:
                out[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def run_case(case: Case, fx: Fixtures, tmp_path: Path) -> tuple[Outcome, dict[str, str], dict[str, str], Path]:
    inputs, outputs, work = tmp_path / "in", tmp_path / "out", tmp_path / "work"
    for d in (inputs, outputs, work):
        d.mkdir()
    if case.make:
        case.make(fx, inputs)
    names = {**fx.names(), "in": str(inputs), "out": str(outputs)}
    args = [a.format(**names) for a in case.args]
    before = snapshot(inputs, outputs)
    if case.program == "dynid":
        done = run_dynid(args, work)
    else:
        done = run_program(program(case.program), args, work)
    return done, before, snapshot(inputs, outputs), outputs


def error_prefix(case: Case) -> str:
    if case.program != "dynid":
        return f"{case.program}: error: "
    command = next((a for a in case.args if not a.startswith("-")), "")
    parsed = command in ("import", "structure", "simulate", "excite", "fit", "validate", "detect", "report", "export", "gaps",
                         "spy", "play", "fleet")
    # argparse refuses an unknown command for the program as a whole; an unknown flag is the command's
    return f"dynid {command}: error: " if parsed else "dynid: error: "


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_hostile_input(case: Case, fixtures: Fixtures, tmp_path: Path) -> None:
    if not case.as_root and os.geteuid() == 0:
        pytest.skip("run as root: a file of mode 000 is readable all the same")
    done, before, after, outputs = run_case(case, fixtures, tmp_path)
    names = {**fixtures.names(), "in": str(tmp_path / "in"), "out": str(outputs)}
    says = case.says.format(**names)
    report = f"exit {done.code}\nstderr:\n{done.stderr}\nstdout:\n{done.stdout[-2000:]}"

    assert done.code >= 0, f"killed by signal {-done.code}\n{report}"
    assert not any(mark in done.stderr for mark in SANITIZER_MARKS), report
    assert "Traceback" not in done.stderr + done.stdout, report
    assert done.code == case.code, report
    warned = [x for x in done.stderr.splitlines() if x.startswith(f"{case.program}: warning: ")]
    assert len(warned) == (1 if case.warns else 0) and case.warns in "".join(warned), report
    lines = [x for x in done.stderr.splitlines() if x not in warned]
    if case.code == 0:
        assert len(lines) == (1 if says else 0) and says in done.stderr and case.prints in done.stdout, report
        created = {str(outputs / name) for name in case.creates}
        assert set(after) - set(before) == created and all(after[k] == v for k, v in before.items()), report
        return
    if case.program == "rt_monitor" and case.code == 6:  # it ran, blind: its start-up line, faults, then the one error
        assert lines[0].startswith("rt_monitor: running:") and all(x.startswith("rt_monitor: fault: ") for x in lines[1:-1])
        assert lines[-1].startswith("rt_monitor: error: ") and says in lines[-1], report
        return
    assert len(lines) == (2 if case.synopsis else 1), f"not one line on stderr\n{report}"
    assert lines[0].startswith(error_prefix(case)) and says in lines[0], report
    if case.synopsis:
        assert lines[1].startswith(f"usage: {case.program} "), report
    assert after == before, f"the refusal changed its directories: {sorted(set(after) ^ set(before))}\n{report}"


def test_the_sweep_covers_every_command_and_program() -> None:
    """Every dynid command (dynid --help), rt_monitor and boards have cases; the sweep is as large as issue 22 asks."""
    from dynid.cli.commands import COMMANDS

    covered = {c.args[0] for c in CASES if c.program == "dynid" and c.args} | {c.program for c in CASES}
    assert set(COMMANDS) | {"rt_monitor", "boards"} <= covered, sorted(set(COMMANDS) - covered)
    assert len(CASES) >= 150 and len({c.name for c in CASES}) == len(CASES)
