"""Decisions that must not hang on the last bit of the BLAS (issue 29, dynid.margins).

Each test runs a command on a run and on the same run with every measured channel multiplied by 1 + 1e-12·N(0, 1)
(far below any sensor's resolution, near what another CPU's kernels change), and asserts the same decisions: the
rank, the determined combinations, the IV iteration settled or not, PLS's ν, the gap workflow's named, tentative and
refused effects, the episodes a detector finds. The numbers behind them may move at 1e-9; the decisions may not.
The whole `numerics` marker also runs under a second OpenBLAS core type in scripts/test.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid

from dynid.io.dataset import Dataset
from dynid.margins import borderline, borderline_log

pytestmark = pytest.mark.numerics

RELATIVE = 1e-12


def perturbed(run: Path, out: Path, seed: int = 1) -> Path:
    """The run's dataset with every measured channel (q, inputs, torques, wrenches) multiplied by 1 + 1e-12·N(0, 1)."""
    ds = Dataset.load(run / "dataset.npz" if run.is_dir() else run)
    rng = np.random.default_rng(seed)

    def nudge(x: np.ndarray) -> np.ndarray:
        return x * (1 + RELATIVE * rng.standard_normal(x.shape))

    ds.q = nudge(ds.q)
    for family in ("pwm", "current", "tau", "ft"):
        setattr(ds, family, {k: nudge(v) for k, v in getattr(ds, family).items()})
    ds.save(out)
    return out


def run_json(*args: str, out: Path) -> dict:
    done = dynid(*args, "--json", str(out))
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


def fit_decisions(result: dict) -> dict:
    """The fit's decisions, each combination named by the parameter that represents it (its printed form carries
    coefficients to six digits, which may move in the sixth)."""
    base = result["base"]
    return {"rank": result["rank"], "independent": base["independent"], "n_components": result["n_components"],
            "determined": [n for n, ok in zip(base["independent"], base["identified"]) if ok],
            "borderline": len(result["borderline"]["determined"]), "iv_borderline": result["borderline"]["iv_settled"]}


def gap_decisions(result: dict) -> dict:
    return {"effects": [(e["name"], e["where"], e["confident"], e["in_model"]) for e in result["effects"]],
            "refused": [r["effect"] for r in result["refused"]],
            "not_significant": (result["not_significant"] or {}).get("effect")}


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("margins") / "run"
    done = dynid("simulate", "--kind", "identification", "--duration", "20", "--seed", "3", "--out", str(out))
    assert done.returncode == 0, done.stderr
    return out


def test_the_margin_helpers() -> None:
    assert borderline(0.2001, 0.2) and not borderline(0.21, 0.2) and not borderline(float("nan"), 0.2)
    assert borderline_log(1.0005e-4, 1e-4) and not borderline_log(2e-4, 1e-4) and not borderline_log(0.0, 1e-4)


def test_fit_decisions_survive_a_perturbation_at_the_last_bits(short_run: Path, tmp_path: Path) -> None:
    base = run_json("fit", "--data", str(short_run), "--out", str(tmp_path / "a.json"), out=tmp_path / "a.fit.json")
    other = run_json("fit", "--data", str(perturbed(short_run, tmp_path / "p.npz")), "--out", str(tmp_path / "b.json"),
                     out=tmp_path / "b.fit.json")
    assert fit_decisions(other) == fit_decisions(base)
    assert base["identified"] > 0 and base["rank"] > 0
    for name, threshold in base["thresholds"].items():  # calibrated thresholds: values, not decisions
        assert other["thresholds"][name] == pytest.approx(threshold, rel=1e-6), name


@pytest.mark.parametrize("estimator", ["iv", "ols"])
def test_a_run_too_short_for_its_rank_decides_the_same(estimator: str, tmp_path: Path) -> None:
    """0.6 s for a rank near 77: the plain IV iteration fell into a cycle on one CPU's rounding and reached a fixed
    point on another's, and one jackknife fold's iteration never settles (the fit succeeded on one CPU and failed on
    another). IV now refuses it everywhere, saying why; OLS fits it, with the same decisions."""
    run = tmp_path / "run"
    assert dynid("simulate", "--kind", "identification", "--duration", "0.6", "--out", str(run)).returncode == 0
    outcomes = []
    for k, data in enumerate((run, perturbed(run, tmp_path / "p.npz"), perturbed(run, tmp_path / "q.npz", seed=2))):
        done = dynid("fit", "--data", str(data), "--estimator", estimator, "--blocks", "1000",
                     "--out", str(tmp_path / f"m{k}.json"), "--json", str(tmp_path / f"f{k}.json"))
        outcomes.append((done.returncode, "did not settle" in done.stderr,
                         fit_decisions(json.loads((tmp_path / f"f{k}.json").read_text())) if done.returncode == 0 else None))
    assert outcomes[1] == outcomes[0] and outcomes[2] == outcomes[0], outcomes
    assert outcomes[0][:2] == ((2, True) if estimator == "iv" else (0, False)), outcomes[0]


def test_gap_decisions_survive_a_perturbation_at_the_last_bits(hidden_effects_runs: dict, default_model: Path,
                                                               tmp_path: Path) -> None:
    """The run of issue 29's report: a Stribeck (elbow) and a spring (shoulder yaw) named on every core type, and the
    armature that comes out tentative beside them stays out of the model file."""
    run = hidden_effects_runs["fit"]
    base = run_json("gaps", "--model", str(default_model), "--data", str(run), out=tmp_path / "a.json")
    other = run_json("gaps", "--model", str(default_model), "--data", str(perturbed(run, tmp_path / "p.npz")),
                     out=tmp_path / "b.json")
    assert gap_decisions(other) == gap_decisions(base)
    named = {(e["name"], e["where"]) for e in base["effects"] if e["confident"]}
    assert named == {("stribeck", "joint r_elbow"), ("spring", "joint r_shoulder_yaw")}
    assert all(e["in_model"] == e["confident"] for e in base["effects"])


def test_detection_decisions_survive_a_perturbation_at_the_last_bits(default_model: Path, tmp_path: Path) -> None:
    run = tmp_path / "contact"
    assert dynid("simulate", "--kind", "contact", "--duration", "30", "--seed", "4", "--out", str(run)).returncode == 0
    args = ("detect", "--model", str(default_model), "--residual", "acceleration")
    base = run_json(*args, "--data", str(run), out=tmp_path / "a.json")
    other = run_json(*args, "--data", str(perturbed(run, tmp_path / "p.npz")), out=tmp_path / "b.json")
    n = 30_000
    for name, variant in base["variants"].items():
        again = other["variants"][name]
        assert again["episodes_detected"] == variant["episodes_detected"], name
        assert again["threshold"] == pytest.approx(variant["threshold"], rel=1e-9), name
        # a sample whose T² sits within rounding of T²_α may count on one side or the other: a handful, not more
        assert abs(again["fpr"] - variant["fpr"]) * n <= 3 and abs(again["tpr"] - variant["tpr"]) * n <= 3, name
