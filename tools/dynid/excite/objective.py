"""The condition number the designer minimises, and the one `dynid excite` reports for any trajectory.

It is the condition number of the regressor the fit solves (docs/design.md §3): every row of the set-up (F/T,
motor or joint-torque equations), each divided by its channel's noise σ, on the **base parameters** of the
configuration (the structural base of `dynid structure`, from random states), each column scaled to unit norm
(as `dynid.robot.regressors.base` scales them to find the rank). A direction the trajectory does not excite makes
it infinite.

The regressor holds the motor inputs too (the gains' columns). A trajectory not yet run has no measured inputs,
so they are predicted: the CAD model's rigid-body joint torques along the trajectory, mapped to the motors through
the coupling and the configured gains (known, else nominal), as the boards' controller would map them. Friction,
which the configuration does not know, is left out of the prediction. Trajectories compared with each other get
the same prediction, so the comparison is fair, but the number is the design's estimate, not the run's:
`dynid structure --data RUN` gives the run's own.

`rows_at_rest`: the report leaves out rows whose joint or motor is slower than `min_speed`, as the fit does
(today's reaching moves dwell at rest); the optimiser keeps them (the rule is a step, which its finite-difference
gradient cannot follow; a designed trajectory is rarely at rest).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..robot.model import RobotModel
from ..robot.regressors.base import structural_base_parameters
from ..robot.regressors.stack import DEFAULT_MIN_SPEED, Signals, fill_rows, group_row_maps, row_channels, row_weights


@dataclass
class ConditionObjective:
    """The weighted, column-scaled base regressor of a configured robot along a trajectory, and its condition."""

    model: RobotModel
    independent: np.ndarray  # columns of Φ that represent the base parameters
    rank: int

    @classmethod
    def of(cls, model: RobotModel) -> ConditionObjective:
        base = structural_base_parameters(model)
        return cls(model, base.independent, base.rank)

    @cached_property
    def _input_map(self) -> list[tuple[slice, np.ndarray, np.ndarray, np.ndarray, list[tuple[int, int]]]]:
        """Per motor-driven group: its rows, L⁻¹ (rows -> joint torques), C (each motor's share of each row, stack.py),
        joint torques -> inputs, and for each motor whose gain is unknown (its index in the group, its gain's column)."""
        cfg, layout = self.model.config, self.model.layout
        out = []
        start = 6 * len(cfg.ft_sensors)
        for g in cfg.actuation:
            rows = slice(start, start + len(g.joints))
            start = rows.stop
            if g.input == "torque":
                continue
            L, C = group_row_maps(g)
            gains = np.array([cfg.motor(m).known_gain or cfg.motor(m).nominal_gain for m in g.motors])
            unknown = [(i, layout.block("motor_gain", m).start) for i, m in enumerate(g.motors)
                       if cfg.motor(m).known_gain is None]
            out.append((rows, np.linalg.inv(L), C, np.linalg.pinv(g.coupling.T) / gains[:, None], unknown))
        return out

    def signals(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> Signals:
        """The signals of a trajectory, with the channels the regressor's A needs; inputs zero (`regressor` puts the
        predicted ones into the gains' columns)."""
        cfg = self.model.config
        n = q.shape[0]
        inputs = {m: np.zeros(n) for g in cfg.actuation if g.input != "torque" for m in g.motors}
        tau_measured = {j: np.zeros(n) for j in cfg.joints_with_input("torque")}
        ft = {s.name: np.zeros((n, 6)) for s in cfg.ft_sensors}
        gravity = None
        if cfg.gravity_imu:  # a tilting base: the design assumes the nominal gravity
            gravity = np.tile(np.asarray(cfg.gravity, float), (n, 1))
        return Signals(q, dq, ddq, inputs, tau_measured, ft, None, gravity)

    def regressor(self, sig: Signals) -> np.ndarray:
        """(N, r, p): A along the signals, the gains' columns holding the predicted inputs: the CAD joint torques
        (the rows' own inertial part times the CAD parameters, L⁻¹ back to joint torques) through the coupling and
        the gains. One regressor build per sample: the torques come out of the rows already built."""
        model = self.model
        n, r, p = sig.q.shape[0], len(row_channels(model)), len(model.layout)
        A, b = np.zeros((n, r, p)), np.zeros((n, r))
        fill_rows(model, sig, A, b)
        inertial, phi = model.layout.span("inertial"), model.cad_inertial_parameters
        for rows, L_inv, C, to_inputs, unknown in self._input_map:
            tau = (A[:, rows, inertial] @ phi) @ L_inv.T  # (N, joints of the group)
            u = tau @ to_inputs.T  # (N, motors)
            for i, col in unknown:
                A[:, rows, col] = -C[None, :, i] * u[:, i, None]
        return A

    def base_regressor(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                       min_speed: float | None = None) -> np.ndarray:
        """(rows, rank): the weighted base regressor, columns not yet scaled; rows at rest dropped with min_speed."""
        sig = self.signals(q, dq, ddq)
        n, r = q.shape[0], len(row_channels(self.model))
        A = self.regressor(sig)
        w = row_weights(self.model, sig, min_speed)
        Ab = (A[:, :, self.independent] * w[:, :, None]).reshape(n * r, self.rank)
        return Ab[(w > 0).ravel()]

    def condition(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, min_speed: float | None = None) -> float:
        """cond of the column-scaled base regressor (inf when a base direction is not excited)."""
        Ab = self.base_regressor(q, dq, ddq, min_speed)
        gram = Ab.T @ Ab
        d = np.sqrt(np.diag(gram))
        if not np.all(d > 0):
            return float("inf")
        lam = np.linalg.eigvalsh(gram / np.outer(d, d))
        if lam[0] <= lam[-1] * 1e-15:
            return float("inf")
        return float(np.sqrt(lam[-1] / lam[0]))

    def _weighted(self, sig: Signals, w: np.ndarray) -> np.ndarray:
        """(N, r, rank): the base columns of A, rows weighted by `w` (N, r)."""
        return self.regressor(sig)[:, :, self.independent] * w[:, :, None]

    def log_condition_and_gradient(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                                   min_speed: float | None = DEFAULT_MIN_SPEED, step: float = 1e-6
                                   ) -> tuple[float, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """log10 cond and its gradient with respect to every sample's q, q̇, q̈ (three (N, J) arrays).

        Each sample's rows depend on that sample's state alone, so one perturbation of a state component at every
        sample at once gives all the samples' derivatives: 3·J + 1 regressor builds, against one per free
        coefficient for a finite-difference gradient. With Gn = D⁻¹GD⁻¹ (G the Gram of the weighted base
        columns, D² its diagonal) and v a unit eigenvector of Gn with eigenvalue λ, dλ = Σ W ⊙ dG with
        W = (v/d)(v/d)ᵀ − λ diag(v²/d²), and dG = Σ_rows aᵀda + daᵀa. Which rows are at rest is held fixed.
        """
        sig = self.signals(q, dq, ddq)
        w = row_weights(self.model, sig, min_speed)
        Ab = self._weighted(sig, w)
        flat = Ab.reshape(-1, self.rank)
        gram = flat.T @ flat
        d = np.sqrt(np.diag(gram))
        zeros = (np.zeros_like(q), np.zeros_like(q), np.zeros_like(q))
        if not np.all(d > 0):
            return 20.0, zeros
        lam, V = np.linalg.eigh(gram / np.outer(d, d))
        if lam[0] <= lam[-1] * 1e-15:
            return 20.0, zeros
        value = 0.5 * float(np.log10(lam[-1] / lam[0]))

        def weight(v: np.ndarray, ev: float) -> np.ndarray:
            x = v / d
            return np.outer(x, x) - ev * np.diag(x * x)

        W = 0.5 / np.log(10.0) * (weight(V[:, -1], lam[-1]) / lam[-1] - weight(V[:, 0], lam[0]) / lam[0])
        AW = Ab @ W  # (N, r, rank)
        grads = []
        for which in range(3):
            g = np.empty_like(q)
            for j in range(q.shape[1]):
                state = [q, dq, ddq]
                moved = state[which].copy()
                moved[:, j] += step
                state[which] = moved
                dA = (self._weighted(self.signals(*state), w) - Ab) / step
                g[:, j] = 2.0 * np.einsum("nrk,nrk->n", AW, dA)
            grads.append(g)
        return value, (grads[0], grads[1], grads[2])

    def report_condition(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                         min_speed: float = DEFAULT_MIN_SPEED) -> float:
        """The condition number `dynid excite` reports: rows at rest left out, as the fit leaves them out."""
        return self.condition(q, dq, ddq, min_speed)
