"""The layout of one sample's rows of A Φ = b (docs/design.md §3): the row channels, each actuation group's rows
and the maps L, C that write a group's joint equations and motor terms into them, and the signals rows are built
from. `stack` builds the rows from this layout, and so does the compiled kernel's plan (`kernel`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from ...config.robot_config import ActuationGroup
from ..model import RobotModel
from ..parameters import WRENCH_FIELDS


@dataclass(frozen=True)
class RowChannel:
    """One row of the per-sample block."""

    name: str  # "ft.<sensor>.<fx..tz>" or "joint.<joint>"
    sigma: float  # noise std in the row's units (N, Nm)


def motor_space(group: ActuationGroup) -> bool:
    """A coupled group with as many motors as joints is written one row per motor (see the module docstring)."""
    return group.input != "torque" and group.coupled and group.coupling.shape[0] == group.coupling.shape[1]


def row_channels(model: RobotModel) -> tuple[RowChannel, ...]:
    cfg = model.config
    rows: list[RowChannel] = []
    for s in cfg.ft_sensors:
        for k, c in enumerate(WRENCH_FIELDS):
            # an estimated value (`fit --noise estimate`) overrides the configuration's
            rows.append(RowChannel(f"ft.{s.name}.{c}", cfg.noise.per_channel.get(f"ft.{s.name}.{c}", s.noise_of(k))))
    for g in cfg.actuation:
        if g.input == "torque":
            rows.extend(RowChannel(f"joint.{j}", cfg.noise.of("torque", j)) for j in g.joints)
            continue
        noise = np.array([cfg.noise.of(g.input, m) for m in g.motors])  # per motor (configuration's noise)
        gains = np.array([cfg.motor(m).known_gain or cfg.motor(m).nominal_gain for m in g.motors])
        if motor_space(g):
            rows.extend(RowChannel(f"motor.{m}", float(s * k)) for m, s, k in zip(g.motors, noise, gains))
            continue
        Tt = g.coupling.T
        for li, j in enumerate(g.joints):
            # An input error δu on motor m is a torque error Tᵀ[j, m]·gain_m·δu on this row.
            rows.append(RowChannel(f"joint.{j}", float(np.linalg.norm(Tt[li] * gains * noise))))
    return tuple(rows)

@dataclass(frozen=True)
class Signals:
    """What the stacked rows need, by name; shapes (N, …). Missing channels raise a DataError when needed."""

    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    inputs: Mapping[str, np.ndarray]  # motor -> PWM duty or current (whichever its group's input is)
    tau: Mapping[str, np.ndarray]  # joint -> measured torque
    ft: Mapping[str, np.ndarray]  # sensor -> (N, 6) measured wrench
    # A known payload carried through the run: its inertial parameters in the layout's inertial span (its
    # body's slot, RobotModel.payload_parameters). Its torques are known, so they move to b: that fixes the
    # scale of a set-up with unknown gains and no F/T sensor (the loaded/unloaded runs of Gautier and Khalil).
    payload: np.ndarray | None = None
    # (N, 3) gravity per sample in the model root's frame, for a base that tilts (config.gravity_imu); None: the
    # configuration's constant gravity
    gravity: np.ndarray | None = None

    def slice(self, s: slice) -> Signals:
        return Signals(
            self.q[s], self.dq[s], self.ddq[s],
            {k: v[s] for k, v in self.inputs.items()},
            {k: v[s] for k, v in self.tau.items()},
            {k: v[s] for k, v in self.ft.items()},
            self.payload,
            None if self.gravity is None else self.gravity[s],
        )

def group_rows(model: RobotModel) -> Iterator[tuple[ActuationGroup, list[int], slice]]:
    """Each actuation group with its joints' columns in q and its rows of the stacked system (after the F/T rows)."""
    cfg = model.config
    joint_col = {j: i for i, j in enumerate(cfg.joints)}
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        rows = slice(start, start + len(g.joints))
        start = rows.stop
        yield g, [joint_col[j] for j in g.joints], rows


STRUCTURAL_RTOL = 1e-12  # an entry of an inverted coupling below this share of its largest is rounding residue


def group_row_maps(group: ActuationGroup) -> tuple[np.ndarray, np.ndarray]:
    """(L, C) of a group: its rows are L times its joint equations, and motor terms enter them through C.

    L inverts the coupling: its structural zeros come out of LAPACK as rounding residue (1e-17) whose value, and
    whether it is exactly zero, depends on the CPU's BLAS kernels. They are set to zero here, once, so that which
    rows a term touches never depends on the machine (couplings have condition numbers near 10: the residue is
    ~1e-15 of the largest entry, a true entry is ~1e-1)."""
    if motor_space(group):
        L = np.linalg.inv(group.coupling.T)
        return np.where(np.abs(L) > STRUCTURAL_RTOL * np.abs(L).max(), L, 0.0), np.eye(len(group.motors))
    return np.eye(len(group.joints)), group.coupling.T
