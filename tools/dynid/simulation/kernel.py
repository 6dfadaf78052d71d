"""The simulated plant through the compiled kernel (dynid.kernels): `experiment.simulate`'s closed loop and
`RigidBodyPlant.sensor_wrenches` over a whole run in C++. The Python loop and method stay the reference; this module
only hands the kernel their arrays (the controller's gains, the boards' quantisers, the actuators' friction laws and
hidden effects) and the serialised Pinocchio models.
"""

from __future__ import annotations

import numpy as np

from .. import kernels
from .actuation import GEAR_RATIO, RIPPLE_HARMONIC, Actuators
from .controller import ImpedanceController
from .plant import BodySite, RigidBodyPlant
from .sensors import InputQuantiser


def _c(x) -> np.ndarray:  # noqa: ANN001
    return np.ascontiguousarray(x, dtype=float)


def closed_loop(plant: RigidBodyPlant, cad_plant: RigidBodyPlant, controller: ImpedanceController,
                actuators: Actuators, board: InputQuantiser, encoder: np.ndarray, noise: bool):
    """The kernel's closed loop of this run, or None where the Python reference runs."""
    native = kernels.native()
    if native is None:
        return None
    law = actuators._law  # noqa: SLF001 - the actuators' base friction law, as drive() starts from it
    plan = {
        "K": _c(controller.K), "D": _c(controller.D), "alpha": float(controller.alpha), "dt": float(controller.dt),
        "to_inputs": _c(controller.to_inputs), "encoder": _c(encoder), "noise": bool(noise),
        "lo": _c(board.lo), "hi": _c(board.hi), "scale": _c(board.scale), "rounded": _c(board.rounded),
        "all_rounded": bool(board.all_rounded),
        "gain": _c(actuators.gain), "deadzone": _c(actuators.deadzone), "has_deadzone": actuators.has_deadzone,
        "ripple": float(actuators.ripple), "ripple_phase": _c(actuators.ripple_phase),
        "ripple_wavenumber": RIPPLE_HARMONIC * GEAR_RATIO,
        "cogging": _c(actuators.cogging), "cogging_wavenumber": _c(actuators.cogging_wavenumber),
        "cogging_phase": _c(actuators.cogging_phase), "direct": _c(actuators.direct), "spring": _c(actuators.spring),
        "spring_rest": _c(actuators.spring_rest), "drag": _c(actuators.drag), "has_effects": actuators.has_effects,
        "lower": _c(actuators.lower), "upper": _c(actuators.upper), "stribeck": _c(actuators.stribeck),
        "stribeck_velocity": _c(actuators.stribeck_velocity), "load_friction": _c(actuators.load_friction),
        "motor_coordinate": _c(actuators.motor_coordinate), "T": _c(actuators.T), "S": _c(actuators.S),
        "coulomb_pos": _c(law.coulomb_pos), "coulomb_neg": _c(law.coulomb_neg),
        "viscous_pos": _c(law.viscous_pos), "viscous_neg": _c(law.viscous_neg),
    }
    armature = None if actuators.armature is None else _c(actuators.armature)
    return native.ClosedLoop(plant.model.saveToString(), cad_plant.model.saveToString(), armature, plan)


def contact_forces(sites: list[BodySite], site_index: np.ndarray, wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) the plant joint each sample's contact acts on (−1: none) and (N, 6) its wrench there (contacts.contact_force:
    the link-frame wrench moved into the joint's frame)."""
    joint = np.full(site_index.shape, -1, dtype=np.int64)
    force = np.zeros((site_index.size, 6))
    for c, site in enumerate(sites):
        at = site_index == c
        if not at.any():
            continue
        R, p = site.placement.rotation, site.placement.translation
        f = wrench[at, :3] @ R.T
        force[at, :3] = f
        force[at, 3:] = wrench[at, 3:] @ R.T + np.cross(p, f)
        joint[at] = site.joint_id
    return joint, force


def sensor_wrenches(plant: RigidBodyPlant, q: np.ndarray, v: np.ndarray, a: np.ndarray, site_index: np.ndarray,
                    wrench: np.ndarray, sites: list[BodySite], gravity: np.ndarray | None):
    """`RigidBodyPlant.sensor_wrenches` through the kernel, or None where the Python reference runs."""
    native = kernels.native()
    if native is None:
        return None
    placement = lambda m: m.rotation.ravel().tolist() + m.translation.tolist()  # noqa: E731
    names = [s.name for s in plant.sensors]
    site_list = [(s.joint_id, placement(s.placement), names.index(s.sensor) if s.sensor in names else -1) for s in sites]
    mounts = [(s.joint_id, placement(s.placement), s.distal_inertia.toDynamicParameters().tolist(),
               list(s.child_joints)) for s in plant.sensors]
    distal = np.array([[plant.side_of(site, s.name) == "distal" for s in plant.sensors] for site in sites],
                      dtype=bool).reshape(len(sites), len(plant.sensors))
    n = q.shape[0]
    measured, from_contact = np.empty((n, len(names), 6)), np.empty((n, len(names), 6))
    tau_contact = np.empty((n, plant.nv))
    native.sensor_wrenches(plant.model.saveToString(), site_list, mounts, np.ascontiguousarray(distal), _c(q), _c(v),
                           _c(a), np.ascontiguousarray(site_index, dtype=np.int64), _c(wrench),
                           None if gravity is None else _c(gravity), measured, from_contact, tau_contact)
    return ({s: measured[:, i] for i, s in enumerate(names)}, {s: from_contact[:, i] for i, s in enumerate(names)},
            tau_contact)
