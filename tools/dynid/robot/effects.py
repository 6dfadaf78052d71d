"""The effects an augmented model carries (named by `dynid gaps`), and its prediction with them.

An effect record of the model file (``effects``, format_version 2):

    kind               "stribeck", "spring", or another effect of dynid.robot.effect_library
    where              "joint r_elbow", "motor m3", "sensor r_arm_ft"
    parameters         {name: value} in the plant's units (Nm, rad/s, Nm/rad, rad, …)
    standard_errors    {name: SE or null}: block-jackknife over the held-out time blocks; null for a value found by
                       search (a Stribeck velocity) rather than by regression
    units              {name: unit}
    coefficients       the regression coefficients θ of the effect's columns (row units), as fitted
    search             the searched nonlinear value(s)

Stribeck and spring torques are joint torques added to τ + τ_f of their joint, exactly as the monitor adds them
(rt_monitor/src/core.cpp): Stribeck s·sign(q̇)·exp(−(q̇/v_s)²), spring k·(q − rest). Other kinds are evaluated
through their candidate columns in dynid.robot.effect_library (the fit's own definition); only Stribeck and spring
export to the monitor.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import DataError
from .effect_library import LIBRARY, Context
from .model import RobotModel
from .outputs import divisors, residuals
from .regressors.friction import stribeck_shape
from .regressors.stack import Signals, joint_row_shares, row_channels

EXPORTABLE = {"stribeck": 1, "spring": 2}  # kind -> the coefficient file's effect_kind
REQUIRED = {"stribeck": ("static_torque", "velocity"), "spring": ("stiffness", "rest")}
UNITS = {"static_torque": "Nm", "velocity": "rad/s", "stiffness": "Nm/rad", "rest": "rad", "amplitude": "Nm",
         "period_deg": "deg", "width": "duty", "tau": "s", "force": "N", "torque": "Nm"}


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
    for i, effect in enumerate(effects):
        kind, name = effect.target
        if effect.kind in REQUIRED and (kind != "joint" or name not in model.config.joints):
            raise DataError(f"{where}: effect {i} ({effect.kind}) acts on '{effect.where}', not a joint of "
                            f"{model.config.name}")
    return effects


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
        if e.kind not in REQUIRED:
            continue
        j = model.config.joints.index(e.target[1])
        p = e.parameters
        if e.kind == "stribeck":
            tau[:, j] += p["static_torque"] * stribeck_shape(dq[:, j], p["velocity"])
        else:
            tau[:, j] += p["stiffness"] * (q[:, j] - p["rest"])
    return tau


def effect_rows(model: RobotModel, effects: list[Effect], sig: Signals, t: np.ndarray | None = None) -> np.ndarray:
    """(N, r) what the effects add to a·Φ of every row channel (row units); t: s since the run's start (only
    time-dependent effects, an F/T drift, need it)."""
    tau = joint_torques(model, effects, sig.q, sig.dq)
    out = sum((np.outer(tau[:, c], share) for c, share in joint_row_shares(model).values()),
              np.zeros((sig.q.shape[0], len(row_channels(model)))))
    others = [e for e in effects if e.kind not in REQUIRED]
    if others:
        out += _library_rows(model, others, sig, t)
    return out


def _library_rows(model: RobotModel, effects: list[Effect], sig: Signals, t: np.ndarray | None) -> np.ndarray:
    """Effects without a closed form here: their candidate columns (the searched value fixed) times θ."""
    if t is None:
        raise DataError("this model's effects depend on time; evaluate them on a run with time stamps")
    ctx = Context(model, sig, np.asarray(t, float))
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
    """e = y − ŷ (N, n_out) of the standard model plus the effects."""
    e = residuals(model, phi, sig)
    if not effects:
        return e
    return e - effect_rows(model, effects, sig, t) / divisors(model, phi)
