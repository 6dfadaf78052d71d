"""Ctrl-C: every command ends promptly with one line, "dynid COMMAND: interrupted", exit code 130, never a
traceback, and leaves nothing behind (docs/design.md §7).

Each signal is sent at a set point of the command (a module starting to load, a file appearing, a function being
called), never after a sleep: a driver script runs the command with a hook at that point."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
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


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3 s identification run of the default arm: enough for a command to start its work."""
    from dynid.config.robot_config import load_config
    from dynid.simulation import SimulationSettings, simulate
    from dynid.simulation.output import write_simulation

    out = tmp_path_factory.mktemp("interrupt") / "run"
    write_simulation(simulate(load_config("icub_right_arm"), SimulationSettings(duration=3.0, seed=0)), out)
    return out


# `dynid fit --workers 2` with Ctrl-C while its LocalCluster starts: to this process alone as the workers are about
# to start ("starting"), or to the whole process group, workers included, once they run but before the start-up
# returns ("started"; what a terminal does). It prints whether the workers hold SIGINT blocked.
INTERRUPT_CLUSTER_START = """
import os, signal, sys
import distributed

when, *argv = sys.argv[1:]
Real = distributed.LocalCluster


def workers_block_sigint():
    me = os.getpid()
    kids = [int(k) for t in os.listdir(f"/proc/{me}/task") for k in open(f"/proc/{me}/task/{t}/children").read().split()]
    workers = [k for k in kids if b"multiprocessing.spawn" in open(f"/proc/{k}/cmdline", "rb").read()]
    masks = [int(line.split()[1], 16) for k in workers for line in open(f"/proc/{k}/status") if line.startswith("SigBlk")]
    return bool(workers) and all(m & (1 << (signal.SIGINT - 1)) for m in masks)


class Interrupted(Real):
    def __init__(self, *args, **kwargs):
        if when == "starting":
            os.kill(os.getpid(), signal.SIGINT)
        super().__init__(*args, **kwargs)
        if when == "started":
            print(f"workers block SIGINT: {workers_block_sigint()}", flush=True)
            os.killpg(0, signal.SIGINT)


distributed.LocalCluster = Interrupted
from dynid.cli import main

sys.exit(main(argv))
"""


@pytest.mark.parametrize("when", ["starting", "started"])
def test_ctrl_c_while_a_local_cluster_starts_stops_the_fit(when: str, short_run: Path, tmp_path: Path) -> None:
    """The workers used to start with SIGINT ignored, this process's own disposition too for the start-up (1-2 s): a
    Ctrl-C then was lost, and the fit ran on, wrote its model and --json and exited 0. It is held now, and delivered
    when the cluster is up: the fit stops, nothing written, one line; the workers, started with SIGINT blocked, print
    nothing."""
    done = driver(INTERRUPT_CLUSTER_START, when, "fit", "--data", str(short_run), "--workers", "2",
                  "--out", "m.json", "--json", "r.json", cwd=tmp_path)
    assert (done.returncode, done.stderr) == (130, "dynid fit: interrupted\n"), done.stderr
    if when == "started":
        assert done.stdout == "workers block SIGINT: True\n"
    assert list(tmp_path.iterdir()) == []


HELD_AND_SWALLOWED = """
import os, signal, time
from dynid.interrupt import interruptible, requested, sigint_held


class Dropped:
    def __del__(self):  # Python cannot raise from here: a KeyboardInterrupt in it is printed and dropped
        os.kill(os.getpid(), signal.SIGINT)
        len("the handler runs at a call")


with interruptible():
    steps = []
    try:
        with sigint_held():
            os.kill(os.getpid(), signal.SIGINT)
            steps.append("held")
    except KeyboardInterrupt:
        steps.append("delivered")
    try:
        Dropped()
        for _ in range(1000):  # within 10 s
            time.sleep(0.01)
        steps.append("swallowed")
    except KeyboardInterrupt:
        steps.append("delivered again")
    print(*steps, requested())
print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)
try:
    with interruptible():
        Dropped()
    print("ended without a word")
except KeyboardInterrupt:
    print("ended as interrupted")
"""


def test_a_ctrl_c_is_held_over_a_step_and_never_swallowed() -> None:
    """sigint_held delivers the Ctrl-C that came during the step once the step is over; one whose KeyboardInterrupt
    Python swallowed (raised inside a __del__ or a weakref callback, as during imports and a Dask cluster's start)
    is delivered again at the next opportunity, or when the block ends; Python's own handler is back after
    interruptible()."""
    done = driver(HELD_AND_SWALLOWED)
    expected = "held delivered delivered again True\nTrue\nended as interrupted\n"
    assert (done.stdout, done.stderr) == (expected, ""), done.stderr


@pytest.mark.parametrize("to", ["group", "process"])
def test_ctrl_c_while_play_writes_a_candump_log_leaves_nothing(to: str, short_run: Path, tmp_path: Path) -> None:
    """`dynid play --realtime --sink candump:p.log` stopped once boards is writing (its temporary file, p.log.XXXXXX,
    exists): boards, stopped by the terminal's SIGINT or killed by subprocess.run, left that file behind (mode 600).
    It writes in a directory of dynid's own now (dynid.outputs.written_by), removed with whatever is in it."""
    from dynid.export.player import BOARDS

    if not BOARDS.is_file():
        pytest.skip(f"{BOARDS} is not built (scripts/setup)")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TOOLS), os.environ.get("PYTHONPATH", "")])}
    p = subprocess.Popen([sys.executable, "-m", "dynid", "play", "--data", str(short_run), "--sink", "candump:p.log",
                          "--realtime", "--json", "p.json"], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not any(f.is_file() for f in tmp_path.rglob("p.log.*")):  # boards's: the log being written
            assert p.poll() is None and time.monotonic() < deadline, p.communicate()
            time.sleep(0.01)
        (os.killpg if to == "group" else os.kill)(p.pid, signal.SIGINT)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert (p.returncode, err) == (130, "dynid play: interrupted\n"), err
    assert [f.name for f in tmp_path.rglob("*")] == []


# `dynid fleet` with Ctrl-C (to the whole group) as its page is drawn: every robot's model fitted and written by then.
INTERRUPT_FLEET_PAGE = """
import os, signal, sys
import dynid.cli.fleet

draw = dynid.cli.fleet.page


def page(*args, **kwargs):
    os.killpg(0, signal.SIGINT)
    return draw(*args, **kwargs)


dynid.cli.fleet.page = page
from dynid.cli import main

sys.exit(main(sys.argv[1:]))
"""


def test_ctrl_c_in_fleet_leaves_no_model_without_its_page(tmp_path: Path) -> None:
    """Interrupted once its models were written, `dynid fleet` left OUT/models/*.json without fleet.html or the --json
    (exit 130). A command's outputs are put in place together when it succeeds now (dynid.outputs), OUT included."""
    from dynid.config.robot_config import load_config
    from dynid.simulation import SimulationSettings, simulate
    from dynid.simulation.output import write_simulation

    config = load_config("icub_right_arm")
    for i in range(3):  # three robots, a folder each; 15 s runs: enough for each robot's fit
        sim = simulate(config, SimulationSettings(duration=15.0, seed=i, robot_seed=i))
        write_simulation(sim, tmp_path / "runs" / f"arm{i}" / "run")
    done = driver(INTERRUPT_FLEET_PAGE, "fleet", "--data", "runs", "--out", "out", "--blocks", "2",
                  "--estimator", "ols", "--json", "fleet.json", cwd=tmp_path)
    assert (done.returncode, done.stderr) == (130, "dynid fleet: interrupted\n"), done.stderr
    assert "[3/3] arm2" in done.stdout  # every robot was fitted
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"]
