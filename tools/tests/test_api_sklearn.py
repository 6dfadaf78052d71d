"""The Python API as scikit-learn users take it (a walkthrough of the API on real runs found each case below): a run
in memory fitted on a window of its file, set_params, clone, cross-validation over a list of runs, parameters of
numpy's types, a model loaded with its settings, a run without labels."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.model_selection import KFold, cross_val_score
from sklearn.utils.validation import check_is_fitted

import dynid
from dynid.io.dataset import Dataset


@pytest.fixture(scope="module")
def part(default_experiments: dict[str, Path]) -> dict:
    """The default identification run read in memory, its first 40 s fitted through the API, and saved."""
    whole = dynid.read_data(default_experiments["identification"])
    first = whole.slice(0, 40_000)
    model = dynid.DynamicsModel(blocks=5).fit(first)
    return {"whole": whole, "first": first, "model": model, "path": default_experiments["identification"]}


def test_a_run_in_memory_records_its_window(part: dict, tmp_path: Path) -> None:
    """A slice of a file fitted through the API was recorded as the whole file: the CLI then called a later window
    of it "in the fit", and the momentum detector refused to calibrate ("None was fitted on …")."""
    saved = tmp_path / "m.json"
    part["model"].save(saved)
    record = json.loads(saved.read_text())["data"][0]
    assert record["window"] == [float(part["first"].t[0]), float(part["first"].t[-1])]
    later = part["whole"].slice(60_000, 80_000)
    assert part["model"].validate(later)["fit_overlap"] == 0.0
    assert part["model"].validate(part["first"].slice(0, 10_000))["fit_overlap"] == 1.0
    detector = dynid.ContactDetector(dynid.load_model(saved), variant="momentum")
    assert np.isfinite(detector.decision_function(later)).mean() > 0.9  # calibrated on the recorded window


def test_set_params_drops_what_was_calibrated_with_the_old_ones(part: dict) -> None:
    model, later = part["model"], part["whole"].slice(60_000, 80_000)
    detector = dynid.ContactDetector(model).fit(part["whole"].slice(40_000, 60_000))
    before = detector._detector().threshold
    with pytest.warns(UserWarning, match=r"set_params dropped the calibration fit\(\) made on its runs: call fit\(\) again"):
        detector.set_params(alpha=0.9)  # its runs are not kept: said, not silently reverted (a walkthrough)
    fresh = dynid.ContactDetector(model, alpha=0.9)
    assert detector._detector().threshold == fresh._detector().threshold < before
    assert np.array_equal(detector.predict(later), fresh.predict(later))


def test_clone_keeps_the_fitted_model_and_the_detector_is_usable_unfitted(part: dict) -> None:
    detector = dynid.ContactDetector(part["model"], variant="paper")
    copy = clone(detector)
    assert copy.model is part["model"] and copy.get_params()["variant"] == "paper"
    check_is_fitted(detector)  # usable: its model is fitted
    later = part["whole"].slice(60_000, 62_000)
    assert np.array_equal(copy.predict(later), detector.predict(later))


def test_cross_validation_over_a_list_of_runs(part: dict) -> None:
    runs = [part["whole"].slice(k, k + 20_000) for k in range(0, 80_000, 20_000)]
    scores = cross_val_score(dynid.DynamicsModel(blocks=4), runs, cv=KFold(2), error_score="raise")
    assert scores.shape == (2,) and np.all((scores > 0.5) & (scores <= 1.0))
    # a list scored at once: its runs' outputs together
    model = part["model"]
    assert model.predict(runs[2:]).shape[0] == sum(r.n_samples for r in runs[2:])


def test_numpy_parameters_and_bad_data_are_plain(part: dict) -> None:
    model = dynid.DynamicsModel(blocks=np.int64(4), n_components=np.int64(20), alpha=np.float64(0.99))
    model._check_params()  # np.arange grids work
    with pytest.raises(dynid.InputError, match="alpha must be in"):
        dynid.DynamicsModel(alpha="0.9")._check_params()
    with pytest.raises(dynid.InputError, match="data must be a path, a Dataset .* not ndarray"):
        part["model"].predict(np.zeros((10, 3)))


def test_a_loaded_model_keeps_its_settings(part: dict, tmp_path: Path) -> None:
    saved = tmp_path / "c.json"
    dynid.DynamicsModel(consistent=True, blocks=5).fit(part["first"]).save(saved)
    params = dynid.load_model(saved).get_params()
    assert params["consistent"] is True and params["cad_pull"] is False and params["blocks"] == 5


def test_evaluate_without_labels_says_its_tpr_is_unknown(part: dict) -> None:
    later = part["whole"].slice(60_000, 62_000)
    unlabelled = Dataset(t=later.t, joints=later.joints, q=later.q, pwm=later.pwm, ft=later.ft, meta=later.meta)
    result = dynid.ContactDetector(part["model"]).evaluate(unlabelled)
    assert result["tpr"] is None and 0.0 <= result["fpr"] <= 1.0


def test_a_walkthroughs_api_mistakes_are_one_clear_error(part: dict) -> None:
    """A user's mistakes through the API (a Panda walkthrough): each one InputError, not a TypeError from pathlib or
    numpy, a ZeroDivisionError, an array taken as a file name, or a `y` silently ignored."""
    model, run = part["model"], part["whole"].slice(40_000, 42_000)
    mistakes = [
        (lambda: dynid.read_data(np.zeros((10, 7))), "data must be a path or a Dataset, not ndarray"),
        (lambda: dynid.DynamicsModel().fit([np.zeros((10, 7))]), "data must be paths or Datasets"),
        (lambda: dynid.ContactDetector(model, alpha="0.99").predict(run), "alpha must be None or in"),
        (lambda: dynid.ContactDetector(model, bandwidth_hz=0).predict(run), "bandwidth_hz must be a positive"),
        (lambda: dynid.ContactDetector(model).score(run, np.zeros(10)), "y has 10 samples, the run 2000"),
        (lambda: model.score(run, np.zeros((2000, 10))), "y is not used"),
    ]
    for call, words in mistakes:
        with pytest.raises(dynid.InputError, match=words):
            call()


def test_a_contact_free_runs_score_is_its_specificity(part: dict) -> None:
    """On a run without contact, balanced accuracy is 1 − FPR (scikit-learn's over the classes present): it was
    (0 + 1 − FPR) / 2, a perfect detector scoring 0.5."""
    detector = dynid.ContactDetector(part["model"])
    run = part["whole"].slice(40_000, 42_000)
    hit = detector.predict(run)
    assert detector.score(run, np.zeros(run.n_samples)) == pytest.approx(1.0 - hit.mean())


def test_a_loaded_models_params_clone_and_refit(part: dict, tmp_path) -> None:
    """After load, `robot` is the bundled name it was given (it was the configuration's file path), and a gaps model
    clones into a fittable estimator (its estimator was 'gaps', which fit refused)."""
    part["model"].save(tmp_path / "m.json")
    loaded = dynid.load_model(tmp_path / "m.json")
    assert loaded.get_params()["robot"] == part["model"].get_params()["robot"]
    augmented = dynid.find_gaps(part["whole"].slice(0, 20_000), model=part["model"]).augmented_model()
    assert augmented.get_params()["estimator"] in ("iv", "ols", "pls")
    assert clone(augmented).get_params()["estimator"] == augmented.get_params()["estimator"]
