"""T² contact detection on a model's residuals over a run, scored against ground truth (`dynid detect`).

Takes the residuals of dynid.identify.validation.evaluate and the model file's T² calibration; hands on
`dynid detect --json`, field for field, and the T² series the report plots.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DataError, InputError
from ..identify.model_file import IdentifiedModel
from ..identify.validation import Evaluated
from ..io.dataset import beside_run
from ..io.derivatives import SavitzkyGolay
from ..robot.outputs import divisors
from .t2 import VARIANTS, Detector, f_threshold, score_with_delays
from .visibility import contact_residuals, episode_visibility


def detectors(identified: IdentifiedModel, alpha: float, n_mode: str) -> dict[str, Detector]:
    """Both variants at confidence `alpha`, from the model file's calibration."""
    det = identified.detector
    if det is None:
        raise DataError(f"{identified.path} has no T² calibration (refit it with this dynid)")
    paper = Detector.of(det.paper)
    n = paper.n if n_mode == "dim" or identified.n_components is None else identified.n_components
    out = {"calibrated": Detector.of(det.calibrated),
           "paper": Detector("paper", paper.variance, f_threshold(n, det.calibration_samples, alpha), alpha,
                             paper.min_speed, n)}
    calibrated = out["calibrated"]
    if alpha != calibrated.alpha:
        # The stored quantiles of the calibration T² (model files of an earlier dynid hold them descending).
        q = det.calibrated_t2_quantiles
        threshold = q.at(alpha)
        if threshold is None:
            raise InputError(f"--alpha {alpha} is outside the calibrated range {q.levels.min():.4g}..{q.levels.max():.4g}")
        out["calibrated"] = Detector("calibrated", calibrated.variance, threshold, alpha, calibrated.min_speed,
                                     calibrated.n)
    return {v: out[v] for v in VARIANTS}


@dataclass(frozen=True)
class Detection:
    result: dict[str, Any]  # `dynid detect --json`
    detectors: dict[str, Detector]
    t2: dict[str, np.ndarray]  # variant -> (N,) T²
    side: np.ndarray | None  # the skin's side per sample: +1 distal, −1 proximal, 0 none


def filter_edges(ev: Evaluated) -> np.ndarray:
    """(N,) True within half the derivative filter's window of the run's two ends. There q̇, q̈ and the filtered
    outputs come from a polynomial fitted off-centre, and the residual is the filter's, not the sample's (on the
    default validation run T² over T²_α reached 1.55 at the first sample and 27 at the last: a contact event at 0 s in
    every `detect`); the monitor never evaluates them either, its window filling first. Left out of the scores."""
    t = ev.dataset.t
    edge = np.zeros(t.size, dtype=bool)
    options = dict(ev.config.derivatives)
    if t.size < 2 or options.pop("method", "savgol") != "savgol":
        return edge
    half = SavitzkyGolay(**options).window_samples(float(np.median(np.diff(t)))) // 2
    if half:
        edge[:half] = edge[-half:] = True
    return edge


def detection(ev: Evaluated, model_label: str, data_label: str, alpha: float, n_mode: str,
              shift_s: float = 0.0) -> Detection:
    """Both acceleration-based variants on one run: scores, every episode's onset delay (and against the labels'
    start + shift_s), and on a simulated run which episodes the sensors can see."""
    dets = detectors(ev.identified, alpha, n_mode)
    side = ev.dataset.extra.get("skin.side")
    # "residual": what the variants here are computed on (dynid detect replaces it by "momentum" when it adds that one)
    result: dict[str, Any] = {"model": model_label, "data": data_label, "alpha": alpha, "residual": "acceleration",
                              "variants": {}}
    t2s = {}
    edge = filter_edges(ev)
    for variant, d in dets.items():
        e = ev.e_constant if variant == "paper" else ev.e  # the paper's model has constant gains
        t2s[variant] = np.where(edge, np.nan, d.t2(ev.model, e, ev.signals.dq, ev.identified.phi))
        result["variants"][variant] = score_with_delays(ev.dataset.t, t2s[variant], d.threshold, ev.dataset.contact,
                                                         side, shift_s)
    stored = ev.identified.detector
    if stored is not None and stored.in_sample is not None and alpha == stored.in_sample.alpha:
        # the calibrated variant as the fit's own residuals would calibrate it: its FPR on the same samples, beside
        in_sample = Detector.of(stored.in_sample)
        alarm = in_sample.t2(ev.model, ev.e, ev.signals.dq) > in_sample.threshold
        free = np.ones(alarm.size, bool) if ev.dataset.contact is None else np.asarray(ev.dataset.contact) == 0
        free &= ~edge
        result["variants"]["calibrated"]["in_sample_fpr"] = float(alarm[free].mean()) if free.any() else None
    truth = beside_run(data_label, "truth.npz")
    if ev.dataset.contact is not None and ev.dataset.contact.any() and truth.is_file():
        rows = truth_rows(np.load(truth), ev.dataset.t)  # the run's samples: a window of it, or all of them
        if rows is not None:
            result["visibility"] = visibility(ev, dets["calibrated"], t2s["calibrated"], np.load(truth), rows)
    return Detection(result, dets, t2s, side)


def truth_rows(truth, t: np.ndarray) -> np.ndarray | None:
    """The rows of the truth beside a simulated run that are the run's samples at times `t` (a --from/--to window
    of it takes some); None where they are not all there (the run is not the truth's)."""
    t_truth = np.asarray(truth["t"], float)
    rows = np.searchsorted(t_truth, t)
    if rows.size and (rows[-1] >= t_truth.size or not np.array_equal(t_truth[rows], t)):
        return None
    return rows


def visibility(ev: Evaluated, det: Detector, t2: np.ndarray, truth, rows: np.ndarray | None = None) -> dict[str, Any]:
    """For a simulated run: which contact episodes the calibrated detector can see at all (the contact's own
    residual, from the plant's truth: dynid.detect.visibility; no debounce offline) and how many of those it found.
    `rows`: the truth's rows that are the run's samples (default: all)."""
    signal = contact_residuals(ev.model, divisors(ev.model, ev.identified.phi), truth)
    if rows is not None:
        signal = signal[rows]
    episodes = episode_visibility(ev.dataset.contact, signal, det.active(ev.model, ev.signals.dq), det.variance,
                                  det.threshold, debounce=1)
    found = [bool(np.any(t2[v.start : v.end] > det.threshold)) for v in episodes]
    t = ev.dataset.t - ev.dataset.t[0]
    return {"visible": sum(v.visible for v in episodes),
            "visible_found": sum(f for v, f in zip(episodes, found) if v.visible),
            "episodes": [{**v.as_dict(), "start_s": float(t[v.start]), "found": f} for v, f in zip(episodes, found)]}


def add_stored_default(ev: Evaluated, found: Detection, alpha: float, shift_s: float = 0.0) -> str | None:
    """The momentum observer's and the combined detector's variants added to `found` (first, as `dynid detect`
    lists them), from the detectors the model file keeps: `detect`'s default and what the monitor runs, without
    recalibrating. Returns why they could not be (a model without them, or other settings), None when added."""
    from .combined import combined_detection, stored_combined
    from .momentum import DEFAULT_BANDWIDTH_HZ, VELOCITY_WINDOW_S
    from .momentum_t2 import momentum_detection, stored_detector, stored_in_sample

    identified = ev.identified
    stored = None if identified.effects else stored_detector(identified, "detect", alpha, DEFAULT_BANDWIDTH_HZ,
                                                             VELOCITY_WINDOW_S)
    combined = None if stored is None or "calibrated" not in found.detectors else stored_combined(identified, alpha)
    if identified.effects:  # as `dynid detect` says of such a model
        return ("an augmented model (named effects) has no momentum residual yet: the acceleration residuals' variants "
                "alone")
    if combined is None:
        return ("the model file keeps no momentum observer and combined detector at this α for its runs "
                "(`dynid detect` calibrates them)")
    momentum = momentum_detection(identified, ev.dataset, None, alpha, DEFAULT_BANDWIDTH_HZ, shift_s, found.side,
                                  detector=stored, folds=identified.folds, in_sample=stored_in_sample(identified))
    both = combined_detection(identified, ev.dataset, momentum, found.t2["calibrated"], found.detectors["calibrated"],
                              combined, found.side, shift_s)
    found.result["variants"] = {"combined": both.result, "momentum": momentum.result, **found.result["variants"]}
    found.result["residual"] = "combined"
    return None

