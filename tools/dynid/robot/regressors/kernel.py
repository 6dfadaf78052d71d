"""The stacked rows of `stack.fill_rows` through the compiled kernel (dynid.kernels): the same rows, computed over a
whole chunk of samples in C++ and written straight into the caller's arrays, weights applied where given.

`stack.fill_rows` stays the reference; this module only turns the robot model into the kernel's plan (which
regressor rows each row combines, where offsets, friction, inputs and torques go) and its signals into arrays.
"""

from __future__ import annotations

import weakref

import numpy as np
import pinocchio as pin

from ... import kernels
from ..model import RobotModel
from .rows import Signals, group_row_maps, group_rows, row_channels

_HELD, _REVOLUTE, _PRISMATIC = 2, 0, 1
_KINDS = {"R": _REVOLUTE, "P": _PRISMATIC}
_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def chain_joints(model: RobotModel) -> list[tuple] | None:
    """The split model's joints as the kernel's chain takes them, or None when it holds a joint the kernel lacks
    (anything but revolute, prismatic and the F/T sensors' held 6-DoF joints)."""
    pm = model.pin_model
    data = pm.createData()
    pin.forwardKinematics(pm, data, pin.neutral(pm))
    held = set(model.sensor_joint_ids.values())
    q_col = {jid: k for k, jid in enumerate(model.joint_ids)}
    out = []
    for jid in range(1, pm.njoints):
        name = pm.joints[jid].shortname().removeprefix("JointModel")
        placement = pm.jointPlacements[jid]
        R, p = placement.rotation.ravel().tolist(), placement.translation.tolist()
        if jid in held:
            if name != "FreeFlyer":
                return None
            out.append((pm.parents[jid] - 1, _HELD, R, p, [0.0, 0.0, 1.0], -1, int(pm.idx_vs[jid]), 6))
            continue
        kind = _KINDS.get(name[0]) if pm.nvs[jid] == 1 and "Mimic" not in name and "Helical" not in name else None
        if kind is None or name.startswith(("Planar", "Spherical")) or jid not in q_col:
            return None
        S = np.asarray(data.joints[jid].S, float).ravel()  # (lin, ang) in the joint frame
        axis = S[3:] if kind == _REVOLUTE else S[:3]
        if not np.allclose(S[:3] if kind == _REVOLUTE else S[3:], 0.0) or not np.isclose(np.linalg.norm(axis), 1.0):
            return None
        out.append((pm.parents[jid] - 1, kind, R, p, axis.tolist(), q_col[jid], int(pm.idx_vs[jid]), 1))
    return out


def _plan(model: RobotModel) -> tuple:
    cfg, layout = model.config, model.layout
    r = len(row_channels(model))
    inertial: list[list[tuple[int, float]]] = [[] for _ in range(r)]
    constants, ft, friction, inputs, torques = [], [], [], [], []
    for i, s in enumerate(cfg.ft_sensors):
        v0 = model.sensor_v_index[s.name]
        offset = layout.block("ft_offset", s.name).start
        for k in range(6):
            inertial[6 * i + k] = [(v0 + k, -1.0)]
            constants.append((6 * i + k, offset + k, 1.0))
            ft.append((6 * i + k, 6 * i + k))
    names = input_names(model)
    taus = torque_names(model)
    nz = lambda col, rows: [(rows.start + ri, float(x)) for ri, x in enumerate(col) if x != 0.0]  # noqa: E731
    for g, gj, rows in group_rows(model):
        L, C = group_row_maps(g)
        for ri in range(L.shape[0]):
            inertial[rows.start + ri] = [(int(model.v_index[c]), float(L[ri, li])) for li, c in enumerate(gj)
                                         if L[ri, li] != 0.0]
        for li, (j, c) in enumerate(zip(g.joints, gj)):
            friction.append(([(c, 1.0)], layout.block("joint_friction", j).start, nz(L[:, li], rows)))
        if g.input == "torque":
            torques += [(taus.index(j), -1, nz(L[:, li], rows)) for li, j in enumerate(g.joints)]
            continue
        for mi, m in enumerate(g.motors):
            if g.coupled:
                velocity = [(c, float(g.coupling[mi, li])) for li, c in enumerate(gj) if g.coupling[mi, li] != 0.0]
                friction.append((velocity, layout.block("motor_friction", m).start, nz(C[:, mi], rows)))
            known = cfg.motor(m).known_gain
            if known is None:
                inputs.append((names.index(m), layout.block("motor_gain", m).start, nz(-C[:, mi], rows)))
            else:
                inputs.append((names.index(m), -1, nz(C[:, mi] * known, rows)))
    return r, len(layout), layout.span("inertial").start, inertial, constants, ft, friction, inputs, torques


def input_names(model: RobotModel) -> list[str]:
    return [m for g in model.config.actuation if g.input != "torque" for m in g.motors]


def torque_names(model: RobotModel) -> list[str]:
    return [j for g in model.config.actuation if g.input == "torque" for j in g.joints]


def chain(model: RobotModel):
    """The kernel's chain of `model` (cached), or None where the kernels are off or lack one of its joints."""
    native = kernels.native()
    if native is None:
        return None
    entry = _CACHE.get(model)
    if entry is None:
        joints = chain_joints(model)
        c = None if joints is None else native.Chain(joints, model.pin_model.gravity.linear.tolist())
        entry = {"chain": c}
        _CACHE[model] = entry
    return entry["chain"]


def stack(model: RobotModel):
    """The kernel's stacked-row plan of `model` (cached), or None where the Python reference must run."""
    c = chain(model)
    if c is None:
        return None
    entry = _CACHE[model]
    if "stack" not in entry:
        entry["stack"] = kernels.native().Stack(c, *_plan(model))
    return entry["stack"]


def _c(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


def _arrays(model: RobotModel, sig: Signals) -> tuple:
    """The kernel's inputs from `sig`: q, q̇, q̈, the inputs, torques and F/T as (N, ·) arrays, gravity, payload."""
    names, taus = input_names(model), torque_names(model)
    n = sig.q.shape[0]
    u = _c(np.column_stack([sig.inputs[m] for m in names])) if names else None
    tau = _c(np.column_stack([sig.tau[j] for j in taus])) if taus else None
    sensors = model.config.ft_sensors
    ft = _c(np.hstack([np.asarray(sig.ft[s.name], float).reshape(n, 6) for s in sensors])) if sensors else None
    gravity = None if sig.gravity is None else _c(sig.gravity)
    payload = None if sig.payload is None else _c(sig.payload)
    return _c(sig.q), _c(sig.dq), _c(sig.ddq), u, tau, ft, gravity, payload


def fill(kernel, model: RobotModel, sig: Signals, A: np.ndarray, b: np.ndarray, weights: np.ndarray | None = None,
         threads: int = 1) -> None:
    """`stack.fill_rows` through the kernel: every entry of A (N, r, p) and b (N, r) written (any strides), each
    row times `weights` (N, r) where given."""
    kernel.fill(*_arrays(model, sig), None if weights is None else _c(weights), A, b, threads)


def row_residuals(kernel, model: RobotModel, sig: Signals, phi: np.ndarray) -> np.ndarray:
    """b − A Φ of every row (N, r), A never stored."""
    e = np.empty((sig.q.shape[0], kernel_rows(kernel)))
    kernel.residuals(*_arrays(model, sig), _c(phi), e, 1)
    return e


def row_residuals_many(kernel, model: RobotModel, sig: Signals, phis: np.ndarray) -> np.ndarray:
    """b − A Φ_m of every row for each row Φ_m of `phis` (K, p): (K, N, r), A built once per sample for all K."""
    e = np.empty((phis.shape[0], sig.q.shape[0], kernel_rows(kernel)))
    kernel.residuals_many(*_arrays(model, sig), _c(phis), e, 1)
    return e


def kernel_rows(kernel) -> int:
    return kernel.rows
