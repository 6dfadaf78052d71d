"""What the boards report: encoders, the strain (F/T) board and the motor boards' PWM, each with its own flaws.

- Encoders: quantised to the configured step (CAN ticks per degree, else the configuration's encoder step).
- F/T: ``w_meas = (I + E) w + w_O(t) + n``, then 16-bit offset binary over the configured full scale, clamped
  at the ends (as the strain board's ADC saturates). E is the hidden gain/cross-talk error, w_O(t) the offset
  (plus the hidden drift), n white noise with the configuration's channel noise.
- PWM: the board's integer duty steps (1 / pwm_full_scale), clamped to ±1; the hidden delay shifts the stream.

With noise off, nothing is quantised and no noise is added; the hidden sensor effects still apply.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.robot_config import RobotConfig
from .effects import Effect

FT_COUNTS = 32768  # 16-bit offset binary: s = raw − 0x8000, value = s · FS / 32768


def encoder_steps(config: RobotConfig) -> np.ndarray:
    """Encoder quantum of every joint, rad."""
    step = {j: config.noise.encoder_step for j in config.joints}
    for board in config.can.get("motor_control", []):
        for axis in board["axes"]:
            step[axis["joint"]] = math.radians(1.0 / float(axis["ticks_per_degree"]))
    return np.array([step[j] for j in config.joints])


def pwm_full_scale(config: RobotConfig) -> np.ndarray:
    """PWM counts per unit duty of every motor (0: not quantised)."""
    scale = {m: 0.0 for m in config.motor_names}
    for board in config.can.get("motor_control", []):
        for axis in board["axes"]:
            if axis.get("motor"):
                scale[axis["motor"]] = float(board["pwm_full_scale"])
    return np.array([scale[m] for m in config.motor_names])


def ft_full_scale(config: RobotConfig, sensor: str) -> np.ndarray | None:
    for s in config.can.get("strain", []):
        if s["sensor"] == sensor:
            return np.asarray(s["full_scale"], float)
    return None


def quantise(x: np.ndarray, step: np.ndarray | float) -> np.ndarray:
    return np.round(x / step) * step


class InputQuantiser:
    """What the motor boards apply: PWM duties clamped to ±1 and rounded to the board's steps; currents as is."""

    def __init__(self, pwm_motors: np.ndarray, counts: np.ndarray) -> None:
        self.lo = np.where(pwm_motors, -1.0, -np.inf)
        self.hi = np.where(pwm_motors, 1.0, np.inf)
        self.rounded = pwm_motors & (counts > 0)
        self.scale = np.where(self.rounded, counts, 1.0)
        self.all_rounded = bool(self.rounded.all())

    def __call__(self, u: np.ndarray) -> np.ndarray:
        u = np.minimum(np.maximum(u, self.lo), self.hi)
        if self.all_rounded:
            return np.round(u * self.scale) / self.scale
        return np.where(self.rounded, np.round(u * self.scale) / self.scale, u)


def ft_offset_track(effects: list[Effect], sensor: str, t: np.ndarray, base: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The true offset w_O(t) of one sensor: constant, plus the hidden drift if switched on. (N, 6)."""
    offset = np.tile(base, (t.shape[0], 1))
    for e in effects:
        if e.kind != "ft_drift" or e.target != sensor:
            continue
        size = np.array([e.params["force"]] * 3 + [e.params["torque"]] * 3, float) * rng.choice([-1.0, 1.0], 6)
        elapsed = t - t[0]
        shape = elapsed / max(elapsed[-1], 1e-9) if e.params["shape"] == "linear" else 1 - np.exp(-elapsed / e.params["tau"])
        offset += shape[:, None] * size
    return offset


def ft_step_sizes(effects: list[Effect], sensor: str, rng: np.random.Generator) -> list[tuple[Effect, np.ndarray]]:
    """Each hidden F/T offset step of one sensor with its (6,) size: force / torque per axis, random signs."""
    out = []
    for e in effects:
        if e.kind == "ft_step" and e.target == sensor:
            size = np.array([e.params["force"]] * 3 + [e.params["torque"]] * 3, float) * rng.choice([-1.0, 1.0], 6)
            out.append((e, size))
    return out


def ft_step_track(steps: list[tuple[Effect, np.ndarray]], t: np.ndarray) -> np.ndarray:
    """(N, 6) what the steps add to the offset: their size while from_s <= t - t[0] < to_s."""
    out = np.zeros((t.shape[0], 6))
    for e, size in steps:
        elapsed = t - t[0]
        out += ((elapsed >= float(e.params["from_s"])) & (elapsed < float(e.params["to_s"])))[:, None] * size
    return out


def ft_gain_matrix(effects: list[Effect], sensor: str, rng: np.random.Generator) -> np.ndarray:
    """I + E for one sensor (identity without the hidden gain/cross-talk effect)."""
    G = np.eye(6)
    for e in effects:
        if e.kind == "ft_gain" and e.target == sensor:
            E = rng.normal(0.0, float(e.params["crosstalk"]), (6, 6))
            E[np.diag_indices(6)] = rng.normal(0.0, float(e.params["gain"]), 6)
            G = G + E
    return G


def measure_ft(
    true_wrench: np.ndarray,
    offset: np.ndarray,
    gain: np.ndarray,
    noise_std: np.ndarray,
    full_scale: np.ndarray | None,
    noisy: bool,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """(measured wrench (N, 6), saturated flags (N, 6) bool)."""
    w = true_wrench @ gain.T + offset
    if noisy:
        w = w + rng.normal(0.0, 1.0, w.shape) * noise_std
    saturated = np.zeros(w.shape, dtype=bool)
    if noisy and full_scale is not None:
        lsb = full_scale / FT_COUNTS
        counts = np.round(w / lsb)
        saturated = (counts < -FT_COUNTS) | (counts > FT_COUNTS - 1)
        w = np.clip(counts, -FT_COUNTS, FT_COUNTS - 1) * lsb
    return w, saturated
