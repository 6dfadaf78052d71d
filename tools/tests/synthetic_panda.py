"""Synthetic Panda runs whose joint torques are the plant's truth: Pinocchio's `rnea` on the CAD inertias (a point
mass at the payload frame where asked), Coulomb and viscous friction per joint where given, every torque scaled where
asked (a torque sensor's gain), and noise at the configuration's level."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from dynid.io.dataset import Dataset
from dynid.robot.model import RobotModel
from dynid.robot.outputs import output_channels

RATE = 1000
HARMONICS = 4


def panda_run(model: RobotModel, seed: int, seconds: float = 12.0, load_kg: float = 0.0,
              friction: Sequence[Sequence[float]] | None = None, scale: float = 1.0) -> Dataset:
    """Sums of sinusoids of the seed's frequencies and phases within the joints' limits, and their torques.
    `friction`: (fc⁺, fc⁻ Nm, fv⁺, fv⁻ Nm s/rad) per joint, dynid's asymmetric model (design.md §3)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE)) / RATE
    lo, hi = (np.array([model.joint_limits[j][i] for j in model.config.joints]) for i in (0, 1))
    mid, amp = (lo + hi) / 2, np.minimum(0.6, 0.4 * (hi - lo) / 2) / HARMONICS
    q, dq, ddq = (np.zeros((t.size, len(lo))) for _ in range(3))
    q += mid
    for _ in range(HARMONICS):  # a sum of sinusoids per joint: every combination excited within a few seconds
        w = 2 * np.pi * rng.uniform(0.1, 0.8, len(lo))
        phase = rng.uniform(0, 2 * np.pi, len(lo))
        q += amp * np.sin(w * t[:, None] + phase)
        dq += amp * w * np.cos(w * t[:, None] + phase)
        ddq -= amp * w**2 * np.sin(w * t[:, None] + phase)
    inertial = model.cad_inertial_parameters + model.payload_parameters(load_kg)[: model.cad_inertial_parameters.size]
    plant = model.with_inertial_parameters(inertial)
    data = plant.createData()
    tau = np.array([pin.rnea(plant, data, q[k], dq[k], ddq[k]) for k in range(t.size)])
    if friction is not None:
        fc_pos, fc_neg, fv_pos, fv_neg = (np.array([f[i] for f in friction]) for i in range(4))
        tau += np.where(dq > 0, fc_pos + fv_pos * dq, np.where(dq < 0, -fc_neg + fv_neg * dq, 0.0))
    sigma = np.array([o.sigma for o in output_channels(model) if o.kind == "torque"])
    tau = scale * tau + rng.normal(0.0, 1.0, tau.shape) * sigma
    return Dataset(t=t, joints=model.config.joints, q=q, dq=dq,
                   tau={j: tau[:, i] for i, j in enumerate(model.config.joints)}, meta={"robot": "panda"})
