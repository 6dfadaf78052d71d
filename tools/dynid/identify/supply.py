"""Supply tracking: the torque a motor gives per unit of duty moves with its board's supply voltage.

A PWM duty u applies the voltage u·V_supply, so the drive torque is φ_m·s(t)·u with s the supply relative to
the identification run's mean. Supplies drift by a few per cent over seconds to minutes (a shared bus sags
under load, a board's regulator drifts), and the data carry no voltage channel (docs/design.md §4). The model with
constant gains then mispredicts each input by (1 − 1/s)·û: on the default simulated arm (3 % supply std) that
is 2.5× the PWM noise on the shoulder motors, which hides contacts that only the PWMs see.

The tracker estimates r(t) = 1/s(t) per input channel from the model's own prediction, causally: exponentially
forgotten least squares of the measured input y on the predicted input ŷ, with time constant τ,

    num ← λ num + (1 − λ) ŷ y,   den ← λ den + (1 − λ) ŷ²,   r = (num + p) / (den + p),   λ = e^(−Δt/τ),

and the residual is e = y − r·ŷ, with the r of the samples before (so a contact cannot explain itself). Two
rules keep contacts out of the estimate: rows at rest never update it (static friction holds them, so ŷ is
not the input there), and neither does a sample whose residual exceeds `gate` noise stds; such a sample
leaves the estimate as it was (a joint resting for a minute keeps its supply estimate). p = prior_input²
is the weight of the prior r = 1: a motor that has not yet driven keeps its identified gain.

The recurrence runs sample by sample in the order the monitor would see them; rt_monitor's core runs the same
one (`rt_monitor/src/core.cpp`), checked against this code. Offline (`validate`, `detect`, the fit's T²
calibration) the estimate is two-sided, as the offline derivatives are: `smoothed_residuals`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .. import kernels
from ..errors import InputError
from ..robot.model import RobotModel
from ..robot.outputs import OutputChannel, output_channels
from ..robot.regressors.stack import Signals, rows_at_rest


def tracked(o: OutputChannel) -> bool:
    """Only a PWM input drifts with its supply: a current or a torque is measured, not commanded by a duty."""
    return o.kind == "input" and o.name.startswith("pwm.")


@dataclass(frozen=True)
class SupplyTracking:
    time_constant_s: float = 3.0  # the monitor's, causal: the supply drifts over tens of seconds, a contact lasts about one (README)
    gate: float = 3.0  # noise stds of the input channel: a larger residual never updates the estimate
    prior_input: float = 0.01  # duty: the prior r = 1 weighs as much as a sample predicting this input
    offline_time_constant_s: float = 1.5  # each pass of the offline, two-sided estimate (`smoothed_residuals`)

    def __post_init__(self) -> None:
        for name in ("time_constant_s", "gate", "prior_input", "offline_time_constant_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"supply tracking: {name} must be a positive number, got {value}")

    def gate_of(self, sigma: float) -> float:
        """The gate of a channel with noise std `sigma`, in its unit."""
        return self.gate * sigma

    def as_dict(self) -> dict[str, float]:
        return {"time_constant_s": self.time_constant_s, "gate": self.gate, "prior_input": self.prior_input,
                "offline_time_constant_s": self.offline_time_constant_s}

    @classmethod
    def from_dict(cls, d: dict) -> SupplyTracking:
        return cls(float(d["time_constant_s"]), float(d["gate"]), float(d["prior_input"]),
                   float(d["offline_time_constant_s"]))


@dataclass
class ChannelState:
    num: float = 0.0
    den: float = 0.0
    ratio: float = 1.0


@dataclass
class SupplyTracker:
    """The tracker of every input channel of one run; `apply` continues from where the previous call ended."""

    model: RobotModel
    settings: SupplyTracking
    min_speed: float
    states: dict[int, ChannelState] = field(default_factory=dict)  # output row -> state
    last_t: float | None = None

    def apply(self, e: np.ndarray, sig: Signals, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(e with the input channels' residuals re-predicted, (N, n_out) ratio r used at each sample; 1 on
        other channels) for the samples of `sig` at times t, which continue the previous call's."""
        e = np.array(e, dtype=float, copy=True)
        ratio = np.ones_like(e)
        if t.size == 0:
            return e, ratio
        moving = ~rows_at_rest(self.model, sig.dq, self.min_speed)
        # The first sample of a run is one nominal period after the (virtual) one before, as in the monitor.
        first = self.last_t if self.last_t is not None else t[0] - (float(np.median(np.diff(t))) if t.size > 1 else 0.0)
        steps = np.diff(t, prepend=first)
        decay = np.exp(-steps / self.settings.time_constant_s)
        self.last_t = float(t[-1])
        prior = self.settings.prior_input ** 2
        for o in output_channels(self.model):
            if not tracked(o):
                continue
            state = self.states.setdefault(o.row, ChannelState())
            y = sig.inputs[o.motor]
            predicted = y - e[:, o.row]
            gate = self.settings.gate_of(o.sigma)
            num, den, r = state.num, state.den, state.ratio
            out, used = np.empty(len(predicted)), np.empty(len(predicted))
            native = kernels.native()
            if native is not None:  # the loop below, compiled: the same operations in the same order
                state.num, state.den, state.ratio = native.supply_track(
                    np.ascontiguousarray(y, dtype=float), np.ascontiguousarray(predicted, dtype=float), decay,
                    np.ascontiguousarray(moving[:, o.row]), gate, prior, num, den, r, out, used)
                e[:, o.row], ratio[:, o.row] = out, used
                continue
            for k, (yk, pk, lam, mk) in enumerate(zip(y.tolist(), predicted.tolist(), decay.tolist(),
                                                       moving[:, o.row].tolist())):
                residual = yk - r * pk
                out[k], used[k] = residual, r
                if mk and abs(residual) <= gate:
                    num = lam * num + (1.0 - lam) * pk * yk
                    den = lam * den + (1.0 - lam) * pk * pk
                    r = (num + prior) / (den + prior)
            state.num, state.den, state.ratio = num, den, r
            e[:, o.row], ratio[:, o.row] = out, used
        return e, ratio


def tracked_residuals(model: RobotModel, settings: SupplyTracking | None, min_speed: float, e: np.ndarray,
                      sig: Signals, t: np.ndarray) -> np.ndarray:
    """e of one whole run with the monitor's causal supply tracking (unchanged when `settings` is None)."""
    if settings is None:
        return e
    return SupplyTracker(model, settings, min_speed).apply(e, sig, t)[0]


def smoothed_residuals(model: RobotModel, settings: SupplyTracking | None, min_speed: float, e: np.ndarray,
                       sig: Signals, t: np.ndarray) -> np.ndarray:
    """e of one whole run with the offline, two-sided supply estimate: the mean of the tracker run forwards and
    backwards in time, with `offline_time_constant_s` (unchanged when `settings` is None).

    Offline, dynid's derivatives are non-causal (the paper's set-up), and so is this: the two passes' lags cancel
    on a supply that drifts linearly, so a shorter time constant keeps the same robustness to contacts. It is
    what `validate`, `detect` and the fit's T² calibration use; the monitor runs the causal tracker."""
    if settings is None:
        return e
    ratio = smoothed_ratios(model, settings, min_speed, e, sig, t)
    out = np.array(e, dtype=float, copy=True)
    for o in output_channels(model):
        if tracked(o):
            y = sig.inputs[o.motor]
            out[:, o.row] = y - ratio[:, o.row] * (y - e[:, o.row])
    return out


def smoothed_ratios(model: RobotModel, settings: SupplyTracking, min_speed: float, e: np.ndarray, sig: Signals,
                    t: np.ndarray) -> np.ndarray:
    """(N, n_out) the offline, two-sided ratio r of every input channel (1 on the others): `smoothed_residuals`'."""
    offline = replace(settings, time_constant_s=settings.offline_time_constant_s)
    forward = SupplyTracker(model, offline, min_speed).apply(e, sig, t)[1]
    back = slice(None, None, -1)
    backward = SupplyTracker(model, offline, min_speed).apply(e[back], sig.slice(back), -t[back])[1][back]
    return 0.5 * (forward + backward)
