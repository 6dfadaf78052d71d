"""`dynid excite`: a Fourier-series excitation trajectory that minimises the condition number of the fit's regressor
(objective.py) within the joints' position, velocity and acceleration limits, at rest at both ends (fourier.py).

The method (Swevers et al. 1997, as FloBaRoID, BIRDy and FIGAROH do it):

1. One period is designed; the trajectory repeats it a whole number of times (the regressor of k periods is k
   times one period's, so its condition number is one period's). The base frequency is rounded to a whole number
   of periods in the duration, so the end is the start, at rest.
2. Limits: positions from the URDF, `limits.position_margin` of the range inside both ends; velocities the
   smaller of the URDF's and the configuration's `limits.velocity`; accelerations `limits.acceleration`. q, q̇,
   q̈ are linear in the coefficients, so on the design grid the limits are linear inequalities, held by SLSQP.
3. Start: many random coefficient vectors, each scaled joint by joint to touch its tightest limit, about the
   middle of the position range; the best few start SLSQP (objective: log10 of the condition number on the
   design grid; its gradient through every sample's state, objective.py), one after the other while time remains.
4. Time is bounded (`max_time_s`): when it runs out, the best feasible point seen so far is kept.
5. Last, the trajectory is checked on a fine grid (1 kHz) and any joint that the design grid let slightly past
   a limit is scaled back about q0 (its rest at both ends unchanged).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from ..errors import InputError
from ..robot.model import RobotModel
from .fourier import FourierTrajectory, Parametrisation
from .objective import ConditionObjective

# With the default period, up to 0.9 Hz (Swevers: 5 harmonics of 0.1 Hz), well inside the simulated arm's 4 Hz.
# Measured on the iCub arm, 60 s, 80 s of search, the reported condition number (objective.py; in brackets, its
# simulated run's): with STICK_SPEED 0.03, 14 harmonics 25.7 (26.8), 18 harmonics 23.5 (24.3), 20 harmonics 22.6
# (after 200 s 22.3 (24.0): more search sharpens what the run does not keep); with 0.05, 18 harmonics 23.8 (23.9).
DEFAULT_HARMONICS = 18
DEFAULT_PERIOD_S = 20.0  # the base frequency's default: the nearest whole number of periods of about 20 s
MAX_HARMONIC_HZ = 5.0  # beyond the highest harmonic a position controller follows (the simulated arm: 4 Hz)
DEFAULT_MAX_TIME_S = 80.0  # keeps a 60 s design, set-up included, under 2 minutes on a shared 2-core machine
DESIGN_RATE_HZ = 10.0  # design-grid samples per second of one period (at least 20 per cycle of the top harmonic)
CHECK_RATE_HZ = 1000.0
RANDOM_STARTS = 60


@dataclass(frozen=True)
class JointLimits:
    lower: np.ndarray  # (J,) rad, the margin applied
    upper: np.ndarray
    velocity: np.ndarray  # (J,) rad/s
    acceleration: np.ndarray  # (J,) rad/s²
    range_lower: np.ndarray  # (J,) the URDF's own limits, without the margin
    range_upper: np.ndarray
    margin: float

    def as_dict(self, joints: tuple[str, ...]) -> dict:
        return {j: {"position": [float(self.lower[i]), float(self.upper[i])],
                    "urdf_position": [float(self.range_lower[i]), float(self.range_upper[i])],
                    "velocity": float(self.velocity[i]), "acceleration": float(self.acceleration[i])}
                for i, j in enumerate(joints)}


def joint_limits(model: RobotModel) -> JointLimits:
    cfg = model.config
    lim = cfg.limits
    lo = np.array([model.joint_limits[j][0] for j in cfg.joints])
    hi = np.array([model.joint_limits[j][1] for j in cfg.joints])
    bad = [j for j, a, b in zip(cfg.joints, lo, hi) if not (np.isfinite(a) and np.isfinite(b) and b > a)]
    if bad:
        raise InputError(f"{cfg.name}: joint '{bad[0]}' has no finite position limits in the URDF: an excitation "
                         "trajectory needs them")
    m = model.pin_model
    urdf_v = np.array([m.velocityLimit[model.v_index[i]] for i in range(len(cfg.joints))])
    v = np.array([lim.velocity[j] for j in cfg.joints])
    v = np.where(np.isfinite(urdf_v) & (urdf_v > 0), np.minimum(v, urdf_v), v)
    a = np.array([lim.acceleration[j] for j in cfg.joints])
    span = hi - lo
    return JointLimits(lo + lim.position_margin * span, hi - lim.position_margin * span, v, a, lo, hi,
                       lim.position_margin)


def whole_periods(duration: float, base_frequency: float | None) -> tuple[int, float]:
    """(periods, base frequency): the given or default frequency rounded to a whole number of periods."""
    f = 1.0 / DEFAULT_PERIOD_S if base_frequency is None else base_frequency
    periods = max(1, int(round(duration * f)))
    return periods, periods / duration


@dataclass
class Design:
    trajectory: FourierTrajectory
    condition: float  # on the design grid, rows at rest left out as the fit does (what `dynid excite` reports)
    starts: int  # SLSQP runs started
    evaluations: int
    seconds: float
    stopped_by_time: bool
    history: list[float] = field(default_factory=list)  # best condition after each SLSQP run


class _OutOfTime(Exception):
    pass


def margins(traj: FourierTrajectory, limits: JointLimits, rate_hz: float = CHECK_RATE_HZ) -> dict[str, np.ndarray]:
    """Peak |q̇|/limit, peak |q̈|/limit, and the closest approach to the URDF limits (fraction of the range), on a
    fine grid of one period."""
    t = np.arange(int(np.ceil(traj.period * rate_hz)) + 1) / rate_hz
    q, dq, ddq = traj.evaluate(t)
    span = limits.range_upper - limits.range_lower
    return {
        "velocity": np.abs(dq).max(axis=0) / limits.velocity,
        "acceleration": np.abs(ddq).max(axis=0) / limits.acceleration,
        "position_clearance": np.minimum(q.min(axis=0) - limits.range_lower, limits.range_upper - q.max(axis=0)) / span,
        "q_min": q.min(axis=0), "q_max": q.max(axis=0),
    }


def _room(traj: FourierTrajectory, limits: JointLimits, rate_hz: float) -> np.ndarray:
    """Per joint, the factor its motion about q0 may be scaled by before it touches its tightest limit, on a grid
    of one period at `rate_hz` (inf or nan for a joint that does not move)."""
    t = np.arange(int(np.ceil(traj.period * rate_hz)) + 1) / rate_hz
    q, dq, ddq = traj.evaluate(t)
    dev = q - traj.q0
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(dev > 0, (limits.upper - traj.q0) / dev, np.inf).min(axis=0)
        down = np.where(dev < 0, (limits.lower - traj.q0) / dev, np.inf).min(axis=0)
        vel = limits.velocity / np.abs(dq).max(axis=0)
        acc = limits.acceleration / np.abs(ddq).max(axis=0)
    return np.minimum.reduce([up, down, vel, acc])


def fit_to_limits(traj: FourierTrajectory, limits: JointLimits, rate_hz: float = CHECK_RATE_HZ) -> FourierTrajectory:
    """Scale each joint's motion about q0 (inside the position box) so that it touches, never passes, its tightest
    limit on a fine grid; a joint already within all of them is scaled up to touch one."""
    traj = FourierTrajectory(np.clip(traj.q0, limits.lower, limits.upper), traj.a, traj.b, traj.base_frequency,
                             traj.duration)
    factor = np.nan_to_num(_room(traj, limits, rate_hz), nan=0.0, posinf=0.0)
    return traj.scaled(factor * (1 - 1e-9))


def fit_to_limits_down(traj: FourierTrajectory, limits: JointLimits) -> FourierTrajectory:
    """Scale back, about q0, any joint that passes a limit between the constraint grid's samples (never up)."""
    factor = np.nan_to_num(_room(traj, limits, CHECK_RATE_HZ), nan=1.0, posinf=1.0)
    return traj.scaled(np.where(factor < 1.0, factor * (1 - 1e-9), 1.0))


def design(model: RobotModel, duration: float, base_frequency: float | None = None,
           harmonics: int = DEFAULT_HARMONICS, max_time_s: float = DEFAULT_MAX_TIME_S, seed: int = 0,
           objective: ConditionObjective | None = None,
           progress: Callable[[str], None] | None = None, max_evaluations: int | None = None) -> Design:
    """The designed trajectory for `duration` seconds (a whole number of periods of the base frequency).

    The search stops at `max_time_s` (wall clock) or after `max_evaluations` objective evaluations, whichever
    comes first: an evaluation budget gives the same trajectory whatever the machine's load."""
    started = time.monotonic()
    periods, f = whole_periods(duration, base_frequency)
    limits = joint_limits(model)
    obj = objective or ConditionObjective.of(model)
    J = model.n_joints
    par = Parametrisation(J, harmonics, f, duration)
    period = 1.0 / f
    n_grid = int(max(20 * harmonics, round(DESIGN_RATE_HZ * period)))
    t = np.arange(n_grid) * period / n_grid
    Mq, Mv, Ma = par.grid_maps(t)
    # Linear inequalities G z <= h on a grid of 12 samples per cycle of the top harmonic (a peak between two samples
    # passes by at most 1 − cos(π/12) = 3.4 %; the fine check scales it back): q within the box, |q̇|, |q̈| within
    # their limits. SLSQP's cost grows with their number: on the design grid they took a quarter of the time.
    n_check = 12 * harmonics
    Cq, Cv, Ca = par.grid_maps(np.arange(n_check) * period / n_check)
    lo, hi = np.tile(limits.lower, n_check), np.tile(limits.upper, n_check)
    v, a = np.tile(limits.velocity, n_check), np.tile(limits.acceleration, n_check)
    G = np.vstack([Cq, -Cq, Cv, -Cv, Ca, -Ca])
    h = np.concatenate([hi, -lo, v, v, a, a])
    scale = np.concatenate([hi - lo, hi - lo, v, v, a, a])  # each inequality in units of its own limit
    G, h = G / scale[:, None], h / scale

    state = {"evaluations": 0, "best": np.inf, "best_z": None}

    def keep(z: np.ndarray, f_val: float) -> None:
        state["evaluations"] += 1
        if f_val < state["best"] and np.all(G @ z <= h + 1e-6):
            state["best"], state["best_z"] = f_val, np.array(z, copy=True)

    def out_of_time() -> bool:
        return time.monotonic() - started > max_time_s or (
            max_evaluations is not None and state["evaluations"] >= max_evaluations)

    def value(z: np.ndarray) -> float:
        if out_of_time():
            raise _OutOfTime
        c = obj.design_condition(*par.trajectory(z).evaluate(t))
        f_val = float(np.log10(c)) if np.isfinite(c) else 20.0
        keep(z, f_val)
        return f_val

    def value_and_gradient(z: np.ndarray) -> tuple[float, np.ndarray]:
        if out_of_time():
            raise _OutOfTime
        f_val, (gq, gv, ga) = obj.log_condition_and_gradient(*par.trajectory(z).evaluate(t))
        keep(z, f_val)
        return f_val, Mq.T @ gq.ravel() + Mv.T @ gv.ravel() + Ma.T @ ga.ravel()

    rng = np.random.default_rng(seed)
    middle = (limits.lower + limits.upper) / 2
    starts: list[tuple[float, np.ndarray]] = []
    try:
        for _ in range(RANDOM_STARTS):
            c = rng.normal(size=(J, par.k))
            traj = fit_to_limits(par.trajectory(np.concatenate([middle, c.ravel()])), limits, CHECK_RATE_HZ / 10)
            z = par.vector(traj)
            z = z * (1 - 1e-3) + np.concatenate([middle, np.zeros(J * par.k)]) * 1e-3  # strictly inside
            starts.append((value(z), z))
    except _OutOfTime:
        pass
    starts.sort(key=lambda s: s[0])
    if progress:
        progress(f"{len(starts)} random starts: best condition number {10 ** starts[0][0]:.4g}" if starts else
                 "no random start finished in time")
    history: list[float] = []
    runs, stopped = 0, False
    constraint = {"type": "ineq", "fun": lambda z: h - G @ z, "jac": lambda z: -G}
    for _, z0 in starts:
        if out_of_time():
            stopped = True
            break
        runs += 1
        try:
            minimize(value_and_gradient, z0, jac=True, method="SLSQP", constraints=[constraint],
                     options={"maxiter": 500, "ftol": 1e-7})
        except _OutOfTime:
            stopped = True
        history.append(10 ** state["best"])
        if progress:
            progress(f"SLSQP run {runs}: best condition number {10 ** state['best']:.4g} "
                     f"({time.monotonic() - started:.0f} s)")
        if stopped:
            break
    if state["best_z"] is None:
        raise InputError(f"no feasible trajectory was found in {time.monotonic() - started:.0f} s and "
                         f"{state['evaluations']} evaluations: give --max-time (or --max-evaluations) more")
    final = fit_to_limits_down(par.trajectory(state["best_z"]), limits)
    q, dq, ddq = final.evaluate(t)
    return Design(final, obj.report_condition(q, dq, ddq), runs, state["evaluations"], time.monotonic() - started, stopped,
                  history)

