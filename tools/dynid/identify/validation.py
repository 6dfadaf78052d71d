"""A model on a run of data: its residuals, and what `dynid validate` reports of them (no printing).

- `evaluate`: the model file, one run of data, its signals and the residuals e = y − ŷ of the model;
- `validation`: the paper's Table II (F/T error norms, identified against CAD) and per-channel RMS.

The result dict is `dynid validate --json`, field for field; the arrays are what the report plots. Detection on
the same residuals is dynid.detect.evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import RobotConfig
from ..errors import DataError
from ..io.bad_rows import DEFAULT_POLICY
from ..io.dataset import Dataset
from ..io.load import apply_window, load_data
from ..robot.effects import FT_STEP, augmented_residuals
from ..robot.model import RobotModel
from ..robot.outputs import OutputChannel, measured_outputs, output_channels, residuals
from ..robot.regressors.stack import Signals, rows_at_rest, signals_from_dataset
from .model_file import IdentifiedModel, load_model
from .supply import smoothed_residuals
from .transfer import why_worse


Window = tuple[float | None, float | None]


def load_run(path: str, model: RobotModel, window: Window = (None, None),
             payload: dict[str, Any] | None = None, bad_rows: str = DEFAULT_POLICY) -> Dataset:
    """A run of data for `model`, cut to `window` (--from/--to, the data's own seconds), marked with the known
    `payload` it carries ({mass, com}), its bad rows refused or skipped (`bad_rows`, dynid.io.bad_rows); data
    recorded on another robot is refused."""
    ds = apply_window(load_data(Path(path), model.config, joint_limits=model.joint_limits, bad_rows=bad_rows),
                      *window, source=path)
    if payload is not None:
        model.payload_parameters(float(payload["mass"]), payload.get("com"))  # the frame exists
        ds.meta["payload"] = payload
    check_robot(path, ds.meta.get("robot"), model)
    return ds


def check_robot(path: str, robot: str | None, model: RobotModel) -> None:
    """Refuse a dataset file imported for another configuration (its `robot`), saying how to read it with this one."""
    if robot is not None and robot != model.config.name:
        raise DataError(f"{path} was imported for '{robot}', not for '{model.config.name}': import the original "
                        f"recording again with this configuration (dynid import --robot ...), or give --robot {robot}")


def cad_phi(model: RobotModel, identified: IdentifiedModel, missing: float = 0.0) -> np.ndarray:
    """The CAD parameters, with the F/T offsets that fit them best on the identification data (when the model
    file has them); `missing` where a CAD model has no value (friction, gains)."""
    phi = np.nan_to_num(model.cad_parameters(), nan=missing)
    offsets = identified.cad_ft_offsets
    if offsets is not None:
        if offsets.shape != (len(model.layout),):
            raise DataError(f"{identified.path or 'model file'}: cad_ft_offsets holds {offsets.size} numbers for "
                            f"{len(model.layout)} parameters")
        span = model.layout.span("ft_offset")
        phi[span] = offsets[span]
    return phi


@dataclass(frozen=True)
class Evaluated:
    """A model's residuals on one run."""

    identified: IdentifiedModel
    model: RobotModel
    dataset: Dataset
    signals: Signals  # with the outputs filtered as q̇, q̈ are (see signals_from_dataset)
    e: np.ndarray  # (N, n_out) e = y − ŷ, the inputs predicted with the model's offline supply estimate (dynid.identify.supply)
    e_constant: np.ndarray  # the same with constant motor gains (the paper's model); e itself without tracking

    @property
    def config(self) -> RobotConfig:
        return self.model.config

    @property
    def outputs(self) -> tuple[OutputChannel, ...]:
        return output_channels(self.model)


def evaluate(model_path: str, data_path: str, identified: IdentifiedModel | None = None,
             dataset: Dataset | None = None, window: Window = (None, None),
             payload: dict[str, Any] | None = None, bad_rows: str = DEFAULT_POLICY) -> Evaluated:
    """Residuals of the model on the run; `identified` and `dataset` when the caller has loaded them already."""
    identified = identified or load_model(model_path)
    model = identified.robot_model
    ds = dataset if dataset is not None else load_run(data_path, model, window, payload, bad_rows)
    sig = signals_from_dataset(model, ds, filter_outputs=True)
    effects = identified.effects  # an augmented model (`dynid gaps --out`) predicts with its named effects
    if effects:
        e = augmented_residuals(model, identified.phi, effects, sig, ds.t)
    else:
        e = residuals(model, identified.phi, sig)
    tracked = smoothed_residuals(model, identified.supply_tracking, identified.min_speed, e, sig, ds.t)
    return Evaluated(identified, model, ds, sig, tracked, e)


def _norm_stats(x: np.ndarray) -> dict[str, float]:
    n = np.linalg.norm(x, axis=1)
    return {"mean": float(n.mean()), "std": float(n.std())}


def cad_ft_residuals(ev: Evaluated) -> np.ndarray | None:
    """(N, 6 per sensor) F/T residuals of the CAD parameters, or None without an F/T sensor. The model's F/T offset
    steps (`ft_step`, what the sensor did, not the bodies) apply to CAD too, with its offsets fitted beside them."""
    outs = ev.outputs
    ft = [o.row for o in outs if o.kind == "ft"]
    if not ft:
        return None
    cad = cad_phi(ev.model, ev.identified)
    gains = [o.gain_index for o in outs if o.gain_index is not None]
    cad[gains] = 1.0  # the CAD model has no gains: its input predictions are undefined, not used
    steps = [e for e in ev.identified.effects if e.kind == FT_STEP]
    if steps:
        return augmented_residuals(ev.model, cad, steps, ev.signals, ev.dataset.t)[:, ft]
    return residuals(ev.model, cad, ev.signals)[:, ft]


def validation(ev: Evaluated, model_label: str, data_label: str,
               cad_e: np.ndarray | None = None, window: Window = (None, None),
               fit_overlap: float | None = None) -> dict[str, Any]:
    """`dynid validate --json`: Table II (identified and CAD F/T error norms) and per-channel RMS against noise; the
    data's `window` and the share of its samples that are the fit's own (`fit_overlap`, dynid.identify.blocks.
    fitted_mask; None: the model file cannot tell)."""
    outs, e = ev.outputs, ev.e
    ft = [o.row for o in outs if o.kind == "ft"]
    result: dict[str, Any] = {"model": model_label, "data": data_label, "samples": ev.dataset.n_samples,
                              "window": list(window), "fit_overlap": fit_overlap, "channels": {}}
    contact = ev.dataset.contact
    if contact is not None and np.any(contact != 0):  # the model has no contact: its error includes the contacts'
        result["contact_fraction"] = float(np.mean(contact != 0))
    if ft:
        cad_e = cad_ft_residuals(ev) if cad_e is None else cad_e
        # Table II per F/T sensor, in the configuration's order (6 rows each); `table_ii` is the first sensor's,
        # the paper's single-sensor table.
        per_sensor = {}
        for k, sensor in enumerate(ev.config.ft_sensors):
            rows = ft[6 * k : 6 * k + 6]
            per_sensor[sensor.name] = {
                "identified": {"force": _norm_stats(e[:, rows[:3]]), "torque": _norm_stats(e[:, rows[3:]])},
                "cad": {"force": _norm_stats(cad_e[:, 6 * k : 6 * k + 3]),
                        "torque": _norm_stats(cad_e[:, 6 * k + 3 : 6 * k + 6])},
            }
        first = ev.config.ft_sensors[0].name
        result["table_ii"] = {**per_sensor[first], "sensor": first}
        result["table_ii_sensors"] = per_sensor
        # where identified is above CAD: the postures the fit never saw, the model's F/T steps (identify/transfer.py)
        result["why_worse_than_cad"] = why_worse(ev.identified, per_sensor, ev.dataset.joints, ev.dataset.q,
                                                 ev.dataset.t, ev.model.joint_limits)
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
        y = measured_outputs(ev.model, ev.signals)[:, torque]
        result["relative_torque_error"] = float(np.linalg.norm(e[:, torque]) / np.linalg.norm(y))
    relative = relative_errors(ev)
    if relative is not None:
        result["relative_error"] = relative
    return result


def raw_outputs(ev: Evaluated) -> np.ndarray:
    """y (N, n_out) as recorded, unfiltered (the signals' outputs are smoothed with q̈'s filter)."""
    ds, cols = ev.dataset, []
    for o in ev.outputs:
        kind, _, rest = o.name.partition(".")
        if kind == "ft":
            sensor, c = rest.rsplit(".", 1)
            cols.append(ds.ft[sensor][:, ("fx", "fy", "fz", "tx", "ty", "tz").index(c)])
        elif kind == "tau":
            cols.append(ds.tau[rest])
        else:
            cols.append((ds.pwm if kind == "pwm" else ds.current)[rest])
    return np.column_stack(cols)


def relative_errors(ev: Evaluated) -> dict[str, Any] | None:
    """The relative error of the predicted inputs or joint torques: per channel ‖y − ŷ‖ / ‖y‖ with the raw,
    unfiltered y, and overall over all channels stacked, each weighted by its gain (Nm per unit input, 1 for a
    torque), ‖K(y − ŷ)‖ / ‖K y‖: the error in joint torque, the figure current- and torque-driven arms report.
    None for F/T-only set-ups."""
    rows = [o for o in ev.outputs if o.kind in ("input", "torque")]
    if not rows:
        return None
    idx = [o.row for o in rows]
    y = raw_outputs(ev)[:, idx]
    predicted = measured_outputs(ev.model, ev.signals)[:, idx] - ev.e[:, idx]
    err = y - predicted
    phi = ev.identified.phi
    gains = np.array([phi[o.gain_index] if o.gain_index is not None else o.known_gain for o in rows])
    per = {o.name: {"relative": float(np.linalg.norm(err[:, k]) / max(np.linalg.norm(y[:, k]), 1e-300)),
                    "rms_error": float(np.sqrt(np.mean(err[:, k] ** 2))), "rms_measured": float(np.sqrt(np.mean(y[:, k] ** 2))),
                    "gain": float(gains[k])}
           for k, o in enumerate(rows)}
    overall = float(np.linalg.norm(err * gains) / max(np.linalg.norm(y * gains), 1e-300))
    return {"overall": overall, "channels": per, "measured": "raw (unfiltered)",
            "weights": "the model's gains (Nm per unit input; 1 for joint torques)"}
