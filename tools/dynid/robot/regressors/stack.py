"""The stacked linear system A Φ = b of docs/design.md §3, for every sample of a dataset.

Per sample the rows are, in this order:

- for each F/T sensor, six rows  ``Y_FT φ + w_O = w_s``                      (b = measured wrench)
- for each joint of an actuation group, one row of its motor equation:
  - input ``pwm`` or ``current``: ``Y_τ φ + Y_F φ_F + Tᵀ Y_Fm φ_Fm − Tᵀ diag(u) φ_m = 0``; a motor whose gain is
    known moves its term to b;
  - input ``torque`` (joint torque sensors): ``Y_τ φ + Y_F φ_F = τ``.

Rows carry different units (N, Nm, and equations whose noise comes from the input), so each row channel has a
noise standard deviation σ from the configuration; estimators weight rows by 1/σ. That weighting assumes
independent rows, which the joint rows of a coupled group are not: Tᵀ spreads each motor's input error over
several joints. A coupled group with a square T is therefore written in motor space, T⁻ᵀ times its joint
rows, one row per motor: ``T⁻ᵀ(Y_τ φ + Y_F φ_F) + Y_Fm φ_Fm − diag(u) φ_m = 0``, whose errors are independent,
σ = σ_input · gain. The solution set is the same; only the weighting changes.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ...errors import DataError
from ...io.derivatives import SavitzkyGolay
from ...progress import track
from ..model import RobotModel
from .friction import friction_regressor
from . import kernel as row_kernel
from .rigid_body import rigid_body_regressors
from .rows import (RowChannel, Signals, group_row_maps, group_rows, motor_space,  # noqa: F401 (re-exported)
                   row_channels)

DEFAULT_CHUNK = 4096  # samples per chunk: bounds the transient memory of the per-sample regressors
# rad/s (m/s): below this speed a friction coordinate counts as at rest. The model's friction has no static
# part, and near zero the sign of an estimated velocity is noise (1.4e-3 rad/s RMS for 16-bit encoders at
# 1 kHz, dynid.io.derivatives), so a row whose friction coordinates rest says nothing the model can explain.
DEFAULT_MIN_SPEED = 0.01


@dataclass
class StackedSystem:
    """A Φ = b over N samples; rows are sample-major (sample k owns rows k·r … k·r + r − 1)."""

    A: np.ndarray  # (N·r, p)
    b: np.ndarray  # (N·r,)
    channels: tuple[RowChannel, ...]  # the r rows of one sample
    parameter_names: tuple[str, ...]

    @property
    def rows_per_sample(self) -> int:
        return len(self.channels)

    @property
    def n_samples(self) -> int:
        return self.A.shape[0] // self.rows_per_sample

    @property
    def row_sigma(self) -> np.ndarray:
        return np.tile([c.sigma for c in self.channels], self.n_samples)

    def weighted(self) -> tuple[np.ndarray, np.ndarray]:
        """(W A, W b) with W = diag(1/σ): every row in units of its own noise."""
        w = 1.0 / self.row_sigma
        return self.A * w[:, None], self.b * w


def payload_of(model: RobotModel, dataset) -> np.ndarray | None:  # dataset: Dataset
    """The inertial parameters of the known payload the run carries (`dataset.meta["payload"]`, --payload), in the
    layout's inertial span (`Signals.payload`); None without one."""
    payload = dataset.meta.get("payload")
    return None if not payload else model.payload_parameters(float(payload["mass"]), payload.get("com"))


def signals_from_dataset(model: RobotModel, dataset, filter_outputs: bool = False) -> Signals:  # dataset: Dataset
    """Pick the channels the configuration's sensor set-up needs; estimate q̇, q̈ when the data lack them.

    `filter_outputs`: when q̇, q̈ are estimated by a smoothing filter (Savitzky-Golay), pass q and every
    measured channel (F/T, inputs, torques) through the same filter, so both sides of each row see the same
    band: a real arm (and the simulated one) vibrates above the filter's band (encoder-quantised impedance
    control, torque ripple), and an unfiltered F/T or PWM would carry forces whose accelerations the
    filtered q̈ no longer holds (Gautier's parallel filtering of regressor and measurement).
    """
    cfg = model.config
    if tuple(dataset.joints) != cfg.joints:
        raise DataError(f"the dataset's joints {list(dataset.joints)} differ from the configuration's {list(cfg.joints)}")
    smoother = None
    if filter_outputs and (dataset.dq is None or dataset.ddq is None):
        options = dict(cfg.derivatives)
        if options.pop("method", "savgol") == "savgol":
            smoother = SavitzkyGolay(**options)
    if dataset.dq is None or dataset.ddq is None:
        options = dict(cfg.derivatives)
        try:
            dataset = dataset.with_derivatives(options.pop("method", None), **options)
        except ValueError as e:  # the estimator's own one-line diagnosis (window too short for the rate, ...)
            raise DataError(f"cannot estimate q̇, q̈ from q: {e}") from None
    inputs: dict[str, np.ndarray] = {}
    tau: dict[str, np.ndarray] = {}
    for g in cfg.actuation:
        if g.input == "torque":
            for j in g.joints:
                if j not in dataset.tau:
                    raise DataError(f"the data have no tau.{j}, which actuation group '{g.name}' needs (input: torque)")
                tau[j] = dataset.tau[j]
            continue
        source = dataset.pwm if g.input == "pwm" else dataset.current
        for m in g.motors:
            if m not in source:
                raise DataError(f"the data have no {g.input}.{m}, which actuation group '{g.name}' needs")
            inputs[m] = source[m]
    for s in cfg.ft_sensors:
        if s.name not in dataset.ft:
            raise DataError(f"the data have no ft.{s.name}.* columns, which the configuration's F/T sensor needs")
    ft = {s.name: dataset.ft[s.name] for s in cfg.ft_sensors}
    phi_payload = payload_of(model, dataset)
    gravity = gravity_per_sample(model, dataset)
    if smoother is None:
        return Signals(dataset.q, dataset.dq, dataset.ddq, inputs, tau, ft, phi_payload, gravity)
    columns = [dataset.q] + [v[:, None] for v in inputs.values()] + [v[:, None] for v in tau.values()] + list(ft.values())
    columns += [] if gravity is None else [gravity]  # a measured signal: filtered like the outputs
    smooth = smoother.smooth(dataset.t, np.hstack(columns))
    cut = np.cumsum([c.shape[1] for c in columns])[:-1]
    parts = iter(np.split(smooth, cut, axis=1))
    q = next(parts)
    inputs = {k: next(parts)[:, 0] for k in inputs}
    tau = {k: next(parts)[:, 0] for k in tau}
    ft = {k: next(parts) for k in ft}
    gravity = None if gravity is None else next(parts)
    return Signals(q, dataset.dq, dataset.ddq, inputs, tau, ft, phi_payload, gravity)


def gravity_per_sample(model: RobotModel, dataset) -> np.ndarray | None:
    """(N, 3) gravity in the model root's frame from the accelerometer's columns, or None for constant gravity.

    At rest an accelerometer measures the specific force −g; the base of a balancing robot tilts slowly, so its
    own acceleration (~0.1 m/s² against 9.81) is left in as noise."""
    cfg = model.config
    if not cfg.gravity_imu:
        return None
    missing = [c for c in cfg.gravity_imu_columns if c not in dataset.extra]
    if missing:
        raise DataError(f"the data have no column {missing[0]}, which the configuration's gravity.imu needs "
                        f"(the accelerometer at {cfg.gravity_imu})")
    a = np.column_stack([dataset.extra[c] for c in cfg.gravity_imu_columns])
    return -a @ model.imu_rotation.T


def motor_velocities(dq_joints: np.ndarray, coupling: np.ndarray) -> np.ndarray:
    """q̇_m = T q̇ per sample (N, n_motors); a velocity that cancels exactly (q̇₀ = q̇₁ in a row [−r, r, 0]) is
    exactly 0, as a product summed term by term gives it, not the ±1e-17 a fused multiply-add may leave (the
    Coulomb sign of a motor at rest must not be a rounding accident)."""
    v = dq_joints @ coupling.T
    v[np.abs(v) <= 1e-12 * (np.abs(dq_joints) @ np.abs(coupling).T)] = 0.0
    return v


@dataclass(frozen=True)
class FrictionCoordinate:
    """A coordinate with its own friction law: a joint, or a coupled motor at q̇_m = T q̇."""

    velocity: np.ndarray  # (N,)
    share: np.ndarray  # (rows of its group,) its friction torque's coefficient in each row; 0 where it is absent
    block: tuple[str, str]  # its friction parameters: ("joint_friction", joint) or ("motor_friction", motor)


def friction_coordinates(model: RobotModel, dq: np.ndarray) -> Iterator[tuple[slice, list[FrictionCoordinate]]]:
    """Per actuation group: its row channels and the friction coordinates that enter them."""
    for g, gj, rows in group_rows(model):
        L, C = group_row_maps(g)
        coordinates = [FrictionCoordinate(dq[:, c], L[:, li], ("joint_friction", j))
                       for li, (j, c) in enumerate(zip(g.joints, gj))]
        if g.input != "torque" and g.coupled:
            v = motor_velocities(dq[:, gj], g.coupling)
            coordinates += [FrictionCoordinate(v[:, mi], C[:, mi], ("motor_friction", m))
                            for mi, m in enumerate(g.motors)]
        yield rows, coordinates


def rows_at_rest(model: RobotModel, dq: np.ndarray, min_speed: float = DEFAULT_MIN_SPEED) -> np.ndarray:
    """(N, r) bool: rows whose equation holds a friction coordinate (a joint, or a coupled motor at q̇_m = T q̇)
    slower than `min_speed`; static friction, which the model lacks, may hold any torque there.

    F/T rows hold no friction and are never at rest.
    """
    out = np.zeros((dq.shape[0], len(row_channels(model))), dtype=bool)
    for rows, coordinates in friction_coordinates(model, dq):
        if not coordinates:
            continue
        # a row rests where any coordinate on it is slow: (N, coordinates) slow × (coordinates, rows) present, as a
        # product of 0/1 (exact in float) rather than an or over full-width copies per coordinate
        slow = np.column_stack([np.abs(c.velocity) < min_speed for c in coordinates]).astype(np.float32)
        present = np.array([c.share != 0 for c in coordinates], dtype=np.float32)
        out[:, rows] = (slow @ present) > 0
    return out


def row_weights(model: RobotModel, sig: Signals, min_speed: float | None = DEFAULT_MIN_SPEED) -> np.ndarray:
    """(N, r) weights 1/σ of every row, 0 for rows at rest (see `rows_at_rest`; None keeps every row)."""
    w = np.tile(1.0 / np.array([c.sigma for c in row_channels(model)]), (sig.q.shape[0], 1))
    if min_speed is not None and min_speed > 0:
        w[rows_at_rest(model, sig.dq, min_speed)] = 0.0
    return w


def fill_rows(model: RobotModel, sig: Signals, A: np.ndarray, b: np.ndarray) -> None:
    """Write the rows of `sig`'s samples into A (N, r, p) and b (N, r), which the caller zeroed: through the
    compiled kernel where it runs (every entry written), else `fill_rows_reference`."""
    kernel = row_kernel.stack(model)
    if kernel is not None:
        row_kernel.fill(kernel, model, sig, A, b)
    else:
        fill_rows_reference(model, sig, A, b)


def weighted_rows(model: RobotModel, sig: Signals, weights: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """[W A | W b] of `sig`'s samples, channel-major (r, N, p + 1): row channel c of sample k is X[c, k], its b last;
    `weights` (N, r). What the per-channel Grams of dynid.identify.statistics are products of. `out`: an (r, ≥ N,
    p + 1) buffer to write into (X is its first N samples), kept by a caller that builds chunk after chunk: a
    chunk's rows are tens of MB, which a fresh array pays for in page faults each time."""
    r, p, n = len(row_channels(model)), len(model.layout), sig.q.shape[0]
    X = np.empty((r, n, p + 1)) if out is None else out[:, :n, :]
    kernel = row_kernel.stack(model)
    if kernel is not None:  # written in place, weighted, through strided views
        row_kernel.fill(kernel, model, sig, X[:, :, :p].transpose(1, 0, 2), X[:, :, p].T, weights)
        return X
    A, b = np.zeros((n, r, p)), np.zeros((n, r))
    fill_rows_reference(model, sig, A, b)
    X[:, :, :p] = (A * weights[:, :, None]).transpose(1, 0, 2)
    X[:, :, p] = (b * weights).T
    return X


def fill_rows_reference(model: RobotModel, sig: Signals, A: np.ndarray, b: np.ndarray) -> None:
    """The Python reference of the rows (the compiled kernel is tested against it): A (N, r, p) and b (N, r) zeroed."""
    cfg, layout = model.config, model.layout
    inertial = layout.span("inertial")
    rb = rigid_body_regressors(model, sig.q, sig.dq, sig.ddq, sig.gravity)

    for i, s in enumerate(cfg.ft_sensors):
        rows = slice(6 * i, 6 * i + 6)
        A[:, rows, inertial] = rb.ft[s.name]
        A[:, rows, layout.block("ft_offset", s.name).slice] = np.eye(6)
        b[:, rows] = sig.ft[s.name]
        if sig.payload is not None:
            b[:, rows] -= rb.ft[s.name] @ sig.payload

    for g, gj, rows in group_rows(model):
        # The group's rows are L times its joint equations (L = T⁻ᵀ in motor space, else I). Motor terms enter
        # the joint equations through Tᵀ, hence the rows through C = L Tᵀ: exactly I in motor space.
        L, C = group_row_maps(g)
        A[:, rows, inertial] = np.einsum("rj,njp->nrp", L, rb.tau[:, gj])
        if sig.payload is not None:  # the payload's known torques, Y_τ φ_payload, on the right-hand side
            b[:, rows] -= (rb.tau[:, gj] @ sig.payload) @ L.T
        for li, (j, c) in enumerate(zip(g.joints, gj)):
            A[:, rows, layout.block("joint_friction", j).slice] = L[:, li, None] * friction_regressor(sig.dq[:, c])[:, None]
        if g.input == "torque":
            b[:, rows] += np.column_stack([sig.tau[j] for j in g.joints]) @ L.T
            continue
        if g.coupled:
            motor_friction = friction_regressor(motor_velocities(sig.dq[:, gj], g.coupling))  # at q̇_m = T q̇_I: (N, n_motors, 4)
        for mi, m in enumerate(g.motors):
            weight = C[:, mi]  # this motor's share of each row
            u = sig.inputs[m][:, None]
            if g.coupled:
                A[:, rows, layout.block("motor_friction", m).slice] = weight[:, None] * motor_friction[:, None, mi]
            known = cfg.motor(m).known_gain
            if known is None:
                A[:, rows, layout.block("motor_gain", m).start] = -weight * u
            else:
                b[:, rows] += weight * known * u


def _allocate(model: RobotModel, shape: tuple[int, ...]) -> np.ndarray:
    """Room for rows: uninitialised where the kernel writes every entry, else zeroed (the reference writes blocks)."""
    return np.empty(shape) if row_kernel.stack(model) is not None else np.zeros(shape)


def iter_stacked(model: RobotModel, sig: Signals, chunk: int = DEFAULT_CHUNK) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield (A, b) a chunk of samples at a time, for estimators that accumulate instead of stacking."""
    r, p = len(row_channels(model)), len(model.layout)
    n = sig.q.shape[0]
    for start in range(0, n, chunk):
        part = sig.slice(slice(start, min(start + chunk, n)))
        m = part.q.shape[0]
        A, b = _allocate(model, (m, r, p)), _allocate(model, (m, r))
        fill_rows(model, part, A, b)
        yield A.reshape(m * r, p), b.reshape(m * r)


def build_stacked(model: RobotModel, sig: Signals, chunk: int = DEFAULT_CHUNK) -> StackedSystem:
    """The complete A Φ = b for all samples, filled in place chunk by chunk (no concatenation copies)."""
    channels = row_channels(model)
    r, p, n = len(channels), len(model.layout), sig.q.shape[0]
    A, b = _allocate(model, (n, r, p)), _allocate(model, (n, r))
    kernel = row_kernel.stack(model)
    if kernel is not None:  # the kernel on every core, in larger chunks (the progress line still moves)
        chunk = max(chunk, 65536)
    starts = range(0, n, chunk)
    for start in track(starts, len(starts), "building regressors"):
        s = slice(start, min(start + chunk, n))
        if kernel is not None:
            row_kernel.fill(kernel, model, sig.slice(s), A[s], b[s], threads=os.cpu_count() or 1)
        else:
            fill_rows_reference(model, sig.slice(s), A[s], b[s])
    return StackedSystem(A.reshape(n * r, p), b.reshape(n * r), channels, model.layout.names)


def joint_row_shares(model: RobotModel) -> dict[str, tuple[int, np.ndarray]]:
    """joint -> (its column in q, its (r,) share of each row channel): joint rows are L times the group's joint
    equations (this module), so a joint torque τ_j adds τ_j·share to the rows."""
    cfg = model.config
    r = len(row_channels(model))
    out: dict[str, tuple[int, np.ndarray]] = {}
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        L, _ = group_row_maps(g)
        for li, j in enumerate(g.joints):
            share = np.zeros(r)
            share[start : start + len(g.joints)] = L[:, li]
            out[j] = (cfg.joints.index(j), share)
        start += len(g.joints)
    return out
