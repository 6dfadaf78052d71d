"""`dynid fit`, `validate` and `detect` on the plant's default experiments, against the plant's truth.

The fit runs once per session (the `default_model` fixture, through the command line as scripts/main runs it);
every figure asserted here is printed by the commands and listed in the README.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid

from dynid.config.robot_config import load_config
from dynid.identify.model_file import load_model
from dynid.io.load import load_data


def truth_of(run: Path) -> dict:
    return json.loads((run / "truth.json").read_text())


def run_json(tmp_path: Path, *args: str) -> dict:
    out = tmp_path / "result.json"
    done = dynid(*args, "--json", str(out))
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


def test_model_file_holds_what_the_monitor_and_the_user_need(default_model: Path, default_experiments) -> None:
    model = load_model(default_model)
    assert set(model.estimators) == {"iv", "pls", "ols"} and model.estimator == "iv"
    assert model.consistent is None  # --consistent off, the default (docs/consistency.md#default)
    assert model.base.rank == 87 and 1 <= model.n_components <= 87
    assert len(model.cv["press"]) == len(model.cv["candidates"])
    assert np.argmin(model.cv["press"]) + 1 == model.n_components
    assert model.output_channels[:6] == [f"ft.r_arm_ft.{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz")]
    assert all(v > 0 for v in model.residual_variance)
    data = model.data[0]
    assert data.samples == 300_000 and len(data.sha256) == 64
    # Parameters by name reproduce the stored base values through the stored combinations.
    assert np.allclose(model.base_values(model.parameters), model.base.values, rtol=1e-9, atol=1e-12)
    # The typed model writes back the file it was read from, section for section.
    assert model.to_json() == json.loads(Path(default_model).read_text())


def test_iv_recovers_the_motor_gains_in_closed_loop_and_ols_does_not(default_model: Path, default_experiments) -> None:
    truth = truth_of(default_experiments["identification"])["parameters"]
    model = load_model(default_model)
    names = model.base.independent
    for est, bound in (("iv", 0.03), ("ols", None)):
        values = dict(zip(names, model.estimators[est].values))
        for motor in ("m0", "m1", "m2", "m3"):
            rel = values[f"{motor}.phi_m"] / truth[f"{motor}.phi_m"] - 1
            if bound is not None:
                assert abs(rel) <= bound, (est, motor, rel)
            elif motor != "m3":  # the shoulder: the closed-loop bias the issue describes (measured −9…−11 %)
                assert rel < -0.05, (est, motor, rel)


def test_friction_where_identified_is_within_ten_percent(default_model: Path, default_experiments) -> None:
    """Every friction combination the run determines (standard error ≤ 10 %) is within 10 % of the truth; the
    ones it flags as undetermined are the ones that are off (the flag is honest)."""
    truth = truth_of(default_experiments["identification"])["parameters"]
    model = load_model(default_model)
    base = model.base
    true_beta = model.base_values(truth)
    friction = [i for i, n in enumerate(base.independent) if ".fc_" in n or ".fv_" in n]
    identified = [i for i in friction if base.identified[i]]
    assert len(identified) >= 12
    rel = np.abs(base.values / true_beta - 1)
    assert rel[identified].max() <= 0.10
    errors = np.abs(base.values - true_beta)
    se = base.standard_errors
    assert np.mean(errors[friction] <= 3 * se[friction]) >= 0.9  # the standard errors are honest too


def test_table_ii_identified_beats_cad(default_model: Path, default_experiments, tmp_path: Path) -> None:
    result = run_json(tmp_path, "validate", "--model", str(default_model), "--data", str(default_experiments["validation"]))
    table = result["table_ii"]
    assert table["identified"]["force"]["mean"] <= 0.7 * table["cad"]["force"]["mean"]  # measured 0.21×
    assert table["identified"]["torque"]["mean"] <= 0.7 * table["cad"]["torque"]["mean"]
    for name, ch in result["channels"].items():
        if name.startswith("ft."):
            assert ch["ratio_to_noise"] <= 1.2, name  # measured 0.32…1.11×
        else:
            assert ch["cad"] is None  # a CAD model has no gains: its PWM prediction is undefined


def test_detect_says_when_the_data_do_not_fit_the_model(default_model: Path, default_experiments, tmp_path: Path) -> None:
    # The validation run with its F/T sensor's offset moved by 40 N (a re-mounted sensor): contact-free, yet every
    # detector is above its level nearly everywhere. That is a model that does not fit, not contact.
    config = load_config("icub_right_arm")
    data = load_data(default_experiments["validation"], config).slice(0, 20000)
    data.ft["r_arm_ft"][:, 0] += 40.0
    data.save(tmp_path / "moved.npz")
    out = tmp_path / "d.json"
    done = dynid("detect", "--model", str(default_model), "--data", str(tmp_path / "moved.npz"), "--json", str(out))
    assert done.returncode == 0, done.stderr
    assert "note: every detector is above its level" in done.stdout and json.loads(out.read_text())["data_misfit"]
    done = dynid("detect", "--model", str(default_model), "--data", str(default_experiments["validation"]) + "@0:20",
                 "--json", str(out))
    assert "do not fit the model" not in done.stdout and "data_misfit" not in json.loads(out.read_text())


def test_validate_on_a_contact_run_says_the_errors_include_the_contacts(default_model: Path, default_experiments,
                                                                         tmp_path: Path) -> None:
    out = tmp_path / "v.json"
    done = dynid("validate", "--model", str(default_model), "--data", str(default_experiments["contact"]) + "@20:40",
                 "--json", str(out))
    assert done.returncode == 0, done.stderr
    fraction = json.loads(out.read_text())["contact_fraction"]
    assert 0.05 < fraction < 0.95  # a window of the default contact run
    assert f"note: {100 * fraction:.1f} % of these samples are in contact" in done.stdout
    done = dynid("validate", "--model", str(default_model), "--data", str(default_experiments["validation"]) + "@0:20",
                 "--json", str(out))
    assert "in contact" not in done.stdout and "contact_fraction" not in json.loads(out.read_text())


def test_calibrated_threshold_keeps_its_promise(default_model: Path, default_experiments, tmp_path: Path) -> None:
    # --residual acceleration: these are the acceleration-based variants' promises (the observer's: test_momentum.py)
    free = run_json(tmp_path, "detect", "--model", str(default_model), "--data", str(default_experiments["validation"]),
                    "--residual", "acceleration")
    calibrated, paper = free["variants"]["calibrated"], free["variants"]["paper"]
    assert calibrated["fpr"] <= 0.02  # measured 1.4 % at α = 0.99
    # The paper's variant (diagonal Λ, F threshold) does not: heavy-tailed, autocorrelated PWM residuals.
    assert paper["fpr"] > 2 * (1 - 0.99)

    contact = run_json(tmp_path, "detect", "--model", str(default_model), "--data", str(default_experiments["contact"]),
                       "--residual", "acceleration")
    cal = contact["variants"]["calibrated"]
    assert cal["tpr_by_side"]["distal"] >= 0.99
    assert cal["fpr"] <= 0.02 and cal["auc"] > 0.85
    assert cal["delay_s"]["median"] is not None and cal["delay_s"]["median"] < 0.1
    # Every episode whose contact alone reaches T²_α (plant truth, dynid.detect.visibility) is found; the
    # others (a push through a joint axis, a resting joint) are below what any T² at this α sees (measured:
    # 22 of 28 visible, 22 found; the six below peak at 0–32 against T²_α 34.9).
    vis = contact["visibility"]
    print(f"visible episodes {vis['visible']} of {len(vis['episodes'])}, found {vis['visible_found']}")
    assert vis["visible"] >= 20 and vis["visible_found"] == vis["visible"]
    # The paper's variant, with the static-friction band at rest, reaches the paper's level on the contact run
    # (paper: TPR 67 %, FPR 6 %; measured 80.9 % / 4.55 %), though not its promise on contact-free data (above).
    paper = contact["variants"]["paper"]
    assert paper["tpr"] >= 0.67 and paper["fpr"] <= 0.06
    # A window of the contact run takes the plant truth's rows of its own samples (it ended in a broadcast
    # traceback: the whole run's truth against the window's samples)
    part = run_json(tmp_path, "detect", "--model", str(default_model), "--data",
                    f"{default_experiments['contact']}@2:18", "--residual", "acceleration")
    start = {round(e["start_s"], 6) for e in part["visibility"]["episodes"]}
    whole = {round(e["start_s"] - 2.0, 6) for e in vis["episodes"] if 2.0 <= e["start_s"] <= 18.0}
    assert start and start <= whole | {0.0}


def test_alpha_moves_the_calibrated_threshold(default_model: Path, default_experiments, tmp_path: Path) -> None:
    data = str(default_experiments["validation"])
    loose, strict = (run_json(tmp_path, "detect", "--model", str(default_model), "--data", data, "--alpha", alpha,
                              "--residual", "acceleration") for alpha in ("0.95", "0.999"))
    assert loose["variants"]["calibrated"]["fpr"] > strict["variants"]["calibrated"]["fpr"]
    assert loose["variants"]["calibrated"]["fpr"] <= 0.1 and strict["variants"]["calibrated"]["fpr"] <= 0.005


# ------------------------------------------------------------------------------------------------------------
# Bad input: exit 2 and one line


def csv_variant(src: Path, dst: Path, rows: int, drop: str | None = None) -> Path:
    with open(src, newline="") as f, open(dst, "w", newline="") as g:
        reader, writer = csv.reader(f), csv.writer(g)
        header = next(reader)
        keep = [i for i, h in enumerate(header) if drop is None or not h.startswith(drop)]
        writer.writerow([header[i] for i in keep])
        for k, row in enumerate(reader):
            if k >= rows:
                break
            writer.writerow([row[i] for i in keep])
    return dst


def refused(done, *words: str) -> None:
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert all(w in lines[0] for w in words), lines[0]


@pytest.mark.parametrize(("drop", "rows", "words"), [
    ("pwm.", 5000, ("pwm",)),
    ("ft.", 5000, ("ft",)),
    (None, 300, ("too few samples",)),
])
def test_fit_refuses_data_it_cannot_fit(default_experiments, tmp_path: Path, drop, rows, words) -> None:
    data = csv_variant(default_experiments["validation"] / "data.csv", tmp_path / "data.csv", rows, drop)
    refused(dynid("fit", "--data", str(data), "--out", str(tmp_path / "m.json")), *words)
    assert not (tmp_path / "m.json").exists()


def test_a_model_of_another_robot_is_refused(default_model: Path, default_experiments, tmp_path: Path) -> None:
    other = json.loads(default_model.read_text())
    panda = Path(load_config("panda").source)
    other["robot"] = {"name": "panda", "config_digest": "0" * 64, "config_source": str(panda),
                      "config_text": panda.read_text()}
    path = tmp_path / "panda_model.json"
    path.write_text(json.dumps(other))
    for cmd in ("validate", "detect"):
        refused(dynid(cmd, "--model", str(path), "--data", str(default_experiments["validation"])), "panda")


@pytest.mark.parametrize("content", ["", "{not json", '{"format": "something-else"}', '{"format": "dynid-model", '
                                     '"format_version": 99}'])
def test_a_corrupt_model_file_is_refused(default_experiments, tmp_path: Path, content: str) -> None:
    path = tmp_path / "model.json"
    path.write_text(content)
    refused(dynid("validate", "--model", str(path), "--data", str(default_experiments["validation"])), "model")
