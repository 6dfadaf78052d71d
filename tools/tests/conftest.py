"""Fixtures shared by the test modules: the default simulated experiments, made once per session."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from filelock import FileLock
from hypothesis import HealthCheck, Phase
from hypothesis import settings as hypothesis_settings

from tests.hostile.run import run_dynid

# The reader property tests (test_reader_properties*.py): CI runs the same examples every time (derandomized, no
# example database), without a deadline (a loaded 2-core machine varies tenfold). DYNID_HYPOTHESIS_EXAMPLES=N
# searches longer by hand, with new random examples each run (property_support.examples).
hypothesis_settings.register_profile(
    "dynid", derandomize=True, database=None, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
hypothesis_settings.register_profile("dynid-search", parent=hypothesis_settings.get_profile("dynid"), derandomize=False)
# `--hypothesis-profile dynid-regressions`: only the kept `@example`s (the inputs of the defects found).
hypothesis_settings.register_profile("dynid-regressions", parent=hypothesis_settings.get_profile("dynid"),
                                     phases=[Phase.explicit])
hypothesis_settings.load_profile("dynid-search" if os.environ.get("DYNID_HYPOTHESIS_EXAMPLES") else "dynid")

KINDS = ("identification", "validation", "contact")


def dynid(*args: str, cwd: Path | None = None, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """`dynid ARGS` as a process of its own, forked from a server that has imported dynid already (the hostile
    sweep's, tests/hostile/run.py): the executable's exit code, stdout and stderr, without an interpreter start and
    dynid's imports per call (0.5-1.5 s each, some 160 calls a run). test_gaps holds it to the executable. `env`:
    environment variables set for the command."""
    done = run_dynid([str(a) for a in args], Path.cwd() if cwd is None else cwd, timeout=900, setenv=env)
    return subprocess.CompletedProcess(["dynid", *args], done.code, done.stdout, done.stderr)


def dynid_executable(*args: str) -> subprocess.CompletedProcess:
    """`dynid ARGS` through the interpreter, as a user's shell runs it."""
    return subprocess.run([sys.executable, "-m", "dynid.cli", *args], capture_output=True, text=True, timeout=900)


def made_once(tmp_path_factory: pytest.TempPathFactory, name: str, make: Callable[[Path], None]) -> Path:
    """A directory `make(dir)` fills once per test run, whichever pytest-xdist worker asks first; the others wait for
    it and read it (pytest-xdist's documented recipe: a lock beside the workers' common base temp). Without xdist,
    simply made. Only what `make` finished is reused: a worker whose `make` failed leaves no mark, and the next one
    tries again and fails the same way."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        root = tmp_path_factory.mktemp(name)
        make(root)
        return root
    shared = tmp_path_factory.getbasetemp().parent / name
    with FileLock(str(shared) + ".lock"):
        done = shared / ".made"
        if not done.is_file():
            shared.mkdir(exist_ok=True)
            make(shared)
            done.write_text(json.dumps({"by": os.environ["PYTEST_XDIST_WORKER"]}))
    return shared


@pytest.fixture(scope="session")
def default_experiments(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The three default experiments, through the command line, as scripts/main runs them.

    DYNID_TEST_EXPERIMENTS=DIR reuses DIR/<kind> from an earlier `dynid simulate` with the defaults (development
    only: it saves three minutes a run; CI always simulates)."""
    reuse = os.environ.get("DYNID_TEST_EXPERIMENTS")
    if reuse:
        return {kind: Path(reuse) / kind for kind in KINDS}

    def simulate(root: Path) -> None:
        for kind in KINDS:
            done = dynid("simulate", "--kind", kind, "--out", str(root / kind), "--json", str(root / f"{kind}.json"))
            assert done.returncode == 0, done.stderr

    root = made_once(tmp_path_factory, "sim", simulate)
    return {kind: root / kind for kind in KINDS}


@pytest.fixture(scope="session")
def default_model(default_experiments: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`dynid fit` on the default identification experiment, as scripts/main runs it."""

    def fit(root: Path) -> None:
        out = root / "model.json"
        done = dynid("fit", "--data", str(default_experiments["identification"]), "--out", str(out),
                     "--json", str(out.with_suffix(".fit.json")))
        assert done.returncode == 0, done.stderr

    return made_once(tmp_path_factory, "fit", fit) / "model.json"


@pytest.fixture(scope="session")
def exported(default_model: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`dynid export` of the default model: the coefficient file rt_monitor loads, as scripts/main writes it."""

    def export(root: Path) -> None:
        done = dynid("export", "--model", str(default_model), "--out", str(root / "model.dcoef"))
        assert done.returncode == 0, done.stderr

    return made_once(tmp_path_factory, "export", export) / "model.dcoef"


HIDDEN_EFFECTS = ["--effect", "stribeck:joint=r_elbow,excess=2,velocity=0.05",
                  "--effect", "spring:joint=r_shoulder_yaw,stiffness=1.0"]


@pytest.fixture(scope="session")
def hidden_effects_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two runs of the default arm with a hidden Stribeck (elbow) and spring (shoulder yaw): "fit" (40 s, seed 0) for
    `dynid gaps`, "replay" (30 s, seed 1) to replay its augmented model on."""
    runs = {"fit": ("0", "40"), "replay": ("1", "30")}

    def simulate(root: Path) -> None:
        for name, (seed, duration) in runs.items():
            done = dynid("simulate", "--kind", "identification", "--duration", duration, "--seed", seed,
                         *HIDDEN_EFFECTS, "--out", str(root / name))
            assert done.returncode == 0, done.stderr

    root = made_once(tmp_path_factory, "hidden_effects", simulate)
    return {name: root / name for name in runs}


def exit_counter(stdout: str, name: str) -> int:
    """A counter of the final line rt_monitor prints at exit ("..., late 12, ...")."""
    return int(stdout.split(f", {name} ")[1].split(",")[0])
