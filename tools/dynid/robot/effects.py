"""The effects an augmented model carries (named by `dynid gaps`), and its prediction with them.

An effect record of the model file (``effects``, format_version 2):

    kind               "stribeck", "spring", or another effect of dynid.robot.effect_library
    where              "joint r_elbow", "motor m3", "sensor r_arm_ft"
    parameters         {name: value} in the plant's units (Nm, rad/s, Nm/rad, rad, …)
    standard_errors    {name: SE or null}: block-jackknife over the held-out time blocks; null for a value found by
                       search (a Stribeck velocity) rather than by regression, or of an effect a fold cannot determine
    units              {name: unit}
    coefficients       the regression coefficients θ of the effect's columns (row units), as fitted
    search             the searched nonlinear value(s)

Stribeck and spring torques are joint torques added to τ + τ_f of their joint, exactly as the monitor adds them
(rt_monitor/src/core.cpp): Stribeck s·sign(q̇)·exp(−(q̇/v_s)²), spring k·(q − rest). An F/T offset step
(`ft_step`) adds d_a to axis a of its sensor while from_s ≤ t < to_s (the data's own seconds; no to_s: to the
end), one parameter d<axis> per axis it acts on. Other kinds are evaluated through their candidate columns in
dynid.robot.effect_library (the fit's own definition); only Stribeck and spring export to the monitor.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import DataError
from ..io.dataset import Dataset
from .effect_library import LIBRARY, Context
from .model import RobotModel
from .outputs import divisors, residuals, residuals_many
from .regressors.friction import stribeck_shape
from .regressors.stack import Signals, joint_row_shares, row_channels

EXPORTABLE = {"stribeck": 1, "spring": 2}  # kind -> the coefficient file's effect_kind
JOINT_EFFECTS = {"stribeck": ("static_torque", "velocity"), "spring": ("stiffness", "rest")}  # closed form, on a joint
FT_STEP = "ft_step"
FT_AXES = ("fx", "fy", "fz", "tx", "ty", "tz")
REQUIRED = {**JOINT_EFFECTS, FT_STEP: ("from_s",)}
UNITS = {"static_torque": "Nm", "velocity": "rad/s", "stiffness": "Nm/rad", "rest": "rad", "amplitude": "Nm",
         "period_deg": "deg", "width": "duty", "tau": "s", "force": "N", "torque": "Nm", "from_s": "s", "to_s": "s",
         "inertia": "kg m²", "ms": "ms", "limit_deg": "deg",
         **{f"d{a}": "N" if a[0] == "f" else "Nm" for a in FT_AXES}}


@dataclass(frozen=True)
class Effect:
    kind: str
    where: str
    parameters: dict[str, float]
    standard_errors: dict[str, float | None] = field(default_factory=dict)
    coefficients: tuple[float, ...] = ()
    search: dict[str, Any] = field(default_factory=dict)

    @property
    def target(self) -> tuple[str, str]:
        """("joint", "r_elbow") from "joint r_elbow"."""
        kind, _, name = self.where.partition(" ")
        return kind, name

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "where": self.where, "parameters": self.parameters,
                "standard_errors": self.standard_errors,
                "units": {k: UNITS.get(k, "") for k in self.parameters},
                "coefficients": list(self.coefficients), "search": self.search}


def parse_effects(raw: Any, where: str = "model file") -> list[Effect]:
    """The ``effects`` section, checked in its shape: a malformed one is a DataError naming the problem (that each
    acts on the robot is `check_effect_targets`')."""
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise DataError(f"{where}: 'effects' must be a list")
    out = []
    for i, e in enumerate(raw):
        if not isinstance(e, dict) or not isinstance(e.get("kind"), str) or not isinstance(e.get("where"), str):
            raise DataError(f"{where}: effect {i} needs a 'kind' and a 'where'")
        params = e.get("parameters")
        if not isinstance(params, dict) or not all(finite_number(v) for v in params.values()):
            raise DataError(f"{where}: effect {i} ({e['kind']}): every parameter must be a finite number")
        try:  # the optional parts too: a list for a mapping, text for a number, is one line, not a traceback
            effect = Effect(e["kind"], e["where"], {k: float(v) for k, v in params.items()},
                            dict(e.get("standard_errors") or {}), tuple(float(c) for c in e.get("coefficients") or ()),
                            dict(e.get("search") or {}))
        except (TypeError, ValueError, OverflowError):
            raise DataError(
                f"{where}: effect {i} ({e['kind']}): standard_errors, coefficients or search is malformed") from None
        missing = [p for p in REQUIRED.get(effect.kind, ()) if p not in effect.parameters]
        if missing:
            raise DataError(f"{where}: effect {i} ({effect.kind}) lacks parameter '{missing[0]}'")
        out.append(effect)
    return out


def check_effect_targets(effects: list[Effect], model: RobotModel, where: str = "model file") -> list[Effect]:
    """`effects`, each of a kind with a closed form acting on a joint of `model` (else a DataError naming it)."""
    sensors = [s.name for s in model.config.ft_sensors]
    for i, effect in enumerate(effects):
        kind, name = effect.target
        if effect.kind in JOINT_EFFECTS and (kind != "joint" or name not in model.config.joints):
            raise DataError(f"{where}: effect {i} ({effect.kind}) acts on '{effect.where}', not a joint of "
                            f"{model.config.name}")
        if effect.kind == FT_STEP:
            if kind != "sensor" or name not in sensors:
                raise DataError(f"{where}: effect {i} (ft_step) acts on '{effect.where}', not an F/T sensor of "
                                f"{model.config.name}")
            if not step_axes(effect) or effect.parameters.get("to_s", np.inf) <= effect.parameters["from_s"]:
                raise DataError(f"{where}: effect {i} (ft_step) needs d<axis> sizes and to_s after from_s")
    return effects


def step_axes(effect: Effect) -> tuple[str, ...]:
    """The axes an `ft_step` acts on: those with a size d<axis>."""
    return tuple(a for a in FT_AXES if f"d{a}" in effect.parameters)


def ft_step_columns(model: RobotModel, sensor: str, t: np.ndarray, from_s: float, to_s: float | None,
                    axes: Sequence[str] = FT_AXES) -> np.ndarray:
    """(N, r, len(axes)): 1 on the row of each axis of `sensor` while from_s ≤ t < to_s (t: the data's own seconds;
    to_s None: to the end), 0 elsewhere: the columns of an F/T offset that steps there."""
    t = np.asarray(t, float)
    index = [s.name for s in model.config.ft_sensors].index(sensor)
    inside = (t >= from_s) & (t < (np.inf if to_s is None else to_s))
    out = np.zeros((t.size, len(row_channels(model)), len(axes)))
    for k, axis in enumerate(axes):
        out[:, 6 * index + FT_AXES.index(axis), k] = inside
    return out


def finite_number(v: Any) -> bool:
    """A finite JSON number: not a bool, not an integer too large for a float (np.isfinite raised TypeError)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return bool(np.isfinite(float(v)))
    except OverflowError:
        return False


def joint_torques(model: RobotModel, effects: list[Effect], q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """(N, n_joints) extra joint torque of the Stribeck and spring effects (others contribute nothing here)."""
    tau = np.zeros_like(np.asarray(q, float))
    for e in effects:
        if e.kind not in JOINT_EFFECTS:
            continue
        j = model.config.joints.index(e.target[1])
        p = e.parameters
        if e.kind == "stribeck":
            tau[:, j] += p["static_torque"] * stribeck_shape(dq[:, j], p["velocity"])
        else:
            tau[:, j] += p["stiffness"] * (q[:, j] - p["rest"])
    return tau


def effect_rows(model: RobotModel, effects: list[Effect], sig: Signals, t: np.ndarray | None = None,
                phi: np.ndarray | None = None) -> np.ndarray:
    """(N, r) what the effects add to a·Φ of every row channel (row units); t: the samples' time in the data's own
    seconds (only time-dependent effects need it: an F/T step at its times, an F/T drift from the first sample);
    phi: the model's Φ, for the effects whose column is the standard model's own prediction (load friction)."""
    tau = joint_torques(model, effects, sig.q, sig.dq)
    out = sum((np.outer(tau[:, c], share) for c, share in joint_row_shares(model).values()),
              np.zeros((sig.q.shape[0], len(row_channels(model)))))
    for e in (e for e in effects if e.kind == FT_STEP):
        if t is None:
            raise DataError("this model's F/T step is at given times; evaluate it on a run with time stamps")
        axes = step_axes(e)
        cols = ft_step_columns(model, e.target[1], t, e.parameters["from_s"], e.parameters.get("to_s"), axes)
        out += cols @ np.array([e.parameters[f"d{a}"] for a in axes])
    others = [e for e in effects if e.kind not in REQUIRED]
    if others:
        out += _library_rows(model, others, sig, t, phi)
    return out


def _library_rows(model: RobotModel, effects: list[Effect], sig: Signals, t: np.ndarray | None,
                  phi: np.ndarray | None) -> np.ndarray:
    """Effects without a closed form here: their candidate columns (the searched value fixed) times θ."""
    if t is None:
        raise DataError("this model's effects depend on time; evaluate them on a run with time stamps")
    ctx = Context(model, sig, np.asarray(t, float), phi)
    out = np.zeros((sig.q.shape[0], len(row_channels(model))))
    for e in effects:
        if e.kind not in LIBRARY:
            raise DataError(f"the model names effect '{e.kind}', which this dynid does not know")
        searched = [float(v) for v in e.search.values() if isinstance(v, (int, float))]
        made = LIBRARY[e.kind](ctx, tuple(searched)) if searched else LIBRARY[e.kind](ctx)
        match = [c for c in made if c.where == e.where
                 and all(c.nonlinear.get(k) == v for k, v in e.search.items())]
        if len(match) != 1 or len(e.coefficients) != match[0].values.shape[2]:
            raise DataError(f"effect {e.kind} on {e.where}: its columns cannot be rebuilt from the model file")
        out += match[0].values @ np.asarray(e.coefficients)
    return out


def augmented_residuals(model: RobotModel, phi: np.ndarray, effects: list[Effect], sig: Signals,
                        t: np.ndarray | None = None) -> np.ndarray:
    """e = y − ŷ (N, n_out) of the standard model plus the effects (t: the data's own seconds, as `effect_rows`)."""
    e = residuals(model, phi, sig)
    if not effects:
        return e
    return e - effect_rows(model, effects, sig, t, phi) / divisors(model, phi)


def augmented_residuals_many(model: RobotModel, phis: Sequence[np.ndarray], effects: list[Effect], sig: Signals,
                             t: np.ndarray | None = None) -> list[np.ndarray]:
    """`augmented_residuals` for each Φ of `phis`; without effects the rows are built once for all of them."""
    if effects:
        return [augmented_residuals(model, phi, effects, sig, t) for phi in phis]
    return residuals_many(model, phis, sig)


def without_ft_steps(model: RobotModel, ds: Dataset, steps: Sequence[Effect]) -> Dataset:
    """A copy of `ds` whose F/T measurements have the `ft_step` effects taken out: a fit on it is the fit with those
    steps known (their times and sizes), whose model then carries them (`dynid fit --steps-from`)."""
    ft = {name: values.copy() for name, values in ds.ft.items()}
    for e in steps:
        sensor = e.target[1]
        if sensor not in ft:
            raise DataError(f"the run has no F/T sensor {sensor} for the step {e.where} ({e.parameters['from_s']:g} s)")
        i = [s.name for s in model.config.ft_sensors].index(sensor)
        ft[sensor] -= effect_rows(model, [e], _no_motion(ds), ds.t)[:, 6 * i : 6 * i + 6]
    out = Dataset(ds.t, ds.joints, ds.q, ds.dq, ds.ddq, ds.pwm, ds.current, ds.tau, ft, ds.contact, ds.extra,
                  dict(ds.meta))
    return out


def _no_motion(ds: Dataset) -> Signals:
    """Signals of `ds` holding only what an F/T step reads (its time): q for the shape, nothing else."""
    zero = np.zeros_like(ds.q)
    return Signals(ds.q, zero, zero, {}, {}, {})
