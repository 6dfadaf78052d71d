"""What the robot is told to do: reach pseudo-random Cartesian points under joint-impedance control (or follow a
given trajectory, `followed_reference`: `dynid simulate --trajectory`).

The reference: the hand (the last body) goes to random points of its workspace, one after the other, each
reached by damped-least-squares inverse kinematics whose null space pulls toward a random posture, so every
joint moves (the wrist included) and every velocity takes both signs. Each move is a minimum-jerk joint path of
random peak speed, followed by a short random dwell. Targets stay 10 % of each range inside the joint limits.

The controller runs on the boards at the sample rate, from what the boards measure (quantised encoders, a
filtered finite-difference velocity): τ = K (q_d − q) + D (q̇_d − q̇) + g_CAD(q). Each joint's stiffness
gives a closed-loop bandwidth at the largest CAD inertia the joint sees, and at least holds the largest contact
push at the arm's tip within a few degrees. Motor inputs solve Tᵀ τ_m = τ with the *nominal* gains.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicHermiteSpline

from ..config.robot_config import RobotConfig
from .plant import RigidBodyPlant

LIMIT_MARGIN = 0.10  # fraction of each joint's range kept free at both ends
BANDWIDTH_HZ = 4.0  # closed-loop bandwidth of the joint impedance, at the heaviest posture
DAMPING_RATIO = 0.9
VELOCITY_FILTER_HZ = 80.0
MAX_DEFLECTION = 0.08  # rad: the most a push of the largest contact force may deflect any joint


@dataclass(frozen=True)
class Reference:
    q: np.ndarray  # (N, J) desired positions
    dq: np.ndarray  # (N, J) desired velocities
    targets: np.ndarray  # (M, 3) Cartesian points of the hand, in the base frame
    target_times: np.ndarray  # (M,) s, when each move starts


def _ik(plant: RigidBodyPlant, frame: int, target: np.ndarray, q0: np.ndarray, posture: np.ndarray,
        lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    m, d = plant.model, plant.data
    q = q0.copy()
    for _ in range(60):
        pin.framesForwardKinematics(m, d, q)
        err = target - d.oMf[frame].translation
        if np.linalg.norm(err) < 1e-4:
            break
        J = pin.computeFrameJacobian(m, d, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
        J_pinv = J.T @ np.linalg.inv(J @ J.T + 1e-4 * np.eye(3))
        dq = J_pinv @ err + (np.eye(m.nv) - J_pinv @ J) @ (0.3 * (posture - q))
        q = np.clip(q + dq, lo, hi)
    return q


def _minimum_jerk(q0: np.ndarray, q1: np.ndarray, n: int, duration: float) -> tuple[np.ndarray, np.ndarray]:
    s = np.arange(n)[:, None] / n
    shape = 10 * s**3 - 15 * s**4 + 6 * s**5
    rate = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    return q0 + (q1 - q0) * shape, (q1 - q0) * rate


def reaching_reference(
    plant: RigidBodyPlant, hand_link: str, limits: np.ndarray, q_start: np.ndarray, n: int, dt: float,
    rng: np.random.Generator,
) -> Reference:
    """N samples of reaching moves from `q_start` (the arm's rest posture)."""
    lo = limits[:, 0] + LIMIT_MARGIN * (limits[:, 1] - limits[:, 0])
    hi = limits[:, 1] - LIMIT_MARGIN * (limits[:, 1] - limits[:, 0])
    frame = plant.model.getFrameId(hand_link)
    qs, dqs, targets, times = [], [], [], []
    q, filled = np.clip(q_start, lo, hi), 0
    while filled < n:
        posture = rng.uniform(lo, hi)
        pin.framesForwardKinematics(plant.model, plant.data, posture)
        target = plant.data.oMf[frame].translation.copy()  # a reachable random point
        goal = _ik(plant, frame, target, q, posture, lo, hi)
        peak = rng.uniform(0.3, 1.5)  # rad/s, peak joint speed of the fastest joint
        duration = float(np.clip(1.875 * np.max(np.abs(goal - q)) / peak, 0.6, 4.0))
        move = max(int(round(duration / dt)), 1)
        pq, pdq = _minimum_jerk(q, goal, move, move * dt)
        dwell = int(round(rng.uniform(0.0, 0.4) / dt))
        qs += [pq, np.tile(goal, (dwell, 1))]
        dqs += [pdq, np.zeros((dwell, len(q)))]
        targets.append(target)
        times.append(filled * dt)
        filled += move + dwell
        q = goal
    return Reference(np.concatenate(qs)[:n], np.concatenate(dqs)[:n], np.array(targets), np.array(times))


@dataclass(frozen=True)
class GivenTrajectory:
    """A reference the user gives (`dynid simulate --trajectory`, e.g. a `dynid excite` design): time from 0, s;
    q and q̇ per joint (N, J), in the configuration's joint order."""

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    source: str = ""

    @property
    def duration(self) -> float:
        return float(self.t[-1])


def followed_reference(traj: GivenTrajectory, n: int, dt: float) -> Reference:
    """The given trajectory on the controller's grid: cubic Hermite interpolation of (q, q̇), so a reference
    written at 100 Hz is followed at 1 kHz with the velocity it was designed with."""
    t = np.arange(n) * dt
    spline = CubicHermiteSpline(traj.t, traj.q, traj.dq, axis=0)
    return Reference(spline(t), spline(t, 1), np.zeros((0, 3)), np.zeros(0))


class ImpedanceController:
    """Joint impedance with CAD gravity compensation, and the mapping of joint torques to motor inputs."""

    def __init__(self, config: RobotConfig, cad_plant: RigidBodyPlant, limits: np.ndarray, dt: float,
                 rng: np.random.Generator, tip_link: str, max_push: float) -> None:
        self.cad = cad_plant
        # Stiffness: the bandwidth at the largest CAD inertia each joint sees over random postures, and at least
        # what holds a push of `max_push` newtons at the arm's tip within MAX_DEFLECTION (light wrist joints
        # would otherwise yield to a touch, as no real arm's controller lets them).
        postures = rng.uniform(limits[:, 0], limits[:, 1], (50, len(limits)))
        inertia = np.max([np.diag(cad_plant.mass_matrix(q)) for q in postures], axis=0)
        omega = 2 * np.pi * BANDWIDTH_HZ
        m, d = cad_plant.model, cad_plant.data
        pin.framesForwardKinematics(m, d, limits.mean(axis=1))
        tip = d.oMf[m.getFrameId(tip_link)].act(2 * cad_plant.model.inertias[m.frames[m.getFrameId(tip_link)].parentJoint].lever)
        lever = np.array([np.linalg.norm(tip - d.oMi[int(j)].translation) for j in range(1, m.njoints)])
        self.K = np.maximum(omega**2 * inertia, max_push * lever / MAX_DEFLECTION)
        self.D = 2 * DAMPING_RATIO * np.sqrt(self.K * inertia)
        self.alpha = float(np.exp(-2 * np.pi * VELOCITY_FILTER_HZ * dt))
        self.dt = dt
        joints, motors = list(config.joints), list(config.motor_names)
        # Motor inputs from joint torques: per drive group, the inverse of the nominal Tᵀ over the gains.
        self.to_inputs = np.zeros((len(motors), len(joints)))
        for g in config.actuation:
            if g.input == "torque":
                continue
            gains = np.array([config.motor(m).known_gain or config.motor(m).nominal_gain for m in g.motors])
            rows, cols = [motors.index(m) for m in g.motors], [joints.index(j) for j in g.joints]
            self.to_inputs[np.ix_(rows, cols)] = np.linalg.pinv(g.coupling.T) / gains[:, None]
        self.reset(limits.mean(axis=1))

    def reset(self, q: np.ndarray) -> None:
        self._q_prev = q.copy()
        self._v = np.zeros_like(q)

    def torque(self, q_measured: np.ndarray, q_desired: np.ndarray, v_desired: np.ndarray) -> np.ndarray:
        v_raw = (q_measured - self._q_prev) / self.dt
        self._v = self.alpha * self._v + (1 - self.alpha) * v_raw
        self._q_prev = q_measured
        return (
            self.K * (q_desired - q_measured)
            + self.D * (v_desired - self._v)
            + self.cad.gravity_torque(q_measured)
        )

    def motor_inputs(self, tau: np.ndarray) -> np.ndarray:
        return self.to_inputs @ tau
