"""How well a simulated experiment meets the identification model: A Φ − b per row channel, on the truth.

The check behind the plant's honesty: the recorded signals with the true q̇, q̈ from the integrator and the
true Φ must satisfy the stacked model (docs/design.md §3) wherever the model's physics holds, and break it exactly
where a hidden effect, a contact or static friction acts.
"""

from __future__ import annotations

import numpy as np

from ..robot.model import RobotModel
from ..robot.parameters import WRENCH_FIELDS
from ..robot.regressors.stack import Signals, build_stacked, motor_space
from .experiment import Simulation


def true_parameters(model: RobotModel, sim: Simulation, overrides: dict[str, float] | None = None) -> np.ndarray:
    """The true Φ in layout order, with some entries replaced (e.g. a payload's equivalent inertia)."""
    values = {**sim.truth["parameters"], **(overrides or {})}
    return np.array([values[n] for n in model.layout.names])


def model_residuals(
    model: RobotModel, sim: Simulation, phi: np.ndarray | None = None, with_contact: bool = False
) -> dict[str, np.ndarray]:
    """Per row channel (N,): A Φ − b on the true state; NaN where a friction coordinate of the row sticks.

    `with_contact` removes the contact's known share (of each F/T channel and, through the rows' L, of each
    joint torque), so that contact samples can be checked too.
    """
    cfg = model.config
    truth, data = sim.truth_signals, sim.dataset
    sig = Signals(truth.q, truth.dq, truth.ddq, {**data.pwm, **data.current}, dict(data.tau), dict(data.ft))
    system = build_stacked(model, sig)
    phi = true_parameters(model, sim) if phi is None else phi
    r = (system.A @ phi - system.b).reshape(system.n_samples, -1)
    out = {c.name: r[:, i].copy() for i, c in enumerate(system.channels)}
    stuck = {k.removeprefix("stuck."): v > 0 for k, v in truth.extra.items() if k.startswith("stuck.")}
    tau_contact = np.column_stack([truth.extra[f"contact.tau.{j}"] for j in cfg.joints])
    for s in cfg.ft_sensors:
        if with_contact:
            for f in WRENCH_FIELDS:
                out[f"ft.{s.name}.{f}"] += truth.extra[f"contact.{s.name}.{f}"]
    for g in cfg.actuation:
        cols = [cfg.joints.index(j) for j in g.joints]
        in_motor_space = motor_space(g)
        L = np.linalg.inv(g.coupling.T) if in_motor_space else np.eye(len(cols))
        rows = [f"motor.{m}" for m in g.motors] if in_motor_space else [f"joint.{j}" for j in g.joints]
        shares = tau_contact[:, cols] @ L.T  # the rows are L times the joint equations
        coordinates = [f"joint.{j}" for j in g.joints] + [f"motor.{m}" for m in g.motors]
        held = np.any([stuck[c] for c in coordinates if c in stuck], axis=0)
        for i, row in enumerate(rows):
            if with_contact:
                out[row] -= shares[:, i]
            out[row][held] = np.nan  # static friction holds it: the model's friction cannot say how much
    return out


def worst(residuals: dict[str, np.ndarray], rows: list[str]) -> float:
    """max |r| over the given rows, ignoring masked samples."""
    return float(max(np.nanmax(np.abs(residuals[row])) for row in rows))
