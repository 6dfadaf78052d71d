"""Fixtures shared by the test modules: the default simulated experiments, made once per session."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase
from hypothesis import settings as hypothesis_settings

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


def dynid(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dynid.cli", *args], capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="session")
def default_experiments(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The three default experiments, through the command line, as scripts/main runs them.

    DYNID_TEST_EXPERIMENTS=DIR reuses DIR/<kind> from an earlier `dynid simulate` with the defaults (development
    only: it saves three minutes a run; CI always simulates)."""
    reuse = os.environ.get("DYNID_TEST_EXPERIMENTS")
    if reuse:
        return {kind: Path(reuse) / kind for kind in KINDS}
    root = tmp_path_factory.mktemp("sim")
    out = {}
    for kind in KINDS:
        out[kind] = root / kind
        done = dynid("simulate", "--kind", kind, "--out", str(out[kind]), "--json", str(root / f"{kind}.json"))
        assert done.returncode == 0, done.stderr
    return out


@pytest.fixture(scope="session")
def default_model(default_experiments: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`dynid fit` on the default identification experiment, as scripts/main runs it."""
    out = tmp_path_factory.mktemp("fit") / "model.json"
    done = dynid("fit", "--data", str(default_experiments["identification"]), "--out", str(out),
                 "--json", str(out.with_suffix(".fit.json")))
    assert done.returncode == 0, done.stderr
    return out


@pytest.fixture(scope="session")
def exported(default_model: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`dynid export` of the default model: the coefficient file rt_monitor loads, as scripts/main writes it."""
    out = tmp_path_factory.mktemp("export") / "model.dcoef"
    done = dynid("export", "--model", str(default_model), "--out", str(out))
    assert done.returncode == 0, done.stderr
    return out


HIDDEN_EFFECTS = ["--effect", "stribeck:joint=r_elbow,excess=2,velocity=0.05",
                  "--effect", "spring:joint=r_shoulder_yaw,stiffness=1.0"]


@pytest.fixture(scope="session")
def hidden_effects_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two runs of the default arm with a hidden Stribeck (elbow) and spring (shoulder yaw): "fit" (40 s, seed 0) for
    `dynid gaps`, "replay" (30 s, seed 1) to replay its augmented model on."""
    root = tmp_path_factory.mktemp("hidden_effects")
    runs = {}
    for name, seed, duration in (("fit", "0", "40"), ("replay", "1", "30")):
        runs[name] = root / name
        done = dynid("simulate", "--kind", "identification", "--duration", duration, "--seed", seed, *HIDDEN_EFFECTS,
                     "--out", str(runs[name]))
        assert done.returncode == 0, done.stderr
    return runs


def exit_counter(stdout: str, name: str) -> int:
    """A counter of the final line rt_monitor prints at exit ("..., late 12, ...")."""
    return int(stdout.split(f", {name} ")[1].split(",")[0])
