"""Supply tracking (dynid.identify.supply): the recurrence on synthetic inputs with a known supply, its two update rules,
continuation across chunks, and on the default simulated runs against the plant's recorded supply."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid
from test_identification import run_json

from dynid.config.robot_config import load_config
from dynid.errors import InputError
from dynid.identify.supply import SupplyTracker, SupplyTracking, smoothed_residuals
from dynid.robot.model import RobotModel
from dynid.robot.outputs import output_channels
from dynid.robot.regressors.stack import Signals


@pytest.fixture(scope="module")
def arm() -> RobotModel:
    return RobotModel(load_config("icub_right_arm"))


def synthetic(model: RobotModel, supply: np.ndarray, moving: bool = True, seed: int = 0):
    """(e, signals, t): every motor predicts ŷ = 0.2 sin(…) and measures y = ŷ / s + noise, every joint and
    motor moving (or all at rest); the other channels' residuals are zero."""
    n = supply.shape[0]
    t = np.arange(n) * 1e-3
    rng = np.random.default_rng(seed)
    outs = output_channels(model)
    e = np.zeros((n, len(outs)))
    inputs = {}
    for o in outs:
        if o.kind != "input":
            continue
        predicted = 0.2 * np.sin(2 * np.pi * 0.5 * t + o.row)
        inputs[o.motor] = predicted / supply + rng.normal(0.0, o.sigma, n)
        e[:, o.row] = inputs[o.motor] - predicted  # the residual with constant gains
    J = len(model.config.joints)
    dq = np.tile(0.3 * (1.0 + np.arange(J)), (n, 1)) * (1.0 if moving else 0.0)  # no motor's T q̇ cancels
    sig = Signals(np.zeros((n, J)), dq, np.zeros((n, J)), inputs, {}, {})
    return e, sig, t


def input_rows(model: RobotModel) -> list[int]:
    return [o.row for o in output_channels(model) if o.kind == "input"]


def test_tracker_follows_a_supply_step_and_removes_its_residual(arm: RobotModel) -> None:
    supply = np.where(np.arange(20_000) < 5000, 1.0, 0.95)  # a 5 % sag at 5 s
    e, sig, t = synthetic(arm, supply)
    tracked, ratio = SupplyTracker(arm, SupplyTracking(time_constant_s=1.0), 0.01).apply(e, sig, t)
    rows = input_rows(arm)
    # Five time constants after the step the ratio is 1/s to within the noise's share.
    np.testing.assert_allclose(ratio[-1, rows], 1 / 0.95, rtol=2e-3)
    np.testing.assert_allclose(ratio[4000, rows], 1.0, rtol=2e-3)
    sigma = np.array([o.sigma for o in output_channels(arm)])[rows]
    late = slice(12_000, None)
    before = np.sqrt(np.mean(e[late][:, rows] ** 2, axis=0)) / sigma
    after = np.sqrt(np.mean(tracked[late][:, rows] ** 2, axis=0)) / sigma
    assert np.all(before > 2.5) and np.all(after < 1.1), (before, after)


def test_gate_and_rest_keep_the_estimate(arm: RobotModel) -> None:
    """A residual beyond the gate (a contact) and rows at rest leave r where it was."""
    supply = np.ones(6000)
    e, sig, t = synthetic(arm, supply)
    rows = input_rows(arm)
    settings = SupplyTracking(time_constant_s=0.5)
    bumped = e.copy()
    bumped[3000:4000, rows] += 0.05  # 25 noise stds for one second
    contact = np.where((t >= 3.0) & (t < 4.0), 0.05, 0.0)
    for m in sig.inputs:
        sig.inputs[m] = sig.inputs[m] + contact
    _, ratio = SupplyTracker(arm, settings, 0.01).apply(bumped, sig, t)
    np.testing.assert_allclose(ratio[1000:, rows], 1.0, atol=5e-3)  # the noise's share once started
    # Without the gate the same bump moves the estimate well away.
    _, loose = SupplyTracker(arm, SupplyTracking(time_constant_s=0.5, gate=1e3), 0.01).apply(bumped, sig, t)
    assert np.max(np.abs(loose[:, rows] - 1.0)) > 0.05

    e, sig, t = synthetic(arm, np.full(4000, 0.9), moving=False)
    tracked, ratio = SupplyTracker(arm, settings, 0.01).apply(e, sig, t)
    assert np.all(ratio[:, rows] == 1.0) and np.array_equal(tracked, e)


def test_chunks_continue_the_same_recurrence(arm: RobotModel) -> None:
    supply = 1.0 + 0.03 * np.sin(np.linspace(0, 6, 9000))
    e, sig, t = synthetic(arm, supply)
    settings = SupplyTracking()
    whole = SupplyTracker(arm, settings, 0.01).apply(e, sig, t)[0]
    tracker = SupplyTracker(arm, settings, 0.01)
    parts = [tracker.apply(e[a:b], sig.slice(slice(a, b)), t[a:b])[0] for a, b in ((0, 2500), (2500, 2501), (2501, 9000))]
    np.testing.assert_array_equal(np.vstack(parts), whole)


def test_two_sided_estimate_has_no_lag_on_a_ramp(arm: RobotModel) -> None:
    """Offline, the forward and backward passes' lags cancel on a supply that drifts linearly: the residual is at
    the noise where the causal tracker, with the same time constant, trails the ramp."""
    supply = np.linspace(1.0, 0.88, 8000)  # −12 % over 8 s: a sagging bus
    e, sig, t = synthetic(arm, supply)
    settings = SupplyTracking(time_constant_s=1.0, offline_time_constant_s=1.0)
    causal = SupplyTracker(arm, settings, 0.01).apply(e, sig, t)[0]
    offline = smoothed_residuals(arm, settings, 0.01, e, sig, t)
    rows = input_rows(arm)
    sigma = np.array([o.sigma for o in output_channels(arm)])[rows]
    middle = slice(2000, 6000)
    lagging = np.sqrt(np.mean(causal[middle][:, rows] ** 2, axis=0)) / sigma
    centred = np.sqrt(np.mean(offline[middle][:, rows] ** 2, axis=0)) / sigma
    print(f"ramp: causal {np.round(lagging, 2)}, two-sided {np.round(centred, 2)} × noise")
    assert np.all(centred < 1.05) and np.all(lagging > 1.2 * centred)
    assert smoothed_residuals(arm, None, 0.01, e, sig, t) is e


def test_no_drive_keeps_the_identified_gain(arm: RobotModel) -> None:
    """A motor that predicts and measures no input gives the estimate nothing: the prior r = 1 holds."""
    e, sig, t = synthetic(arm, np.full(3000, 0.9))
    idle = Signals(sig.q, sig.dq, sig.ddq, {m: np.zeros(3000) for m in sig.inputs}, {}, {})
    _, ratio = SupplyTracker(arm, SupplyTracking(), 0.01).apply(np.zeros_like(e), idle, t)
    assert np.all(ratio[:, input_rows(arm)] == 1.0)


@pytest.mark.parametrize("field,value", [("time_constant_s", 0.0), ("gate", -1.0), ("prior_input", float("nan")),
                                         ("offline_time_constant_s", float("inf"))])
def test_bad_settings_are_refused(field: str, value: float) -> None:
    with pytest.raises(InputError, match=field):
        SupplyTracking(**{field: value})


def test_on_the_default_runs_the_tracker_follows_the_plant_supply(default_model: Path, default_experiments) -> None:
    """The plant records the supply it applied (truth): on the 300 s identification run, 1/r must follow it and
    take out most of its variation (measured: correlation 0.89–0.93, what is left 0.38–0.48× the supply's std;
    on the 120 s validation run 0.74–0.87 and 0.50–0.67×)."""
    from dynid.identify.validation import evaluate

    # (run, least correlation, most left): the shorter validation run has less motion per supply excursion
    for kind, min_corr, max_left in (("identification", 0.85, 0.55), ("validation", 0.7, 0.75)):
        run = default_experiments[kind]
        ev = evaluate(str(default_model), str(run))
        assert ev.identified.supply_tracking == SupplyTracking()
        _, ratio = SupplyTracker(ev.model, ev.identified.supply_tracking, ev.identified.min_speed).apply(
            ev.e_constant, ev.signals, ev.dataset.t)
        truth = np.load(Path(run) / "truth.npz")
        late = ev.dataset.t - ev.dataset.t[0] > 10.0  # after the tracker's start-up
        inputs = [o for o in ev.outputs if o.kind == "input"]
        assert len(inputs) == 4
        for o in inputs:
            supply, tracked = truth[f"extra/supply.{o.motor}"][late], 1.0 / ratio[late, o.row]
            corr = np.corrcoef(tracked, supply)[0, 1]
            left = np.std(tracked / tracked.mean() - supply / supply.mean()) / np.std(supply)
            print(f"{kind} {o.motor}: corr(1/r, supply) {corr:.3f}, left {left:.2f}× the supply's std")
            assert corr >= min_corr and left <= max_left, (kind, o.motor)


def test_validate_reports_moving_rows_with_and_without_tracking(default_model: Path, default_experiments, tmp_path: Path) -> None:
    result = run_json(tmp_path, "validate", "--model", str(default_model), "--data", str(default_experiments["validation"]))
    pwm = {name: ch for name, ch in result["channels"].items() if name.startswith("pwm.")}
    assert len(pwm) == 4
    for name, ch in pwm.items():
        print(f"{name}: moving rows {ch['ratio_to_noise_moving']:.2f}× (constant gains "
              f"{ch['ratio_to_noise_moving_constant_gains']:.2f}×)")
        assert ch["ratio_to_noise_moving"] < ch["ratio_to_noise_moving_constant_gains"]
        # Issue 4: ≤ 1.2× the injected noise (measured 1.15, 0.63, 0.26, 0.36×; constant gains 2.47, 2.49, 0.56, 0.72×).
        assert ch["ratio_to_noise_moving"] <= 1.2, name


def test_a_bad_supply_section_is_one_line_exit_2(default_model: Path, default_experiments, tmp_path: Path) -> None:
    record = json.loads(Path(default_model).read_text())
    record["supply_tracking"] = {"time_constant_s": -3.0, "gate": 3.0, "prior_input": 0.01}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(record))
    done = dynid("validate", "--model", str(bad), "--data", str(default_experiments["validation"]))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "supply_tracking" in lines[0] and "Traceback" not in done.stderr


def test_a_model_without_tracking_predicts_with_constant_gains(default_model: Path, default_experiments,
                                                               tmp_path: Path) -> None:
    """`dynid fit --supply-time-constant 0` writes `supply_tracking: null`: validate then reports the constant-gain
    residuals, and export writes a coefficient file with tracking off."""
    from dynid.export.coefficients import read_coefficients
    from dynid.identify.validation import evaluate

    record = json.loads(Path(default_model).read_text())
    record["supply_tracking"] = None
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps(record))
    ev = evaluate(str(plain), str(default_experiments["validation"]))
    assert ev.identified.supply_tracking is None and np.array_equal(ev.e, ev.e_constant)
    result = run_json(tmp_path, "validate", "--model", str(plain), "--data", str(default_experiments["validation"]))
    ch = result["channels"]["pwm.m0"]
    assert ch["ratio_to_noise_moving"] == ch["ratio_to_noise_moving_constant_gains"]
    done = dynid("export", "--model", str(plain), "--out", str(tmp_path / "plain.dcoef"))
    assert done.returncode == 0, done.stderr
    c = read_coefficients(tmp_path / "plain.dcoef")
    assert c.supply_time_constant == 0.0 and c.supply_prior == 0.0 and not any(c.supply_gate)


def test_fit_refuses_a_negative_time_constant(tmp_path: Path) -> None:
    done = dynid("fit", "--data", str(tmp_path), "--out", str(tmp_path / "m.json"), "--supply-time-constant", "-1")
    assert done.returncode == 2 and "--supply-time-constant" in done.stderr and "Traceback" not in done.stderr
