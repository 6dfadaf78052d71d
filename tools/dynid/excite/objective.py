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

import numpy as np
import pinocchio as pin

from ..robot.model import RobotModel
from ..robot.regressors.base import structural_base_parameters
from ..robot.regressors.stack import DEFAULT_MIN_SPEED, Signals, fill_rows, row_channels, row_weights


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

    def _input_map(self) -> list[tuple[str, list[int], np.ndarray]]:
        """Per motor-driven group: its motors, its joints' columns, and the map joint torques -> motor inputs."""
        cfg = self.model.config
        out = []
        for g in cfg.actuation:
            if g.input == "torque":
                continue
            gains = np.array([cfg.motor(m).known_gain or cfg.motor(m).nominal_gain for m in g.motors])
            out.append((g.name, [cfg.joints.index(j) for j in g.joints], np.linalg.pinv(g.coupling.T) / gains[:, None]))
        return out

    def _cad_torques(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """(N, J) joint torques of the CAD model (RNEA: a tenth of a regressor's cost)."""
        model = self.model
        m = model.pin_model
        data = m.createData()
        Q, V, A = model.pinocchio_configuration(q), model.pinocchio_velocity(dq), model.pinocchio_velocity(ddq)
        out = np.empty((q.shape[0], m.nv))
        for k in range(q.shape[0]):
            out[k] = pin.rnea(m, data, Q[k], V[k], A[k])
        return out[:, model.v_index]

    def signals(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> Signals:
        """The signals of a trajectory, with the inputs and measured channels the regressor's A needs."""
        cfg, model = self.model.config, self.model
        n = q.shape[0]
        inputs: dict[str, np.ndarray] = {}
        groups = self._input_map()
        if groups:
            tau = self._cad_torques(q, dq, ddq)
            for name, cols, to_inputs in groups:
                g = next(x for x in cfg.actuation if x.name == name)
                u = tau[:, cols] @ to_inputs.T
                inputs.update({m: u[:, i] for i, m in enumerate(g.motors)})
        tau_measured = {j: np.zeros(n) for j in cfg.joints_with_input("torque")}
        ft = {s.name: np.zeros((n, 6)) for s in cfg.ft_sensors}
        gravity = None
        if cfg.gravity_imu:  # a tilting base: the design assumes the nominal gravity
            gravity = np.tile(np.asarray(cfg.gravity, float), (n, 1))
        return Signals(q, dq, ddq, inputs, tau_measured, ft, None, gravity)

    def base_regressor(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                       min_speed: float | None = None) -> np.ndarray:
        """(rows, rank): the weighted base regressor, columns not yet scaled; rows at rest dropped with min_speed."""
        sig = self.signals(q, dq, ddq)
        n, r, p = q.shape[0], len(row_channels(self.model)), len(self.model.layout)
        A, b = np.zeros((n, r, p)), np.zeros((n, r))
        fill_rows(self.model, sig, A, b)
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
        n, r, p = sig.q.shape[0], len(row_channels(self.model)), len(self.model.layout)
        A, b = np.zeros((n, r, p)), np.zeros((n, r))
        fill_rows(self.model, sig, A, b)
        return A[:, :, self.independent] * w[:, :, None]

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
