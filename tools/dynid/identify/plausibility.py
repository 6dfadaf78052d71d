"""Warnings for physically implausible estimates: a negative mass, an inertia that no body has, a centre of mass far
outside its link.

The fit's full parameter vector Φ̂ reproduces the identified base parameters; the directions the data do not see
keep the CAD values. Nothing in the regression keeps each body physical, so a real run can return a link of
−6.1 kg. These checks say so in the output and the JSON instead of passing it on silently:

- mass ≤ 0;
- the rotational inertia about the centre of mass not positive definite, or violating the triangle inequality
  (I₁ + I₂ ≥ I₃): equivalently, the pseudo-inertia J = [[½ tr(I)·1 − I, h], [hᵀ, m]] (Wensing, Kim and Slotine,
  RA-L 2018) is not positive definite;
- the centre of mass farther from the body's frame than 1.5 × the link's extent + 5 cm, the extent being the
  farthest of its child joints, its fixed frames and its CAD centre of mass;
- a joint's or motor's friction coefficient (fc±, fv±) negative: friction that feeds energy into the motion (the
  consistent fit bounds them at 0; the monitor evaluates what the file holds).

Listed first, two checks of gravity's direction, which every fit determines best: the mass beyond each F/T sensor,
and the joints' gravity torques against the CAD's over postures within the joints' limits (a robot without an F/T
sensor too).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..robot.model import RobotModel
from ..robot.regressors.rigid_body import rigid_body_regressors

COM_MARGIN_FACTOR = 1.5
COM_MARGIN_M = 0.05
FRICTION_TOLERANCE = 1e-6  # Nm, Nm s/rad: below a solver's rounding of a bound at 0, far below any real friction
# Gravity torques opposite to the CAD's: a least-squares slope of the fitted on the CAD's under 0 with a correlation
# under this. Fits under the right gravity: slope 0.89-1.31, correlation 0.96-1.00 (the simulated arm, the UR10e
# alone and from its pair, the Panda, TIAGo, the iCub leg, unconstrained and consistent: their docs/robots fits);
# the UR10e and the Panda given +z: slopes −0.89 and −0.93, correlations −1.00
# (tools/benchmarks/plausibility_figures.py).
GRAVITY_CORRELATION = -0.5
GRAVITY_POSTURES = 256
# A body's mass this many times its CAD's, and this much heavier: not a mass the data determined. Physical, so not
# implausible; said apart (the consistent fit puts what the data leave free where its constraints cost the fit least:
# the simulated arm's shoulders at 9-29 kg, their CAD 0.12-0.36 kg; the Panda's link2 at 108 kg, CAD 0.65 kg)
MASS_RATIO = 5.0
MASS_EXCESS_KG = 1.0


def inertia_about_com(phi_body: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(m, c, I_c) of one body's 10 parameters (Pinocchio's order: m, mc, Ixx, Ixy, Iyy, Ixz, Iyz, Izz at the
    frame's origin); c and I_c are NaN for m ≤ 0."""
    m, h = float(phi_body[0]), np.asarray(phi_body[1:4], float)
    ixx, ixy, iyy, ixz, iyz, izz = phi_body[4:10]
    i_o = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], float)
    if m <= 0:
        return m, np.full(3, np.nan), np.full((3, 3), np.nan)
    c = h / m
    i_c = i_o - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))  # parallel axis theorem
    return m, c, i_c


def link_extent(model: RobotModel, body: int) -> float:
    """How far the link reaches from its frame: its child joints, fixed frames and CAD centre of mass (m)."""
    m = model.pin_model
    jid = model.bodies[body].joint_id
    reach = [float(np.linalg.norm(m.jointPlacements[j].translation)) for j in range(1, m.njoints) if m.parents[j] == jid]
    reach += [float(np.linalg.norm(f.placement.translation)) for f in m.frames if f.parentJoint == jid]
    reach.append(float(np.linalg.norm(model.cad_inertial_parameters[10 * body + 1 : 10 * body + 4]))
                 / max(float(model.cad_inertial_parameters[10 * body]), 1e-9))
    return max(reach)


def implausible(model: RobotModel, phi: np.ndarray) -> list[dict[str, Any]]:
    """One entry per problem found in the inertial part of Φ̂: body, problem, and the figures behind it."""
    found: list[dict[str, Any]] = []
    inertial = np.asarray(phi, float)[model.layout.span("inertial")]
    for k, body in enumerate(model.bodies):
        mass, c, i_c = inertia_about_com(inertial[10 * k : 10 * k + 10])
        if not mass > 0:
            found.append({"body": body.name, "problem": "mass", "mass_kg": mass,
                          "text": f"{body.name}: mass {mass:.3g} kg"})
            continue
        eig = np.linalg.eigvalsh(i_c)
        if eig[0] <= 0 or eig[0] + eig[1] < eig[2]:
            what = "not positive definite" if eig[0] <= 0 else "breaks the triangle inequality (I1 + I2 < I3)"
            found.append({"body": body.name, "problem": "inertia", "principal_moments_kgm2": eig.tolist(),
                          "text": f"{body.name}: inertia about the centre of mass {what}: principal moments "
                                  + ", ".join(f"{e:.3g}" for e in eig) + " kg m²"})
        distance, extent = float(np.linalg.norm(c)), link_extent(model, k)
        if distance > COM_MARGIN_FACTOR * extent + COM_MARGIN_M:
            found.append({"body": body.name, "problem": "com", "distance_m": distance, "extent_m": extent,
                          "text": f"{body.name}: centre of mass {distance:.3g} m from its frame, the link reaches "
                                  f"{extent:.3g} m"})
    cad = model.cad_inertial_parameters
    for f in found:  # a body the data leave at its CAD values: the URDF's own figures, not an estimate
        k = next(i for i, b in enumerate(model.bodies) if b.name == f["body"])
        if np.array_equal(inertial[10 * k : 10 * k + 10], cad[10 * k : 10 * k + 10]):
            f["urdf_values"] = True
            f["text"] += " (the URDF's own values: the data leave this body at its CAD)"
    return distal_masses(model, phi) + gravity_torques(model, phi) + found + negative_friction(model, phi)


def distal_masses(model: RobotModel, phi: np.ndarray) -> list[dict[str, Any]]:
    """One entry per F/T sensor whose fitted mass beyond it is not positive while its CAD's is: that total is what the
    sensor weighs at rest, which its forces fix whatever the bodies one by one (a base combination), so a negative
    one is gravity given the wrong way (the iCub leg with gravity +z: three bodies' masses negative), or the forces'
    sign."""
    m = model.pin_model
    inertial = np.asarray(phi, float)[model.layout.span("inertial")]
    cad = model.cad_inertial_parameters
    found: list[dict[str, Any]] = []
    for sensor, jid in model.sensor_joint_ids.items():
        beyond = [k for k, b in enumerate(model.bodies) if b.joint_id in set(m.subtrees[jid])]
        fitted, own = (float(sum(x[10 * k] for k in beyond)) for x in (inertial, cad))
        if own > 0 and not fitted > 0:
            found.append({"sensor": sensor, "problem": "distal_mass", "mass_kg": fitted, "cad_kg": own,
                          "text": f"the mass beyond ft.{sensor} fits {fitted:.3g} kg (its CAD {own:.3g} kg), which "
                                  "its forces at rest fix: is gravity's direction in the configuration right, the "
                                  "forces' sign, and the sensor's joint (its frame)?"})
    return found


def masses_far_from_cad(model: RobotModel, phi: np.ndarray) -> list[dict[str, Any]]:
    """One entry per body whose fitted mass exceeds MASS_RATIO times its CAD's and its CAD's by MASS_EXCESS_KG: the
    data rarely fix a body's mass alone, and a full set that puts tens of kilograms on a shoulder reproduces the base
    parameters as well as CAD's does. Not `implausible` (such a body can exist), but not to be read as measured."""
    cad = model.cad_inertial_parameters
    inertial = np.asarray(phi, float)[model.layout.span("inertial")]
    found = []
    for k, body in enumerate(model.bodies):
        mass, own = float(inertial[10 * k]), float(cad[10 * k])
        if own > 0 and mass > MASS_RATIO * own and mass - own > MASS_EXCESS_KG:
            found.append({"body": body.name, "problem": "mass_far_from_cad", "mass_kg": mass, "cad_kg": own,
                          "text": f"{body.name}: mass {mass:.3g} kg, {mass / own:.0f} times its CAD {own:.3g} kg"})
    return found


def gravity_torques(model: RobotModel, phi: np.ndarray, seed: int = 0) -> list[dict[str, Any]]:
    """One entry when the fitted Φ's gravity torques run against the CAD's over postures within the joints' limits
    (each one ±π where unbounded): what a fit on joint torques, currents or PWM gives with gravity given the wrong
    way, or the inputs' sign turned, since the data fix the torques, not gravity's direction. Not for gravity measured
    per sample (`gravity.imu`), where the configuration's direction is not what the fit used."""
    if model.config.gravity_imu:
        return []
    agreement = gravity_agreement(model, phi, seed)
    if agreement is None or not (agreement[0] < 0 and agreement[1] < GRAVITY_CORRELATION):
        return []
    slope, correlation = agreement
    return [{"problem": "gravity", "slope": slope, "correlation": correlation,
             "text": f"the fitted gravity torques run against the CAD's (slope {slope:.2f}, correlation "
                     f"{correlation:.2f} over {GRAVITY_POSTURES} postures within the joints' limits): is gravity's "
                     "direction in the configuration right, and the inputs' sign?"}]


def gravity_agreement(model: RobotModel, phi: np.ndarray, seed: int = 0) -> tuple[float, float] | None:
    """(slope, correlation) of the fitted Φ's gravity torques on the CAD's over GRAVITY_POSTURES postures drawn within
    the joints' limits (±π where unbounded), every joint's torque one point; None where either set is constant or the
    fitted one not finite."""
    lo, hi = (np.array([model.joint_limits[j][i] for j in model.config.joints]) for i in (0, 1))
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    q = np.random.default_rng(seed).uniform(lo, hi, (GRAVITY_POSTURES, len(lo)))
    Y = rigid_body_regressors(model, q, np.zeros_like(q), np.zeros_like(q)).tau  # (N, joints, 10 bodies)
    fitted = (Y @ np.asarray(phi, float)[model.layout.span("inertial")]).ravel()
    cad = (Y @ model.cad_inertial_parameters).ravel()
    if not np.all(np.isfinite(fitted)) or not np.std(cad) > 0 or not np.std(fitted) > 0:
        return None
    return float(fitted @ cad / (cad @ cad)), float(np.corrcoef(fitted, cad)[0, 1])


def negative_friction(model: RobotModel, phi: np.ndarray) -> list[dict[str, Any]]:
    """One entry per joint or motor with a negative friction coefficient: which, and the coefficients."""
    found: list[dict[str, Any]] = []
    for kind, who in (("joint_friction", "joint"), ("motor_friction", "motor")):
        for block in model.layout.blocks_of(kind):
            values = np.asarray(phi, float)[block.slice]
            negative = {name.rsplit(".", 1)[1]: float(v) for name, v in zip(block.names, values)
                        if v < -FRICTION_TOLERANCE}
            if negative:
                found.append({who: block.owner, "problem": "friction", "negative": negative,
                              "text": f"{block.owner}: negative friction "
                                      + ", ".join(f"{k} {v:.3g}" for k, v in negative.items())
                                      + " (it would drive the motion, not damp it)"})
    return found
