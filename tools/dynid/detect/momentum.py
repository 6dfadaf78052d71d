"""Generalized-momentum residuals (De Luca and Mattone 2003; Haddadin, De Luca, Albu-Schäffer, T-RO 2017): a
contact residual that needs no acceleration, for the joint and motor channels and for every F/T sensor's subtree.

With p = M(q) q̇ the identity ṗ = τ + Cᵀ(q, q̇) q̇ − g(q) (Ṁ = C + Cᵀ) holds for every generalized coordinate of
the split model (dynid.robot.model), the F/T sensors' 6-DoF joints included: they never move, and their "torque"
is the wrench the proximal part exerts on the distal one, minus the sensor's reading. So the observer

    r(t) = K_O ( p(t) − p(0) − ∫ (τ_meas + Cᵀq̇ − g + r) dt )

is, coordinate by coordinate, the first-order low-pass (bandwidth K_O) of τ_meas − τ_model, where τ_model would
need q̈; here it needs q and q̇ only. τ_meas is the motors' torque through the coupling (gain × input, as the
motor equations of dynid.robot.regressors.stack write it) minus the identified friction, a joint torque sensor's
reading, or, on a sensor's coordinates, minus the measured wrench without its identified offset. M, Cᵀq̇ and g
come from Pinocchio (crba, computeCoriolisMatrix, computeGeneralizedGravity) on the split model whose inertias are
the identified full set Φ̂ (it reproduces the identified base parameters, which is all these need).

Each channel of r is put in the row space of the stacked system (motor space for a square coupling: L r), so
r is the low-passed e·g of dynid.robot.outputs: on an F/T channel the low-passed w − ŵ (N, Nm), on a motor row
the low-passed torque the motors gave beyond the model (Nm), which is minus the external joint torque.

Discretely, per sample k (Δt_k its step; exact for a residual held over the step):

    r_k = a_k r_{k−1} + (1 − a_k) (Δp_k / Δt_k − β_k),  a_k = exp(−K_O Δt_k)

with β = τ_meas + Cᵀq̇ − g at sample k (only q, q̇ and the inputs: no q̈).

**q̇** is the data's measured joint velocity where they carry one for every joint (extra columns
`velocity.<joint>`, rad/s: a controller's own, as the UR10e logs hold it, or recorded `dq` columns, as the Panda's;
`measured_velocity`), else a causal estimator (`causal_velocity`: a quadratic fitted by least squares to the last
`window` samples at their own time stamps, evaluated at the newest: on uniform samples the monitor's
fixed-lag Savitzky-Golay filter with lag 0, dynid.detect.online).

**Friction at rest.** Where a friction coordinate (a joint, a coupled motor) is slower than the model's
`min_speed`, its Coulomb friction is a band, not a value: any torque in [−fc_neg, fc_pos] holds it. The observer
then leaves that coordinate's Coulomb term out, and the residual of a row at rest is its distance outside the
band (zero inside), the band widened by `band_sigmas` standard errors of the Coulomb coefficients where the
model file carries them (`friction_band`). A push on a resting arm that the motors or the friction have to
hold shows as a residual outside the band.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .. import kernels
from ..errors import DataError
from ..identify.model_sections import BaseSection
from ..robot.model import RobotModel
from ..robot.outputs import output_channels
from ..robot.regressors.friction import friction_regressor
from ..robot.regressors.stack import DEFAULT_MIN_SPEED, friction_coordinates, group_row_maps, group_rows

DEFAULT_BANDWIDTH_HZ = 15.0  # K_O = 2π·15 rad/s: a 10.6 ms time constant (chosen by measurement: docs/detection.md)
VELOCITY_WINDOW_S = 0.02  # the causal q̇ estimator's window (s); at least 5 samples
MIN_VELOCITY_SAMPLES = 5
# After a coordinate leaves rest, r still carries the static friction it held and follows the moving friction law
# with the observer's lag; its row may keep the band for this many time constants. Off by default: measured on the
# simulated arm (docs/detection.md), 3 time constants lower T²_α (57.8 -> 42.3) and raise the proximal TPR (23 ->
# 40 %), but the contact-free FPR rises (0.83 -> 1.27 %) and the slowest onsets slow (p90 96 -> 243 ms).
HOLD_TIME_CONSTANTS = 0.0


def velocity_window_samples(t: np.ndarray, window_s: float = VELOCITY_WINDOW_S) -> int:
    """The causal q̇ estimator's window in samples for data sampled at times t: `window_s`, at least 5 samples."""
    steps = np.diff(np.asarray(t, float))
    if steps.size == 0 or np.any(steps <= 0):
        raise DataError("the causal q̇ estimator needs strictly increasing time stamps")
    return max(MIN_VELOCITY_SAMPLES, int(round(window_s / float(np.median(steps)))) + 1)


def causal_velocity_weights(window: int, sample_period: float) -> np.ndarray:
    """(window,) the estimator's weights on uniform samples, oldest first: q̇_k = Σ w_i q_{k−window+1+i} (the
    monitor's; the quadratic least-squares slope at the newest sample, as `causal_velocity` computes it)."""
    s = np.arange(window, dtype=float) - (window - 1)
    return np.linalg.pinv(np.vander(s, 3, increasing=True))[1] / sample_period


def causal_velocity(t: np.ndarray, q: np.ndarray, window_s: float = VELOCITY_WINDOW_S) -> np.ndarray:
    """(N, n) q̇ at each sample from the samples of the last `window_s` seconds (at least 5), a quadratic
    least-squares fit at their own time stamps, evaluated at the newest sample (causal); the first samples use
    what there is (two at least; q̇ = 0 at the very first)."""
    t = np.asarray(t, float)
    q = np.atleast_2d(np.asarray(q, float))
    n = t.size
    w = min(velocity_window_samples(t, window_s), n)
    out = np.zeros_like(q)
    steps = np.diff(t)
    if w >= 3 and np.allclose(steps, steps[0], rtol=1e-9, atol=0):
        # Uniform steps: every full window has the same weights (the monitor's, `causal_velocity_weights`), so q̇ is
        # one weighted sum of shifted copies of q, not a 3 × 3 solve per sample (issue 32: a tenth of `dynid fit`).
        weights = causal_velocity_weights(w, (t[-1] - t[0]) / (n - 1))
        m = n - w + 1
        full = out[w - 1:]
        for i, weight in enumerate(weights):
            full += weight * q[i : i + m]
    else:
        _local_quadratic_slopes(t, q, w, out)
    for k in range(1, min(w - 1, n)):  # the start: a line through what there is
        s = t[: k + 1] - t[k]
        V = np.column_stack([np.ones_like(s), s])
        out[k] = np.linalg.lstsq(V, q[: k + 1], rcond=None)[0][1]
    return out


def _local_quadratic_slopes(t: np.ndarray, q: np.ndarray, w: int, out: np.ndarray) -> None:
    """`causal_velocity` on any stamps: out[k] for the windows ending at k ≥ w − 1, batched normal equations of the
    quadratic in local time s = t_i − t_k."""
    n = t.size
    idx = np.arange(w - 1, n)[:, None] + np.arange(-(w - 1), 1)[None, :]  # (M, w)
    for lo in range(0, idx.shape[0], 20000):
        part = idx[lo : lo + 20000]
        s = t[part] - t[part[:, -1:]]
        scale = np.maximum(-s[:, :1], 1e-12)  # conditioning: local time in units of the window span
        u = s / scale
        V = np.stack([np.ones_like(u), u, u * u], axis=-1)  # (M, w, 3)
        G = np.einsum("mwi,mwj->mij", V, V)
        rhs = np.einsum("mwi,mwc->mic", V, q[part])
        coef = np.linalg.solve(G, rhs)  # (M, 3, n_joints)
        out[part[:, -1]] = coef[:, 1] / scale


def measured_velocity(model: RobotModel, dataset) -> np.ndarray | None:
    """(N, n_joints) the robot's own joint velocity: the data's `velocity.<joint>` extra columns when every joint
    has one, else their recorded `dq` columns (not an estimate dynid made from q); None when the data carry neither.
    A log whose positions stall for a few samples while its stamps advance (the Panda's) would otherwise stall a
    q̇ estimated from q, and the observer would read the stall as a momentum jump."""
    return robot_velocity(model.config.joints, dataset)


def robot_velocity(joints: Sequence[str], dataset) -> np.ndarray | None:
    """`measured_velocity` for the joints named (a coefficient file's, where no model is at hand)."""
    cols = [dataset.extra.get(f"velocity.{j}") for j in joints]
    if any(c is None for c in cols):
        recorded = dataset.meta.get("derivatives", {}).get("dq", "recorded") == "recorded"
        return None if dataset.dq is None or not recorded else np.asarray(dataset.dq, float)
    dq = np.column_stack([np.asarray(c, float) for c in cols])
    if not np.all(np.isfinite(dq)):
        raise DataError("the data's velocity.<joint> columns hold a value that is not a finite number")
    return dq


def _held(t: np.ndarray, mask: np.ndarray, hold_s: float) -> np.ndarray:
    """mask, and the samples up to hold_s after each stretch of it ends (causal: only the past decides)."""
    if hold_s <= 0 or not mask.any():
        return mask
    idx = np.flatnonzero(mask)
    last = np.full(t.size, -np.inf)
    last[idx] = t[idx]
    last = np.maximum.accumulate(last)  # the time the mask last held, at every sample
    return mask | (t - last <= hold_s)


def identified_pinocchio(model: RobotModel, phi: np.ndarray) -> pin.Model:
    """A copy of the split model whose bodies carry the inertial parameters of Φ (the layout's bodies are the
    model's joints in order, dynid.robot.model)."""
    pm = pin.Model(model.pin_model)
    for body, block in zip(model.bodies, model.layout.blocks_of("inertial")):
        pm.inertias[body.joint_id] = pin.Inertia.FromDynamicParameters(np.asarray(phi[block.slice], float))
    return pm


@dataclass(frozen=True)
class MomentumTerms:
    """Per sample: p = M q̇ and Cᵀq̇ − g, in Pinocchio's velocity coordinates (N, nv)."""

    p: np.ndarray
    beta_rb: np.ndarray


def momentum_terms(model: RobotModel, phi: np.ndarray, q: np.ndarray, dq: np.ndarray,
                   gravity: np.ndarray | None = None) -> MomentumTerms:
    """p and Cᵀq̇ − g of every sample: through the compiled kernel where it runs (dynid.kernels: Pinocchio's C++ on
    the whole run), else `momentum_terms_reference`."""
    native = kernels.native()
    if native is None:
        return momentum_terms_reference(model, phi, q, dq, gravity)
    pm = identified_pinocchio(model, phi)
    Q, V = model.pinocchio_configuration(q), model.pinocchio_velocity(dq)
    P, B = np.empty((Q.shape[0], pm.nv)), np.empty((Q.shape[0], pm.nv))
    native.MomentumTerms(pm.saveToString()).compute(
        np.ascontiguousarray(Q), np.ascontiguousarray(V),
        None if gravity is None else np.ascontiguousarray(gravity, dtype=float), P, B)
    return MomentumTerms(P, B)


def momentum_terms_reference(model: RobotModel, phi: np.ndarray, q: np.ndarray, dq: np.ndarray,
                             gravity: np.ndarray | None = None) -> MomentumTerms:
    """The Python reference of `momentum_terms`: Pinocchio's bindings one sample at a time."""
    pm = identified_pinocchio(model, phi)
    data = pm.createData()
    Q, V = model.pinocchio_configuration(q), model.pinocchio_velocity(dq)
    n = Q.shape[0]
    P, B = np.empty((n, pm.nv)), np.empty((n, pm.nv))
    rest = np.zeros(pm.nv)
    for k in range(n):
        if gravity is not None:
            pm.gravity = pin.Motion(np.asarray(gravity[k], float), np.zeros(3))
        g = pin.computeGeneralizedGravity(pm, data, Q[k])
        P[k] = pin.rnea(pm, data, Q[k], rest, V[k]) - g  # M q̇: RNEA at rest with q̇ as the acceleration, no M formed
        C = pin.computeCoriolisMatrix(pm, data, Q[k], V[k])
        B[k] = C.T @ V[k] - g
    return MomentumTerms(P, B)


def first_order(t: np.ndarray, x: np.ndarray, bandwidth_hz: float) -> np.ndarray:
    """The causal first-order low-pass the observer is: y_k = a_k y_{k−1} + (1 − a_k) x_k, a_k = exp(−2π f Δt_k),
    started at rest (y_{−1} = 0); the first step is taken as long as the second."""
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    k_o = 2.0 * np.pi * bandwidth_hz
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]) if t.size > 1 else t[0] - 1e-3)
    native = kernels.native()
    if native is not None and x.ndim in (1, 2):  # the loop below, compiled (same operations in the same order)
        columns = x.reshape(x.shape[0], -1)
        y = np.empty(columns.shape)
        native.first_order(np.ascontiguousarray(dt, dtype=float), np.ascontiguousarray(columns), k_o, y)
        return y.reshape(x.shape)
    a = np.exp(-k_o * dt)
    if np.allclose(dt, dt[0], rtol=1e-9, atol=0):
        from scipy.signal import lfilter  # uniform steps: one IIR pass (scipy.signal's import is 0.35 s)

        return lfilter([1.0 - a[0]], [1.0, -a[0]], x, axis=0)
    y = np.empty_like(x)
    prev = np.zeros(x.shape[1:])
    for k in range(x.shape[0]):
        prev = a[k] * prev + (1.0 - a[k]) * x[k]
        y[k] = prev
    return y


def friction_band(model: RobotModel, phi: np.ndarray, base: BaseSection | None, band_sigmas: float) -> dict:
    """{(kind, owner): (fc_pos, fc_neg)} of every friction block, each widened by `band_sigmas` standard errors
    where the model file's base section identifies the Coulomb coefficient alone (a base combination with no
    dependent part: its standard error is the coefficient's own)."""
    se = {} if base is None else base.standard_error_alone()
    out = {}
    names = model.layout.names
    for b in model.layout.blocks_of("joint_friction") + model.layout.blocks_of("motor_friction"):
        fc_pos, fc_neg = (float(v) for v in phi[b.slice][:2])
        d_pos, d_neg = (band_sigmas * se.get(names[i], 0.0) for i in (b.start, b.start + 1))
        out[(b.kind, b.owner)] = (max(fc_pos, 0.0) + d_pos, max(fc_neg, 0.0) + d_neg)
    return out


def band_at_rest(model: RobotModel, dq: np.ndarray, band: dict, min_speed: float,
                 hold: Callable[[np.ndarray], np.ndarray] = lambda slow: slow
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(at_rest, lo, hi), each (N, n_out): the rows holding a friction coordinate slower than `min_speed` (its mask
    passed through `hold`), and the static torque they may carry there: the sum over those coordinates of
    share·[−fc⁻, fc⁺], from `band` {(kind, owner): (fc⁺, fc⁻)} (`friction_band`)."""
    n, n_out = dq.shape[0], len(output_channels(model))
    at_rest = np.zeros((n, n_out), dtype=bool)
    lo, hi = np.zeros((n, n_out)), np.zeros((n, n_out))
    for rows, coordinates in friction_coordinates(model, dq):
        for c in coordinates:
            fc_pos, fc_neg = band[c.block]
            ends = np.stack([c.share * fc_pos, -c.share * fc_neg])
            slow = hold(np.abs(c.velocity) < min_speed)
            at_rest[:, rows] |= slow[:, None] & (c.share != 0)[None, :]
            lo[:, rows] += np.where(slow[:, None], ends.min(axis=0), 0.0)
            hi[:, rows] += np.where(slow[:, None], ends.max(axis=0), 0.0)
    return at_rest, lo, hi


@dataclass(frozen=True)
class MomentumResiduals:
    t: np.ndarray  # (N,)
    r: np.ndarray  # (N, n_out) the observer's output per row channel (row-space units: N, Nm)
    e: np.ndarray  # (N, n_out) r with every row at rest replaced by its distance outside the friction band
    dq: np.ndarray  # (N, n_joints) the causal q̇ the observer used
    at_rest: np.ndarray  # (N, n_out) rows holding a resting friction coordinate
    tau_ext: np.ndarray  # (N, n_joints) estimated external joint torque (−r in joint space), Nm


def momentum_residuals(model: RobotModel, phi: np.ndarray, t: np.ndarray, q: np.ndarray,
                       inputs: dict[str, np.ndarray], tau: dict[str, np.ndarray], ft: dict[str, np.ndarray],
                       gravity: np.ndarray | None = None, *, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
                       min_speed: float = DEFAULT_MIN_SPEED, band: dict | None = None,
                       velocity_window_s: float = VELOCITY_WINDOW_S, tracking=None,
                       dq: np.ndarray | None = None, hold_time_constants: float = HOLD_TIME_CONSTANTS
                       ) -> MomentumResiduals:
    """The observer over one run of raw signals (as the monitor receives them: dynid.detect.online.raw_signals);
    with `tracking` (dynid.identify.supply.SupplyTracking) each PWM row's drive torque is re-scaled by the monitor's
    causal supply estimate, fitted on the low-passed input against the low-passed prediction (`_tracked`)."""
    if not (np.isfinite(bandwidth_hz) and bandwidth_hz > 0):
        raise DataError(f"the observer's bandwidth must be positive, got {bandwidth_hz} Hz")
    t = np.asarray(t, float)
    if t.size > 1 and bandwidth_hz >= 0.5 / float(np.median(np.diff(t))):
        raise DataError(f"the observer's bandwidth {bandwidth_hz:g} Hz is at or above the data's Nyquist frequency "
                        f"({0.5 / float(np.median(np.diff(t))):.4g} Hz): give a lower --bandwidth")
    options = dict(bandwidth_hz=bandwidth_hz, min_speed=min_speed, band=band, tracking=tracking,
                   hold_time_constants=hold_time_constants)
    if dq is not None:
        return _observe(model, phi, t, q, inputs, tau, ft, gravity, np.asarray(dq, float), **options)
    # With estimated q̇ the observer starts, at rest, once the estimator's window is full: as the monitor's does
    # (rt_monitor/src/core.cpp), so the two agree from the first sample on; r = 0 before.
    dq = causal_velocity(t, q, velocity_window_s)
    start = min(velocity_window_samples(t, velocity_window_s), t.size) - 1
    if start == 0:
        return _observe(model, phi, t, q, inputs, tau, ft, gravity, dq, **options)
    cut = slice(start, None)
    later = _observe(model, phi, t[cut], q[cut], {k: np.asarray(v)[cut] for k, v in inputs.items()},
                     {k: np.asarray(v)[cut] for k, v in tau.items()}, {k: np.asarray(v)[cut] for k, v in ft.items()},
                     None if gravity is None else gravity[cut], dq[cut], **options)
    pad = lambda x: np.concatenate([np.zeros((start,) + x.shape[1:], x.dtype), x])  # noqa: E731
    return MomentumResiduals(t, pad(later.r), pad(later.e), dq, pad(later.at_rest), pad(later.tau_ext))


def _observe(model: RobotModel, phi: np.ndarray, t: np.ndarray, q: np.ndarray, inputs: dict, tau: dict, ft: dict,
             gravity: np.ndarray | None, dq: np.ndarray, *, bandwidth_hz: float, min_speed: float, band: dict | None,
             tracking, hold_time_constants: float) -> MomentumResiduals:
    cfg, layout = model.config, model.layout
    terms = momentum_terms(model, phi, q, dq, gravity)
    n = t.size
    outs = output_channels(model)
    n_out = len(outs)
    # The rate of change of the momentum (a difference of p: what the discrete observer integrates exactly)
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    pdot = np.diff(terms.p, axis=0, prepend=terms.p[:1]) / dt[:, None]
    pdot[0] = 0.0
    # x = τ_meas − τ_model with τ_model = ṗ − (Cᵀq̇ − g), in generalized coordinates
    x_rb = terms.beta_rb - pdot  # the τ_meas part is added per channel below
    del terms, pdot  # freed as soon as they are used: the observer runs over calibration runs of 150 000 samples
    x = np.zeros((n, n_out))
    for i, s in enumerate(cfg.ft_sensors):
        v0 = model.sensor_v_index[s.name]
        offset = phi[layout.block("ft_offset", s.name).slice]
        # the sensor coordinate's τ_meas is −(w − w_O); its row channel is w − ŵ = −(τ_meas − τ_model)
        x[:, 6 * i : 6 * i + 6] = (np.asarray(ft[s.name], float) - offset) - x_rb[:, v0 : v0 + 6]
    x_joint = x_rb[:, model.v_index]  # (N, n_joints), still without the joint's τ_meas
    for g, gj, rows in group_rows(model):
        L, C = group_row_maps(g)
        x[:, rows] = x_joint[:, gj] @ L.T
        if g.input == "torque":
            x[:, rows] += np.column_stack([tau[j] for j in g.joints]) @ L.T
            continue
        for mi, m in enumerate(g.motors):
            known = cfg.motor(m).known_gain
            gain = known if known is not None else phi[layout.block("motor_gain", m).start]
            x[:, rows] += np.outer(np.asarray(inputs[m], float) * gain, C[:, mi])
    del x_rb, x_joint
    # friction: the identified law where the coordinate moves; its Coulomb part left out where it rests
    for rows, coordinates in friction_coordinates(model, dq):
        for c in coordinates:
            F = friction_regressor(c.velocity)
            F[np.abs(c.velocity) < min_speed, :2] = 0.0
            x[:, rows] -= np.outer(F @ phi[layout.block(*c.block).slice], c.share)
    hold_s = hold_time_constants / (2.0 * np.pi * bandwidth_hz)
    at_rest, lo, hi = band_at_rest(model, dq, band or friction_band(model, phi, None, 0.0), min_speed,
                                   lambda slow: _held(t, slow, hold_s))
    r = first_order(t, x, bandwidth_hz)
    del x
    if tracking is not None and inputs:  # the monitor's causal supply tracking, on the low-passed rows
        r = _tracked(model, phi, tracking, min_speed, t, q, dq, inputs, r, bandwidth_hz)
    # r ≈ friction held − external torque on a resting row: outside the band only
    e = np.where(at_rest, r - np.clip(r, lo, hi), r)
    tau_ext = np.zeros((n, len(cfg.joints)))
    for g, gj, rows in group_rows(model):
        L, _ = group_row_maps(g)
        tau_ext[:, gj] = -np.linalg.solve(L, r[:, rows].T).T
    return MomentumResiduals(t, r, e, dq, at_rest, tau_ext)


def _tracked(model: RobotModel, phi: np.ndarray, tracking, min_speed: float, t: np.ndarray, q: np.ndarray,
             dq: np.ndarray, inputs: dict, r: np.ndarray, bandwidth_hz: float) -> np.ndarray:
    """r with the PWM rows re-predicted through the causal supply tracker (dynid.identify.supply): on a PWM row,
    r = lowpass(u)·g − lowpass(prediction), so lowpass(u) and r/g are the tracker's input and residual."""
    from ..identify.supply import tracked_residuals
    from ..robot.outputs import divisors
    from ..robot.regressors.stack import Signals

    g = divisors(model, phi)
    u_f = {m: first_order(t, np.asarray(v, float), bandwidth_hz) for m, v in inputs.items()}
    sig = Signals(q, dq, dq, u_f, {}, {})
    e = tracked_residuals(model, tracking, min_speed, r / g, sig, t)
    return e * g
