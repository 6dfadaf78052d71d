"""The coefficient file's known answers (format version 7): a stretch of the calibration data and what dynid computes
on it, offline and from the model file, through the file's own filter, observer and detector.

rt_monitor runs its core over the stored samples when it loads the file and refuses one that does not give the same
numbers (rt_monitor/src/known_answers.cpp). The CRC catches a corrupt file; this catches a file that is well formed
but wrong: an edited value that is plausible on its own (a joint without friction, a gate lost, supply tracking
off, a band or a side threshold changed), an exporter that writes a field wrongly, a loader that reads one wrongly.
Each of these went unseen before (docs/fuzzing.md, "The mutation sweep").

Per sample, the columns are the detector's statistic over the T²_α in force at that sample; the combined detector then
adds each residual's ratio (the observer's, then the acceleration residuals'); then each F/T sensor's share of T² over
its side threshold (the combined detector: the observer's shares, then the acceleration residuals'). NaN where the
monitor has not yet evaluated a sample (its windows are filling).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np

from ..detect.combined import combined_statistic
from ..detect.momentum import causal_velocity, momentum_residuals, robot_velocity
from ..detect.online import FixedLagSavitzkyGolay, online_signals, online_times, raw_signals
from ..errors import DataError
from ..identify.supply import tracked_residuals
from ..io.dataset import Dataset
from ..robot.effects import augmented_residuals
from ..robot.regressors.stack import gravity_per_sample
from .lcm_coefficients import coefficients_t
from .rt_eval_io import raw_samples

EVALUATED = 1000  # samples the monitor evaluates in the test, after its windows have filled
CANDIDATE_STEP = 50  # where the stretch may start, in samples
# A decision the core makes on a velocity (the gates at min_speed): stretches where one falls this close to its edge
# are passed over, so that rounding (another CPU, another order of sums) cannot take a sample the other way.
VELOCITY_MARGIN = 1e-9  # rad/s (m/s)
# The monitor compares with |a − b| ≤ 1e-6·max(|a|, |b|) + 1e-9 (rt_monitor/src/known_answers.cpp): the two sides
# agree to about 1e-12; an edit that matters moves the numbers by far more.


def first_evaluated(c: coefficients_t) -> int:
    """The index of the first sample the core evaluates (its windows full), as rt_monitor/src/core.cpp."""
    if c.residual == 0:
        return c.window - 1
    if c.residual == 1:
        return c.velocity_window - 1
    return max(c.window, c.velocity_window) - 1


def first_decision(c: coefficients_t) -> int:
    """The first sample at which the core decides on a q̇ (the earlier of its residuals' windows)."""
    if c.residual == 2:
        return min(c.window, c.velocity_window) - 1
    return first_evaluated(c)


def answer_columns(c: coefficients_t) -> int:
    return (3 + 2 * c.n_sensors) if c.residual == 2 else 1 + c.n_sensors


def _uniform(ds: Dataset, period: float) -> Dataset:
    # The monitor takes one sample a period, whatever its stamp: the answers use the same clock.
    return replace(ds, t=ds.t[0] + period * np.arange(ds.n_samples))


def _gate_mask(c: coefficients_t, dq: np.ndarray) -> np.ndarray:
    """(N, n_outputs) the channels in the acceleration residuals' T² at each q̇ (the core's gates)."""
    nj, nm, nft = c.n_joints, c.n_motors, 6 * c.n_sensors
    slow_j = np.abs(dq) < c.min_speed
    vm = dq @ np.asarray(c.motor_velocity, float).reshape(nm, nj).T if nm else np.zeros((dq.shape[0], 0))
    slow_m = np.abs(vm) < c.min_speed
    active = np.ones((dq.shape[0], c.n_outputs), dtype=bool)
    for i in range(nft, c.n_outputs):
        joints = [j for j in range(nj) if c.gate_joints[i] >> j & 1]
        motors = [m for m in range(nm) if c.gate_motors[i] >> m & 1]
        if joints:
            active[:, i] &= ~slow_j[:, joints].any(axis=1)
        if motors:
            active[:, i] &= ~slow_m[:, motors].any(axis=1)
    return active


def _shares(c: coefficients_t, z: np.ndarray, thresholds: Sequence[float]) -> np.ndarray:
    return np.column_stack([z[:, 6 * k : 6 * k + 6].sum(axis=1) / thresholds[k] for k in range(c.n_sensors)]) \
        if c.n_sensors else np.zeros((z.shape[0], 0))


def answers(identified, c: coefficients_t, ds: Dataset, effects: Sequence = ()) -> tuple[np.ndarray, np.ndarray]:
    """(answers (N, answer_columns), edge (N,) bool): what the core must give on `ds` (uniform samples) with the file
    `c`, and the samples where a velocity decision sits within VELOCITY_MARGIN of its edge."""
    model, phi = identified.robot_model, identified.phi
    ds = _uniform(ds, c.sample_period)
    n = ds.n_samples
    t, q, inputs, tau, ft = raw_signals(model, ds)
    gravity = gravity_per_sample(model, ds)
    out = np.full((n, answer_columns(c)), np.nan)
    edge = np.zeros(n, dtype=bool)
    ratio_a = shares_a = ratio_o = shares_o = None
    if c.residual in (0, 2):
        est = FixedLagSavitzkyGolay(c.window, c.order, c.lag, c.sample_period)
        sig = online_signals(model, est, t, q, inputs, tau, ft, gravity)
        e = augmented_residuals(model, phi, list(effects), sig)
        e = tracked_residuals(model, identified.supply_tracking, c.min_speed, e, sig, online_times(est, t))
        z = e**2 / np.asarray(c.residual_variance, float)
        t2 = np.where(_gate_mask(c, sig.dq), z, 0.0).sum(axis=1)
        ratio_a, shares_a = np.full(n, np.nan), np.full((n, c.n_sensors), np.nan)
        ratio_a[c.window - 1 :] = t2 / c.threshold
        shares_a[c.window - 1 :] = _shares(c, z, c.ft_threshold)
        edge[c.window - 1 :] |= near_speed_edge(c, sig.dq)
    if c.residual in (1, 2):
        band = {("joint_friction", j): tuple(c.joint_band[i]) for i, j in enumerate(c.joint_names)}
        band.update({("motor_friction", m): tuple(c.motor_band[i]) for i, m in enumerate(c.motor_names)})
        options = dict(bandwidth_hz=c.observer_bandwidth, min_speed=c.min_speed, band=band,
                       tracking=identified.supply_tracking)
        start = c.velocity_window - 1  # the core's observer starts, at rest, once its q̇ window is full
        if c.observer_velocity == 1:  # the robot's q̇: from the same sample on
            later = ds.slice(start, None)
            res = momentum_residuals(model, phi, *raw_signals(model, later), gravity_per_sample(model, later),
                                     dq=robot_velocity(c.joint_names, later), **options)
            e, at_rest, dq = (np.concatenate([np.full((start,) + x.shape[1:], np.nan), x])
                              for x in (res.e, res.at_rest.all(axis=1), res.dq))
        else:
            res = momentum_residuals(model, phi, t, q, inputs, tau, ft, gravity,
                                     velocity_window_s=start * c.sample_period, **options)
            e, at_rest, dq = res.e, res.at_rest.all(axis=1), res.dq
        z = e**2 / np.asarray(c.observer_variance, float)
        ratio_o = z.sum(axis=1) / np.where(at_rest == 1, c.observer_rest_threshold, c.observer_threshold)
        shares_o = _shares(c, z, c.observer_ft_threshold)
        edge[start:] |= near_speed_edge(c, dq[start:])
    first = first_evaluated(c)
    if c.residual == 0:
        out[first:] = np.column_stack([ratio_a, shares_a])[first:]
    elif c.residual == 1:
        out[first:] = np.column_stack([ratio_o, shares_o])[first:]
    else:
        s = combined_statistic(ratio_o, ratio_a, at_rest == 1, c.combined_scale)
        out[first:] = np.column_stack([s, ratio_o, ratio_a, shares_o, shares_a])[first:]
    return out, edge


def _speeds(c: coefficients_t, dq: np.ndarray) -> np.ndarray:
    """(N, joints + motors) |q̇| and |q̇_m|: what the core's gates compare with min_speed."""
    nj, nm = c.n_joints, c.n_motors
    speeds = np.abs(dq)
    if nm:
        speeds = np.hstack([speeds, np.abs(dq @ np.asarray(c.motor_velocity, float).reshape(nm, nj).T)])
    return speeds


def near_speed_edge(c: coefficients_t, dq: np.ndarray) -> np.ndarray:
    """(N,) True where a joint's or motor's speed is within VELOCITY_MARGIN of the gates' min_speed: a sample the
    core and dynid could gate differently at rounding."""
    speeds = _speeds(c, dq)
    edge = np.abs(speeds - c.min_speed) < VELOCITY_MARGIN
    if c.min_speed == 0:  # no gates: the sign of a resting coordinate's friction is the edge
        edge |= speeds < VELOCITY_MARGIN
    return edge.any(axis=1)


def _velocities(c: coefficients_t, ds: Dataset) -> list[tuple[int, np.ndarray]]:
    """The q̇ estimates the core decides on over a whole piece, each with the sample its first row is of: the fixed-lag
    filter's (at its tick) and the observer's causal one. They depend on the last window of q only, so a stretch
    started anywhere later sees the same."""
    q, out = ds.q, []
    if c.residual in (0, 2):
        out.append((c.window - 1, FixedLagSavitzkyGolay(c.window, c.order, c.lag, c.sample_period).apply(q)[1]))
    if c.residual in (1, 2) and c.observer_velocity == 1:
        out.append((0, robot_velocity(c.joint_names, ds)))
    elif c.residual in (1, 2):
        t = c.sample_period * np.arange(ds.n_samples)
        out.append((0, causal_velocity(t, q, (c.velocity_window - 1) * c.sample_period)))
    return out


def _stretch(c: coefficients_t, datasets: Sequence[Dataset]) -> tuple[int, int, int] | None:
    """(piece, start, stop): the stretch whose evaluated samples hold no decision at its edge and rest the most gated
    coordinates (the gates and the bands are then tested), as long as EVALUATED allows, or the longest such."""
    first = first_evaluated(c)
    best, best_key = None, None
    for k, ds in enumerate(datasets):
        n = ds.n_samples
        if n < first + 2:
            continue
        edge, resting = np.zeros(n, dtype=bool), np.zeros((n, c.n_joints + c.n_motors), dtype=bool)
        for at, dq in _velocities(c, ds):
            edge[at : at + dq.shape[0]] |= near_speed_edge(c, dq)
            resting[at : at + dq.shape[0]] |= _speeds(c, dq) < c.min_speed
        bad = np.concatenate([[0], np.cumsum(edge)])  # edges in [a, b): bad[b] - bad[a]
        for lo in range(0, max(n - first - 1, 1), CANDIDATE_STEP):
            hi = min(lo + first + 1 + EVALUATED, n)
            start = lo + first_decision(c)
            edges = np.flatnonzero(edge[start:hi])
            if edges.size:  # cut the stretch before its first edge
                hi = start + int(edges[0])
            if hi - lo - first < 1 or bad[hi] - bad[start]:
                continue
            key = (hi - lo, int(resting[lo + first : hi].any(axis=0).sum()))
            if best_key is None or key > best_key:
                best, best_key = (k, lo, hi), key
    return best


def attach(c: coefficients_t, identified, datasets: Sequence[Dataset], effects: Sequence = ()) -> None:
    """Store in `c` (known_input, known_answer) a stretch of the (uniform) calibration pieces `datasets` and what the
    core must give on it."""
    chosen = _stretch(c, datasets)
    if chosen is None:
        raise DataError("no stretch of the calibration data is long enough for the coefficient file's known answers "
                        "without a joint speed at the gates' edge (min_speed) to within rounding; give other --data")
    k, lo, hi = chosen
    piece = datasets[k].slice(lo, hi)
    table, edge = answers(identified, c, piece, effects)
    if edge[first_decision(c):].any():  # _stretch saw the same q̇: a disagreement is a bug here
        raise RuntimeError("known answers: the chosen stretch has a decision at its edge")
    if not np.isfinite(table[first_evaluated(c):]).all():
        raise DataError("the known answers are not finite (a calibration sample the model cannot evaluate)")
    raw = raw_samples(piece, c)
    c.n_known, c.known_width = raw.shape
    c.known_input = raw.tolist()
    c.known_columns = table.shape[1]
    c.known_answer = table.tolist()
