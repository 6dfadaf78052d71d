"""Check an exported URDF against the model it came from: Pinocchio's `rnea` on the URDF against the model's own
rigid-body predictions (Y_τ Φ̂ and Y_FT Φ̂, dynid's regressors), sample by sample.

Two readings of the URDF:

- plain: `pinocchio.buildModelFromUrdf` as any user would load it (fixed joints merged, the F/T sensor's two links
  one body), every joint but the configured ones locked at zero: its joint torques;
- split: the configuration with its URDF replaced by the exported one (dynid.robot.model: the sensor as a joint,
  the tree re-rooted where the configuration says so): its joint torques and the F/T wrenches, minus the sensor
  joint's `rnea` rows (docs/design.md §3).

The plain reading needs the URDF's own root as the fixed base; a re-rooted configuration is checked by the split
reading alone.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..identify.model_file import IdentifiedModel
from ..robot.model import RobotModel
from ..robot.regressors.rigid_body import rigid_body_regressors


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    """max |a − b| / max |b| over a channel's samples."""
    return float(np.abs(a - b).max() / max(float(np.abs(b).max()), 1e-300))


def round_trip(identified: IdentifiedModel, urdf: str | Path, q: np.ndarray, dq: np.ndarray,
               ddq: np.ndarray) -> dict[str, float]:
    """The largest relative difference per channel ('plain.tau.<joint>', 'split.tau.<joint>', 'split.ft.<sensor>.<k>')
    between `rnea` on the exported URDF and the model's predictions, over the samples (N, n_joints) given."""
    robot = identified.robot_model
    cfg = robot.config
    phi = identified.phi[robot.layout.span("inertial")]
    reg = rigid_body_regressors(robot, q, dq, ddq)
    tau_model = reg.tau @ phi
    out: dict[str, float] = {}

    if not robot.reversed_joints:
        full = pin.buildModelFromUrdf(str(urdf))
        lock = [i for i in range(1, full.njoints) if full.names[i] not in cfg.joints]
        plain = pin.buildReducedModel(full, lock, pin.neutral(full))
        plain.gravity = pin.Motion(np.asarray(cfg.gravity, float), np.zeros(3))
        data = plain.createData()
        ids = [plain.getJointId(j) for j in cfg.joints]
        tau = np.empty_like(tau_model)
        for k in range(q.shape[0]):
            qk, vk, ak = pin.neutral(plain), np.zeros(plain.nv), np.zeros(plain.nv)
            for c, i in enumerate(ids):
                if plain.nqs[i] == 2:  # continuous: (cos, sin)
                    qk[plain.idx_qs[i]: plain.idx_qs[i] + 2] = np.cos(q[k, c]), np.sin(q[k, c])
                else:
                    qk[plain.idx_qs[i]] = q[k, c]
                vk[plain.idx_vs[i]], ak[plain.idx_vs[i]] = dq[k, c], ddq[k, c]
            tau[k] = pin.rnea(plain, data, qk, vk, ak)[[plain.idx_vs[i] for i in ids]]
        out.update({f"plain.tau.{j}": _relative(tau[:, c], tau_model[:, c]) for c, j in enumerate(cfg.joints)})

    split = RobotModel(replace(cfg, urdf=Path(urdf)))
    Q, V, A = (split.pinocchio_configuration(q), split.pinocchio_velocity(dq), split.pinocchio_velocity(ddq))
    data = split.pin_model.createData()
    taus = np.array([pin.rnea(split.pin_model, data, Q[k], V[k], A[k]) for k in range(Q.shape[0])])
    out.update({f"split.tau.{j}": _relative(taus[:, split.v_index[c]], tau_model[:, c])
                for c, j in enumerate(cfg.joints)})
    for s, v0 in split.sensor_v_index.items():
        ft_model = reg.ft[s] @ phi
        for c, k in enumerate(("fx", "fy", "fz", "tx", "ty", "tz")):
            out[f"split.ft.{s}.{k}"] = _relative(-taus[:, v0 + c], ft_model[:, c])
    return out


def physical_model(identified: IdentifiedModel) -> IdentifiedModel:
    """A copy of the model whose inertial Φ is the nearest physical set (`--nearest-physical`'s) and whose base
    values are that set's: a model that carries a physical full Φ reproducing its own base parameters, as a
    physically consistent fit hands on (for the round-trip tests while the fit they use is unconstrained)."""
    from .physical_set import nearest_physical_set
    from .urdf import base_map, link_parts

    robot = identified.robot_model
    tree = ET.parse(robot.config.urdf)
    parts = link_parts(robot, tree)
    phi = identified.phi
    span = robot.layout.span("inertial")
    B, B_in, sigma = base_map(identified)
    rows = np.flatnonzero(np.abs(B_in).max(axis=1) > 0)
    done = nearest_physical_set(parts, phi[span], B_in[rows], sigma[rows], allow_residual=True)
    written = {p.link: done.links.get(p.link, p.cad) for p in parts}
    phi[span] = np.concatenate([sum((p.A @ written[p.link] for p in parts if p.body == k), np.zeros(10))
                                for k in range(len(robot.bodies))])
    assert identified.base is not None  # base_map refused a model without one
    return replace(identified, parameters=dict(zip(robot.layout.names, phi.tolist())),
                   base=replace(identified.base, values=B @ phi), path=None)
