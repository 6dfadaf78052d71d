"""The Python API (dynid/__init__.py, dynid/api.py) against the command line it shares its code with."""

from __future__ import annotations

import json
import pydoc
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

import dynid
from dynid.robot.outputs import measured_outputs
from dynid.robot.regressors.stack import signals_from_dataset

DYNID = Path(sys.executable).with_name("dynid")


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(DYNID), *args], capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def runs(default_experiments: dict[str, Path]) -> Path:
    """The session's default runs (conftest): DIR/identification, DIR/contact."""
    root = default_experiments["identification"].parent
    assert default_experiments["contact"] == root / "contact"
    return root


@pytest.fixture(scope="module")
def fitted(runs: Path) -> dynid.DynamicsModel:
    return dynid.DynamicsModel().fit(str(runs / "identification"))


def test_help_shows_the_api() -> None:
    text = pydoc.render_doc(dynid, renderer=pydoc.plaintext)
    for name in ("DynamicsModel", "ContactDetector", "export_coefficients", "find_gaps", "load_robot", "read_data"):
        assert name in text
    assert set(dynid.__all__) <= set(dir(dynid))


def test_the_api_loads_lazily() -> None:
    code = "import sys, dynid.cli; print('dynid.api' in sys.modules, 'sklearn' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120).stdout.split()
    assert out == ["False", "False"]


def test_parameters_are_checked_at_fit_and_clone_keeps_them(runs: Path) -> None:
    model = dynid.DynamicsModel(estimator="lasso")
    assert clone(model).get_params()["estimator"] == "lasso"  # scikit-learn's contract: no check in __init__
    with pytest.raises(dynid.InputError, match="estimator must be one of"):
        model.fit(str(runs / "identification"))
    with pytest.raises(dynid.InputError, match="alpha"):
        dynid.DynamicsModel(alpha=1.5).fit(str(runs / "identification"))
    with pytest.raises(dynid.InputError, match="consistent must be None, True, False or 'pseudo-inertia', got 'psd'"):
        dynid.DynamicsModel(consistent="psd").fit(str(runs / "identification"))
    with pytest.raises(dynid.InputError, match="cad_pull weighs the CAD prior of the physically consistent fit"):
        dynid.DynamicsModel(cad_pull=True).fit(str(runs / "identification"))
    with pytest.raises(NotFittedError):
        dynid.DynamicsModel().predict(str(runs / "contact"))


def test_the_api_fit_is_the_cli_fit(fitted: dynid.DynamicsModel, default_model: Path) -> None:
    cli = json.loads(default_model.read_text())  # `dynid fit` on the same run (conftest)
    assert cli["parameters"] == fitted.parameters_
    assert cli["detector"] == fitted.model_.to_json()["detector"]
    assert fitted.rank_ == cli["base"]["rank"] and fitted.rank_ > 0


def test_predict_score_and_the_saved_model(runs: Path, fitted: dynid.DynamicsModel, tmp_path: Path) -> None:
    data = dynid.read_data(str(runs / "contact"))
    y_hat = fitted.predict(data)
    assert y_hat.shape == (data.n_samples, len(fitted.output_channels_))
    # ŷ + e is the measurement: the outputs of the run's signals, filtered as the fit filters them.
    robot = fitted.model_.robot_model
    y = measured_outputs(robot, signals_from_dataset(robot, data, filter_outputs=True))
    assert np.allclose(y_hat + fitted.residuals(data), y)
    r2 = fitted.score(str(runs / "identification"))
    assert 0.9 < r2 <= 1.0  # the F/T and the PWMs are predicted well on the data it was fitted on
    fitted.save(tmp_path / "m.json")
    loaded = dynid.load_model(tmp_path / "m.json")
    assert loaded.get_params()["estimator"] == "iv"
    assert np.array_equal(loaded.predict(data), y_hat)


def test_the_detector_and_the_cli_agree(runs: Path, fitted: dynid.DynamicsModel, tmp_path: Path) -> None:
    fitted.save(tmp_path / "m.json")
    detector = dynid.ContactDetector(dynid.load_model(tmp_path / "m.json"))
    api = detector.evaluate(str(runs / "contact"))
    done = run("detect", "--model", str(tmp_path / "m.json"), "--data", str(runs / "contact"), "--json", "-")
    cli = json.loads(done.stdout)["variants"]["combined"]  # the default of both
    assert api["tpr"] == cli["tpr"] and api["fpr"] == cli["fpr"]
    hit = detector.predict(str(runs / "contact"))
    contact = dynid.read_data(str(runs / "contact")).contact != 0
    assert hit[contact].mean() == pytest.approx(cli["tpr"])
    assert 0.5 < detector.score(str(runs / "contact")) <= 1.0
    # Recalibrated on the identification run itself: α keeps its promise there.
    refit = dynid.ContactDetector(fitted).fit(str(runs / "identification"))
    assert refit.detector_.threshold > 0


def test_export_coefficients_writes_what_the_monitor_loads(fitted: dynid.DynamicsModel, tmp_path: Path) -> None:
    out = dynid.export_coefficients(fitted, tmp_path / "m.dcoef")
    assert out.size == (tmp_path / "m.dcoef").stat().st_size > 0
    done = run("export", "--print", str(tmp_path / "m.dcoef"), "--json", "-")
    assert done.returncode == 0 and json.loads(done.stdout)["robot"] == "icub_right_arm"


def test_find_gaps_is_the_workflow_of_dynid_gaps(runs: Path, fitted: dynid.DynamicsModel) -> None:
    """Against the model fitted on the same run, the gap workflow names nothing it cannot defend: the control."""
    gaps = dynid.find_gaps(str(runs / "identification"), model=fitted)
    result = gaps.result
    assert result["data"] == str(runs / "identification") and result["given_model"] is not None
    assert {g["channel"] for g in result["gap"]} == set(fitted.output_channels_)
    assert all(np.isfinite(g["before_rms"]) and np.isfinite(g["after_rms"]) for g in result["gap"])
    augmented = gaps.augmented_model()  # a fitted DynamicsModel, as fit's (it was the file's IdentifiedModel)
    assert isinstance(augmented, dynid.DynamicsModel)
    assert [e.kind for e in augmented.model_.named_effects] == [e.kind for e in gaps.effects]
    assert augmented.model_.detector.calibrated.threshold > 0
