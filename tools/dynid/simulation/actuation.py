"""Motors, transmissions and friction: from the boards' inputs to the torques on the rigid bodies.

For the motors M (all in configuration order) and the joints J::

    q̇_m   = T q̇                      (T stacks every group's coupling: the true one, not the configured one)
    τ_in  = φ_m s(t) u_eff (1 + ε sin(h N θ_m + ψ))       drive torque: gain × supply × duty, with ripple
    τ_0   = Tᵀ (τ_in [+ cogging]) + τ_direct [+ spring, end stops]
    τ     = τ_0 − Sᵀ f(S q̇)

`τ_direct` drives the joints that no motor of the configuration drives (ideal torque sources, e.g. the iCub
wrist) and the groups with joint torque sensors. u_eff is the duty after the dead-zone effect; s(t) (the supply
relative to nominal) and the ripple are the disturbance that closed-loop control compensates.

Friction acts on *friction coordinates* w = S q̇: every joint, then every motor of a coupled group. A directly
driven joint's motor turns with the joint, so its friction and back-EMF add to the joint's coordinate. Each
coordinate has f(w) = c⁺[w>0] − c⁻[w<0] + v⁺max(w,0) + v⁻min(w,0) (back-EMF in v±) while it slides, and
sticks at w = 0 while the static force it needs stays within [−c⁻, c⁺]. The plant resolves that implicitly
(plant.py); here we give it S and the coefficients of the step (the hidden Stribeck and load-dependent effects
raise the Coulomb levels).
"""

from __future__ import annotations

import numpy as np

from ..config.robot_config import RobotConfig
from .effects import Effect
from .true_robot import TrueRobot

GEAR_RATIO = 100.0  # harmonic drive, for the ripple's frequency
RIPPLE_HARMONIC = 6.0  # torque ripple per electrical revolution of a 3-phase brushless motor
END_STOP_STIFFNESS = 200.0  # Nm/rad beyond a joint limit (a rubber stop)
END_STOP_DAMPING = 2.0  # Nm s/rad beyond a joint limit
STICK_BAND = 1e-4  # rad/s: a friction coordinate slower than this is stuck (far below one encoder step per ms)


class FrictionStep:
    """The friction law of one step on the coordinates w = S q̇ (arrays over coordinates).

    Sliding: f = c⁺ + v⁺w (w > 0) or −c⁻ + v⁻w (w < 0), the model's law. Sticking band: f = k w with
    k = mean Coulomb / STICK_BAND, between the edges where that line meets the sliding law (f continuous).
    """

    __slots__ = ("S", "St", "coulomb_pos", "coulomb_neg", "viscous_pos", "viscous_neg", "band_slope", "upper", "lower")

    def __init__(self, S: np.ndarray, coulomb_pos: np.ndarray, coulomb_neg: np.ndarray, viscous_pos: np.ndarray,
                 viscous_neg: np.ndarray) -> None:
        self.S, self.St = S, S.T.copy()
        self.coulomb_pos, self.coulomb_neg = coulomb_pos, coulomb_neg
        self.viscous_pos, self.viscous_neg = viscous_pos, viscous_neg
        self.band_slope = 0.5 * (coulomb_pos + coulomb_neg) / STICK_BAND + viscous_pos + viscous_neg
        self.upper = coulomb_pos / (self.band_slope - viscous_pos)
        self.lower = -coulomb_neg / (self.band_slope - viscous_neg)


class Actuators:
    """The true actuation of one plant, with its hidden actuator effects."""

    def __init__(
        self,
        config: RobotConfig,
        truth: TrueRobot,
        effects: list[Effect],
        joint_limits: np.ndarray,
        ripple: float,
        rng: np.random.Generator,
    ) -> None:
        joints, motors = list(config.joints), list(config.motor_names)
        nj, nm = len(joints), len(motors)
        self.motors = tuple(motors)
        T = np.zeros((nm, nj))
        direct = np.ones(nj, dtype=bool)
        coupling_errors = {e.target: e for e in effects if e.kind == "coupling_error"}
        friction = np.array([truth.joint_friction[j] for j in joints])  # (J, 4) joint coordinates first
        coordinates = [f"joint.{j}" for j in joints]
        rows = [np.eye(nj)[i] for i in range(nj)]
        self.motor_coordinate = np.full(nm, -1)  # each motor's friction coordinate
        emf = np.array([0.0, 0.0, 1.0, 1.0])
        for g in config.actuation:
            cols = [joints.index(j) for j in g.joints]
            if g.input == "torque":
                continue
            direct[cols] = False
            true_T = g.coupling.copy()
            if g.name in coupling_errors:  # the ratio entries (not 0, not ±1), of one joint's column or all, are off
                error = coupling_errors[g.name]
                ratio = ~np.isclose(np.abs(true_T), 1.0) & (true_T != 0)
                if error.params.get("joint", "all") != "all":
                    ratio &= (np.array(g.joints) == error.params["joint"])[None, :]
                true_T[ratio] *= 1.0 + float(error.params["error"])
            for mi, m in enumerate(g.motors):
                T[motors.index(m), cols] = true_T[mi]
                law = truth.motor_friction[m] + truth.back_emf[m] * emf
                if g.coupled:
                    self.motor_coordinate[motors.index(m)] = len(rows)
                    rows.append(T[motors.index(m)].copy())
                    coordinates.append(f"motor.{m}")
                    friction = np.vstack([friction, law])
                else:  # turns with its joint: one coordinate
                    self.motor_coordinate[motors.index(m)] = cols[mi]
                    friction[cols[mi]] += law
        self.T, self.Tt = T, T.T.copy()
        self.S = np.array(rows)
        self.coordinates = tuple(coordinates)
        self.friction = friction
        self.direct = direct.astype(float)  # 1 where τ_direct drives the joint
        self.gain = np.array([truth.gains[m] for m in motors])
        self.lower, self.upper = joint_limits[:, 0], joint_limits[:, 1]
        self.ripple = ripple
        self.ripple_phase = rng.uniform(0, 2 * np.pi, nm)

        # Hidden actuator effects, as per-motor / per-joint coefficient arrays (zero when off).
        def per(kind: str, key: str, names: list[str]) -> np.ndarray:
            out = np.zeros(len(names))
            for e in effects:
                if e.kind == kind and e.target in names:
                    out[names.index(e.target)] += float(e.params[key])
            return out

        self.deadzone = per("pwm_deadzone", "width", motors)
        self.load_friction = per("load_friction", "coefficient", motors)
        self.cogging = per("cogging", "amplitude", motors)
        period = np.deg2rad(np.where(self.cogging != 0, per("cogging", "period_deg", motors), 1.0))
        self.cogging_wavenumber = 2 * np.pi / period
        self.cogging_phase = rng.uniform(0, 2 * np.pi, nm)
        joint_coulomb = self.friction[:nj, :2].mean(axis=1)
        self.stribeck = per("stribeck", "excess", joints) * joint_coulomb
        self.stribeck_velocity = np.where(self.stribeck != 0, per("stribeck", "velocity", joints), 1.0)
        self.spring = per("spring", "stiffness", joints)
        rest = np.zeros(nj)
        for e in effects:
            if e.kind == "spring":
                i = joints.index(e.target)
                value = e.params["rest"]
                rest[i] = 0.5 * (self.lower[i] + self.upper[i]) if value == "mid" else float(value)
        self.spring_rest = rest
        J = per("armature", "inertia", motors)
        self.armature = self.Tt @ np.diag(J) @ self.T if J.any() else None
        self.drag = per("drag", "coefficient", joints)
        self.has_effects = bool(self.cogging.any() or self.spring.any() or self.drag.any())
        self.has_deadzone = bool(self.deadzone.any())
        self._law = FrictionStep(self.S, *self.friction.T.copy())
        self._stribeck_rows = np.arange(nj)

    def effective_duty(self, u: np.ndarray) -> np.ndarray:
        if not self.has_deadzone:
            return u
        return np.sign(u) * np.maximum(np.abs(u) - self.deadzone, 0.0)

    def drive(self, q: np.ndarray, v: np.ndarray, u: np.ndarray, supply: np.ndarray, tau_direct: np.ndarray) -> tuple[np.ndarray, FrictionStep]:
        """(τ_0, the friction law of this step) for positions q, velocities v, inputs u, supply factors s(t)."""
        drive = self.gain * supply * self.effective_duty(u)
        if self.ripple:
            drive = drive * (1.0 + self.ripple * np.sin(RIPPLE_HARMONIC * GEAR_RATIO * (self.T @ q) + self.ripple_phase))
        motor = drive
        if self.has_effects:
            motor = drive + self.cogging * np.sin(self.cogging_wavenumber * (self.T @ q) + self.cogging_phase)
        tau = self.Tt @ motor + self.direct * tau_direct
        if self.has_effects:
            tau -= self.spring * (q - self.spring_rest) + self.drag * v * np.abs(v)
        below, above = q < self.lower, q > self.upper
        if below.any() or above.any():  # rubber end stops: never reached in the default experiments
            past = np.where(below, q - self.lower, 0.0) + np.where(above, q - self.upper, 0.0)
            tau -= (below | above) * (END_STOP_STIFFNESS * past + END_STOP_DAMPING * v)
        law = self._law
        if self.stribeck.any() or self.load_friction.any():
            extra = np.zeros(self.S.shape[0])
            nj = len(q)
            extra[:nj] = self.stribeck * np.exp(-((v / self.stribeck_velocity) ** 2))
            np.add.at(extra, self.motor_coordinate, self.load_friction * np.abs(drive))
            law = FrictionStep(self.S, law.coulomb_pos + extra, law.coulomb_neg + extra, law.viscous_pos, law.viscous_neg)
        return tau, law


def friction_force(w: np.ndarray, law: FrictionStep) -> np.ndarray:
    """f(w) of every coordinate while sliding (zero Coulomb at exactly w = 0, as the model has it)."""
    return (
        law.coulomb_pos * (w > 0)
        - law.coulomb_neg * (w < 0)
        + law.viscous_pos * np.maximum(w, 0.0)
        + law.viscous_neg * np.minimum(w, 0.0)
    )
