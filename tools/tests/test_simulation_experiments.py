"""`dynid simulate` as users run it: the default experiments' realism, the files, and every bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid

from dynid.config.robot_config import load_config
from dynid.io.csv_format import read_csv
from dynid.io.dataset import Dataset
from dynid.io.load import load_data
from dynid.robot.model import RobotModel
from dynid.robot.regressors.base import data_base_parameters, structural_base_parameters
from dynid.robot.regressors.stack import Signals, signals_from_dataset
from dynid.simulation import KINDS, SimulationSettings, simulate

ICUB = load_config("icub_right_arm")
MODEL = RobotModel(ICUB)


@pytest.mark.parametrize("kind", list(KINDS))
def test_default_experiments_are_realistic(default_experiments: dict[str, Path], kind: str) -> None:
    truth = json.loads((default_experiments[kind] / "truth.json").read_text())
    assert truth["duration_s"] == KINDS[kind] and truth["samples"] == int(KINDS[kind] * 1000)
    dataset = Dataset.load(default_experiments[kind] / "dataset.npz")
    pwm = np.column_stack(list(dataset.pwm.values()))
    assert np.mean(np.all(np.abs(pwm) < 1.0, axis=1)) >= 0.999  # the board's limit, as on the real arm
    assert np.abs(pwm).max() <= 1.0
    true_q = Dataset.load(default_experiments[kind] / "truth.npz").q
    for i, j in enumerate(ICUB.joints):
        lo, hi = MODEL.joint_limits[j]
        assert lo <= true_q[:, i].min() and true_q[:, i].max() <= hi, j
    assert truth["realism"]["joint_limits_respected"] == 1.0
    assert truth["plant"]["unconverged_friction_steps"] == 0
    assert truth["disturbance"] is True  # closed-loop identification is hard by default
    supply = Dataset.load(default_experiments[kind] / "truth.npz").extra["supply.m0"]
    assert 0.005 < np.std(supply) < 0.1 and abs(np.mean(supply) - 1) < 0.1  # the gains wander with the supply


def test_identification_excites_the_full_base_rank(default_experiments: dict[str, Path]) -> None:
    dataset = load_data(default_experiments["identification"], ICUB, MODEL.joint_limits)
    full = signals_from_dataset(MODEL, dataset)  # derivatives estimated at the full rate, as fit will
    every = slice(None, None, 10)  # every tenth sample of the whole experiment: the same excitation, less work
    sig = Signals(full.q[every], full.dq[every], full.ddq[every], {k: v[every] for k, v in full.inputs.items()}, {},
                  {k: v[every] for k, v in full.ft.items()})
    assert data_base_parameters(MODEL, sig).rank == structural_base_parameters(MODEL).rank == 87
    # Rows at rest add no excitation the model can use (static friction, which it lacks, holds any torque there);
    # keeping them can only seem to separate more Coulomb combinations, never fewer.
    assert data_base_parameters(MODEL, sig, min_speed=None).rank >= 87


def test_contact_experiment_has_skin_ground_truth_on_both_sides(default_experiments: dict[str, Path]) -> None:
    truth = json.loads((default_experiments["contact"] / "truth.json").read_text())
    dataset = load_data(default_experiments["contact"], ICUB, MODEL.joint_limits)
    episodes = truth["contacts"]
    assert len(episodes) >= 15 and {e["side"] for e in episodes} == {"distal", "proximal"}
    for e in episodes:
        assert 0.3 <= e["end_s"] - e["onset_s"] <= 3.0 and 2.0 <= e["magnitude_n"] <= 15.0
        inside = (dataset.t > e["onset_s"]) & (dataset.t < e["end_s"])
        assert dataset.contact[inside].all()
        assert np.all(dataset.extra["skin.side"][inside] == (1.0 if e["side"] == "distal" else -1.0))
    assert 0.1 < dataset.contact.mean() < 0.6
    # The skin's side is physics: a distal push shows in the F/T sensor, a proximal one does not.
    signals = Dataset.load(default_experiments["contact"] / "truth.npz").extra
    share = np.abs(signals["contact.r_arm_ft.fx"]) + np.abs(signals["contact.r_arm_ft.fy"]) + np.abs(signals["contact.r_arm_ft.fz"])
    side = dataset.extra["skin.side"]
    assert share[side < 0].max() == 0.0 and np.median(share[side > 0]) > 1.0


def test_the_csv_is_the_dataset_and_every_command_reads_the_directory(default_experiments: dict[str, Path]) -> None:
    directory = default_experiments["validation"]
    dataset = load_data(directory, ICUB, MODEL.joint_limits)
    from_csv = read_csv(directory / "data.csv", ICUB, joint_limits=MODEL.joint_limits)
    assert np.array_equal(from_csv.q, dataset.q) and np.array_equal(from_csv.t, dataset.t)
    assert all(np.array_equal(from_csv.pwm[m], dataset.pwm[m]) for m in ICUB.motor_names)
    assert np.array_equal(from_csv.ft["r_arm_ft"], dataset.ft["r_arm_ft"])
    imported = dynid("import", "--data", str(directory / "data.csv"), "--out", str(directory / "imported.npz"))
    assert imported.returncode == 0, imported.stderr
    structure = dynid("structure", "--data", str(directory), "--json", "-")
    assert structure.returncode == 0, structure.stderr
    assert json.loads(structure.stdout)["rank"] == 87


def test_json_result_and_human_report(tmp_path: Path) -> None:
    done = dynid("simulate", "--kind", "contact", "--duration", "6", "--seed", "2", "--effect", "cogging",
                 "--effect", "ft_drift:force=1", "--out", str(tmp_path / "c"), "--json", "-")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["samples"] == 6000 and result["kind"] == "contact" and result["seed"] == 2
    assert [e["name"] for e in result["effects"]] == ["cogging", "ft_drift"]
    assert result["effects"][0]["target"] == "m3" and result["effects"][1]["force"] == 1.0
    assert set(result["files"]) == {"dataset", "csv", "truth", "truth_signals"}
    assert "simulated contact" in done.stderr and "hidden effects: cogging on m3" in done.stderr
    truth = json.loads((tmp_path / "c" / "truth.json").read_text())
    assert truth["effects"] == result["effects"]
    listing = dynid("simulate", "--list-effects")
    assert listing.returncode == 0 and "stribeck" in listing.stdout and "ft_gain" in listing.stdout


def test_noise_none_is_deterministic_physics(tmp_path: Path) -> None:
    a = simulate(ICUB, SimulationSettings(duration=0.5, noise=False, seed=1))
    b = simulate(ICUB, SimulationSettings(duration=0.5, noise=False, seed=1, disturbance=True))
    assert not a.truth["disturbance"] and not b.truth["disturbance"]  # noise none turns the disturbance off too
    assert np.array_equal(a.dataset.q, b.dataset.q)


def test_the_same_seed_gives_the_same_files(tmp_path: Path) -> None:
    """Two `dynid simulate` processes of one seed write the same bytes, whatever BLAS thread count each has (on one
    CPU: another CPU's BLAS kernels round differently, docs/consistency.md)."""
    args = ["simulate", "--kind", "contact", "--duration", "20", "--seed", "3", "--effect", "cogging"]
    for threads in ("1", "2"):
        env = {**os.environ, "OPENBLAS_NUM_THREADS": threads}
        done = subprocess.run([sys.executable, "-m", "dynid.cli", *args, "--out", str(tmp_path / threads)],
                              capture_output=True, text=True, timeout=600, env=env)
        assert done.returncode == 0, done.stderr
    for name in ("data.csv", "truth.json"):
        assert (tmp_path / "1" / name).read_bytes() == (tmp_path / "2" / name).read_bytes(), name
    one, two = np.load(tmp_path / "1" / "dataset.npz"), np.load(tmp_path / "2" / "dataset.npz")
    assert sorted(one.files) == sorted(two.files)
    for key in one.files:
        assert np.array_equal(one[key], two[key]), key


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--effect", "bogus"], "unknown hidden effect 'bogus'"),
        (["--effect", "cogging:motor=m9"], "targets 'm9', which is not a motor"),
        (["--effect", "cogging:amplitude=strong"], "amplitude must be a number"),
        (["--effect", "cogging:speed=1"], "has no parameter 'speed'"),
        (["--effect", "cogging:amplitude"], "expected key=value"),
        (["--effect", "ft_drift:shape=square"], "shape must be one of thermal, linear"),
        (["--effect", "spring:joint=r_wrist_yaw"], "not a joint it can act on"),
        (["--effect", "coupling_error:joint=r_elbow"], "joint 'r_elbow' is not in group shoulder"),
        (["--effect", "spring:rest=middle"], "rest must be a number"),
        # physically impossible values: each used to end in the plant's traceback or in ruined data
        (["--effect", "stribeck:joint=r_elbow,excess=-50"], "effect 'stribeck': excess must be at least 0, got '-50'"),
        (["--effect", "stribeck:joint=r_elbow,velocity=0"], "effect 'stribeck': velocity must be above 0, got '0'"),
        (["--effect", "spring:joint=r_elbow,stiffness=-1000"], "stiffness must be at least 0"),
        (["--effect", "payload:link=r_hand,mass=-5"], "effect 'payload': mass must be above 0"),
        (["--effect", "cogging:motor=m0,period_deg=0"], "period_deg must be above 0"),
        (["--effect", "ft_drift:tau=0"], "effect 'ft_drift': tau must be above 0"),
        (["--effect", "pwm_delay:ms=-3"], "effect 'pwm_delay': ms must be at least 0"),
        (["--effect", "pwm_delay:ms=1e9"], "effect 'pwm_delay': 1e+09 ms is not shorter than the run (0.1 s)"),
        (["--effect", "pwm_deadzone:width=1"], "width must be at least 0 and below 1"),
        (["--effect", "drag:coefficient=1e6", "--duration", "2"], "the plant diverged at t = "),
        (["--duration", "-1"], "must be a positive number"),
        (["--duration", "nan"], "must be a positive number"),
        (["--seed", "-3"], "must be 0 or more"),
        (["--duration", "7200"], "fit in memory"),
        (["--rate", "50"], "outside 250..10000 Hz"),
        (["--kind", "dance"], "invalid choice"),
        (["--robot", "no_such_robot"], "unknown robot configuration"),
        ([], "--out DIR is required"),
    ],
)
def test_bad_input_is_one_line_and_exit_code_2(tmp_path: Path, args: list[str], message: str) -> None:
    out = [] if args == [] else ["--out", str(tmp_path / "x")]
    done = dynid("simulate", "--duration", "0.1", *args, *out) if "--duration" not in args else dynid("simulate", *args, *out)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
    assert not (tmp_path / "x").exists()


def test_output_path_that_is_a_file_is_refused(tmp_path: Path) -> None:
    target = tmp_path / "taken"
    target.write_text("keep me")
    done = dynid("simulate", "--duration", "0.1", "--out", str(target))
    assert done.returncode == 2 and "not a directory" in done.stderr
    assert target.read_text() == "keep me"


def _recorded_csv(folder: Path) -> None:
    folder.mkdir()
    (folder / "data.csv").write_text("t,q.r_elbow\n0,0.1\n")


def _imported_dataset(folder: Path) -> None:
    folder.mkdir()
    t = np.arange(200) * 0.01
    Dataset(t=t, joints=("a",), q=np.sin(t)[:, None], meta={"source": "lab/run.csv"}).save(folder / "dataset.npz")


def _yarp_folder(folder: Path) -> None:
    (folder / "icub" / "right_arm" / "stateExt:o").mkdir(parents=True)
    (folder / "icub" / "right_arm" / "stateExt:o" / "data.log").write_text("1 0.5 (1 2 3) [ok]\n")


@pytest.mark.parametrize("make", [_recorded_csv, _imported_dataset, _yarp_folder])
def test_out_onto_a_folder_that_is_not_a_simulated_run_is_refused(tmp_path: Path, make: Callable[[Path], None]
                                                                  ) -> None:
    """A recorded run's folder given as --out by mistake: its data.csv used to be replaced, and a YARP or logger
    folder given a dataset.npz read as the simulated run from then on. Refused before any work, nothing touched."""
    folder = tmp_path / "run"
    make(folder)
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    done = dynid("simulate", "--duration", "0.2", "--out", str(folder))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "not an earlier `dynid simulate` run" in done.stderr and "new or empty directory" in done.stderr
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no temporary directory left beside it


def test_out_onto_an_earlier_simulated_run_replaces_its_files_only(tmp_path: Path) -> None:
    """As `fit --out` replaces a model file, simulate replaces its own earlier run (scripts/main runs again into the
    same folders); what else the user put there stays. An empty folder is written to."""
    run = tmp_path / "run"
    assert dynid("simulate", "--duration", "0.2", "--out", str(run)).returncode == 0
    (run / "model.json").write_text("{}")
    done = dynid("simulate", "--duration", "0.3", "--seed", "1", "--out", str(run))
    assert done.returncode == 0, done.stderr
    assert json.loads((run / "truth.json").read_text())["duration_s"] == 0.3
    assert Dataset.load(run / "dataset.npz").n_samples == 300 and (run / "model.json").read_text() == "{}"
    assert sorted(p.name for p in run.iterdir()) == ["data.csv", "dataset.npz", "model.json", "truth.json", "truth.npz"]
    (tmp_path / "empty").mkdir()
    assert dynid("simulate", "--duration", "0.2", "--out", str(tmp_path / "empty")).returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "run"]
