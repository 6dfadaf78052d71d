"""T² on the generalized-momentum residuals (dynid.detect.momentum): calibration, contact events with isolation
and the estimated external torque and wrench, scoring against labels (`dynid detect --residual momentum`).

- **Calibration** as dynid's calibrated detector does it (dynid.detect.t2): Λ per channel from contact-free runs
  through the same observer (the rows of resting coordinates left out of Λ, where the band-clipped residual is
  zero by construction), and T²_α the empirical α-quantile of T² on those runs, so α keeps its promise on data
  like them. Every channel enters T² at every sample: at rest a row's residual is its distance outside the
  static-friction band, so a resting arm can be pushed and seen.
- **Isolation**: per F/T sensor, the share of T² on its six channels against that share's α-quantile on the
  calibration runs: above it, the contact is on the sensor's distal side, else proximal; the joint: the most
  distal joint whose external torque estimate exceeds `ISOLATION_SIGMAS` of its calibration noise (its link or
  one beyond it carries the contact).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..io.bad_rows import DEFAULT_POLICY
from ..identify.model_sections import ALPHA, CROSS_VALIDATED, IN_SAMPLE, BaseSection, FoldsSection, Quantiles
from ..identify.observer_sections import CombinedCalibration, MomentumCalibration, ObserverEntry, ObserverSection
from ..robot.model import RobotModel
from ..robot.outputs import output_channels
from ..robot.regressors.stack import gravity_per_sample
from .momentum import (DEFAULT_BANDWIDTH_HZ, VELOCITY_WINDOW_S, MomentumResiduals, friction_band, measured_velocity,
                       momentum_residuals)
from .online import raw_signals
from .t2 import QUANTILE_LEVELS, chi2_quantile, score_with_delays

ISOLATION_SIGMAS = 3.0
BAND_SIGMAS = 1.0  # the static-friction band is widened by this many standard errors of the Coulomb terms
SETTLE_TIME_CONSTANTS = 5  # the observer starts at rest: its first 5 time constants are not calibrated on
MERGE_GAP_S = 0.02  # alarms closer than this form one event
CALIBRATION_MAX_S = 150.0  # each calibration run's first 150 s
CONTACT_MARGIN_S = 0.5  # a calibration run's labelled contacts are left out with this margin on each side


@dataclass(frozen=True)
class MomentumDetector:
    bandwidth_hz: float
    variance: np.ndarray  # Λ (n_out,) of the band-clipped observer residuals
    tau_variance: np.ndarray  # (n_joints,) of the external joint torque estimate, for isolation
    threshold: float
    alpha: float
    min_speed: float
    band_sigmas: float
    ft_thresholds: dict[str, float]  # sensor -> α-quantile of its channels' share of T²
    samples: int
    velocity_window_s: float = VELOCITY_WINDOW_S
    quantiles: Quantiles | None = None  # of the calibration T²

    def t2(self, e: np.ndarray) -> np.ndarray:
        return np.sum(e**2 / self.variance, axis=1)

    @property
    def rest_threshold(self) -> float:
        """T²_α where every row rests: χ²(n_out) at α (on contact-free runs T² is 0 there by construction)."""
        return chi2_quantile(self.alpha, self.variance.size)

    def statistic(self, e: np.ndarray, at_rest: np.ndarray) -> np.ndarray:
        """T² / T²_α per sample, T²_α the calibrated threshold, or `rest_threshold` where every row rests:
        a contact is a value above 1."""
        all_rest = at_rest.all(axis=1)
        return self.t2(e) / np.where(all_rest, self.rest_threshold, self.threshold)

    def as_dict(self) -> dict:
        return {"variant": "momentum", "bandwidth_hz": self.bandwidth_hz, "variance": self.variance.tolist(),
                "tau_variance": self.tau_variance.tolist(), "threshold": self.threshold,
                "rest_threshold": self.rest_threshold, "alpha": self.alpha,
                "min_speed": self.min_speed, "band_sigmas": self.band_sigmas, "ft_thresholds": self.ft_thresholds,
                "calibration_samples": self.samples, "velocity_window_s": self.velocity_window_s}

    def section(self) -> MomentumCalibration:
        """What the model file keeps of it (an `observer` entry's detector)."""
        extra = {"variant": "momentum", "rest_threshold": self.rest_threshold}
        return MomentumCalibration(self.bandwidth_hz, self.variance, self.tau_variance, self.threshold, self.alpha,
                                   self.min_speed, self.band_sigmas, dict(self.ft_thresholds), self.samples,
                                   self.velocity_window_s, self.quantiles, extra)

    @classmethod
    def of(cls, s: MomentumCalibration) -> MomentumDetector:
        return cls(s.bandwidth_hz, s.variance, s.tau_variance, s.threshold, s.alpha, s.min_speed, s.band_sigmas,
                   dict(s.ft_thresholds), s.calibration_samples, s.velocity_window_s, s.quantiles)


def run_residuals(model: RobotModel, phi: np.ndarray, dataset, bandwidth_hz: float, min_speed: float,
                  band: dict, tracking=None, velocity_window_s: float = VELOCITY_WINDOW_S,
                  measured: bool = True) -> MomentumResiduals:
    """The observer over one run; q̇ the data's own where they carry it (and `measured`), else estimated causally
    (as the monitor, which reads encoders only, does: `measured=False`). A known payload the run carries
    (`dataset.meta["payload"]`, --payload) joins its body's inertial parameters."""
    t, q, inputs, tau, ft = raw_signals(model, dataset)
    payload = dataset.meta.get("payload")
    if payload:
        phi = np.array(phi, float)
        phi[model.layout.span("inertial")] += model.payload_parameters(float(payload["mass"]), payload.get("com"))
    return momentum_residuals(model, phi, t, q, inputs, tau, ft, gravity_per_sample(model, dataset),
                              bandwidth_hz=bandwidth_hz, min_speed=min_speed, band=band, tracking=tracking,
                              velocity_window_s=velocity_window_s,
                              dq=measured_velocity(model, dataset) if measured else None)


def calibrate_momentum(model: RobotModel, phi: np.ndarray, base: BaseSection | None, datasets: Sequence,
                       alpha: float, min_speed: float, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
                       band_sigmas: float = BAND_SIGMAS, tracking=None,
                       velocity_window_s: float = VELOCITY_WINDOW_S, measured: bool = True,
                       folds: FoldsSection | None = None) -> MomentumDetector:
    """Λ and T²_α of the momentum residuals on contact-free runs: each run's first CALIBRATION_MAX_S seconds (the
    observer runs every sample: a bounded time), less its first 5 time constants. With `folds` (the runs are the
    ones the model was fitted on, in its `data` order), each time block's residuals come through the Φ fitted
    without it: cross-validated, what a new run would see (docs/detection.md#out-of-sample)."""
    e, rest, tau = momentum_calibration_residuals(model, phi, base, datasets, min_speed, bandwidth_hz, band_sigmas,
                                                  tracking, velocity_window_s, measured, folds)
    return momentum_detector(model, e, rest, tau, alpha, min_speed, bandwidth_hz, band_sigmas, velocity_window_s)


def momentum_calibration_residuals(model: RobotModel, phi: np.ndarray, base: BaseSection | None, datasets: Sequence,
                                   min_speed: float, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
                                   band_sigmas: float = BAND_SIGMAS, tracking=None,
                                   velocity_window_s: float = VELOCITY_WINDOW_S, measured: bool = True,
                                   folds: FoldsSection | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(e, rows at rest, τ_ext) of `calibrate_momentum`'s samples (`momentum_calibration_samples` without where
    they are)."""
    e, rest, tau, _ = momentum_calibration_samples(model, phi, base, datasets, min_speed, bandwidth_hz, band_sigmas,
                                                   tracking, velocity_window_s, measured, folds)
    return e, rest, tau


def momentum_calibration_samples(model: RobotModel, phi: np.ndarray, base: BaseSection | None, datasets: Sequence,
                                 min_speed: float, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
                                 band_sigmas: float = BAND_SIGMAS, tracking=None,
                                 velocity_window_s: float = VELOCITY_WINDOW_S, measured: bool = True,
                                 folds: FoldsSection | None = None
                                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(e, rows at rest, τ_ext, where) of `calibrate_momentum`'s samples, `where` (N, 2) each one's run (its index in
    `datasets`) and sample in that run. With `folds` the observer runs block by block, each through its fold's Φ
    (and friction band), started `warm-up` seconds before the block (its time constants, the velocity window, and
    three of the supply tracker's where it tracks) so that only the block's samples count."""
    es, rests, taus, wheres = [], [], [], []
    settle = SETTLE_TIME_CONSTANTS / (2 * np.pi * bandwidth_hz)
    warm_s = settle + velocity_window_s + (3.0 * tracking.time_constant_s if tracking is not None else 0.0)
    for i, ds in enumerate(datasets):
        ds = calibration_head(ds)
        segments = [(0, ds.n_samples, phi)] if folds is None else folds.segments(i, ds.n_samples, phi)
        warm = int(np.ceil(warm_s / ds.median_step()))
        t0 = float(ds.t[0])
        for lo, hi, phi_k in segments:
            start = 0 if lo <= warm else lo - warm
            part = ds if (start, hi) == (0, ds.n_samples) else ds.slice(start, hi)
            band = friction_band(model, phi_k, base, band_sigmas)
            res = run_residuals(model, phi_k, part, bandwidth_hz, min_speed, band, tracking, velocity_window_s,
                                measured)
            index = start + np.arange(res.t.size)
            keep = (index >= lo) & (res.t - t0 >= settle)
            if part.contact is not None:  # a labelled run: its contacts, widened by CONTACT_MARGIN_S, are left out
                keep &= ~_widened(res.t, np.asarray(part.contact) != 0, CONTACT_MARGIN_S)
            es.append(res.e[keep])
            rests.append(res.at_rest[keep])
            taus.append(res.tau_ext[keep])
            wheres.append(np.column_stack([np.full(int(keep.sum()), i), index[keep]]))
    return np.vstack(es), np.vstack(rests), np.vstack(taus), np.vstack(wheres)


def calibration_head(ds):  # Dataset -> Dataset
    """The samples a run calibrates the observer on: its first CALIBRATION_MAX_S seconds, a copy (the run itself where
    it is no longer); each calibration cuts its own, for as long as it runs."""
    from ..io.load import apply_window

    if ds.duration > CALIBRATION_MAX_S:
        return apply_window(ds, None, float(ds.t[0]) + CALIBRATION_MAX_S, source="calibration run")
    return ds


def momentum_detector(model: RobotModel, e: np.ndarray, rest: np.ndarray, tau: np.ndarray, alpha: float,
                      min_speed: float, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ, band_sigmas: float = BAND_SIGMAS,
                      velocity_window_s: float = VELOCITY_WINDOW_S) -> MomentumDetector:
    """Λ, T²_α, the sides' thresholds and the τ_ext noise from contact-free observer residuals."""
    if e.shape[0] < 100:
        raise DataError(f"{e.shape[0]} calibration samples for the momentum detector: too few")
    moving = (~rest).sum(axis=0)
    variance = np.where(rest, 0.0, e**2).sum(axis=0) / np.maximum(moving, 1)
    variance = np.where((moving > 0) & (variance > 0), variance, np.mean(e**2, axis=0))
    noise = np.array([o.sigma for o in output_channels(model)]) ** 2
    variance = np.where(variance > 0, variance, noise)
    tau_variance = np.maximum(np.mean(tau**2, axis=0), 1e-12)
    t2 = np.sum(e**2 / variance, axis=1)
    ft_thresholds = {}
    for i, s in enumerate(model.config.ft_sensors):
        rows = slice(6 * i, 6 * i + 6)
        ft_thresholds[s.name] = float(np.quantile(np.sum(e[:, rows] ** 2 / variance[rows], axis=1), alpha))
    return MomentumDetector(bandwidth_hz, variance, tau_variance, float(np.quantile(t2, alpha)), alpha, min_speed,
                            band_sigmas, ft_thresholds, int(e.shape[0]), velocity_window_s,
                            Quantiles(QUANTILE_LEVELS.copy(), np.quantile(t2, QUANTILE_LEVELS)))


# The calibration made once, at fit time, and kept in the model file's `observer` section (docs/formats.md): `detect`
# and `export` read it instead of running the observer over the identification runs again. Bumped whenever the
# calibration's procedure changes (a stored one of another version is recomputed, as a file without one is).
OBSERVER_VERSION = 3  # 3: the combined level over samples with a moving row; 2: cross-validated over the fit's time blocks (the model's `folds`); 1: in-sample
# The versions whose momentum detectors are today's: 3 changed only the combined level kept beside them, so a file of
# version 2 keeps its observer calibration (detect's slowest part) and has only κ calibrated again (stored_combined).
MOMENTUM_VERSIONS = (2, 3)


class ObserverCalibrations:
    """The calibrations behind the model file's `observer` section, read by `observer_record`. The momentum
    detector's samples with the data's q̇ ("detect") and with the monitor's causal q̇ ("monitor": the same ones where
    the runs carry no q̇ of their own, one observer pass for both: a third of the section's time on the simulated arm)
    start at once, each a task of `submit` where given (a thread pool's: `dynid fit` calibrates T² meanwhile; the
    observer runs block by block, so they hold little memory while T² holds its own). With the model's `folds`, the
    detect entry's in-sample calibration (what `detect` compares against) runs when it is read: a pass over each whole
    run, kept out of the overlap for its memory. `identified` needs Φ, the base, the folds, min_speed and the supply
    tracking only."""

    def __init__(self, identified, datasets: Sequence, submit: Callable[..., Future] | None = None) -> None:
        submit = submit or _run_now
        model, phi, folds = identified.robot_model, identified.phi, identified.folds
        common = (model, phi, identified.base, datasets, identified.min_speed)
        options = dict(tracking=identified.supply_tracking, folds=folds)
        causal_only = all(measured_velocity(model, ds) is None for ds in datasets)
        self.samples = {"detect": submit(momentum_calibration_samples, *common, measured=True, **options)}
        self.samples["monitor"] = (self.samples["detect"] if causal_only else
                                   submit(momentum_calibration_samples, *common, measured=False, **options))
        self._in_sample = None if folds is None else (common, identified.supply_tracking)

    def in_sample(self) -> MomentumCalibration | None:
        """The detect entry's in-sample calibration (None without folds), computed here, now."""
        if self._in_sample is None:
            return None
        (model, phi, base, datasets, min_speed), tracking = self._in_sample
        return calibrate_momentum(model, phi, base, datasets, ALPHA, min_speed, tracking=tracking,
                                  measured=True).section()


def _run_now(fn: Callable, *args, **kwargs) -> Future:  # noqa: ANN002, ANN003 - fn's own
    """`fn(*args, **kwargs)` run here, as a finished future (its value or its exception)."""
    done: Future = Future()
    try:
        done.set_result(fn(*args, **kwargs))
    except Exception as error:  # noqa: BLE001 - handed to whoever reads the result, as a pool's future does
        done.set_exception(error)
    return done


def observer_record(identified, datasets: Sequence, monitor_alpha: float,
                    combine: Callable[[MomentumDetector, tuple], CombinedCalibration | None] | None = None,
                    calibrations: ObserverCalibrations | None = None) -> ObserverSection:
    """The model file's `observer` section: the momentum detector calibrated on the fit's own (whole, contact-free)
    runs as `dynid detect` calibrates it by default (the data's q̇, α = ALPHA) and as `dynid export` does for the
    monitor (its causal q̇, the model's α), with the sha256 of the runs it was calibrated on: cross-validated where the
    model has its `folds`, with the detect entry's in-sample calibration beside (what `detect` compares against), and
    `combine(detector, its calibration samples)`'s combined level on the detect entry (dynid.detect.combined, which
    builds on this module: the caller hands it in). `calibrations`: the ones already started for these runs (else
    they run here)."""
    model, folds = identified.robot_model, identified.folds
    calibrations = calibrations or ObserverCalibrations(identified, datasets)
    entries = {}
    for key, measured, alpha in (("detect", True, ALPHA), ("monitor", False, monitor_alpha)):
        samples = calibrations.samples[key].result()
        det = momentum_detector(model, *samples[:3], alpha, identified.min_speed)
        in_sample = combined = None
        if key == "detect":
            in_sample = calibrations.in_sample()
        if key == "detect" and combine is not None:
            combined = combine(det, samples)
        entries[key] = ObserverEntry(det.alpha, det.bandwidth_hz, det.velocity_window_s, det.band_sigmas, measured,
                                     det.section(), CROSS_VALIDATED if folds is not None else IN_SAMPLE, in_sample,
                                     combined)
    return ObserverSection(OBSERVER_VERSION, tuple(run.sha256 for run in identified.data), **entries)


def stored_detector(identified, use: str, alpha: float, bandwidth_hz: float, velocity_window_s: float,
                    band_sigmas: float = BAND_SIGMAS, min_speed: float | None = None) -> MomentumDetector | None:
    """The detector the fit kept for `use` ("detect" or "monitor"), where it was calibrated with these settings on
    the runs the model names, unchanged since (sha256); else None, and the caller calibrates as an older file
    without the section needs."""
    from ..identify.model_file import data_digest

    section = identified.observer
    entry = None if section is None else section.entry(use)
    if entry is None or section.version not in MOMENTUM_VERSIONS:
        return None
    if (entry.alpha, entry.bandwidth_hz, entry.velocity_window_s, entry.band_sigmas) != (
            alpha, bandwidth_hz, velocity_window_s, band_sigmas):
        return None
    if entry.detector.min_speed != (identified.min_speed if min_speed is None else min_speed):
        return None
    paths = identified.data_paths
    stored = section.data_sha256
    if not paths or len(stored) != len(paths) or any(d is None for d in stored):
        return None
    if any(data_digest(p) != d for p, d in zip(paths, stored)):
        return None
    return MomentumDetector.of(entry.detector)


def stored_in_sample(identified, use: str = "detect") -> MomentumDetector | None:
    """The in-sample calibration the fit kept beside its cross-validated one (for `detect`'s comparison); None where
    it kept none (an older file, or a model without folds). Read after `stored_detector` accepted the entry."""
    section = identified.observer
    entry = None if section is None else section.entry(use)
    return None if entry is None or entry.in_sample is None else MomentumDetector.of(entry.in_sample)


def contact_free_rate(alarm: np.ndarray, contact: np.ndarray | None) -> float | None:
    """The share of alarms among the samples without contact (all of them without labels); None: no such sample."""
    free = np.ones(alarm.size, dtype=bool) if contact is None else np.asarray(contact) == 0
    return float(alarm[free].mean()) if free.any() else None


def _widened(t: np.ndarray, mask: np.ndarray, margin_s: float) -> np.ndarray:
    from ..io.dataset import contact_episodes

    out = np.zeros(t.size, dtype=bool)
    for a, b in contact_episodes(mask):
        out[(t >= t[a] - margin_s) & (t <= t[b - 1] + margin_s)] = True
    return out


def alarm_runs(t: np.ndarray, stat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, last sample) of each run of a normalised statistic above 1, runs closer than MERGE_GAP_S merged."""
    idx = np.flatnonzero(np.asarray(stat) > 1.0)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    breaks = np.flatnonzero(np.diff(t[idx]) > MERGE_GAP_S)
    return np.r_[idx[0], idx[breaks + 1]], np.r_[idx[breaks], idx[-1]]


def contact_events(model: RobotModel, det: MomentumDetector, res: MomentumResiduals, stat: np.ndarray,
                   limit: int = 200) -> list[dict]:
    """Alarm runs (gaps under MERGE_GAP_S merged): onset, end, peak T², and at the peak the isolation (side of
    each F/T sensor, the most distal joint with a significant external torque) and the estimates: external joint
    torques (Nm) and, per sensor, the contact's wrench at the sensor (w − ŵ low-passed: N, Nm)."""
    cfg = model.config
    starts, stops = alarm_runs(res.t, stat)
    events = []
    for a, b in zip(starts[:limit], stops[:limit]):
        k = a + int(np.argmax(stat[a : b + 1]))
        z = res.tau_ext[k] / np.sqrt(det.tau_variance)
        significant = np.flatnonzero(np.abs(z) > ISOLATION_SIGMAS)
        sides, wrenches = {}, {}
        for i, s in enumerate(cfg.ft_sensors):
            rows = slice(6 * i, 6 * i + 6)
            share = float(np.sum(res.e[k, rows] ** 2 / det.variance[rows]))
            sides[s.name] = "distal" if share > det.ft_thresholds[s.name] else "proximal"
            wrenches[s.name] = res.r[k, rows].tolist()
        events.append({"onset_s": float(res.t[a]), "end_s": float(res.t[b]), "peak_s": float(res.t[k]),
                       "peak_t2": float(det.t2(res.e[k : k + 1])[0]),
                       "peak_ratio": float(stat[k]),
                       "joint": cfg.joints[int(significant[-1])] if significant.size else None,
                       "largest": cfg.joints[int(np.argmax(np.abs(z)))] if np.any(z) else None,
                       "side": sides, "tau_ext_nm": dict(zip(cfg.joints, res.tau_ext[k].tolist())),
                       "wrench": wrenches})
    return events


def calibration_runs(identified, paths: Sequence[str] | None, window=(None, None)) -> tuple[list, list[str]]:
    """The contact-free runs to calibrate on: `paths` (cut to `window`), or the runs the model was fitted on."""
    from ..identify.validation import load_run

    model = identified.robot_model
    given = bool(paths)
    if not paths:
        paths = identified.data_paths
        missing = [p for p in paths if not Path(p).exists()]
        if not paths or missing:
            raise DataError(f"{identified.path}: the runs it was fitted on are not at hand ({(missing or ['none'])[0]}); "
                            "give contact-free runs to calibrate the momentum detector with --calibration DATA")
    runs = []
    records = {} if given else {run.path: run for run in identified.data}
    for p in paths:
        entry = records.get(p)
        own, policy = (entry.reload_window, entry.bad_rows_policy) if entry else ((None, None), DEFAULT_POLICY)
        run_window = window if window != (None, None) else own  # the fit's window and --bad-rows, unless given
        ds = load_run(str(p), model, run_window, entry.payload_dict if entry else None, policy)  # a payload the fit was told of
        fitted = entry.samples if entry else None
        if fitted is not None and run_window == (None, None) and fitted != ds.n_samples:  # a window the file does not name
            raise DataError(f"{identified.path or 'the model'} was fitted on {fitted} of the {ds.n_samples} samples of {p} (a --from/--to "
                            "window); give the contact-free runs to calibrate the momentum detector with --calibration "
                            "DATA --calibration-from S --calibration-to S")
        runs.append(ds)
    return runs, [str(p) for p in paths]


@dataclass(frozen=True)
class MomentumDetection:
    result: dict
    detector: MomentumDetector
    residuals: MomentumResiduals
    statistic: np.ndarray  # T²/T²_α per sample
    events: list


def momentum_detection(identified, dataset, calibration: Sequence | None, alpha: float,
                       bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ, shift_s: float = 0.0,
                       side: np.ndarray | None = None,
                       velocity_window_s: float = VELOCITY_WINDOW_S,
                       detector: MomentumDetector | None = None, folds: FoldsSection | None = None,
                       in_sample: MomentumDetector | None = None) -> MomentumDetection:
    """Calibrate on the contact-free `calibration` runs (cross-validated with the model's `folds` when they are the
    runs it was fitted on), or take `detector`, calibrated already (the model file's, `stored_detector`), then T²,
    events and scores on `dataset`; with `in_sample` (the detector the fit's own residuals calibrate) its FPR on the
    same samples comes beside (`in_sample_fpr`)."""
    model, phi = identified.robot_model, identified.phi
    if identified.effects:
        raise DataError(f"{identified.path}: an augmented model (named effects) has no momentum residual yet; use "
                        "--residual acceleration")
    tracking = identified.supply_tracking
    det = detector or calibrate_momentum(model, phi, identified.base, calibration or [], alpha, identified.min_speed,
                                         bandwidth_hz, tracking=tracking, velocity_window_s=velocity_window_s,
                                         folds=folds)
    if in_sample is None and detector is None and folds is not None:
        in_sample = calibrate_momentum(model, phi, identified.base, calibration or [], alpha, identified.min_speed,
                                       bandwidth_hz, tracking=tracking, velocity_window_s=velocity_window_s)
    band = friction_band(model, phi, identified.base, det.band_sigmas)
    res = run_residuals(model, phi, dataset, bandwidth_hz, identified.min_speed, band, tracking, velocity_window_s)
    stat = det.statistic(res.e, res.at_rest)
    result = score_with_delays(dataset.t, stat, 1.0, dataset.contact, side, shift_s)
    result["threshold"] = det.threshold
    result["statistic"] = "T²/T²_α (T²_α: calibrated, or rest_threshold where every row rests); a contact above 1"
    result["detector"] = det.as_dict()
    if in_sample is not None:
        result["in_sample_fpr"] = contact_free_rate(in_sample.statistic(res.e, res.at_rest) > 1.0, dataset.contact)
    events = contact_events(model, det, res, stat)
    return MomentumDetection(result, det, res, stat, events)
