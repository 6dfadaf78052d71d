"""Hotelling T² contact detection on the model's residuals (docs/design.md §3), two variants.

- ``paper`` (Traversaro et al. 2013): T² = eᵀ Λ⁻¹ e over every output, Λ = diag of the residual variances on
  the identification data, threshold T²_α = n(N−1)/(N−n)·F(n, N−n; α), n = dim(e) by default (the paper writes
  n = ν; `n_mode="nu"`). That F threshold assumes independent Gaussian residuals; the PWM residuals are neither:
  at velocity reversals and while a joint rests, Coulomb friction flips or static friction holds what the
  model cannot say, so they are heavy-tailed and autocorrelated, and the threshold does not keep its promise.
  While a friction coordinate rests its Coulomb law is set-valued (any torque in [−fc_neg, fc_pos] holds it), so
  the residual of a row at rest is its distance to that band (`static_band_residuals`), not its distance to
  the sign an encoder-derived q̇ happens to give; the band uses only the model's own Coulomb coefficients.
- ``calibrated`` (dynid's default): a motor channel whose row is at rest (a joint or motor of it slower than
  `min_speed`, `dynid.robot.regressors.stack.rows_at_rest`) is left out of the sum for that sample, Λ of the motor
  channels comes from moving samples only, and the threshold is the empirical α-quantile of this T² on the
  contact-free identification data: a false-positive rate of 1 − α by construction, whatever the residuals'
  distribution, as long as new contact-free data look like the identification data.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from ..identify.fit import SignalSource
from ..identify.model_sections import (ALPHA, CROSS_VALIDATED, DEFAULT_N_MODE, IN_SAMPLE, DetectorSection,
                                      Quantiles, T2Calibration)
from ..identify.supply import SupplyTracking, smoothed_residuals
from ..io.dataset import contact_episodes
from ..robot.model import RobotModel
from ..robot.outputs import divisors, output_channels
from ..robot.regressors.friction import friction_regressor
from ..robot.regressors.stack import DEFAULT_MIN_SPEED, Signals, friction_coordinates, rows_at_rest

VARIANTS: tuple[str, ...] = ("calibrated", "paper")
CALIBRATION_CHUNK = 30_000  # samples (even, so the stride stays aligned across chunks)
CALIBRATION_STRIDE = 2  # every other sample of the identification run calibrates T² (quantiles need no more)
# At most this many samples calibrate T², all runs together: a coarser stride past it (an hour at 1 kHz: every 6th
# sample, 10 per tracker time constant of the tracked supply at 1.5 s still). The residuals, q̇ and the inputs of these
# samples are what the calibration holds in memory (about 0.2 GB at the cap on the default arm).
MAX_CALIBRATION_SAMPLES = 600_000
QUANTILE_LEVELS = np.sort(1.0 - np.logspace(-4, np.log10(0.5), 240))  # α in 0.5 … 0.9999, ascending


def f_threshold(n: int, N: int, alpha: float) -> float:
    """T²_α = n(N−1)/(N−n) · F(n, N−n; α)."""
    # The F quantile scipy.stats.f.ppf computes, from scipy.special: scipy.stats' import (0.15 s more) is left to
    # the commands that need it.
    from scipy.special import fdtri

    return float(n * (N - 1) / (N - n) * fdtri(n, N - n, alpha))


def chi2_quantile(alpha: float, dof: int) -> float:
    """χ²(dof) at α: scipy.stats.chi2.ppf's own formula, 2·P⁻¹(dof/2, α), from scipy.special."""
    from scipy.special import gammaincinv

    return float(2.0 * gammaincinv(dof / 2.0, alpha))


@dataclass(frozen=True)
class Detector:
    variant: str
    variance: np.ndarray  # Λ (n_out,)
    threshold: float
    alpha: float
    min_speed: float
    n: int  # the n of the F threshold (paper) or dim(e)

    def active(self, model: RobotModel, dq: np.ndarray) -> np.ndarray:
        """(N, n_out) bool: the channels that enter T² at each sample."""
        if self.variant == "paper":
            return np.ones((dq.shape[0], len(self.variance)), dtype=bool)
        return ~rows_at_rest(model, dq, self.min_speed)

    def t2(self, model: RobotModel, e: np.ndarray, dq: np.ndarray, phi: np.ndarray | None = None) -> np.ndarray:
        """T² per sample; the paper's variant needs the model's Φ for the static-friction band."""
        if self.variant == "paper":
            if phi is None:
                raise ValueError("the paper's T² needs Φ (the static-friction band of resting rows)")
            e = static_band_residuals(model, phi, dq, e, self.min_speed)
        return np.sum(np.where(self.active(model, dq), e**2 / self.variance, 0.0), axis=1)

    def section(self) -> T2Calibration:
        """What the model file keeps of it (its `detector` section's entry)."""
        return T2Calibration(self.variant, self.variance, self.threshold, self.alpha, self.min_speed, self.n)

    @classmethod
    def of(cls, s: T2Calibration) -> Detector:
        return cls(s.variant, s.variance, s.threshold, s.alpha, s.min_speed, s.n)


def static_band_residuals(model: RobotModel, phi: np.ndarray, dq: np.ndarray, e: np.ndarray,
                          min_speed: float) -> np.ndarray:
    """e with every row at rest replaced by its distance to the static-friction band of its resting coordinates.

    A coordinate (joint, or coupled motor at q̇_m = T q̇) slower than `min_speed` contributes L·[−fc_neg, fc_pos]
    (C· for a motor) to its rows instead of the Coulomb term its derived q̇'s sign chose. Rows with no resting
    coordinate, and the F/T rows, are returned unchanged.
    """
    g = divisors(model, phi)
    out = e.copy()
    for rows, coordinates in friction_coordinates(model, dq):
        applied = np.zeros((dq.shape[0], rows.stop - rows.start))  # the Coulomb torque the sign chose, on resting ones
        lo, hi = np.zeros_like(applied), np.zeros_like(applied)
        for c in coordinates:
            fc_pos, fc_neg = phi[model.layout.block(*c.block).slice][:2]
            slow = (np.abs(c.velocity) < min_speed)[:, None]
            coulomb = friction_regressor(c.velocity)[:, :2] @ np.array([fc_pos, fc_neg])  # the law's sign, as fitted
            applied += np.where(slow, coulomb[:, None] * c.share, 0.0)
            ends = np.stack([c.share * fc_pos, -c.share * fc_neg])
            lo += np.where(slow, ends.min(axis=0), 0.0)
            hi += np.where(slow, ends.max(axis=0), 0.0)
        gain = g[rows]
        free = e[:, rows] + applied / gain  # e = (b − AΦ)/g: the residual without the resting Coulomb terms
        band_lo, band_hi = np.minimum(lo / gain, hi / gain), np.maximum(lo / gain, hi / gain)
        out[:, rows] = free - np.clip(free, band_lo, band_hi)
    return out


def calibration_stride(total_samples: int) -> int:
    """Every how many samples calibrate T²: `CALIBRATION_STRIDE`, coarser once the runs hold more than
    `MAX_CALIBRATION_SAMPLES` together (the calibration's memory then stays bounded, whatever the logs' length)."""
    return max(CALIBRATION_STRIDE, -(-int(total_samples) // MAX_CALIBRATION_SAMPLES))


Segments = Sequence[tuple[int, int, np.ndarray]]  # [start, stop) of a run's samples and the Φ its residual takes
# residuals_of(signals, t in the data's own seconds, [Φ, ...]) -> each Φ's e of those samples
# (dynid.robot.effects.augmented_residuals_many: the rows built once for every Φ)
ResidualsOf = Callable[[Signals, np.ndarray, Sequence[np.ndarray]], list[np.ndarray]]


def calibration_residuals(model: RobotModel, datasets: Sequence, settings,
                          residuals_of: ResidualsOf, tracking: SupplyTracking | None = None,
                          phi: np.ndarray | None = None,
                          segments: Sequence[Segments | None] | None = None) -> tuple[np.ndarray, ...]:
    """(e, q̇, e with constant gains, e in-sample) on every `calibration_stride`-th sample of the contact-free runs,
    a chunk at a time (bounded memory), with offline derivatives; `residuals_of` gives each Φ's e of a chunk (see
    `ResidualsOf`). With each run's `segments` (dynid.identify.model_sections.FoldsSection.segments), e is
    cross-validated: each block's through the Φ fitted without it; the in-sample e (through `phi`) comes beside.
    With `tracking`, the input channels are those of the offline, two-sided supply estimate
    (dynid.identify.supply.smoothed_residuals) of each run; without, e and e with constant gains are the same."""
    stride = calibration_stride(sum(ds.n_samples for ds in datasets))
    parts = [run_calibration_residuals(model, ds, settings, residuals_of, tracking, stride, phi,
                                       None if segments is None else segments[i]) for i, ds in enumerate(datasets)]
    return join_calibration(parts)


def join_calibration(parts: Sequence[tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
    """`calibration_residuals`' arrays from each run's, in the runs' order."""
    return tuple(np.vstack([p[i] for p in parts]) for i in range(len(parts[0])))


def run_calibration_residuals(model: RobotModel, ds, settings,  # noqa: ANN001 - a Run, FitSettings
                              residuals_of: ResidualsOf, tracking: SupplyTracking | None, stride: int,
                              phi: np.ndarray | None = None,
                              segments: Segments | None = None) -> tuple[np.ndarray, ...]:
    """One run's part of `calibration_residuals` (a task of its own on a Dask cluster)."""
    source = SignalSource(model, ds, settings, instruments=False)
    keep = slice(None, None, stride)
    chunk = stride * (CALIBRATION_CHUNK // stride)  # about CALIBRATION_CHUNK samples, a multiple of the stride
    run_e, run_in, run_dq, run_t, run_inputs = [], [], [], [], []
    for lo in range(0, ds.n_samples, chunk):
        hi = min(lo + chunk, ds.n_samples)
        sig = source(lo, hi)[0].slice(keep)
        t = ds.times(lo, hi)[keep].copy()
        if segments is None:
            e_in = e = residuals_of(sig, t, [phi])[0]
        else:
            e_in, e = _segment_residuals(sig, t, lo, stride, segments, residuals_of, phi)
        run_in.append(e_in)
        run_e.append(e)
        # Copies: a strided view would keep its whole chunk alive, and every chunk of the run with it
        run_dq.append(sig.dq.copy())
        run_t.append(t)
        run_inputs.append({m: v.copy() for m, v in sig.inputs.items()})
    e, e_in, dq = np.vstack(run_e), np.vstack(run_in), np.vstack(run_dq)
    del run_e, run_in, run_dq  # the chunks, now copied: half the memory of a long run's calibration
    constant = e
    if tracking is not None:  # two-sided over the whole run (the strided samples: the same seconds)
        inputs = {m: np.concatenate([part[m] for part in run_inputs]) for m in run_inputs[0]}
        whole = Signals(dq, dq, dq, inputs, {}, {})  # the tracker reads q̇ and the inputs only
        t_all = np.concatenate(run_t)
        e = smoothed_residuals(model, tracking, settings.min_speed, e, whole, t_all)
        e_in = e if segments is None else smoothed_residuals(model, tracking, settings.min_speed, e_in, whole, t_all)
    return e, dq, constant, e_in


def _segment_residuals(sig: Signals, t: np.ndarray, lo: int, stride: int, segments: Segments,
                       residuals_of: ResidualsOf, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(e through `phi`, e through each segment's Φ) of a strided chunk whose first sample is the run's sample `lo`;
    the segments cover the run, so both hold every row of the chunk."""
    index = lo + stride * np.arange(t.size)  # the run's sample of each row
    whole, own = [], []
    for a, b, phi_k in segments:
        i, j = np.searchsorted(index, a), np.searchsorted(index, b)
        if j > i:
            part = sig.slice(slice(i, j))
            e = residuals_of(part, t[i:j], [phi] if phi_k is phi else [phi, phi_k])
            whole.append(e[0])
            own.append(e[-1])
    return np.vstack(whole), np.vstack(own)


def detector_record(model: RobotModel, detectors: dict[str, Detector], e: np.ndarray,
                    dq: np.ndarray, in_sample: Detector | None = None) -> DetectorSection:
    """The model file's `detector` section: both variants, N, the calibrated T²'s quantiles (`--alpha`), and with
    `in_sample` (e cross-validated) the calibrated variant as the fit's own residuals would have calibrated it."""
    t2 = detectors["calibrated"].t2(model, e, dq)
    return DetectorSection(detectors["paper"].section(), detectors["calibrated"].section(), int(e.shape[0]),
                           Quantiles(QUANTILE_LEVELS.copy(), np.quantile(t2, QUANTILE_LEVELS)),
                           CROSS_VALIDATED if in_sample is not None else IN_SAMPLE,
                           None if in_sample is None else in_sample.section())


def calibrate(model: RobotModel, phi: np.ndarray, e: np.ndarray, dq: np.ndarray, alpha: float = ALPHA,
              min_speed: float = DEFAULT_MIN_SPEED,
              n_mode: str = DEFAULT_N_MODE, nu: int | None = None, variants: Sequence[str] = VARIANTS,
              e_constant: np.ndarray | None = None) -> dict[str, Detector]:
    """The detectors (both by default) from contact-free residuals e (N, n_out) of the identification data, fitted Φ;
    the paper's variant, as published, on the residuals with constant gains `e_constant` (default e)."""
    N, n_out = e.shape
    # A channel whose residual never varies (a constant channel the model reproduces) keeps its noise variance.
    noise = np.array([o.sigma for o in output_channels(model)]) ** 2
    out: dict[str, Detector] = {}
    if "paper" in variants:
        n = n_out if n_mode == "dim" else int(nu or n_out)
        if N <= n:
            raise DataError(f"{N} calibration samples for a T² of {n} outputs: too few")
        banded = static_band_residuals(model, phi, dq, e if e_constant is None else e_constant, min_speed)
        variance = banded.var(axis=0)
        out["paper"] = Detector("paper", np.where(variance > 0, variance, noise), f_threshold(n, N, alpha), alpha,
                                min_speed, n)
    if "calibrated" not in variants:
        return out
    rest = rows_at_rest(model, dq, min_speed)
    moving = (~rest).sum(axis=0)  # a channel can have none: a joint that never moves
    variance = np.where(rest, 0.0, e**2).sum(axis=0) / np.maximum(moving, 1)
    variance = np.where((moving > 0) & (variance > 0), variance, e.var(axis=0))
    variance = np.where(variance > 0, variance, noise)
    draft = Detector("calibrated", variance, np.inf, alpha, min_speed, n_out)
    threshold = float(np.quantile(draft.t2(model, e, dq), alpha))
    out["calibrated"] = Detector("calibrated", variance, threshold, alpha, min_speed, n_out)
    return out


# ------------------------------------------------------------------------------------------------------------
# Scoring against the skin's ground truth


ONSET_S = 0.010  # an episode is found by T² above its level this long in a row: the monitor's default onset


def onset_samples(t: np.ndarray) -> int:
    """The samples in a row an onset takes at `t`'s median step (ONSET_S; at least one)."""
    return max(1, round(ONSET_S / float(np.median(np.diff(t))))) if t.size > 1 else 1


def sustained(alarm: np.ndarray, k: int) -> np.ndarray:
    """The alarm's samples that belong to a run of at least `k` in a row: what the monitor's debounce keeps."""
    if k <= 1:
        return alarm
    on = np.zeros(alarm.size, dtype=bool)
    for a, b in contact_episodes(alarm):  # the alarm's runs, as a contact column's episodes
        if b - a >= k:
            on[a:b] = True
    return on


def debounced_events(statistic: np.ndarray, threshold: float, on: int, off: int,
                     hysteresis: float) -> list[tuple[int, int | None]]:
    """The contact events the monitor's detector makes of these samples (rt_monitor's Core::detect): an onset at the
    `on`-th sample in a row above `threshold`, its end at the `off`-th in a row under `hysteresis` × `threshold`
    (NaN is neither), each count starting afresh after the other's event. (onset, end) sample indices; the end None
    where the run ends in contact."""
    def first_run(mask: np.ndarray, length: int) -> Callable[[int], int | None]:
        total = np.concatenate([[0], np.cumsum(mask, dtype=np.int64)])
        starts = np.flatnonzero(total[length:] - total[:-length] == length)  # windows of `length` all in mask

        def at_or_after(lo: int) -> int | None:  # the last sample of the first such window starting at lo or later
            i = int(np.searchsorted(starts, lo))
            return int(starts[i]) + length - 1 if i < starts.size else None

        return at_or_after

    statistic = np.asarray(statistic, float)
    onset = first_run(statistic > threshold, max(1, on))
    end = first_run(statistic < hysteresis * threshold, max(1, off))
    events: list[tuple[int, int | None]] = []
    lo = 0
    while (k := onset(lo)) is not None:
        j = end(k + 1)
        events.append((k, j))
        if j is None:
            break
        lo = j + 1
    return events


def episode_peaks(statistic: np.ndarray, events: Sequence[tuple[int, int | None]]) -> list[int]:
    """The sample each of `debounced_events`' contacts peaks at, which the monitor's end event describes (its sides,
    wrenches, external torques, isolated link: rt_monitor's Core::detect): the first largest statistic from the onset
    to the sample before the end (to the last sample where it does not end); NaN never."""
    statistic = np.where(np.isnan(statistic), -np.inf, np.asarray(statistic, float))
    return [k + int(np.argmax(statistic[k : statistic.size if j is None else j])) for k, j in events]


def episode_onsets(t: np.ndarray, alarm: np.ndarray, contact: np.ndarray, k: int = 1) -> list[float | None]:
    """Each contact episode's delay from its start to its first alarm sample (with `k` > 1, of an alarm sustained
    for `k` samples: `sustained`), None where it has none."""
    on = sustained(alarm, k)
    delays: list[float | None] = []
    for a, b in contact_episodes(contact):
        hits = np.flatnonzero(on[a:b])
        delays.append(float(t[a + hits[0]] - t[a]) if hits.size else None)
    return delays


def score(t: np.ndarray, t2: np.ndarray, threshold: float, contact: np.ndarray | None,
          side: np.ndarray | None = None) -> dict:
    """TPR, FPR (per sample), ROC and AUC, detection delays per episode, TPR per side of the F/T sensor. An episode
    counts as found by its first sample above the level (`episodes_detected`, the delays) and, apart, by an alarm
    sustained for ONSET_S as the monitor's onset takes it (`episodes_sustained`): at a 1 % false-positive rate a
    single sample finds an episode of 70 samples by chance one time in two."""
    return _score(t, t2, threshold, contact, side)[0]


def _score(t: np.ndarray, t2: np.ndarray, threshold: float, contact: np.ndarray | None,
           side: np.ndarray | None = None) -> tuple[dict, list[float | None]]:
    """(`score`'s result, each episode's onset delay: None where missed)."""
    from sklearn.metrics import roc_auc_score, roc_curve  # ~0.3 s: only where detection is scored

    keep = np.isfinite(t2)  # NaN: a sample not evaluated (the derivative filter's edges: evaluation.filter_edges)
    if not keep.all():
        t, t2 = np.asarray(t)[keep], np.asarray(t2)[keep]
        contact = None if contact is None else np.asarray(contact)[keep]
        side = None if side is None else np.asarray(side)[keep]
    alarm = t2 > threshold
    out: dict = {"threshold": threshold, "alarm_rate": float(alarm.mean()), "samples": int(t2.size)}
    if contact is None:
        out["fpr"] = out["alarm_rate"]
        return out, []
    truth = contact != 0
    out["contact_fraction"] = float(truth.mean())
    out["tpr"] = float(alarm[truth].mean()) if truth.any() else None
    out["fpr"] = float(alarm[~truth].mean()) if (~truth).any() else None
    if truth.any() and (~truth).any():
        fpr, tpr, _ = roc_curve(truth, t2)
        keep = np.unique(np.linspace(0, fpr.size - 1, min(fpr.size, 400)).round().astype(int))
        out["auc"] = float(roc_auc_score(truth, t2))
        out["roc"] = {"fpr": fpr[keep].tolist(), "tpr": tpr[keep].tolist()}
    onsets = episode_onsets(t, alarm, contact)
    delays = [d for d in onsets if d is not None]
    out["episodes"] = len(onsets)
    out["episodes_detected"] = len(delays)
    k = onset_samples(t)
    held = episode_onsets(t, alarm, contact, k)
    out["episodes_sustained"] = {"samples": k, "found": sum(d is not None for d in held)}
    out["delay_s"] = {"median": float(np.median(delays)) if delays else None,
                      "p90": float(np.percentile(delays, 90)) if delays else None}
    if side is not None:
        out["tpr_by_side"] = {}
        for name, code in (("distal", 1.0), ("proximal", -1.0)):
            sel = truth & (side == code)
            out["tpr_by_side"][name] = float(alarm[sel].mean()) if sel.any() else None
    return out, onsets


def channel_names(model: RobotModel) -> list[str]:
    return [o.name for o in output_channels(model)]


def score_with_delays(t: np.ndarray, t2: np.ndarray, threshold: float, contact: np.ndarray | None,
                      side: np.ndarray | None = None, shift_s: float = 0.0) -> dict:
    """dynid.detect.t2.score plus every episode's onset delay (None: missed) and, with `shift_s`, the delays
    against the labels' start + shift_s (labels widened by shift_s, as the UR10e folder's are)."""
    out, delays = _score(t, t2, threshold, contact, side)
    if contact is None:
        return out
    out["onset_delays_s"] = delays
    found = [d for d in delays if d is not None]
    if found:
        out["delay_s"]["max"] = float(max(found))
    if shift_s and found:
        shifted = [d - shift_s for d in found]
        out["delay_s_shifted"] = {"shift_s": shift_s, "median": float(np.median(shifted)),
                                  "p90": float(np.percentile(shifted, 90)), "max": float(max(shifted))}
    return out
