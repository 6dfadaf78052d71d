"""The monitor's own derivative estimator, mirrored: a fixed-lag Savitzky-Golay filter on uniform samples.

At sample k the monitor fits a polynomial of degree `order` by least squares to the last `window` samples and
evaluates it, and its first two derivatives, at sample k − `lag` (lag 0: purely causal, at the newest sample;
lag (window − 1)/2: the centred, offline filter). The fit is linear in the samples, so each estimate is a fixed
set of weights, oldest sample first; the coefficient file carries the weights and rt_monitor applies them in
the same order as `FixedLagSavitzkyGolay.apply`, so the two agree to rounding.

Like `dynid.io.derivatives`' offline filter, the same value weights also smooth the measured outputs (F/T, PWM),
so the regressor and the measurement see the same band and the same delay (Gautier's parallel filtering).
Λ and the T² thresholds of the coefficient file are computed on signals made here (docs/design.md §3): the monitor
then meets the false-positive rate its threshold promises.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..errors import DataError
from ..identify.model_sections import FoldsSection
from ..identify.supply import SupplyTracking, tracked_residuals
from ..io.derivatives import SavitzkyGolay
from ..robot.effects import augmented_residuals
from ..robot.model import RobotModel
from ..robot.outputs import divisors, output_channels
from ..robot.regressors.stack import Signals, gravity_per_sample, payload_of
from .t2 import calibrate

# The monitor's filter takes one sample per period, whatever its stamp: a logged run whose stamps jitter around the
# median step (a UR10e log at 100 Hz: 8-16 ms) is taken one sample per median step, as `dynid play --stamps nominal`
# plays it and the robot's own loop sends it. A step this many periods long or more has samples missing in it.
MISSING_STEPS = 1.75
# As the monitor's sample clock does (rt_monitor/include/rt_monitor/sample_clock.hpp, kMaxBridge): up to this many
# missing samples in a row are bridged by linear interpolation; a longer gap restarts its filter.
MAX_BRIDGE = 3


@dataclass(frozen=True)
class FixedLagSavitzkyGolay:
    window: int  # samples
    order: int  # polynomial degree (≥ 2 for q̈)
    lag: int  # samples behind the newest (0 = causal)
    sample_period: float  # s

    def __post_init__(self) -> None:
        if self.window < 3 or self.order < 2 or self.order >= self.window:
            raise DataError(f"fixed-lag filter: need 2 ≤ order < window and window ≥ 3 (window {self.window}, "
                            f"order {self.order})")
        if not 0 <= self.lag < self.window:
            raise DataError(f"fixed-lag filter: lag must be in [0, {self.window - 1}], got {self.lag}")
        if not (np.isfinite(self.sample_period) and self.sample_period > 0):
            raise DataError(f"fixed-lag filter: sample period must be positive, got {self.sample_period}")

    def weights(self) -> np.ndarray:
        """(3, window): value, first and second derivative at sample k − lag from samples k − window + 1 … k."""
        # Fit in units of samples (well conditioned), then scale by the period.
        s = np.arange(self.window, dtype=float) - (self.window - 1 - self.lag)
        V = np.vander(s, self.order + 1, increasing=True)  # columns 1, s, s², …
        P = np.linalg.pinv(V)  # rows: polynomial coefficients as weights on the samples
        dt = self.sample_period
        return np.vstack([P[0], P[1] / dt, 2.0 * P[2] / dt**2])

    def apply(self, x: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
        """(3, N − window + 1, c) estimates for samples window − 1 − lag … N − 1 − lag of x (N, c)."""
        w = self.weights() if weights is None else weights
        x = np.asarray(x, dtype=float)
        n = x.shape[0] - self.window + 1
        if n <= 0:
            raise DataError(f"{x.shape[0]} samples are fewer than the monitor's filter window ({self.window})")
        out = np.zeros((3, n) + x.shape[1:])
        for i in range(self.window):  # the monitor's summation order: oldest sample first
            out += w[:, i, None, None] * x[None, i : i + n] if x.ndim == 2 else w[:, i, None] * x[None, i : i + n]
        return out

    def as_dict(self) -> dict:
        return {"method": "fixed-lag savgol", "window": self.window, "order": self.order, "lag": self.lag,
                "sample_period": self.sample_period, "delay_s": self.lag * self.sample_period}


def estimator_for(model: RobotModel, t: np.ndarray, lag: int | None, window: int | None = None,
                  period: float | None = None) -> FixedLagSavitzkyGolay:
    """The online filter for data sampled at times t (at `period`, default their median step): window and order of
    the configuration's offline smoother."""
    steps = np.diff(np.asarray(t, float))
    if steps.size == 0:
        raise DataError("the data have a single sample: no sample period")
    dt = float(np.median(steps)) if period is None else float(period)
    if not dt > 0:
        raise DataError(f"the data's median sample step is {dt:.6g} s: stamps must increase")
    if np.any(steps <= 0) or np.max(steps) >= MISSING_STEPS * dt:
        k = int(np.argmax((steps <= 0) | (steps >= MISSING_STEPS * dt))) + 1
        raise DataError(f"the monitor's filter takes one sample per period; step {k} is {steps[k - 1]:.6g} s against a "
                        f"median of {dt:.6g} s (samples missing or out of order there): cut the run around it "
                        "with RUN@FROM:TO")
    options = {k: v for k, v in model.config.derivatives.items() if k in ("window_s", "polyorder")}
    sg = SavitzkyGolay(**options)
    w = window or sg.window_samples(dt)
    return FixedLagSavitzkyGolay(int(w), int(sg.polyorder), int((w - 1) // 4 if lag is None else lag), dt)


def uniform_pieces(ds, dt: float) -> list:  # Dataset, s -> [(Dataset, (N',) int)]: io is a lower layer
    """The run as the monitor's filter takes it: gaps of up to MAX_BRIDGE missing samples (a step of MISSING_STEPS
    periods or more: round(step/dt) − 1 samples) bridged by linear interpolation, as its sample clock bridges them,
    and the run cut where more are missing (the monitor restarts its filter there). Each piece with its rows'
    original indices (a bridged row: the one before it)."""
    from ..io.dataset import Dataset

    steps = np.diff(ds.t)
    gaps = np.flatnonzero(steps >= MISSING_STEPS * dt)
    if gaps.size == 0:
        return [(ds, np.arange(ds.n_samples))]
    missing = np.maximum(np.rint(steps[gaps] / dt).astype(int), 2) - 1
    cuts = gaps[missing > MAX_BRIDGE] + 1  # the first row after each long gap
    base = np.arange(ds.n_samples, dtype=float)
    pieces = []
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, ds.n_samples]):
        inside = (gaps >= lo) & (gaps < hi - 1)
        position = np.concatenate([np.arange(lo, hi, dtype=float)] +
                                  [g + np.arange(1, m + 1) / (m + 1) for g, m in zip(gaps[inside], missing[inside])])
        position.sort(kind="stable")

        def at(x: np.ndarray, position: np.ndarray = position) -> np.ndarray:
            if x.ndim == 1:
                return np.interp(position, base, x)
            return np.column_stack([np.interp(position, base, x[:, j]) for j in range(x.shape[1])])

        origin = np.floor(position).astype(int)
        pieces.append((Dataset(t=at(ds.t), joints=ds.joints, q=at(ds.q), dq=None if ds.dq is None else at(ds.dq),
                               ddq=None if ds.ddq is None else at(ds.ddq), pwm={k: at(v) for k, v in ds.pwm.items()},
                               current={k: at(v) for k, v in ds.current.items()},
                               tau={k: at(v) for k, v in ds.tau.items()}, ft={k: at(v) for k, v in ds.ft.items()},
                               contact=None if ds.contact is None else ds.contact[origin],
                               extra={k: at(v) for k, v in ds.extra.items()},
                               meta={**ds.meta, "bridged_samples": int(len(position) - (hi - lo))}), origin))
    return pieces


@dataclass(frozen=True)
class PieceFolds:
    """The model's folds (time blocks and the Φ fitted without each) seen from runs cut by `uniform_pieces`: what
    FoldsSection.segments gives for a run, for a piece of it. `origins[i]`: piece i's rows' original indices,
    `runs[i]`: the run (the model's `data` order) it is of."""

    folds: FoldsSection
    origins: Sequence[np.ndarray]
    runs: Sequence[int]

    def segments(self, piece: int, n_samples: int, phi: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
        """[start, stop) of piece rows 0 … n_samples and the Φ that never saw their original samples (a bridged row
        is of the sample before it: its origin)."""
        origin = np.asarray(self.origins[piece])[:n_samples]
        out = []
        for a, b, phi_k in self.folds.segments(int(self.runs[piece]), int(origin[-1]) + 1, phi):
            lo, hi = int(np.searchsorted(origin, a)), int(np.searchsorted(origin, b))
            if hi > lo:
                out.append((lo, hi, phi_k))
        return out


def online_signals(model: RobotModel, est: FixedLagSavitzkyGolay, t: np.ndarray, q: np.ndarray,
                   inputs: dict[str, np.ndarray], tau: dict[str, np.ndarray],
                   ft: dict[str, np.ndarray], gravity: np.ndarray | None = None) -> Signals:
    """What the monitor sees: every channel through the fixed-lag filter (estimates at k − lag, k ≥ window − 1);
    `gravity` (N, 3) per sample for a tilting base, filtered like the rest."""
    columns = [q] + [v[:, None] for v in inputs.values()] + [v[:, None] for v in tau.values()] + list(ft.values())
    columns += [] if gravity is None else [gravity]
    x = np.hstack(columns)
    value, d1, d2 = est.apply(x)
    nj = q.shape[1]
    cut = np.cumsum([c.shape[1] for c in columns])[:-1]
    parts = iter(np.split(value, cut, axis=1))
    qf = next(parts)
    inputs_f = {k: next(parts)[:, 0] for k in inputs}
    tau_f = {k: next(parts)[:, 0] for k in tau}
    ft_f = {k: next(parts) for k in ft}
    return Signals(qf, d1[:, :nj], d2[:, :nj], inputs_f, tau_f, ft_f, None,
                   None if gravity is None else next(parts))


def raw_signals(model: RobotModel, dataset) -> tuple[np.ndarray, np.ndarray, dict, dict, dict]:  # dataset: Dataset
    """(t, q, inputs, tau, ft) as the monitor receives them, unfiltered, picked as the configuration names them."""
    cfg = model.config
    if tuple(dataset.joints) != cfg.joints:
        raise DataError(f"the dataset's joints {list(dataset.joints)} differ from the configuration's {list(cfg.joints)}")
    inputs, tau = {}, {}
    for g in cfg.actuation:
        if g.input == "torque":
            for j in g.joints:
                if j not in dataset.tau:
                    raise DataError(f"the data have no tau.{j}, which actuation group '{g.name}' needs")
                tau[j] = dataset.tau[j]
            continue
        source = dataset.pwm if g.input == "pwm" else dataset.current
        for m in g.motors:
            if m not in source:
                raise DataError(f"the data have no {g.input}.{m}, which actuation group '{g.name}' needs")
            inputs[m] = source[m]
    ft = {}
    for s in cfg.ft_sensors:
        if s.name not in dataset.ft:
            raise DataError(f"the data have no ft.{s.name}.* columns, which the configuration's F/T sensor needs")
        ft[s.name] = dataset.ft[s.name]
    return dataset.t, dataset.q, inputs, tau, ft


@dataclass(frozen=True)
class OnlineCalibration:
    variance: np.ndarray  # Λ (n_out,), through the online filter
    threshold: float  # T²_α of the calibrated detector (dynid.detect.t2), through the online filter
    ft_thresholds: dict[str, float]  # sensor -> α-quantile of its six channels' share of T² (the contact's side)
    samples: int
    # (n_joints,) variance of τ_ext = map · (divisor ⊙ e) over the rows in T² (rt_monitor's acceleration isolation)
    tau_variance: np.ndarray | None = None


def online_times(est: FixedLagSavitzkyGolay, t: np.ndarray) -> np.ndarray:
    """The time stamps of the samples `online_signals` estimates (k − lag for k = window − 1 … N − 1)."""
    return np.asarray(t, float)[est.window - 1 - est.lag : len(t) - est.lag]


def calibrate_online(model: RobotModel, phi: np.ndarray, datasets: list, est: FixedLagSavitzkyGolay, alpha: float,
                     min_speed: float, stride: int = 2, effects: list | None = None,
                     tracking: SupplyTracking | None = None, tau_map: np.ndarray | None = None,
                     folds: FoldsSection | None = None, origins: list[np.ndarray] | None = None,
                     runs: list[int] | None = None) -> OnlineCalibration:
    """Λ and the thresholds of dynid's calibrated detector, on contact-free data seen through the online filter
    (with the augmented model's `effects`, dynid.robot.effects, and the supply `tracking`, as the monitor evaluates
    them; the tracker sees every `stride`-th sample, with the same time constant in seconds). With `folds` (the runs
    are those the model was fitted on, in its `data` order) each time block's residual is taken through the Φ
    fitted without it: cross-validated, what the monitor sees on a new run. Runs cut by uniform_pieces: `origins`,
    each piece's rows' original indices, and `runs`, the run each piece is of (the folds hold the original ones)."""
    if folds is not None and origins is not None:
        folds = PieceFolds(folds, origins, runs if runs is not None else range(len(datasets)))
    es, dqs = [], []
    for i, ds in enumerate(datasets):
        raw = raw_signals(model, ds)
        keep = slice(None, None, stride)
        sig = online_signals(model, est, *raw, gravity=gravity_per_sample(model, ds))
        sig = replace(sig, payload=payload_of(model, ds)).slice(keep)  # a loaded run's known payload, as the fit had it
        if folds is None:
            e = augmented_residuals(model, phi, effects or [], sig)
        else:  # the filter's k-th estimate is of sample window − 1 − lag + k of the run (or piece)
            index = est.window - 1 - est.lag + stride * np.arange(sig.q.shape[0])
            parts = []
            for a, b, phi_k in folds.segments(i, ds.n_samples, phi):
                lo, hi = np.searchsorted(index, a), np.searchsorted(index, b)
                if hi > lo:
                    parts.append(augmented_residuals(model, phi_k, effects or [], sig.slice(slice(lo, hi))))
            e = np.vstack(parts)
        es.append(tracked_residuals(model, tracking, min_speed, e, sig, online_times(est, raw[0])[keep]))
        dqs.append(sig.dq)
    e, dq = np.vstack(es), np.vstack(dqs)
    det = calibrate(model, phi, e, dq, alpha, min_speed, variants=("calibrated",))["calibrated"]
    outs = output_channels(model)
    ft_thresholds = {}
    for s in model.config.ft_sensors:
        rows = [o.row for o in outs if o.kind == "ft" and o.name.startswith(f"ft.{s.name}.")]
        ft_thresholds[s.name] = float(np.quantile(np.sum(e[:, rows] ** 2 / det.variance[rows], axis=1), alpha))
    return OnlineCalibration(det.variance, det.threshold, ft_thresholds, int(e.shape[0]),
                             accel_tau_variance(model, phi, e, det.active(model, dq), tau_map))


def accel_tau_variance(model: RobotModel, phi: np.ndarray, e: np.ndarray, active: np.ndarray,
                       tau_map: np.ndarray | None) -> np.ndarray | None:
    """(n_joints,) variance of the external joint torques the monitor estimates from the acceleration residuals,
    τ_ext = map · (divisor ⊙ e) over the rows in T², on contact-free residuals e; 0 where no row sees a joint."""
    if tau_map is None:
        return None
    rows = np.where(active, e * divisors(model, phi), 0.0)
    rows[:, [o.row for o in output_channels(model) if o.kind == "ft"]] = 0.0
    tau = rows @ tau_map.T
    return np.mean(tau**2, axis=0)
