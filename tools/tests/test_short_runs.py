"""`dynid fit` on runs too short for every jackknife fold to see every base direction, through the command line.

A 20 s identification run (default seed 0) has a time block (4-6 s) without which the shoulder's Coulomb
friction is never seen in one of its sign patterns: that jackknife fold's system is singular in directions the
whole run determines (it ended in numpy's LinAlgError). The fit must still succeed and name those combinations as
not determined; a run too short to fit anything must end with one line and exit 2, leaving no model file. Only
the command line is used here (no `import dynid`).
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.numerics

DYNID = Path(sys.executable).parent / "dynid"


def dynid(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(DYNID), *args], capture_output=True, text=True, timeout=600)


def strict_json(path: Path) -> dict:
    """The JSON at `path`, refusing NaN and infinities (the model file and the result must be finite)."""

    def refuse(token: str) -> None:
        raise AssertionError(f"{path} holds {token}")

    return json.loads(path.read_text(), parse_constant=refuse)


def ok(done: subprocess.CompletedProcess) -> None:
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "Warning" not in done.stderr, done.stderr


def refused(done: subprocess.CompletedProcess, *words: str) -> None:
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("dynid fit: error: "), done.stderr
    assert all(w in lines[0] for w in words), lines[0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("short")
    out = {"identification": root / "id20", "validation": root / "val5"}
    ok(dynid("simulate", "--kind", "identification", "--duration", "20", "--out", str(out["identification"])))
    ok(dynid("simulate", "--kind", "validation", "--duration", "5", "--seed", "7", "--out", str(out["validation"])))
    return out


@pytest.fixture(scope="module")
def fitted(runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, str]:
    """(model file, fit JSON, human report) of `dynid fit` on the 20 s run."""
    root = tmp_path_factory.mktemp("fit")
    model, result = root / "m.json", root / "fit.json"
    done = dynid("fit", "--data", str(runs["identification"]), "--out", str(model), "--json", str(result))
    ok(done)
    return model, strict_json(result), done.stdout


def test_a_20_s_run_fits_and_names_what_a_fold_cannot_see(fitted) -> None:
    model, result, report = fitted
    assert model.is_file() and strict_json(model)["format"] == "dynid-model"
    assert 0 < result["identified"] < result["rank"]
    assert len(result["determined"]) == result["identified"]
    assert len(result["undetermined"]) == result["rank"] - result["identified"]
    # The singular fold is named, with the combinations it cannot see; each of them is listed as undetermined.
    jack = result["jackknife"]
    assert jack["folds"] == 10 and jack["rank_deficient"], jack
    for fold in jack["rank_deficient"]:
        assert fold["unseen"] and set(fold["unseen"]) <= set(result["undetermined"]), fold
        assert ".fc_" in " ".join(fold["unseen"])  # a joint's Coulomb friction seen one way in one block only
        assert f"time block left out: {fold['block']}" in report
    assert all(e > 0 for e in result["base"]["standard_errors"])


def test_the_short_run_model_validates_on_another_short_run(fitted, runs, tmp_path: Path) -> None:
    model, _, _ = fitted
    done = dynid("validate", "--model", str(model), "--data", str(runs["validation"]), "--json", str(tmp_path / "v.json"))
    ok(done)
    channels = strict_json(tmp_path / "v.json")["channels"]
    assert len(channels) == 10 and all(c["rms"] > 0 for c in channels.values())


def test_a_joint_that_never_moves_leaves_its_motor_unexcited_not_a_traceback(runs, tmp_path: Path) -> None:
    """The elbow held still for the whole run: its friction and its motor's gain see no row. The fit names them,
    keeps the nominal gain for that motor (its input must still be predicted) and the model validates."""
    data = tmp_path / "still_elbow.csv"
    with open(runs["identification"] / "data.csv", newline="") as f, open(data, "w", newline="") as g:
        reader, writer = csv.reader(f), csv.writer(g)
        header = next(reader)
        col = header.index("q.r_elbow")
        writer.writerow(header)
        first = None
        for row in reader:
            first = first or row[col]
            row[col] = first
            writer.writerow(row)
    model, result = tmp_path / "m.json", tmp_path / "fit.json"
    ok(dynid("fit", "--data", str(data), "--out", str(model), "--json", str(result)))
    fit = strict_json(result)
    assert {"m3.phi_m", "r_elbow.fc_pos", "r_elbow.fc_neg"} <= set(fit["unidentifiable"])
    assert strict_json(model)["parameters"]["m3.phi_m"] > 0  # the configured nominal gain
    ok(dynid("validate", "--model", str(model), "--data", str(runs["validation"])))


def test_a_tiny_run_is_refused_in_one_line_without_a_model(tmp_path: Path) -> None:
    run, model = tmp_path / "tiny", tmp_path / "m.json"
    ok(dynid("simulate", "--kind", "identification", "--duration", "0.3", "--out", str(run)))
    refused(dynid("fit", "--data", str(run), "--out", str(model)), "too few samples")
    assert not model.exists()


def test_blocks_beyond_what_the_samples_allow(runs, tmp_path: Path) -> None:
    """One block leaves no jackknife and no cross-validation: refused in one line. More blocks than 200-sample
    stretches: capped (0.6 s: 3 blocks), and every fold fitted."""
    model = tmp_path / "m.json"
    refused(dynid("fit", "--data", str(runs["validation"]), "--blocks", "1", "--out", str(model)), "--blocks 1")
    assert not model.exists()
    run = tmp_path / "short"
    ok(dynid("simulate", "--kind", "identification", "--duration", "0.6", "--out", str(run)))
    # 600 samples for a rank of 77: the IV iteration of a jackknife fold wanders (its steps end near 5 or 160,
    # depending on the CPU's rounding), so IV determines nothing here, on every CPU, and says why
    refused(dynid("fit", "--data", str(run), "--blocks", "1000", "--out", str(model)), "iv iteration did not settle")
    ols = ("--estimator", "ols")
    ok(dynid("fit", "--data", str(run), *ols, "--blocks", "1000", "--out", str(model), "--json", str(tmp_path / "fit.json")))
    result = strict_json(tmp_path / "fit.json")
    assert result["jackknife"]["folds"] == 3 and result["identified"] > 0
    # ν given: said as given, not as cross-validated (more than the rank is allowed: PLS then runs until Xᵀy is
    # exhausted, which floating point needs to reach least squares, test_estimators.py)
    done = dynid("fit", "--data", str(run), *ols, "--n-components", str(result["rank"] + 1), "--out", str(tmp_path / "n.json"))
    ok(done)
    assert f"the PLS estimate beside it with ν = {result['rank'] + 1} (--n-components)" in done.stdout, done.stdout
