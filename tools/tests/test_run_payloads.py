"""A run carrying a load the others do not, with no --payload: named by `dynid fit` (dynid.identify.run_payloads).

The plant's truth: Panda runs whose joint torques are Pinocchio's `rnea` on the CAD inertias, one of them with a
point mass at the configuration's payload frame; a clean set names nothing, and a load that is declared is the user's.
The real runs' figures (the UR10e's 2.805 kg run, the iCub leg's windows): tests/realdata and
tools/benchmarks/run_payloads.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import dynid
from synthetic_panda import panda_run

from dynid.config.robot_config import load_config
from dynid.identify.fit import FitSettings, fit
from dynid.identify.run_payloads import apparent_payloads
from dynid.io.dataset import Dataset
from dynid.robot.model import RobotModel

LOAD_KG = 0.5  # the fit determines combinations across the runs beside it
HEAVY_KG = 2.0  # it no longer does: the refusal names the load
SECONDS = 12.0


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    return RobotModel(load_config("panda"))


def run(model: RobotModel, seed: int, load_kg: float = 0.0) -> Dataset:
    return panda_run(model, seed, SECONDS, load_kg)


@pytest.fixture(scope="module")
def runs(panda: RobotModel) -> list[Dataset]:
    return [run(panda, 1), run(panda, 2), run(panda, 3, LOAD_KG)]


def named(model: RobotModel, data: list[Dataset], declared: list[bool]) -> list:
    result = fit(model, data, FitSettings(estimator="ols"))
    return apparent_payloads(model, result.statistics, result.base.independent, declared)


def test_the_loaded_run_is_named_with_its_mass(panda: RobotModel, runs: list[Dataset]) -> None:
    loads = named(panda, runs, [False] * 3)
    assert [a.run for a in loads] == [2], loads
    assert loads[0].mass_kg == pytest.approx(LOAD_KG, rel=0.05)  # a point mass at the frame: what the test fits
    assert loads[0].residual_drop > 0.5


def test_runs_of_one_robot_as_it_is_name_nothing(panda: RobotModel, runs: list[Dataset]) -> None:
    assert named(panda, runs[:2] + [run(panda, 4)], [False] * 3) == []


def test_a_declared_load_is_the_users(panda: RobotModel, runs: list[Dataset]) -> None:
    """Given with --payload the run is no candidate; the unloaded runs beside it ask for nothing."""
    runs[2].meta["payload"] = {"mass": LOAD_KG}
    try:
        assert named(panda, runs, [False, False, True]) == []
    finally:
        del runs[2].meta["payload"]


def saved(runs: list[Dataset], folder: Path) -> list[str]:
    paths = []
    for i, ds in enumerate(runs):
        paths += ["--data", str(folder / f"run{i}.npz")]
        ds.save(folder / f"run{i}.npz")
    return paths


def test_fit_warns_and_reports_it(runs: list[Dataset], tmp_path: Path) -> None:
    paths = saved(runs, tmp_path)
    done = dynid("fit", "--robot", "panda", *paths, "--out", tmp_path / "m.json", "--json", tmp_path / "fit.json")
    assert done.returncode == 0, done.stderr
    warned = [line for line in done.stdout.splitlines() if "rows ask for" in line]
    assert len(warned) == 1 and "run2.npz" in warned[0] and "a load not given" in warned[0], done.stdout
    found = json.loads((tmp_path / "fit.json").read_text())["apparent_payloads"]
    assert len(found) == 1 and found[0]["data"].endswith("run2.npz")
    assert found[0]["mass_kg"] == pytest.approx(LOAD_KG, rel=0.05)
    done = dynid("fit", "--robot", "panda", *paths, "--payload", "0", "--payload", "0", "--payload", str(LOAD_KG),
                 "--out", tmp_path / "m2.json")
    assert done.returncode == 0, done.stderr
    assert "rows ask for" not in done.stdout


def test_a_fit_the_load_makes_impossible_names_it(panda: RobotModel, runs: list[Dataset], tmp_path: Path) -> None:
    """2 kg on the third run: every estimate moves with the run left out and the fit is refused; the line said "a
    longer run, or one that moves every joint both ways", which these runs are not short of."""
    paths = saved([*runs[:2], run(panda, 3, HEAVY_KG)], tmp_path)
    done = dynid("fit", "--robot", "panda", *paths, "--out", tmp_path / "m.json")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "run 3 (in --data order) asks for +2 kg at panda_link7" in done.stderr, done.stderr
    assert "a longer run" not in done.stderr and not (tmp_path / "m.json").exists()


@pytest.mark.parametrize("loaded_first", [True, False], ids=["loaded first", "unloaded first"])
def test_of_two_runs_the_loaded_one_is_named_in_either_order(panda: RobotModel, runs: list[Dataset],
                                                             loaded_first: bool) -> None:
    """Two runs left free are one difference: +m on one or -m on the other remove the same residual, and the first
    candidate was named (a review: the unloaded run "asking for -0.5 kg" half the time). The run asking for the load
    is named, whatever the order."""
    pair = [runs[2], runs[0]] if loaded_first else [runs[0], runs[2]]
    loads = named(panda, pair, [False, False])
    assert [a.run for a in loads] == [0 if loaded_first else 1]
    assert loads[0].mass_kg == pytest.approx(LOAD_KG, rel=0.05)
