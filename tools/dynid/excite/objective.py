"""The condition number the designer minimises, and the one `dynid excite` reports for any trajectory.

It is the number `dynid structure --data RUN` prints for a recorded run (`BaseParameters.condition_number`): the
regressor the fit solves (docs/design.md §3), every row of the set-up (F/T, motor or joint-torque equations) divided
by its channel's noise σ, rows at rest left out, **every column** of Φ that acts on some row scaled to unit norm,
and the ratio of its largest singular value to its rank-th (the smallest one the structure does not set to zero).
The columns the base parameters leave out (combinations of the others on every trajectory) count: they change the
nonzero spectrum. An earlier version took the base columns alone; it found designs at 24.4 whose runs measured 30.6,
the same design's full-column number (31.1 on its reference), while today's trajectory measured about the same
either way (56.4 and 56.1). A direction the trajectory does not excite makes the number infinite.

The regressor holds the motor inputs too (the gains' columns). A trajectory not yet run has no measured inputs,
so they are predicted: the CAD model's rigid-body joint torques along the trajectory, mapped to the motors through
the coupling and the configured gains (known, else nominal), as the boards' controller would map them. Friction,
which the configuration does not know, is left out of the prediction: on the simulated arm the measured inputs
instead change the run's number by 0.2 % (30.60 against 30.66), and so do filtered against raw signals.

Rows at rest: the reported number leaves out rows whose joint or motor is slower than `min_speed`, as the fit and
`dynid structure` do. The search minimises the same number with those rows faded out smoothly up to a higher speed
(`design_weights`): a run's joints stick around reversals, so it loses more rows than its reference, and a step
would be invisible to the gradient.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..robot.model import RobotModel
from ..robot.regressors.base import structural_base_parameters
from ..robot.regressors.stack import (DEFAULT_MIN_SPEED, Signals, fill_rows, friction_coordinates, group_row_maps,
                                      row_channels, row_weights)

# An eigenvalue of the column-scaled Gram counts as zero below this fraction of the largest (a condition number
# above 3e6): its structural zeros come out of eigh at round-off, about 1e-16 of the largest; the smallest nonzero
# one of a usable trajectory is near 1e-3.
RANK_RTOL = 1e-13
# rad/s: the search's rows fade out below this speed of a friction coordinate (`design_weights`). On the simulated
# arm the joints stick around a reversal (static friction) while the reference moves on, so a run loses more rows
# than its reference's own rows at rest: where a run's joint was at rest, the reference's speed had a median of
# 0.01-0.045 rad/s per joint. 60 s designs (80 s of search), their runs against the reported number: searched with
# the fit's own 0.01 (14 harmonics), 8 % above (27.4 against 25.3); with 0.03 (18 harmonics), 4-8 % above; with
# 0.05 and 0.06, within 2.5 % either way, and lower (23.5-23.9 for seed 0); with 0.1, 27.3.
STICK_SPEED = 0.05


@dataclass
class ConditionObjective:
    """The weighted, column-scaled regressor of a configured robot along a trajectory, and its condition."""

    model: RobotModel
    columns: np.ndarray  # columns of Φ that act on some row (all but the structure's unidentifiable ones)
    rank: int  # the structural rank: the spectrum's first len(columns) − rank eigenvalues are zero on any trajectory

    @classmethod
    def of(cls, model: RobotModel) -> ConditionObjective:
        base = structural_base_parameters(model)
        gone = set(base.unidentifiable)
        columns = np.array([i for i, n in enumerate(model.layout.names) if n not in gone])
        return cls(model, columns, base.rank)

    @property
    def nullity(self) -> int:
        """Index of the smallest nonzero eigenvalue of the column-scaled Gram (eigenvalues ascending)."""
        return len(self.columns) - self.rank

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

    def weighted_regressor(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                           min_speed: float | None = None) -> np.ndarray:
        """(rows, columns): the weighted regressor, columns not yet scaled; rows at rest dropped with min_speed."""
        sig = self.signals(q, dq, ddq)
        w = row_weights(self.model, sig, min_speed)
        Ab = self._weighted(sig, w).reshape(-1, len(self.columns))
        return Ab[(w > 0).ravel()]

    def condition(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, min_speed: float | None = None) -> float:
        """cond of the column-scaled regressor on its rank (inf when a base direction is not excited)."""
        return _condition(self.weighted_regressor(q, dq, ddq, min_speed), self.nullity)

    def _weighted(self, sig: Signals, w: np.ndarray) -> np.ndarray:
        """(N, r, columns): the used columns of A, rows weighted by `w` (N, r)."""
        return self.regressor(sig)[:, :, self.columns] * w[:, :, None]

    def design_weights(self, dq: np.ndarray) -> np.ndarray:
        """(N, r) row weights of the objective the search minimises: 1/σ times, for each friction coordinate the
        row holds, a smooth step in its speed v, 1 / (1 + (STICK_SPEED/v)⁴) (0.5 at STICK_SPEED, below 0.002
        at the fit's min_speed). It anticipates the rows a run loses around reversals, where the joints stick, and,
        being smooth, lets the gradient see them: the search learns to reverse briskly."""
        w = np.tile(1.0 / np.array([c.sigma for c in row_channels(self.model)]), (dq.shape[0], 1))
        for rows, coordinates in friction_coordinates(self.model, dq):
            for c in coordinates:
                ratio = STICK_SPEED / np.maximum(np.abs(c.velocity), 1e-12)
                w[:, rows] *= np.where(c.share != 0, 1.0 / (1.0 + ratio ** 4)[:, None], 1.0)
        return w

    def design_condition(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> float:
        """The search's objective: the condition number with `design_weights`."""
        return _condition(self._weighted(self.signals(q, dq, ddq), self.design_weights(dq)), self.nullity)

    def log_condition_and_gradient(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, step: float = 1e-6
                                   ) -> tuple[float, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """log10 of `design_condition` and its gradient with respect to every sample's q, q̇, q̈ (three (N, J)
        arrays).

        Each sample's rows depend on that sample's state alone, so one perturbation of a state component at every
        sample at once gives all the samples' derivatives: 3·J + 1 regressor builds, against one per free
        coefficient for a finite-difference gradient. With Gn = D⁻¹GD⁻¹ (G the Gram of the weighted columns,
        D² its diagonal) and v a unit eigenvector of Gn with a simple eigenvalue λ (the largest, and the smallest
        nonzero one: the zero ones are the structure's and stay zero), dλ = Σ W ⊙ dG with
        W = (v/d)(v/d)ᵀ − λ diag(v²/d²), and dG = Σ_rows aᵀda + daᵀa (the weights' change with q̇ included).
        """
        sig = self.signals(q, dq, ddq)
        w = self.design_weights(dq)
        Ab = self._weighted(sig, w)
        flat = Ab.reshape(-1, len(self.columns))
        gram = flat.T @ flat
        d = np.sqrt(np.diag(gram))
        zeros = (np.zeros_like(q), np.zeros_like(q), np.zeros_like(q))
        if not np.all(d > 0):
            return 20.0, zeros
        lam, V = np.linalg.eigh(gram / np.outer(d, d))
        k = self.nullity
        if lam[k] <= lam[-1] * RANK_RTOL:
            return 20.0, zeros
        value = 0.5 * float(np.log10(lam[-1] / lam[k]))

        def weight(v: np.ndarray, ev: float) -> np.ndarray:
            x = v / d
            return np.outer(x, x) - ev * np.diag(x * x)

        W = 0.5 / np.log(10.0) * (weight(V[:, -1], lam[-1]) / lam[-1] - weight(V[:, k], lam[k]) / lam[k])
        AW = Ab @ W  # (N, r, columns)
        grads = []
        for which in range(3):
            g = np.empty_like(q)
            for j in range(q.shape[1]):
                state = [q, dq, ddq]
                moved = state[which].copy()
                moved[:, j] += step
                state[which] = moved
                w_moved = self.design_weights(moved) if which == 1 else w
                dA = (self._weighted(self.signals(*state), w_moved) - Ab) / step
                g[:, j] = 2.0 * np.einsum("nrk,nrk->n", AW, dA)
            grads.append(g)
        return value, (grads[0], grads[1], grads[2])

    def report_condition(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                         min_speed: float = DEFAULT_MIN_SPEED) -> float:
        """The condition number `dynid excite` reports: rows at rest left out, as the fit leaves them out."""
        return self.condition(q, dq, ddq, min_speed)


def _condition(A: np.ndarray, nullity: int) -> float:
    """sqrt(λ_max / λ_nullity) of the column-scaled Gram of A (..., columns): its largest singular value over its
    smallest nonzero one; inf when a column is zero or the rank falls short of the structure's."""
    flat = A.reshape(-1, A.shape[-1])
    gram = flat.T @ flat
    d = np.sqrt(np.diag(gram))
    if not np.all(d > 0):
        return float("inf")
    lam = np.linalg.eigvalsh(gram / np.outer(d, d))
    if lam[nullity] <= lam[-1] * RANK_RTOL:
        return float("inf")
    return float(np.sqrt(lam[-1] / lam[nullity]))
