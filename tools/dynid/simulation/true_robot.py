"""The true robot behind a simulation: one physical arm, drawn once per robot seed, never the CAD model.

What differs from the CAD model and the configuration's nominal values, and by how much (uniform draws):

- every body: mass ×[0.9, 1.1]; centre of mass moved up to 5 mm per axis; principal moments about the centre
  of mass ×[0.85, 1.15] each and the principal axes turned by up to 5° (redrawn until physically consistent);
- cables: a point mass of 2–5 % of each body's mass plus 5 g, within 2 cm of its centre of mass;
- F/T offsets: up to 5 % of the sensor's full scale per channel (10 N / 0.5 Nm without a CAN full scale);
- motor gains: nominal ×[0.85, 1.15];
- joint friction (all four coefficients drawn independently, hence asymmetric): Coulomb 5–12 % and viscous
  3–8 % per rad/s of the joint's load scale, the RMS CAD gravity torque over random postures;
- motor friction, in joint-scale motor coordinates: Coulomb 0.4–1 % and viscous 0.3–0.8 % per rad/s of the
  motor's nominal gain; back-EMF damping 0.4–0.8 % per rad/s of the nominal gain.

The model's true Φ (`parameters`) folds these as docs/design.md §3 does: cables into the bodies, back-EMF into the
viscous terms, and the motor friction of a directly driven joint into the joint's friction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..config.robot_config import RobotConfig
from ..robot.model import RobotModel
from ..robot.parameters import WRENCH_FIELDS

ROBOT_STREAM = 0x7255  # SeedSequence spawn key of the true-robot draws (independent of experiment draws)


@dataclass(frozen=True)
class Cable:
    link: str
    mass: float  # kg
    point: np.ndarray  # (3,) in the link frame, m


@dataclass
class TrueRobot:
    seed: int
    cad_inertias: list[pin.Inertia]  # per body of the identification layout
    inertias: list[pin.Inertia]  # perturbed, cables included
    cables: list[Cable]
    ft_offsets: dict[str, np.ndarray]  # sensor -> (6,)
    joint_friction: dict[str, np.ndarray]  # every configured joint -> (4,) [fc_pos, fc_neg, fv_pos, fv_neg]
    motor_friction: dict[str, np.ndarray]  # every motor -> (4,), motor side, joint-scale motor coordinates
    back_emf: dict[str, float]  # motor -> Nm per rad/s
    gains: dict[str, float]  # motor -> Nm per unit input, at nominal supply
    load_scale: dict[str, float]  # joint -> Nm, what the friction ranges scale with

    def parameters(self, model: RobotModel) -> dict[str, float]:
        """Φ of the identification model, by name (docs/design.md §3)."""
        cfg, layout = model.config, model.layout
        phi = np.full(len(layout), np.nan)
        phi[layout.span("inertial")] = np.concatenate([i.toDynamicParameters() for i in self.inertias])
        for s in layout.owners("ft_offset"):
            phi[layout.block("ft_offset", s).slice] = self.ft_offsets[s]
        for g in cfg.actuation:
            for j in g.joints:
                total = self.joint_friction[j].copy()
                if g.input != "torque" and not g.coupled:  # one motor per joint: its friction is the joint's
                    m = g.motors[g.joints.index(j)]
                    total += self.motor_friction[m] + self.back_emf[m] * np.array([0, 0, 1, 1])
                phi[layout.block("joint_friction", j).slice] = total
        for m in layout.owners("motor_friction"):
            phi[layout.block("motor_friction", m).slice] = self.motor_friction[m] + self.back_emf[m] * np.array([0, 0, 1, 1])
        for m in layout.owners("motor_gain"):
            phi[layout.block("motor_gain", m).start] = self.gains[m]
        return dict(zip(layout.names, phi.tolist()))

    def describe(self, model: RobotModel) -> dict:
        """The plant's own values that Φ folds together or leaves out (JSON-able)."""
        return {
            "seed": self.seed,
            "cables": [{"link": c.link, "mass_kg": c.mass, "point_m": c.point.tolist()} for c in self.cables],
            "joint_friction": {j: v.tolist() for j, v in self.joint_friction.items()},
            "motor_friction": {m: v.tolist() for m, v in self.motor_friction.items()},
            "back_emf": dict(self.back_emf),
            "load_scale_nm": dict(self.load_scale),
            "cad_mass_kg": {b.name: float(i.mass) for b, i in zip(model.bodies, self.cad_inertias)},
            "true_mass_kg": {b.name: float(i.mass) for b, i in zip(model.bodies, self.inertias)},
        }


def _perturbed_inertia(inertia: pin.Inertia, rng: np.random.Generator) -> pin.Inertia:
    mass_factor = rng.uniform(0.9, 1.1)
    com = inertia.lever + rng.uniform(-0.005, 0.005, 3)
    moments, axes = np.linalg.eigh(inertia.inertia)  # about the centre of mass
    for _ in range(50):
        scaled = moments * mass_factor * rng.uniform(0.85, 1.15, 3)
        a, b, c = scaled
        if a + b > c and a + c > b and b + c > a:
            break
    else:  # a flat body that no draw keeps consistent: scale it uniformly
        scaled = moments * mass_factor
    turn = pin.exp3(rng.normal(size=3) / np.sqrt(3) * np.deg2rad(5.0) * rng.uniform())
    R = turn @ axes
    return pin.Inertia(inertia.mass * mass_factor, com, R @ np.diag(scaled) @ R.T)


def _load_scale(model: RobotModel, rng: np.random.Generator, samples: int = 200) -> np.ndarray:
    """RMS of each joint's CAD gravity torque over random postures within the limits (with a small floor)."""
    m = model.pin_model
    data = m.createData()
    lo, hi = np.array([model.joint_limits[j] for j in model.config.joints]).T
    q_joint = rng.uniform(lo, hi, size=(samples, len(lo)))
    g = np.array([pin.computeGeneralizedGravity(m, data, q)[model.v_index] for q in model.pinocchio_configuration(q_joint)])
    rms = np.sqrt(np.mean(g**2, axis=0))
    return np.maximum(rms, 0.02 * rms.max())


def draw_true_robot(model: RobotModel, seed: int) -> TrueRobot:
    """The one true arm for `seed`: the same for every experiment kind run with it."""
    cfg: RobotConfig = model.config
    rng = np.random.default_rng(np.random.SeedSequence([seed, ROBOT_STREAM]))
    cad = [model.pin_model.inertias[b.joint_id].copy() for b in model.bodies]
    inertias, cables = [], []
    for body, inertia in zip(model.bodies, cad):
        true = _perturbed_inertia(inertia, rng)
        cable_mass = float(rng.uniform(0.02, 0.05) * inertia.mass + 0.005)
        point = true.lever + rng.uniform(-0.02, 0.02, 3)
        cables.append(Cable(body.name, cable_mass, point))
        inertias.append(true + pin.Inertia(cable_mass, point, np.zeros((3, 3))))

    full_scale = {s["sensor"]: np.asarray(s["full_scale"], float) for s in cfg.can.get("strain", [])}
    offsets = {}
    for s in cfg.ft_sensors:
        fs = full_scale.get(s.name, np.array([200.0] * 3 + [10.0] * 3))
        offsets[s.name] = rng.uniform(-0.05, 0.05, len(WRENCH_FIELDS)) * fs

    scale = _load_scale(model, rng)
    joint_friction = {
        j: np.concatenate([rng.uniform(0.05, 0.12, 2), rng.uniform(0.03, 0.08, 2)]) * scale[i]
        for i, j in enumerate(cfg.joints)
    }
    motor_friction, back_emf, gains = {}, {}, {}
    for mc in cfg.motors:
        nominal = mc.known_gain or mc.nominal_gain
        motor_friction[mc.name] = np.concatenate([rng.uniform(0.004, 0.010, 2), rng.uniform(0.003, 0.008, 2)]) * nominal
        back_emf[mc.name] = float(rng.uniform(0.004, 0.008) * nominal)
        gains[mc.name] = float(mc.known_gain if mc.known_gain is not None else nominal * rng.uniform(0.85, 1.15))
    return TrueRobot(
        seed=seed,
        cad_inertias=cad,
        inertias=inertias,
        cables=cables,
        ft_offsets=offsets,
        joint_friction=joint_friction,
        motor_friction=motor_friction,
        back_emf=back_emf,
        gains=gains,
        load_scale=dict(zip(cfg.joints, scale.tolist())),
    )
