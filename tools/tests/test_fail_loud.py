"""Nonsense is refused in one line, never fitted, run or scored quietly (issue 31).

- A motionless run (one row repeated) used to fit with exit 0, rank 7 and negative residual variances, export, and
  drive the monitor into a contact that never ended (T² 1.7e21).
- A model file with a zero motor gain ended `validate`, `detect` and `export` in a traceback; a body mass of 1e308
  passed with NaN thresholds; a detector threshold of −1 scored 100 % false positives with exit 0.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from conftest import dynid


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
