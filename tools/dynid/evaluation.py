"""What `dynid validate`, `dynid detect` and `dynid report` compute, as pure functions (no printing).

- `evaluate`: the model file, one run of data, its signals and the residuals e = y − ŷ of the model;
- `validation`: the paper's Table II (F/T error norms, identified against CAD) and per-channel RMS;
- `detection`: T² of both detector variants, scored against the skin's ground truth.

The result dicts are the commands' `--json` results, field for field; the arrays are what the report plots.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .config import RobotConfig
from .dataset import Dataset, beside_run, load_data
from .errors import DataError, InputError
from .identified import IdentifiedModel, load_model
from .model import RobotModel
from .outputs import OutputChannel, output_channels, residuals
from .regressors.stack import Signals, rows_at_rest, signals_from_dataset
from .supply import smoothed_residuals

if TYPE_CHECKING:  # dynid.detection pulls in scipy.stats (0.6 s): imported where T² is computed, not by every command
    from .detection import Detector


def load_run(path: str, model: RobotModel) -> Dataset:
    """A run of data for `model`; data recorded on another robot is refused."""
    ds = load_data(Path(path), model.config, joint_limits=model.joint_limits)
    robot = ds.meta.get("robot")
    if robot is not None and robot != model.config.name:
        raise DataError(f"{path} was recorded on '{robot}', not on '{model.config.name}'")
    return ds


def cad_phi(model: RobotModel, record: dict, missing: float = 0.0) -> np.ndarray:
    """The CAD parameters, with the F/T offsets that fit them best on the identification data (when the model
    file has them); `missing` where a CAD model has no value (friction, gains)."""
    phi = np.nan_to_num(model.cad_parameters(), nan=missing)
    offsets = record.get("cad_ft_offsets")
    if offsets is not None:
        span = model.layout.span("ft_offset")
        phi[span] = np.asarray(offsets, float)[span]
    return phi


@dataclass(frozen=True)
class Evaluated:
    """A model's residuals on one run."""

    identified: IdentifiedModel
    model: RobotModel
    dataset: Dataset
    signals: Signals  # with the outputs filtered as q̇, q̈ are (see signals_from_dataset)
    e: np.ndarray  # (N, n_out) e = y − ŷ, the inputs predicted with the model's offline supply estimate (dynid.supply)
    e_constant: np.ndarray  # the same with constant motor gains (the paper's model); e itself without tracking

    @property
    def config(self) -> RobotConfig:
        return self.model.config

    @property
    def outputs(self) -> tuple[OutputChannel, ...]:
        return output_channels(self.model)


def evaluate(model_path: str, data_path: str, identified: IdentifiedModel | None = None,
             dataset: Dataset | None = None) -> Evaluated:
    """Residuals of the model on the run; `identified` and `dataset` when the caller has loaded them already."""
    identified = identified or load_model(model_path)
    model = identified.robot_model
    ds = dataset if dataset is not None else load_run(data_path, model)
    sig = signals_from_dataset(model, ds, filter_outputs=True)
    effects = identified.effects  # an augmented model (`dynid gaps --out`) predicts with its named effects
    if effects:
        from .augmented import augmented_residuals

        e = augmented_residuals(model, identified.phi, effects, sig, ds.t - ds.t[0])
    else:
        e = residuals(model, identified.phi, sig)
    tracked = smoothed_residuals(model, identified.supply_tracking, identified.min_speed, e, sig, ds.t)
    return Evaluated(identified, model, ds, sig, tracked, e)


def _norm_stats(x: np.ndarray) -> dict[str, float]:
    n = np.linalg.norm(x, axis=1)
    return {"mean": float(n.mean()), "std": float(n.std())}


def cad_ft_residuals(ev: Evaluated) -> np.ndarray | None:
    """(N, 6 per sensor) F/T residuals of the CAD parameters, or None without an F/T sensor."""
    outs = ev.outputs
    ft = [o.row for o in outs if o.kind == "ft"]
    if not ft:
        return None
    cad = cad_phi(ev.model, ev.identified.record)
    gains = [o.gain_index for o in outs if o.gain_index is not None]
    cad[gains] = 1.0  # the CAD model has no gains: its input predictions are undefined, not used
    return residuals(ev.model, cad, ev.signals)[:, ft]


def validation(ev: Evaluated, model_label: str, data_label: str,
               cad_e: np.ndarray | None = None) -> dict[str, Any]:
    """`dynid validate --json`: Table II (identified and CAD F/T error norms) and per-channel RMS against noise."""
    outs, e = ev.outputs, ev.e
    ft = [o.row for o in outs if o.kind == "ft"]
    result: dict[str, Any] = {"model": model_label, "data": data_label, "samples": ev.dataset.n_samples,
                              "channels": {}}
    if ft:
        cad_e = cad_ft_residuals(ev) if cad_e is None else cad_e
        result["table_ii"] = {"identified": {"force": _norm_stats(e[:, ft[:3]]), "torque": _norm_stats(e[:, ft[3:6]])},
                              "cad": {"force": _norm_stats(cad_e[:, :3]), "torque": _norm_stats(cad_e[:, 3:6])}}
    rest = rows_at_rest(ev.model, ev.signals.dq, ev.identified.min_speed)
    for o in outs:
        rms = float(np.sqrt(np.mean(e[:, o.row] ** 2)))
        entry = {"rms": rms, "mean": float(e[:, o.row].mean()), "std": float(e[:, o.row].std()),
                 "noise_std": o.sigma, "ratio_to_noise": rms / o.sigma}
        if o.kind == "input":
            entry["cad"] = None  # no friction and no gains in a CAD model: undefined (the paper says so too)
            # Static friction holds a resting joint with any torque inside its band: the model says nothing
            # there, so the motor rows at rest are also left out, as in the fit and in T².
            moving = ~rest[:, o.row]
            entry["moving_samples"] = int(moving.sum())
            if moving.any():
                entry["rms_moving"] = float(np.sqrt(np.mean(e[moving, o.row] ** 2)))
                entry["ratio_to_noise_moving"] = entry["rms_moving"] / o.sigma
                const = float(np.sqrt(np.mean(ev.e_constant[moving, o.row] ** 2)))
                entry["ratio_to_noise_moving_constant_gains"] = const / o.sigma
        result["channels"][o.name] = entry
    torque = [o.row for o in outs if o.kind == "torque"]
    if torque:  # joint torque sensors: the error the torque-identification literature reports
        from .outputs import measured_outputs

        y = measured_outputs(ev.model, ev.signals)[:, torque]
        result["relative_torque_error"] = float(np.linalg.norm(e[:, torque]) / np.linalg.norm(y))
    return result


def detectors(identified: IdentifiedModel, alpha: float, n_mode: str) -> dict[str, Detector]:
    """Both variants at confidence `alpha`, from the model file's calibration."""
    from .detection import VARIANTS, Detector, f_threshold

    det = identified.record.get("detector")
    if not det:
        raise DataError(f"{identified.path} has no T² calibration (refit it with this dynid)")
    out = {}
    for variant in VARIANTS:
        d = Detector.from_dict(det[variant])
        if variant == "paper":
            n = d.n if n_mode == "dim" else int(identified.record.get("n_components", d.n))
            d = Detector("paper", d.variance, f_threshold(n, det["calibration_samples"], alpha), alpha, d.min_speed, n)
        elif alpha != d.alpha:
            # The stored quantiles of the calibration T² (model files of an earlier dynid hold them descending).
            q = det["calibrated_t2_quantiles"]
            order = np.argsort(q["levels"])
            levels, values = np.asarray(q["levels"], float)[order], np.asarray(q["values"], float)[order]
            if not levels[0] <= alpha <= levels[-1]:
                raise InputError(f"--alpha {alpha} is outside the calibrated range {levels[0]:.4g}..{levels[-1]:.4g}")
            d = Detector("calibrated", d.variance, float(np.interp(alpha, levels, values)), alpha, d.min_speed, d.n)
        out[variant] = d
    return out


@dataclass(frozen=True)
class Detection:
    result: dict[str, Any]  # `dynid detect --json`
    detectors: dict[str, Detector]
    t2: dict[str, np.ndarray]  # variant -> (N,) T²
    side: np.ndarray | None  # the skin's side per sample: +1 distal, −1 proximal, 0 none


def detection(ev: Evaluated, model_label: str, data_label: str, alpha: float, n_mode: str) -> Detection:
    from .detection import score

    dets = detectors(ev.identified, alpha, n_mode)
    side = ev.dataset.extra.get("skin.side")
    result: dict[str, Any] = {"model": model_label, "data": data_label, "alpha": alpha, "variants": {}}
    t2s = {}
    for variant, d in dets.items():
        e = ev.e_constant if variant == "paper" else ev.e  # the paper's model has constant gains
        t2s[variant] = d.t2(ev.model, e, ev.signals.dq, ev.identified.phi)
        result["variants"][variant] = score(ev.dataset.t, t2s[variant], d.threshold, ev.dataset.contact, side)
    truth = beside_run(data_label, "truth.npz")
    if ev.dataset.contact is not None and ev.dataset.contact.any() and truth.is_file():
        result["visibility"] = visibility(ev, dets["calibrated"], t2s["calibrated"], np.load(truth))
    return Detection(result, dets, t2s, side)


def visibility(ev: Evaluated, det: Detector, t2: np.ndarray, truth) -> dict[str, Any]:
    """For a simulated run: which contact episodes the calibrated detector can see at all (the contact's own
    residual, from the plant's truth: dynid.contact_visibility; no debounce offline) and how many of those it found."""
    from .contact_visibility import contact_residuals, episode_visibility
    from .outputs import divisors

    signal = contact_residuals(ev.model, divisors(ev.model, ev.identified.phi), truth)
    episodes = episode_visibility(ev.dataset.contact, signal, det.active(ev.model, ev.signals.dq), det.variance,
                                  det.threshold, debounce=1)
    found = [bool(np.any(t2[v.start : v.end] > det.threshold)) for v in episodes]
    t = ev.dataset.t - ev.dataset.t[0]
    return {"visible": sum(v.visible for v in episodes),
            "visible_found": sum(f for v, f in zip(episodes, found) if v.visible),
            "episodes": [{**v.as_dict(), "start_s": float(t[v.start]), "found": f} for v, f in zip(episodes, found)]}
