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

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from ...config.robot_config import ActuationGroup
from ...errors import DataError
from ...io.derivatives import SavitzkyGolay
from ...progress import track
from ..model import RobotModel
from ..parameters import WRENCH_FIELDS
from .friction import friction_regressor
from .rigid_body import rigid_body_regressors

DEFAULT_CHUNK = 4096  # samples per chunk: bounds the transient memory of the per-sample regressors
# rad/s (m/s): below this speed a friction coordinate counts as at rest. The model's friction has no static
# part, and near zero the sign of an estimated velocity is noise (1.4e-3 rad/s RMS for 16-bit encoders at
# 1 kHz, dynid.io.derivatives), so a row whose friction coordinates rest says nothing the model can explain.
DEFAULT_MIN_SPEED = 0.01


@dataclass(frozen=True)
class RowChannel:
    """One row of the per-sample block."""

    name: str  # "ft.<sensor>.<fx..tz>" or "joint.<joint>"
    sigma: float  # noise std in the row's units (N, Nm)


def motor_space(group: ActuationGroup) -> bool:
    """A coupled group with as many motors as joints is written one row per motor (see the module docstring)."""
    return group.input != "torque" and group.coupled and group.coupling.shape[0] == group.coupling.shape[1]


def row_channels(model: RobotModel) -> tuple[RowChannel, ...]:
    cfg = model.config
    rows: list[RowChannel] = []
    for s in cfg.ft_sensors:
        for k, c in enumerate(WRENCH_FIELDS):
            # an estimated value (`fit --noise estimate`) overrides the configuration's
            rows.append(RowChannel(f"ft.{s.name}.{c}", cfg.noise.per_channel.get(f"ft.{s.name}.{c}", s.noise_of(k))))
    for g in cfg.actuation:
        if g.input == "torque":
            rows.extend(RowChannel(f"joint.{j}", cfg.noise.of("torque", j)) for j in g.joints)
            continue
        noise = np.array([cfg.noise.of(g.input, m) for m in g.motors])  # per motor (configuration's noise)
        gains = np.array([cfg.motor(m).known_gain or cfg.motor(m).nominal_gain for m in g.motors])
        if motor_space(g):
            rows.extend(RowChannel(f"motor.{m}", float(s * k)) for m, s, k in zip(g.motors, noise, gains))
            continue
        Tt = g.coupling.T
        for li, j in enumerate(g.joints):
            # An input error δu on motor m is a torque error Tᵀ[j, m]·gain_m·δu on this row.
            rows.append(RowChannel(f"joint.{j}", float(np.linalg.norm(Tt[li] * gains * noise))))
    return tuple(rows)


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


@dataclass(frozen=True)
class Signals:
    """What the stacked rows need, by name; shapes (N, …). Missing channels raise a DataError when needed."""

    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    inputs: Mapping[str, np.ndarray]  # motor -> PWM duty or current (whichever its group's input is)
    tau: Mapping[str, np.ndarray]  # joint -> measured torque
    ft: Mapping[str, np.ndarray]  # sensor -> (N, 6) measured wrench
    # A known payload carried through the run: its inertial parameters in the layout's inertial span (its
    # body's slot, RobotModel.payload_parameters). Its torques are known, so they move to b: that fixes the
    # scale of a set-up with unknown gains and no F/T sensor (the loaded/unloaded runs of Gautier and Khalil).
    payload: np.ndarray | None = None
    # (N, 3) gravity per sample in the model root's frame, for a base that tilts (config.gravity_imu); None: the
    # configuration's constant gravity
    gravity: np.ndarray | None = None

    def slice(self, s: slice) -> Signals:
        return Signals(
            self.q[s], self.dq[s], self.ddq[s],
            {k: v[s] for k, v in self.inputs.items()},
            {k: v[s] for k, v in self.tau.items()},
            {k: v[s] for k, v in self.ft.items()},
            self.payload,
            None if self.gravity is None else self.gravity[s],
        )


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
    payload = dataset.meta.get("payload")
    phi_payload = None if not payload else model.payload_parameters(float(payload["mass"]), payload.get("com"))
    gravity = gravity_per_sample(model, dataset)
    if smoother is None:
        return Signals(dataset.q, dataset.dq, dataset.ddq, inputs, tau, ft, phi_payload, gravity)
    columns = [dataset.q] + [v[:, None] for v in inputs.values()] + [v[:, None] for v in tau.values()] + list(ft.values())
    columns += [] if gravity is None else [gravity]  # a measured signal: filtered like the outputs
    smooth = smoother(dataset.t, np.hstack(columns)).q
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


def group_rows(model: RobotModel) -> Iterator[tuple[ActuationGroup, list[int], slice]]:
    """Each actuation group with its joints' columns in q and its rows of the stacked system (after the F/T rows)."""
    cfg = model.config
    joint_col = {j: i for i, j in enumerate(cfg.joints)}
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        rows = slice(start, start + len(g.joints))
        start = rows.stop
        yield g, [joint_col[j] for j in g.joints], rows


STRUCTURAL_RTOL = 1e-12  # an entry of an inverted coupling below this share of its largest is rounding residue


def group_row_maps(group: ActuationGroup) -> tuple[np.ndarray, np.ndarray]:
    """(L, C) of a group: its rows are L times its joint equations, and motor terms enter them through C.

    L inverts the coupling: its structural zeros come out of LAPACK as rounding residue (1e-17) whose value, and
    whether it is exactly zero, depends on the CPU's BLAS kernels. They are set to zero here, once, so that which
    rows a term touches never depends on the machine (couplings have condition numbers near 10: the residue is
    ~1e-15 of the largest entry, a true entry is ~1e-1)."""
    if motor_space(group):
        L = np.linalg.inv(group.coupling.T)
        return np.where(np.abs(L) > STRUCTURAL_RTOL * np.abs(L).max(), L, 0.0), np.eye(len(group.motors))
    return np.eye(len(group.joints)), group.coupling.T


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
        for c in coordinates:
            out[:, rows] |= (np.abs(c.velocity) < min_speed)[:, None] & (c.share != 0)[None, :]
    return out


def row_weights(model: RobotModel, sig: Signals, min_speed: float | None = DEFAULT_MIN_SPEED) -> np.ndarray:
    """(N, r) weights 1/σ of every row, 0 for rows at rest (see `rows_at_rest`; None keeps every row)."""
    w = np.tile(1.0 / np.array([c.sigma for c in row_channels(model)]), (sig.q.shape[0], 1))
    if min_speed is not None and min_speed > 0:
        w[rows_at_rest(model, sig.dq, min_speed)] = 0.0
    return w


def fill_rows(model: RobotModel, sig: Signals, A: np.ndarray, b: np.ndarray) -> None:
    """Write the rows of `sig`'s samples into A (N, r, p) and b (N, r), which the caller zeroed."""
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


def iter_stacked(model: RobotModel, sig: Signals, chunk: int = DEFAULT_CHUNK) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield (A, b) a chunk of samples at a time, for estimators that accumulate instead of stacking."""
    r, p = len(row_channels(model)), len(model.layout)
    n = sig.q.shape[0]
    for start in range(0, n, chunk):
        part = sig.slice(slice(start, min(start + chunk, n)))
        m = part.q.shape[0]
        A, b = np.zeros((m, r, p)), np.zeros((m, r))
        fill_rows(model, part, A, b)
        yield A.reshape(m * r, p), b.reshape(m * r)


def build_stacked(model: RobotModel, sig: Signals, chunk: int = DEFAULT_CHUNK) -> StackedSystem:
    """The complete A Φ = b for all samples, filled in place chunk by chunk (no concatenation copies)."""
    channels = row_channels(model)
    r, p, n = len(channels), len(model.layout), sig.q.shape[0]
    A, b = np.zeros((n, r, p)), np.zeros((n, r))
    starts = range(0, n, chunk)
    for start in track(starts, len(starts), "building regressors"):
        s = slice(start, min(start + chunk, n))
        fill_rows(model, sig.slice(s), A[s], b[s])
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
