"""The estimators against scikit-learn and against data the model explains exactly."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.cross_decomposition import PLSRegression

from dynid.config.robot_config import load_config
from dynid.identify.fit import FitSettings, fit
from dynid.identify.pls import NipalsPLS
from dynid.identify.regression import nipals_pls1, pls_path
from dynid.io.dataset import Dataset
from dynid.robot.model import RobotModel
from dynid.robot.outputs import output_channels, residuals
from dynid.robot.regressors.stack import Signals
from dynid.simulation import SimulationSettings, simulate

ICUB = load_config("icub_right_arm")
MODEL = RobotModel(ICUB)


def problem(seed: int = 0, n: int = 400, p: int = 9) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, p)) @ rng.normal(size=(p, p)) * rng.uniform(0.01, 100, p)  # mixed column scales
    return X, X @ rng.normal(size=p) + rng.normal(size=n)


@pytest.mark.parametrize("scale", [False, True])
@pytest.mark.parametrize("k", [1, 3, 9])
def test_nipals_equals_scikit_learn_where_the_problems_coincide(scale: bool, k: int) -> None:
    """scikit-learn always centres; on centred data the no-intercept PLS is the same estimator."""
    X, y = problem()
    Xc, yc = X - X.mean(axis=0), y - y.mean()
    ours = NipalsPLS(k, scale=scale).fit(Xc, yc)
    theirs = PLSRegression(n_components=k, scale=scale).fit(Xc, yc)
    assert np.allclose(ours.coef_, theirs.coef_.ravel(), rtol=1e-9, atol=1e-12 * np.abs(theirs.coef_).max())
    assert np.allclose(ours.predict(Xc), theirs.predict(Xc).ravel(), rtol=1e-9, atol=1e-9)
    # With center=True ours fits the intercept scikit-learn fits, on the raw data.
    centred = NipalsPLS(k, scale=scale, center=True).fit(X, y)
    raw = PLSRegression(n_components=k, scale=scale).fit(X, y)
    assert np.allclose(centred.predict(X), raw.predict(X).ravel(), rtol=1e-9, atol=1e-8)


def test_no_intercept_pls_is_not_scikit_learn_on_uncentred_data() -> None:
    """The reason for our own estimator: the stacked system's constant columns are parameters (F/T offsets)."""
    X, y = problem(1)
    X[:, 0] = 1.0  # a constant column, like an offset
    ours = NipalsPLS(9).fit(X, y)
    theirs = PLSRegression(n_components=9).fit(X, y)
    assert abs(ours.coef_[0] - theirs.coef_.ravel()[0]) > 0.1  # scikit-learn moved it into the intercept


def test_kernel_pls_from_the_gram_equals_nipals_on_the_stacked_data() -> None:
    X, y = problem(2)
    s = np.linalg.norm(X, axis=0)
    for k in (1, 4, 9):
        stacked = nipals_pls1(X / s, y, k).coefficients(k) / s
        assert np.allclose(pls_path(X.T @ X, X.T @ y, k)[k - 1], stacked, rtol=1e-9, atol=1e-12)
    # With every latent variable PLS is least squares.
    assert np.allclose(pls_path(X.T @ X, X.T @ y, 9)[-1], np.linalg.lstsq(X, y, rcond=None)[0], rtol=1e-8)


def _noise_free_run(kind: str, seconds: float, seed: int) -> tuple[Dataset, Signals, np.ndarray]:
    """A plant run without noise, quantisation or disturbance, seen with the integrator's own q̇ and q̈."""
    sim = simulate(ICUB, SimulationSettings(kind=kind, duration=seconds, noise=False, disturbance=False, seed=seed))
    truth = sim.truth_signals
    data = Dataset(t=truth.t, joints=truth.joints, q=truth.q, dq=truth.dq, ddq=truth.ddq, pwm=dict(sim.dataset.pwm),
                   ft=dict(sim.dataset.ft), meta={"robot": ICUB.name})
    sig = Signals(truth.q, truth.dq, truth.ddq, dict(sim.dataset.pwm), {}, dict(sim.dataset.ft))
    return data, sig, np.array([sim.truth["parameters"][n] for n in MODEL.layout.names])


def test_noise_free_plant_runs_validate_at_the_integration_error_level() -> None:
    """The plant's OWN PWMs (its implicit-friction Euler step leaves 1e-6 duty of integration error, and joints
    stick): the fit generalises to a validation run as well as the true parameters do. Measured: validation PWM
    residual 1.17–1.56× the truth's (1e-6…5e-6 duty; noise std 2e-3), F/T 3e-7 N, 3e-6 Nm; gains within 5e-5,
    combinations median 6e-5 (max 2.7e-3, a weakly excited one): 1e-6 needs the model-consistent inputs below."""
    from dynid.robot.regressors.stack import rows_at_rest

    data, _, phi_true = _noise_free_run("identification", 40.0, seed=4)
    _, validation, _ = _noise_free_run("validation", 20.0, seed=5)
    result = fit(MODEL, [data], FitSettings(blocks=4, workers=1))
    rest = rows_at_rest(MODEL, validation.dq)  # static friction holds what the model cannot say

    def rms(phi: np.ndarray) -> np.ndarray:
        return np.sqrt(np.nanmean(np.where(rest, np.nan, residuals(MODEL, phi, validation)) ** 2, axis=0))

    identified, integration_error = rms(result.phi), rms(phi_true)
    sigma = np.array([o.sigma for o in output_channels(MODEL)])
    motors = [o.row for o in output_channels(MODEL) if o.motor]
    gains = [MODEL.layout.index(f"{m}.phi_m") for m in ICUB.motor_names]
    beta_true = result.base.base(phi_true)
    scale = np.maximum(np.abs(beta_true), 1e-3 * np.abs(beta_true).max())
    rel = np.abs(result.estimates[result.chosen].beta - beta_true) / scale
    print(f"noise-free plant run: validation PWM residual {np.round(identified[motors] / integration_error[motors], 2)}"
          f"× the true Φ's ({identified[motors].min():.2g}…{identified[motors].max():.2g} duty); every channel ≤ "
          f"{100 * (identified / sigma).max():.2f} % of its noise std; gains within "
          f"{np.abs(result.phi[gains] / phi_true[gains] - 1).max():.1e}; combinations median {np.median(rel):.1e}, "
          f"max {rel.max():.1e}")
    assert np.all(identified[motors] <= 2.0 * integration_error[motors])
    assert np.all(identified <= 5e-3 * sigma)  # every channel under 0.5 % of its noise std (measured ≤ 0.26 %)
    assert np.allclose(result.phi[gains], phi_true[gains], rtol=2e-4)
    assert np.median(rel) < 5e-4


def test_model_consistent_data_are_recovered_exactly() -> None:
    """On data the model explains exactly (the plant's noise-free trajectory, the integrator's q̇ and q̈, inputs
    solved from the motor equations with the true Φ), every estimator recovers every identifiable combination
    and every motor gain to 1e-6 relative. The plant's own PWMs differ from these by its integration error (the
    simulation tests bound it); this isolates the estimators' algebra."""
    sim = simulate(ICUB, SimulationSettings(duration=20.0, noise=False, seed=4))
    truth = sim.truth_signals
    phi = np.array([sim.truth["parameters"][n] for n in MODEL.layout.names])
    sig = Signals(truth.q, truth.dq, truth.ddq, dict(sim.dataset.pwm), {}, dict(sim.dataset.ft))
    e = residuals(MODEL, phi, sig)
    pwm = {o.motor: sim.dataset.pwm[o.motor] - e[:, o.row] for o in output_channels(MODEL) if o.motor}
    data = Dataset(t=truth.t, joints=truth.joints, q=truth.q, dq=truth.dq, ddq=truth.ddq, pwm=pwm,
                   ft=dict(sim.dataset.ft), meta={"robot": ICUB.name})
    result = fit(MODEL, [data], FitSettings(blocks=4, workers=1))
    beta_true = result.base.base(phi)
    scale = np.maximum(np.abs(beta_true), 1e-3 * np.abs(beta_true).max())
    for name, est in result.estimates.items():
        print(f"model-consistent data, {name}: max relative error {np.max(np.abs(est.beta - beta_true) / scale):.1e}")
        if name == "pls":
            continue  # ν ≤ rank latent variables shrink (on purpose, or by rounding): full PLS is checked below
        assert np.max(np.abs(est.beta - beta_true) / scale) < 1e-6, name
    # With every latent variable PLS is least squares. ν = rank is enough in exact arithmetic; in floating point
    # the Krylov recursion loses the smallest directions (2.5e-3 here), so it runs until Xᵀy is exhausted.
    full = fit(MODEL, [data], FitSettings(blocks=4, workers=1, estimator="pls", n_components=len(phi)))
    print(f"model-consistent data, PLS with every latent variable: "
          f"{np.max(np.abs(full.estimates['pls'].beta - beta_true) / scale):.1e}")
    assert np.max(np.abs(full.estimates["pls"].beta - beta_true) / scale) < 1e-6
    gains = [MODEL.layout.index(f"{m}.phi_m") for m in ICUB.motor_names]
    assert np.allclose(result.phi[gains], phi[gains], rtol=1e-6)
