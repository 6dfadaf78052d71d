"""Rigid-body regressors Y_τ and Y_FT from Pinocchio, for a batch of samples.

Both come from one `computeJointTorqueRegressor` call per sample on the model whose F/T sensors are 6-DoF
joints held at identity (see `dynid.robot.model`): the configured joints' rows are Y_τ, and minus the six rows of a
sensor joint are Y_FT, because those rows are the wrench the proximal part exerts on the distal part and the
sensor reports the opposite one (child to parent), in the sensor frame, force first.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..model import RobotModel


@dataclass(frozen=True)
class RigidBodyRegressors:
    tau: np.ndarray  # (N, n_joints, 10·n_bodies): joint torques = tau @ φ
    ft: dict[str, np.ndarray]  # sensor -> (N, 6, 10·n_bodies): w_s (without offset) = ft @ φ


def iter_joint_torque_regressors(
    model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, gravity: np.ndarray | None = None
) -> Iterator[np.ndarray]:
    """Yield, per sample, Pinocchio's full joint-torque regressor (nv, 10·n_bodies) of the split model;
    `gravity` (N, 3), in the root's frame, replaces the model's for each sample (a tilting base)."""
    pm = model.pin_model
    data = pm.createData()
    Q, V, A = model.pinocchio_configuration(q), model.pinocchio_velocity(dq), model.pinocchio_velocity(ddq)
    saved = pm.gravity.copy()
    try:
        for k in range(Q.shape[0]):
            if gravity is not None:
                pm.gravity = pin.Motion(gravity[k], np.zeros(3))
            # eigenpy returns a 1-row matrix as a 1-D array: restore (nv, 10·n_bodies) for 1-DoF chains.
            yield pin.computeJointTorqueRegressor(pm, data, Q[k], V[k], A[k]).reshape(pm.nv, -1)
    finally:
        pm.gravity = saved


def rigid_body_regressors(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                          gravity: np.ndarray | None = None) -> RigidBodyRegressors:
    """Y_τ and Y_FT for a batch of states (N, n_joints) each; `gravity` (N, 3) per sample, or the model's."""
    q, dq, ddq = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, dq, ddq))
    # One Pinocchio call and one copy per sample; the rows are picked afterwards, vectorised over the batch.
    Y = np.empty((q.shape[0], model.pin_model.nv, 10 * len(model.bodies)))
    for k, Yk in enumerate(iter_joint_torque_regressors(model, q, dq, ddq, gravity)):
        Y[k] = Yk
    ft = {s: -Y[:, v0 : v0 + 6] for s, v0 in model.sensor_v_index.items()}
    return RigidBodyRegressors(Y[:, model.v_index], ft)
