"""Nonsense is refused in one line, never fitted, run or scored quietly (issue 31).

- A motionless run (one row repeated) used to fit with exit 0, rank 7 and negative residual variances, export, and
  drive the monitor into a contact that never ended (T² 1.7e21).
- A model file with a zero motor gain ended `validate`, `detect` and `export` in a traceback; a body mass of 1e308
  passed with NaN thresholds; a detector threshold of −1 scored 100 % false positives with exit 0.
- F/T torques in N·mm fitted with exit 0 and a warning (a centre of mass 87.8 m away, a residual 1659 times the
  noise): nothing checked an F/T sensor's magnitudes (dynid.io.wrenches).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid

from dynid.io.csv_format import write_csv
from dynid.io.dataset import Dataset


def test_a_motionless_run_is_refused_naming_what_never_moves(default_experiments: dict, tmp_path: Path) -> None:
    lines = (Path(default_experiments["validation"]) / "data.csv").read_text().splitlines()
    head, row = lines[0], lines[1].split(",")
    t = head.split(",").index("t")
    rows = [",".join(row[:t] + [f"{k * 0.001:.3f}"] + row[t + 1 :]) for k in range(3000)]
    (tmp_path / "still.csv").write_text("\n".join([head, *rows]) + "\n")
    done = dynid("fit", "--data", str(tmp_path / "still.csv"), "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    # One posture repeated: q̇ = q̈ = 0 exactly, the PWM rows are at rest (weighted out), and the six F/T rows see the
    # six offsets (gravity's wrench at one posture is one of them). While the filtered q̇ was rounding noise (~1e-13
    # rad/s, whose signs the friction columns took), the rank landed anywhere in 1..10 (6 or 7 were seen).
    excited = re.search(r"the run excites (\d+) of the 87 directions", done.stderr)
    assert excited and int(excited.group(1)) == 6, done.stderr
    assert "joints that never move: r_shoulder_pitch, r_shoulder_roll, r_shoulder_yaw, r_elbow" in done.stderr
    assert not (tmp_path / "m.json").exists()


def _edited(model: Path, out: Path, change) -> Path:
    data = json.loads(model.read_text())
    change(data)
    out.write_text(json.dumps(data))
    return out


EDITS = {
    "zero gain": (lambda d: d["parameters"].__setitem__("m2.phi_m", 0.0), "motor m2's gain is 0: a motor gain must be positive"),
    "negative gain": (lambda d: d["parameters"].__setitem__("m0.phi_m", -20.0), "motor m0's gain is -20"),
    "huge mass": (lambda d: d["parameters"].__setitem__("r_hand.m", 1e308), "r_hand.m is 1e+308 kg, beyond any robot link's"),
    "negative threshold": (lambda d: d["detector"]["calibrated"].__setitem__("threshold", -1),
                           "detector.calibrated.threshold is -1: T²_α must be a positive number"),
    "zero variance": (lambda d: d["detector"]["calibrated"]["variance"].__setitem__(3, 0.0),
                      "detector.calibrated.variance must be positive on every channel"),
}


@pytest.mark.parametrize("edit", list(EDITS))
def test_an_impossible_model_file_is_refused_by_every_command(edit: str, default_model: Path, default_experiments: dict,
                                                             tmp_path: Path) -> None:
    change, words = EDITS[edit]
    model = _edited(default_model, tmp_path / "edited.json", change)
    run = str(default_experiments["validation"])
    for args in (("validate", "--model", str(model), "--data", run), ("detect", "--model", str(model), "--data", run),
                 ("export", "--model", str(model), "--out", str(tmp_path / "c.dcoef"))):
        done = dynid(*args)
        assert done.returncode == 2 and done.stderr.count("\n") == 1 and words in done.stderr, (args[0], done.stderr)
        assert "Traceback" not in done.stderr
    assert not (tmp_path / "c.dcoef").exists()


# (what is done to the run's F/T columns, words of the refusal): the default arm's sensor, columns fx fy fz tx ty tz.
WRENCHES = {
    "torques in N·mm": (lambda w: w * [1, 1, 1, 1e3, 1e3, 1e3], "torques in N·mm"),
    "forces in mN": (lambda w: w * [1e3, 1e3, 1e3, 1, 1, 1], "forces in mN"),
    "force and torque swapped": (lambda w: w[:, [3, 4, 5, 0, 1, 2]], "swapped"),
    "both ×1000": (lambda w: w * 1e3, "forces in mN"),  # the lever is the same: the forces' swing gives it away
    # N·m declared N·mm: the torques read 1000 times too small, and a fit to them looked excellent (the iCub leg)
    "torques ÷1000": (lambda w: w * [1, 1, 1, 1e-3, 1e-3, 1e-3], "torques in N·m declared N·mm"),
}


def _short_run(default_experiments: dict, change=None) -> Dataset:  # noqa: ANN001 - change: (N, 6) -> (N, 6)
    run = Dataset.load(Path(default_experiments["validation"]) / "dataset.npz").slice(0, 20000)  # 20 s
    if change is not None:
        run.ft = {name: change(w) for name, w in run.ft.items()}
    return run


@pytest.mark.parametrize("case", list(WRENCHES))
def test_an_ft_sensor_in_another_unit_is_refused_at_load(case: str, default_experiments: dict, tmp_path: Path) -> None:
    change, words = WRENCHES[case]
    run = _short_run(default_experiments, change)
    run.save(tmp_path / "run.npz")  # a dataset file: fit streams it and checks its first rows
    done = dynid("fit", "--data", str(tmp_path / "run.npz"), "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "ft.r_arm_ft" in done.stderr and words in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "m.json").exists()
    write_csv(run, tmp_path / "run.csv")  # a CSV: read whole (load_data)
    done = dynid("import", "--data", str(tmp_path / "run.csv"), "--out", str(tmp_path / "run2.npz"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and words in done.stderr, done.stderr
    assert not (tmp_path / "run2.npz").exists()


def test_large_ft_offsets_pass_the_unit_check(default_experiments: dict, tmp_path: Path) -> None:
    """An untared sensor (the TIAGo's Fz reads −69 N at rest) is not a wrong unit: every figure is taken about the
    channels' medians. 400 N and 30 Nm of offset, beyond any of the real runs', on the default arm's 2 kg forearm."""
    _short_run(default_experiments, lambda w: w + [400, -250, 300, 30, -20, 25]).save(tmp_path / "run.npz")
    done = dynid("structure", "--data", str(tmp_path / "run.npz"))
    assert done.returncode == 0, done.stderr


def test_a_fit_on_samples_labelled_contact_says_so(default_experiments: dict, tmp_path: Path) -> None:
    """The model has no contact: a run whose contact column labels samples (a contact run given to `fit` by
    mistake) is fitted, with a note naming the share, streamed (a dataset file) or read whole (a CSV)."""
    run = _short_run(default_experiments)
    run.contact = np.zeros(run.n_samples, np.uint8)
    run.contact[5000:6000] = 1  # 5 % of the 20 s
    run.save(tmp_path / "run.npz")
    write_csv(run, tmp_path / "run.csv")
    for data in ("run.npz", "run.csv"):
        done = dynid("fit", "--data", str(tmp_path / data), "--out", str(tmp_path / f"{data}.json"))
        assert done.returncode == 0, done.stderr
        notes = [line for line in done.stderr.splitlines() if "labelled contact" in line]
        assert len(notes) == 1 and "5 % of the samples" in notes[0] and "--from/--to" in notes[0], done.stderr
    run.contact[:] = 0  # labelled contact-free: no note
    run.save(tmp_path / "free.npz")
    done = dynid("fit", "--data", str(tmp_path / "free.npz"), "--out", str(tmp_path / "free.json"))
    assert done.returncode == 0 and "labelled contact" not in done.stderr, done.stderr


def test_a_model_on_another_urdf_than_its_fit_is_refused(default_experiments: dict, tmp_path: Path) -> None:
    """Φ is the fitted URDF's bodies: the model file keeps that URDF's sha256, and every command that reads the model
    refuses another one (a walkthrough edited the URDF after the fit: validate ran on it, silently another number)."""
    from dynid.config.robot_config import load_config

    urdf = tmp_path / "arm.urdf"
    urdf.write_bytes(load_config().urdf.read_bytes())
    _short_run(default_experiments).save(tmp_path / "run.npz")
    model = tmp_path / "m.json"
    done = dynid("fit", "--urdf", str(urdf), "--data", str(tmp_path / "run.npz"), "--out", str(model))
    assert done.returncode == 0, done.stderr
    assert json.loads(model.read_text())["robot"]["urdf_sha256"]
    validate = ("validate", "--model", str(model), "--data", str(tmp_path / "run.npz"))
    assert dynid(*validate).returncode == 0
    urdf.write_text(urdf.read_text().replace('<mass value="', '<mass value="1', 1))  # a link 10 to 20 kg heavier
    done = dynid(*validate)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert f"the model was fitted with the URDF {urdf}" in done.stderr and "is another file" in done.stderr
    done = dynid("export", "--model", str(model), "--out", str(tmp_path / "m.dcoef"))
    assert done.returncode == 2 and "is another file" in done.stderr and not (tmp_path / "m.dcoef").exists()
