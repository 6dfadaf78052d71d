"""Running the programs of the hostile-input sweep: `dynid` (every command), `rt_monitor` and `boards`.

`dynid` runs in a child process forked from a server that has already imported the command modules
(multiprocessing's forkserver, preloaded): the command's `main` in a fresh process of its own, with its own exit
code, signals and stdout/stderr files, without paying Python's and numpy's start-up (about 2 s on a busy machine)
for each of some 200 cases. `HOSTILE_SUBPROCESS=1` runs every dynid case through the `dynid` executable instead
(slower, the same verdicts). tools/tests' `dynid()` (its conftest.py) and the UR10e's every-command test run their
commands this way too. The C programs run as they are: from `build-asan/` (AddressSanitizer + UBSan), where
scripts/setup builds them, unless `build/` holds a newer build.
"""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
DYNID = Path(sys.executable).with_name("dynid")
TIMEOUT_S = 120.0
# What the forkserver imports once: every command group's module (dynid.cli.commands) and the heavy imports the
# commands make lazily, so that a case pays only for the work it does.
PRELOAD = ["dynid.cli", "dynid.cli.app", "dynid.cli.data", "dynid.cli.identify", "dynid.cli.detect",
           "dynid.cli.report", "dynid.cli.export", "dynid.cli.gaps", "dynid.cli.spy", "dynid.simulation", "dynid.pipeline",
           "dynid.detect.evaluation", "scipy.signal", "lcm"]
# Text that only a sanitizer (ASan, LSan, UBSan) writes.
SANITIZER_MARKS = ("AddressSanitizer", "LeakSanitizer", "UndefinedBehaviorSanitizer", "runtime error:")


def program(name: str) -> Path:
    """The C program `name` (rt_monitor or boards): the sanitizer build's, unless build/ holds a newer one (a
    developer rebuilt only build/: the sweep must not test yesterday's program)."""
    sub = {"rt_monitor": "rt_monitor", "boards": "firmware_like"}[name]
    built = [p for p in (ROOT / "build-asan" / sub / name, ROOT / "build" / sub / name) if p.is_file()]
    if not built:
        raise FileNotFoundError(f"{name} is not built (scripts/setup)")
    return max(built, key=lambda p: p.stat().st_mtime)


@dataclass(frozen=True)
class Outcome:
    code: int  # the exit code; minus the signal's number if a signal ended the process
    stdout: str
    stderr: str
    seconds: float


def _dynid_child(argv: list[str], cwd: str, out: str, err: str, unset: tuple[str, ...] = (),
                 setenv: tuple[tuple[str, str], ...] = ()) -> None:
    """In the forked child: the `dynid` entry point on argv, stdout and stderr (fds 1, 2) into files, without the
    environment variables `unset` and with those of `setenv`."""
    for name in unset:
        os.environ.pop(name, None)
    os.environ.update(setenv)
    for fd, path in ((1, out), (2, err)):
        f = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(f, fd)
        os.close(f)
    os.chdir(cwd)
    sys.argv = ["dynid", *argv]
    from dynid.cli import main

    code: object = 1
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    finally:  # the exit code beside the streams too: the forkserver's report of it can be lost (below)
        sys.stdout.flush()
        sys.stderr.flush()
        Path(out).with_name("code").write_text(str(code if isinstance(code, int) else 0 if code is None else 1))
    sys.exit(code)  # multiprocessing turns SystemExit into the exit code, as the interpreter would


_context: Any = None


def _forkserver() -> Any:
    global _context
    if _context is None:
        _context = multiprocessing.get_context("forkserver")
        _context.set_forkserver_preload(PRELOAD)
    return _context


def run_dynid(argv: list[str], cwd: Path, timeout: float = TIMEOUT_S, unset: tuple[str, ...] = (),
              setenv: dict[str, str] | None = None) -> Outcome:
    """`dynid argv` in `cwd` as a process of its own, forked from the preloaded server; `unset`: environment
    variables the command runs without; `setenv`: variables it runs with (the server's environment is the one it
    started with, not the caller's of now)."""
    pairs = tuple((setenv or {}).items())
    if os.environ.get("HOSTILE_SUBPROCESS") == "1":
        return run_program(DYNID, argv, cwd, timeout, unset, pairs)
    with tempfile.TemporaryDirectory(prefix="hostile-") as streams:  # beside no case's files: they stay untouched
        out, err = Path(streams) / "stdout", Path(streams) / "stderr"
        started = time.perf_counter()
        child = _forkserver().Process(target=_dynid_child,
                                      args=(argv, str(cwd), str(out), str(err), tuple(unset), pairs))
        child.start()
        child.join(timeout)
        if child.exitcode is None:
            child.kill()
            child.join()
            raise AssertionError(f"dynid {' '.join(argv)}: still running after {timeout:g} s")
        code = child.exitcode
        written = Path(streams) / "code"
        if code == 255 and written.is_file():  # multiprocessing's 255: the forkserver's status read hit EOF, seen
            code = int(written.read_text())  # once in a CI run after a complete command; the child's own word
        return Outcome(code, _text(out), _text(err), time.perf_counter() - started)


def _text(path: Path) -> str:
    return path.read_bytes().decode(errors="replace") if path.exists() else ""


def run_program(path: Path, argv: list[str], cwd: Path, timeout: float = TIMEOUT_S,
                unset: tuple[str, ...] = (), setenv: tuple[tuple[str, str], ...] = ()) -> Outcome:
    env = {k: v for k, v in os.environ.items() if k not in unset} | dict(setenv)
    env.update(ASAN_OPTIONS="detect_leaks=1:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
    started = time.perf_counter()
    done = subprocess.run([str(path), *argv], cwd=cwd, capture_output=True, timeout=timeout, env=env)
    return Outcome(done.returncode, done.stdout.decode(errors="replace"), done.stderr.decode(errors="replace"),
                   time.perf_counter() - started)
