"""The static-friction band of the paper's T²: a resting coordinate's Coulomb law is set-valued.

Reference: the residual with that coordinate's Coulomb coefficients set to zero in Φ (computed by the regressors,
not by the band code), then its distance to the interval the coordinate's static friction can cover in each row.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.detect.t2 import static_band_residuals
from dynid.robot.model import RobotModel
from dynid.robot.outputs import divisors, output_channels, residuals
from dynid.robot.regressors.stack import Signals, group_row_maps, motor_velocities

CONFIG = load_config()
MODEL = RobotModel(CONFIG)
MIN_SPEED = 0.01
N = 400


def _signals(rng: np.random.Generator, slow_joint: str) -> Signals:
    n = len(CONFIG.joints)
    q = rng.uniform(-0.5, 0.5, (N, n))
    dq = rng.choice([-1.0, 1.0], (N, n)) * rng.uniform(0.2, 1.0, (N, n))
    dq[:, CONFIG.joints.index(slow_joint)] = rng.uniform(-0.009, 0.009, N)  # at rest, either sign
    ddq = rng.normal(0.0, 2.0, (N, n))
    pwm = {m: rng.normal(0.0, 0.2, N) for m in CONFIG.motor_names}
    ft = {s.name: rng.normal(0.0, 5.0, (N, 6)) for s in CONFIG.ft_sensors}
    return Signals(q, dq, ddq, pwm, {}, ft)


def _phi(rng: np.random.Generator) -> np.ndarray:
    phi = rng.uniform(0.01, 0.1, len(MODEL.layout.names))
    for m in CONFIG.motor_names:
        phi[MODEL.layout.block("motor_gain", m).start] = rng.uniform(15.0, 25.0)
    return phi


def _motor_at_rest(dq: np.ndarray) -> np.ndarray:
    shoulder = next(g for g in CONFIG.actuation if g.coupled)
    cols = [CONFIG.joints.index(j) for j in shoulder.joints]
    return np.any(np.abs(motor_velocities(dq[:, cols], shoulder.coupling)) < MIN_SPEED, axis=1)


@pytest.mark.parametrize("slow_joint", ["r_elbow", "r_shoulder_roll", "r_shoulder_yaw"])  # uncoupled; coupled (L shares of both signs)
def test_a_resting_joint_gives_the_distance_to_its_static_friction_band(slow_joint: str) -> None:
    rng = np.random.default_rng(7)
    sig, phi = _signals(rng, slow_joint), _phi(rng)
    # PWMs that leave residuals of the static band's size (±0.004 duty ≈ ±0.08 Nm): inside and outside it.
    e = residuals(MODEL, phi, sig)
    for o in output_channels(MODEL):
        if o.motor:
            sig.inputs[o.motor][:] += -e[:, o.row] + rng.uniform(-0.004, 0.004, N)
    e = residuals(MODEL, phi, sig)
    friction = MODEL.layout.block("joint_friction", slow_joint).slice
    no_coulomb = phi.copy()
    no_coulomb[friction.start : friction.start + 2] = 0.0  # fc_pos, fc_neg
    free = residuals(MODEL, no_coulomb, sig)
    fc_pos, fc_neg = phi[friction.start], phi[friction.start + 1]

    group = next(g for g in CONFIG.actuation if slow_joint in g.joints)
    L, _ = group_row_maps(group)
    share = L[:, group.joints.index(slow_joint)]
    rows = [o.row for o in output_channels(MODEL) if o.motor in group.motors]
    g = divisors(MODEL, phi)[rows]
    ends = np.stack([share * fc_pos / g, -share * fc_neg / g])
    lo, hi = ends.min(axis=0), ends.max(axis=0)
    expected = free[:, rows] - np.clip(free[:, rows], lo, hi)

    banded = static_band_residuals(MODEL, phi, sig.dq, e, MIN_SPEED)
    keep = ~_motor_at_rest(sig.dq)  # a resting coupled motor would add its own band
    banded, e, expected = banded[keep], e[keep], expected[keep]
    touched = np.abs(share) > 1e-9
    assert np.allclose(banded[:, rows][:, touched], expected[:, touched], rtol=0, atol=1e-12)
    assert np.any(banded[:, rows][:, touched] == 0.0) and np.any(banded[:, rows][:, touched] != 0.0)  # both cases
    others = np.setdiff1d(np.arange(e.shape[1]), np.asarray(rows)[touched])
    assert np.array_equal(banded[:, others], e[:, others])  # F/T rows and untouched rows unchanged


def test_nothing_at_rest_changes_nothing() -> None:
    rng = np.random.default_rng(3)
    sig, phi = _signals(rng, "r_elbow"), _phi(rng)
    sig.dq[:, CONFIG.joints.index("r_elbow")] = 0.5
    moving = Signals(sig.q, sig.dq, sig.ddq, sig.inputs, sig.tau, sig.ft)
    e = residuals(MODEL, phi, moving)
    banded = static_band_residuals(MODEL, phi, moving.dq, e, MIN_SPEED)
    still = _motor_at_rest(moving.dq)
    assert (~still).sum() > N // 2
    assert np.array_equal(banded[~still], e[~still])


def test_an_episode_found_by_one_sample_above_is_not_a_sustained_onset() -> None:
    """`episodes_detected` counts an episode's first sample above the level; `episodes_sustained` only an alarm held
    ONSET_S (10 samples at 1 kHz, 1 at 100 Hz), as the monitor's onset: a lone sample is what a 1 % false-positive
    rate puts into half the episodes of 70 samples."""
    from dynid.detect.t2 import score

    t = np.arange(1000) * 1e-3
    contact = np.zeros(1000)
    contact[100:170] = contact[400:470] = 1
    t2 = np.zeros(1000)
    t2[130] = 5.0  # one sample above in the first episode
    t2[420:431] = 5.0  # eleven in a row in the second, 20 ms after its start
    s = score(t, t2, 1.0, contact)
    assert (s["episodes"], s["episodes_detected"]) == (2, 2) and s["delay_s"]["median"] == pytest.approx(0.025)
    assert s["episodes_sustained"] == {"samples": 10, "found": 1}
    t2[425] = 0.0  # the run broken into 5 and 5: no onset
    assert score(t, t2, 1.0, contact)["episodes_sustained"]["found"] == 0
    slow = score(t * 10, t2, 1.0, contact)  # at 100 Hz one sample is an onset
    assert slow["episodes_sustained"] == {"samples": 1, "found": 2}


def _core_detect(t2: np.ndarray, threshold: float, on: int, off: int,
                 hysteresis: float) -> tuple[list[tuple[int, int]], list[int]]:
    """rt_monitor's Core::detect transcribed sample by sample (rt_monitor/src/core.cpp): (sample, 1 onset / 2 end),
    and each contact's peak (the sample its end event describes)."""
    out, peaks, in_contact, above, below, peak_t2 = [], [], False, 0, 0, 0.0
    for k, x in enumerate(t2):
        event = 0
        if not in_contact:
            above = above + 1 if x > threshold else 0
            if above >= on:
                in_contact, below, event = True, 0, 1
                out.append((k, 1))
        else:
            below = below + 1 if x < hysteresis * threshold else 0
            if below >= off:
                in_contact, above = False, 0
                out.append((k, 2))
        if in_contact and (event == 1 or x > peak_t2):
            peak_t2 = x
            if event == 1:
                peaks.append(k)
            peaks[-1] = k
    return out, peaks


@pytest.mark.parametrize("seed", range(6))
def test_offline_events_are_the_monitors_debounce_and_hysteresis(seed: int) -> None:
    """`dynid detect`'s monitor_events: the same onsets and ends as the monitor's per-sample state machine, on
    statistics that dwell near both levels (bursts, dips under the end level, NaN) with short and long counts."""
    from dynid.detect.t2 import debounced_events, episode_peaks

    rng = np.random.default_rng(seed)
    n = 5000
    level = np.repeat(rng.choice([0.2, 0.45, 0.8, 1.5, 4.0], size=n // 50), 50)
    t2 = level * rng.lognormal(0.0, 0.4, n)
    t2[rng.random(n) < 0.01] = np.nan
    for on, off, hysteresis in ((1, 1, 1.0), (10, 100, 0.5), (3, 7, 0.3), (25, 2, 0.9)):
        got = debounced_events(t2, 1.0, on, off, hysteresis)
        flat = [e for k, j in got for e in ((k, 1), (j, 2)) if e[0] is not None]
        events, peaks = _core_detect(t2, 1.0, on, off, hysteresis)
        assert flat == events
        assert episode_peaks(t2, got) == peaks
        assert len(got) > 0
    assert debounced_events(np.zeros(10), 1.0, 1, 1, 0.5) == []
    assert debounced_events(np.full(10, 2.0), 1.0, 3, 1, 0.5) == [(2, None)]  # in contact at the end
