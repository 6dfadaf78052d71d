"""The monitored outputs y and the model's prediction ŷ (docs/design.md §3): y = [w_s (6 per F/T sensor); inputs].

Each row channel of the stacked system is one output: an F/T row predicts its wrench channel, a motor row its
motor's input (PWM duty or current), a torque-sensor row its joint torque. With a row written as
``a·Φ = b`` the residual is uniformly

    e = y − ŷ = (b − a·Φ) / g

where g is what multiplies the measured output in the row: 1 for F/T and torque rows, the motor gain φ_m for a
motor row (its input enters as −u·φ_m with b = 0), or the known gain of a known-gain motor. A motor row must hold
one motor's input; motor-space rows of a coupled group and directly driven joints do.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .model import RobotModel
from .parameters import WRENCH_FIELDS
from .regressors import kernel as row_kernel
from .regressors.stack import DEFAULT_CHUNK, Signals, group_row_maps, iter_stacked, motor_space, row_channels


@dataclass(frozen=True)
class OutputChannel:
    name: str  # "ft.<sensor>.<fx..tz>", "pwm.<motor>", "current.<motor>" or "tau.<joint>"
    row: int  # its row channel (index into row_channels)
    kind: str  # "ft", "input" or "torque"
    unit: str
    sigma: float  # noise std in the output's own units
    motor: str | None = None
    gain_index: int | None = None  # Φ index of the unknown gain dividing the residual (None: a known divisor)
    known_gain: float = 1.0


def output_channels(model: RobotModel) -> tuple[OutputChannel, ...]:
    cfg, layout = model.config, model.layout
    rows = row_channels(model)
    out: list[OutputChannel] = []
    for s in cfg.ft_sensors:
        for k, c in enumerate(WRENCH_FIELDS):
            i = len(out)
            out.append(OutputChannel(f"ft.{s.name}.{c}", i, "ft", "N" if k < 3 else "Nm", rows[i].sigma))
    for g in cfg.actuation:
        if g.input == "torque":
            for j in g.joints:
                i = len(out)
                out.append(OutputChannel(f"tau.{j}", i, "torque", "Nm", rows[i].sigma))
            continue
        _, C = group_row_maps(g)
        if not (motor_space(g) or np.allclose(C, np.eye(len(g.motors)))) or C.shape[0] != C.shape[1]:
            raise ConfigError(
                f"{cfg.name}: actuation group '{g.name}' mixes several motors' inputs in one row; the outputs "
                "need one motor per row (a square coupling, or one motor per joint)"
            )
        unit = "duty" if g.input == "pwm" else "A"
        for m in g.motors:
            i = len(out)
            known = cfg.motor(m).known_gain
            gain_index = None if known is not None else layout.block("motor_gain", m).start
            out.append(OutputChannel(f"{g.input}.{m}", i, "input", unit, cfg.noise.of(g.input, m), m, gain_index,
                                     known or 1.0))
    assert [o.row for o in out] == list(range(len(rows)))
    return tuple(out)


def divisors(model: RobotModel, phi: np.ndarray) -> np.ndarray:
    """g of every output channel for parameters Φ."""
    return np.array([phi[o.gain_index] if o.gain_index is not None else o.known_gain for o in output_channels(model)])


def measured_outputs(model: RobotModel, sig: Signals) -> np.ndarray:
    """y (N, n_out) in the channels' own units."""
    cols = []
    for o in output_channels(model):
        if o.kind == "ft":
            sensor, c = o.name.split(".")[1], o.name.split(".")[2]
            cols.append(sig.ft[sensor][:, WRENCH_FIELDS.index(c)])
        elif o.kind == "torque":
            cols.append(sig.tau[o.name.removeprefix("tau.")])
        else:
            cols.append(sig.inputs[o.motor])
    return np.column_stack(cols)


def residuals_many(model: RobotModel, phis: Sequence[np.ndarray], sig: Signals) -> list[np.ndarray]:
    """`residuals` for each Φ of `phis`, the same numbers: through the kernel the rows are built once for all of them
    (the T² calibration takes each sample through the fit's Φ and its time block's)."""
    kernel = row_kernel.stack(model)
    if kernel is None or len(phis) == 1:
        return [residuals(model, phi, sig) for phi in phis]
    gs = [_checked_divisors(model, phi) for phi in phis]
    e = row_kernel.row_residuals_many(kernel, model, sig, np.vstack(phis))
    return [e[m] / g for m, g in enumerate(gs)]


def _checked_divisors(model: RobotModel, phi: np.ndarray) -> np.ndarray:
    g = divisors(model, phi)
    if np.any(g == 0) or not np.all(np.isfinite(g)):
        raise ValueError("a motor gain of Φ is zero or not finite: the model cannot predict that motor's input")
    return g


def residuals(model: RobotModel, phi: np.ndarray, sig: Signals, chunk: int = DEFAULT_CHUNK) -> np.ndarray:
    """e = y − ŷ (N, n_out) for parameters Φ; ŷ = y − e."""
    g = _checked_divisors(model, phi)
    r = len(g)
    kernel = row_kernel.stack(model)
    if kernel is not None:  # b − A Φ row by row in the kernel, A never stored
        return row_kernel.row_residuals(kernel, model, sig, phi) / g
    out = np.empty((sig.q.shape[0], r))
    start = 0
    for A, b in iter_stacked(model, sig, chunk):
        n = A.shape[0] // r
        out[start : start + n] = ((b - A @ phi).reshape(n, r)) / g
        start += n
    return out
