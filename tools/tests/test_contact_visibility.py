"""dynid.detect.visibility: the contact's own residual against the residual the plant actually produced, and the
visibility rule on hand-made episodes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.detect.visibility import contact_residuals, episode_visibility
from dynid.errors import DataError
from dynid.robot.model import RobotModel
from dynid.robot.outputs import output_channels


@pytest.fixture(scope="module")
def arm() -> RobotModel:
    return RobotModel(load_config("icub_right_arm"))


def test_the_contact_is_the_residual_the_plant_produced(default_model: Path, default_experiments) -> None:
    """On the default contact run, regressing the model's residual on the contact's own residual from the truth
    gives slope ≈ 1 on every channel the contact moves (measured: F/T 1.00, motors 0.94–0.98)."""
    from dynid.identify.validation import evaluate
    from dynid.robot.outputs import divisors

    run = default_experiments["contact"]
    ev = evaluate(str(default_model), str(run))
    signal = contact_residuals(ev.model, divisors(ev.model, ev.identified.phi), np.load(Path(run) / "truth.npz"))
    during = ev.dataset.contact != 0
    for o in ev.outputs:
        x, y = signal[during, o.row], ev.e[during, o.row]
        assert np.std(x) > 2 * o.sigma, o.name  # every channel sees some contact in this run
        slope, corr = np.dot(x, y) / np.dot(x, x), np.corrcoef(x, y)[0, 1]
        print(f"{o.name}: slope {slope:.3f}, correlation {corr:.3f}")
        assert 0.9 <= slope <= 1.1 and corr >= 0.75, o.name


def synthetic_truth(model: RobotModel, n: int, elbow_torque: np.ndarray) -> dict[str, np.ndarray]:
    truth = {f"extra/contact.tau.{j}": np.zeros(n) for j in model.config.joints}
    truth["extra/contact.tau.r_elbow"] = elbow_torque
    truth.update({f"extra/contact.r_arm_ft.{c}": np.zeros(n) for c in ("fx", "fy", "fz", "tx", "ty", "tz")})
    return truth


def test_visibility_rule(arm: RobotModel) -> None:
    outs = output_channels(arm)
    n = 1000
    contact = np.zeros(n, np.uint8)
    contact[100:300] = 1  # a push on the elbow
    contact[500:700] = 1  # a push through the elbow's axis: no torque
    torque = np.where(contact[:400] != 0, 0.5, 0.0)
    truth = synthetic_truth(arm, n, np.concatenate([torque, np.zeros(600)]))
    gains = np.full(len(outs), 20.0)
    signal = contact_residuals(arm, gains, truth)
    elbow = next(o.row for o in outs if o.motor == "m3")
    np.testing.assert_allclose(signal[150, elbow], -0.5 / 20.0)  # the elbow is uncoupled: L = 1
    assert np.count_nonzero(signal[:, [o.row for o in outs if o.row != elbow]]) == 0
    variance = np.full(len(outs), 0.002**2)
    moving = np.ones((n, len(outs)), bool)
    seen, through_axis = episode_visibility(contact, signal, moving, variance, threshold=30.0, debounce=10)
    assert seen.visible and seen.longest_run == 200 and seen.peak_t2 == pytest.approx((0.025 / 0.002) ** 2)
    assert seen.earliest == 9  # a step: above T²_α from the first sample, confirmed on the tenth
    assert not through_axis.visible and through_axis.peak_t2 == 0.0 and through_axis.earliest == -1
    # A 30 ms raised-cosine ramp (the simulator's): the contact alone passes T²_α = 30 where (1 − cos(πk/30))/2 · 0.025
    # reaches √30 · 0.002, k = 30/π · acos(1 − 2·√30·0.002/0.025) = 13.8, so from k = 14, confirmed 9 samples later
    ramp = signal.copy()
    k = np.arange(30)
    ramp[100:130, elbow] *= 0.5 * (1 - np.cos(np.pi * k / 30))
    got = episode_visibility(contact, ramp, moving, variance, threshold=30.0, debounce=10)[0]
    first = int(np.ceil(30 / np.pi * np.arccos(1 - 2 * np.sqrt(30.0) * 0.002 / 0.025)))
    assert first == 14 and got.earliest == first + 9
    resting = moving.copy()
    resting[:, elbow] = False  # static friction holds the elbow: its row is out of T²
    assert not episode_visibility(contact, signal, resting, variance, 30.0, 10)[0].visible
    short = moving.copy()
    short[:, elbow] = (np.arange(n) % 20) < 9  # never 10 samples in a row
    assert not episode_visibility(contact, signal, short, variance, 30.0, 10)[0].visible


def test_a_run_without_contact_truth_is_refused(arm: RobotModel) -> None:
    with pytest.raises(DataError, match="no contact record"):
        contact_residuals(arm, np.ones(10), {})
