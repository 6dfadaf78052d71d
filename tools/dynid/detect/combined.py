"""The combined detector (issue 30, "no blind side"): the momentum observer's T² and the acceleration residuals' T²
in one statistic.

The momentum observer sees a contact beyond an F/T sensor at once (the sensor's six channels) but is noisy on the
motor rows, which alone carry a contact before the sensor; the acceleration residuals see those better
(docs/detection.md#no-blind-side). The combined detector stacks the two, each normalised by its own T²_α:

    s = (T²_m / T²_m,α + T²_c / T²_c,α) / κ,      a contact where s > 1

(T²_m,α the observer's rest threshold where every row rests, as its own statistic takes it.) κ is the α-quantile of
the sum on contact-free residuals the fit did not see (each time block of the fit's own runs through the Φ fitted
without it, as each detector's own calibration), paired sample by sample, over the samples where some row moves: its
per-sample false-positive rate there is 1 − α. Where every row rests (a robot without F/T rows holding still) the
acceleration residuals carry nothing (they leave resting rows out) and the observer's own test decides alone, s =
T²_m / T²_m,α: dividing it by κ made the combined detector less sensitive than the observer on a resting arm.
Measured against an OR of the two at a common level, a per-row choice (the observer's F/T channels, the acceleration
residuals' motor channels) and one T² over both residual vectors with their joint covariance, the sum finds the most
proximal contacts at the lowest false-positive rate (tools/benchmarks/combined_detector.py).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..errors import DataError
from ..identify.model_sections import Quantiles
from ..identify.observer_sections import CombinedCalibration
from ..identify.supply import SupplyTracker, smoothed_residuals
from ..robot.outputs import residuals
from ..robot.regressors.stack import payload_of, signals_from_dataset
from .momentum_t2 import MomentumDetector, calibration_head, momentum_calibration_samples
from .online import FixedLagSavitzkyGolay, online_signals, online_times, raw_signals
from .t2 import QUANTILE_LEVELS, Detector


@dataclass(frozen=True)
class CombinedDetector:
    scale: float  # κ: the α-quantile of the summed normalised statistics on the paired calibration samples
    alpha: float
    samples: int  # paired calibration samples
    quantiles: Quantiles  # of that sum (κ at another α without a recalibration)

    def statistic(self, momentum: np.ndarray, acceleration: np.ndarray, all_rest: np.ndarray) -> np.ndarray:
        """s per sample from the two normalised statistics (T²/T²_α each): a contact above 1. Where every row rests
        (`all_rest`, the observer's own test: its rest threshold) the momentum statistic alone: the acceleration
        residuals leave resting rows out, and κ is the level of the sum where something moves."""
        return combined_statistic(momentum, acceleration, all_rest, self.scale)

    def at(self, alpha: float) -> CombinedDetector | None:
        """The same calibration at another α (its quantiles); None outside their levels."""
        if alpha == self.alpha:
            return self
        kappa = self.quantiles.at(alpha)
        return None if kappa is None else CombinedDetector(kappa, alpha, self.samples, self.quantiles)

    def as_dict(self) -> dict:
        return {"variant": "combined", "scale": self.scale, "alpha": self.alpha, "calibration_samples": self.samples,
                "statistic": "(T²_m/T²_m,α + T²_c/T²_c,α)/κ: the momentum and the calibrated acceleration detectors' "
                             "statistics summed; a contact above 1"}

    def section(self) -> CombinedCalibration:
        return CombinedCalibration(self.scale, self.alpha, self.samples, self.quantiles)

    @classmethod
    def of(cls, s: CombinedCalibration) -> CombinedDetector:
        return cls(s.scale, s.alpha, s.calibration_samples, s.quantiles)


class TooFewMoving(DataError):
    """Too few calibration samples with a moving row to set κ (a run that mostly rests)."""


def combined_statistic(momentum: np.ndarray, acceleration: np.ndarray, all_rest: np.ndarray,
                       scale: float) -> np.ndarray:
    """s from the normalised statistics: their sum over κ (`scale`), the observer's alone where every row rests."""
    return np.where(all_rest, momentum, (momentum + acceleration) / scale)


def combined_detector(momentum: np.ndarray, acceleration: np.ndarray, all_rest: np.ndarray,
                      alpha: float) -> CombinedDetector:
    """κ from the two normalised statistics on the same contact-free samples, over those where some row moves (where
    every row rests the statistic is the observer's own, `CombinedDetector.statistic`)."""
    if not (momentum.shape == acceleration.shape == all_rest.shape):
        raise ValueError("the two statistics and the rest flags must be of the same samples")
    moving = ~np.asarray(all_rest, dtype=bool)
    if moving.sum() < 100:
        raise TooFewMoving(f"{int(moving.sum())} paired calibration samples with a moving row for the combined "
                           "detector: too few")
    both = momentum[moving] + acceleration[moving]
    return CombinedDetector(float(np.quantile(both, alpha)), alpha, int(both.size),
                            Quantiles(QUANTILE_LEVELS.copy(), np.quantile(both, QUANTILE_LEVELS)))


def acceleration_statistic(model, det: Detector, e: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """T²/T²_α of the calibrated acceleration detector (its resting motor channels left out)."""
    return det.t2(model, e, dq) / det.threshold


def offline_acceleration(identified, ds, segments) -> tuple[np.ndarray, np.ndarray]:  # -> (e, q̇)
    """The acceleration residuals of a run as `dynid detect` computes them (offline derivatives, two-sided supply
    estimate: dynid.identify.validation.evaluate), each segment's samples through its own Φ."""
    model = identified.robot_model
    sig = signals_from_dataset(model, ds, filter_outputs=True)
    e = np.vstack([residuals(model, phi_k, sig.slice(slice(a, b))) for a, b, phi_k in segments if b > a])
    return smoothed_residuals(model, identified.supply_tracking, identified.min_speed, e, sig, ds.t), sig.dq


def monitor_acceleration(identified, ds, segments, est: FixedLagSavitzkyGolay, min_speed: float
                         ) -> tuple[np.ndarray, np.ndarray]:  # -> (e, q̇) per monitor tick
    """The acceleration residuals as the monitor computes them on uniform raw samples: the fixed-lag filter, each
    estimate through the Φ of its sample's segment, the causal supply tracker; row k is the monitor's tick k (its
    estimate of sample k − lag), NaN before the filter's window is full."""
    model = identified.robot_model
    t, q, inputs, tau, ft = raw_signals(model, ds)
    sig = replace(online_signals(model, est, t, q, inputs, tau, ft), payload=payload_of(model, ds))
    sample = est.window - 1 - est.lag + np.arange(sig.q.shape[0])  # the sample each estimate is of
    parts = []
    for a, b, phi_k in segments:
        lo, hi = np.searchsorted(sample, a), np.searchsorted(sample, b)
        if hi > lo:
            parts.append(residuals(model, phi_k, sig.slice(slice(lo, hi))))
    e = np.vstack(parts)
    if identified.supply_tracking is not None:
        e, _ = SupplyTracker(model, identified.supply_tracking, min_speed).apply(e, sig, online_times(est, t))
    ticks = np.full((ds.n_samples, e.shape[1]), np.nan)
    dq = np.full((ds.n_samples, sig.dq.shape[1]), np.nan)
    ticks[est.window - 1 :], dq[est.window - 1 :] = e, sig.dq
    return ticks, dq


def paired_statistics(identified, det_m: MomentumDetector, det_c: Detector, datasets: Sequence, folds=None,
                      measured: bool = True, est: FixedLagSavitzkyGolay | None = None,
                      with_residuals: bool = False, momentum_samples: tuple | None = None) -> dict[str, np.ndarray]:
    """Both normalised statistics (`m`, `c`) on the same contact-free samples: the momentum detector's calibration
    samples of `datasets` (with the model's `folds` where they are the runs it was fitted on: cross-validated), and
    the acceleration residuals there through the same Φ: offline (`est` None, as `dynid detect`), or as the monitor
    has them at the same tick (its filter `est`, the observer's q̇ causal: `measured` False). With `with_residuals`,
    the residuals too (`e_m`, `e_c`, `active`: the channels in the acceleration T²). `momentum_samples`: what
    dynid.detect.momentum_t2.momentum_calibration_samples gave for the same arguments, where the caller has it."""
    model, phi = identified.robot_model, identified.phi
    e_m, rest, _, where = momentum_samples or momentum_calibration_samples(
        model, phi, identified.base, datasets, det_m.min_speed, det_m.bandwidth_hz, det_m.band_sigmas,
        identified.supply_tracking, det_m.velocity_window_s, measured, folds)
    e_c, active = np.zeros_like(e_m), np.zeros(e_m.shape, dtype=bool)
    for i, ds in enumerate(datasets):
        ds = calibration_head(ds)
        segments = [(0, ds.n_samples, phi)] if folds is None else folds.segments(i, ds.n_samples, phi)
        e, dq = (offline_acceleration(identified, ds, segments) if est is None
                 else monitor_acceleration(identified, ds, segments, est, det_c.min_speed))
        mine = where[:, 0] == i
        rows = where[mine, 1]
        e_c[mine] = e[rows]
        active[mine] = det_c.active(model, dq[rows])
    keep = np.all(np.isfinite(e_c), axis=1)  # the monitor's acceleration residuals start a filter window later
    e_m, rest, e_c, active = e_m[keep], rest[keep], e_c[keep], active[keep]
    stat_c = np.sum(np.where(active, e_c**2 / det_c.variance, 0.0), axis=1) / det_c.threshold
    out = {"m": det_m.statistic(e_m, rest), "c": stat_c, "rest": rest.all(axis=1)}
    if with_residuals:
        out.update(e_m=e_m, e_c=e_c, active=active)
    return out


def calibrate_combined(identified, det_m: MomentumDetector, det_c: Detector, datasets: Sequence, folds=None,
                       measured: bool = True, est: FixedLagSavitzkyGolay | None = None,
                       momentum_samples: tuple | None = None) -> CombinedDetector:
    """κ at det_m's α on the paired statistics of `paired_statistics`."""
    pair = paired_statistics(identified, det_m, det_c, datasets, folds, measured, est,
                             momentum_samples=momentum_samples)
    return combined_detector(pair["m"], pair["c"], pair["rest"], det_m.alpha)


def stored_combined(identified, alpha: float) -> CombinedDetector | None:
    """The combined detector the fit kept beside its `detect` observer entry, at `alpha`; None where it kept none.
    Read after dynid.detect.momentum_t2.stored_detector accepted that entry (the same runs and settings); a level of
    an earlier version (κ over every sample, before version 3) is not today's: None, and the caller calibrates it."""
    from .momentum_t2 import OBSERVER_VERSION

    section = identified.observer
    entry = None if section is None else section.entry("detect")
    if entry is None or entry.combined is None or section.version != OBSERVER_VERSION:
        return None
    return CombinedDetector.of(entry.combined).at(alpha)


@dataclass(frozen=True)
class CombinedDetection:
    result: dict
    detector: CombinedDetector
    statistic: np.ndarray  # s per sample
    events: list


def combined_detection(identified, dataset, momentum, acceleration_t2: np.ndarray, det_c: Detector,
                       detector: CombinedDetector, side: np.ndarray | None = None,
                       shift_s: float = 0.0) -> CombinedDetection:
    """The combined detector on a run, from the momentum detection (dynid.detect.momentum_t2.MomentumDetection) and
    the calibrated acceleration detector's T² on the same samples: scores and events (alarm runs of s; at their
    peak the observer's isolation and estimates, as the momentum detector's events carry them)."""
    from .momentum_t2 import contact_events
    from .t2 import score_with_delays

    stat = detector.statistic(momentum.statistic, acceleration_t2 / det_c.threshold,
                              momentum.residuals.at_rest.all(axis=1))
    result = score_with_delays(dataset.t, stat, 1.0, dataset.contact, side, shift_s)
    result["threshold"] = detector.scale
    result["statistic"] = detector.as_dict()["statistic"]
    result["detector"] = detector.as_dict()
    events = contact_events(identified.robot_model, momentum.detector, momentum.residuals, stat)
    return CombinedDetection(result, detector, stat, events)


def fit_combined(identified, datasets: Sequence) -> Callable[[MomentumDetector, tuple], CombinedCalibration | None]:
    """What `dynid fit` hands dynid.detect.momentum_t2.observer_record: the combined level on the momentum detector's
    own calibration samples (cross-validated with the model's folds), against the fit's calibrated acceleration
    detector at the same α; None for an augmented model (no momentum form) or another α."""
    def combine(det_m: MomentumDetector, samples: tuple) -> CombinedCalibration | None:
        if identified.detector is None or identified.effects:
            return None
        det_c = Detector.of(identified.detector.calibrated)
        if det_c.alpha != det_m.alpha:
            return None
        try:
            return calibrate_combined(identified, det_m, det_c, datasets, identified.folds,
                                      momentum_samples=samples).section()
        except TooFewMoving:  # the observer is kept, without a combined level
            return None

    return combine
