"""The simulated arm's rigid bodies: a Pinocchio model of its own, forward dynamics, and the F/T measurement.

The plant must not agree with the identification by construction, so it shares none of its shortcuts:

- The identification splits each F/T-sensor body with a 6-DoF joint and reads Y_FT from the joint-torque
  regressor. The plant builds a *separate* Pinocchio model in which the sensor is what it physically is, a rigid
  mount: the distal sub-body is welded onto the proximal joint's body, so the model has only the moving joints.
- It is integrated from CRBA and RNEA with the friction implicit (`step`): the stiff friction of the coupled
  motors and Coulomb sticking need the mass matrix, which ABA does not expose.
- The sensor wrench is measured by Newton–Euler on the distal side: the force that RNEA transmits into each
  moving joint beyond the sensor, plus the momentum rate of the distal sub-body, minus gravity and the contact
  forces acting on it, carried to the sensor frame.

Bodies carry the true inertia (perturbed CAD, cables, payloads), given per body of the identification layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv

from ..errors import ConfigError
from ..robot.model import RobotModel
from .actuation import FrictionStep

MAX_ACTIVE_SET_ITERATIONS = 12


def _friction(w: np.ndarray, law: FrictionStep) -> np.ndarray:
    """f(w), any shape (..., F): the sliding law outside the sticking band, its line inside."""
    return np.where(
        w > law.upper,
        law.coulomb_pos + law.viscous_pos * w,
        np.where(w < law.lower, -law.coulomb_neg + law.viscous_neg * w, law.band_slope * w),
    )


def _line_search(x: np.ndarray, d: np.ndarray, M: np.ndarray, base: np.ndarray, h: float, law: FrictionStep) -> float:
    """The exact minimiser t ∈ (0, 1] of the step's convex objective along x + t d.

    The objective's derivative along d is piecewise linear and increasing in t, with kinks where a friction
    coordinate crosses a band edge: evaluate it at every kink, then solve linearly within the bracketing piece.
    """
    w0, dw = law.S @ x, law.S @ d
    with np.errstate(divide="ignore", invalid="ignore"):
        kinks = np.concatenate([(law.upper - w0) / dw, (law.lower - w0) / dw])
    ts = np.unique(np.append(kinks[(kinks > 0) & (kinks < 1)], 1.0))
    a0, a1 = d @ (M @ x - base), d @ M @ d
    slope = a0 + ts * a1 + h * (_friction(w0 + ts[:, None] * dw, law) @ dw)
    first = int(np.argmax(slope >= 0)) if (slope >= 0).any() else len(ts)
    if first == len(ts):
        return 1.0
    t_lo = ts[first - 1] if first else 0.0
    g_lo = slope[first - 1] if first else a0 + h * (_friction(w0, law) @ dw)
    g_hi = slope[first]
    return float(t_lo + (ts[first] - t_lo) * (-g_lo) / (g_hi - g_lo)) if g_hi > g_lo else float(ts[first])


@dataclass(frozen=True)
class SensorMount:
    """Where an F/T sensor sits in the plant model."""

    name: str
    joint_id: int  # plant joint whose body carries the sensor (the proximal body)
    placement: pin.SE3  # sensor frame in that joint's frame
    distal_inertia: pin.Inertia  # the distal sub-body, about the sensor frame
    child_joints: tuple[int, ...]  # plant joints directly beyond the sensor


@dataclass(frozen=True)
class BodySite:
    """A link of the identification model, located in the plant: for contacts and payloads."""

    link: str
    joint_id: int  # plant joint that moves it
    placement: pin.SE3  # link frame in that joint's frame
    sensor: str | None  # the F/T sensor whose distal sub-body it is (None: a body of a moving joint)


class RigidBodyPlant:
    """The moving joints of the configured chain as one Pinocchio model, with the sensors as rigid mounts."""

    def __init__(self, robot: RobotModel, inertias: list[pin.Inertia], gravity: np.ndarray | None = None) -> None:
        src = robot.pin_model
        if any(src.nqs[j] != src.nvs[j] for j in robot.joint_ids):
            raise ConfigError(f"{robot.config.name}: the plant simulates revolute and prismatic joints only")
        if len(inertias) != len(robot.bodies):
            raise ValueError("one inertia per body of the identification layout")
        inertia_of = {b.joint_id: inertias[k] for k, b in enumerate(robot.bodies)}
        sensor_of_joint = {jid: name for name, jid in robot.sensor_joint_ids.items()}

        m = pin.Model()
        m.name = f"{robot.config.name}-plant"
        # anchor[src joint] = (plant joint that carries its frame, that frame in the plant joint's frame)
        anchor: dict[int, tuple[int, pin.SE3]] = {0: (0, pin.SE3.Identity())}
        new_id: dict[int, int] = {}
        mounts: dict[str, dict] = {}
        sites: list[BodySite] = []
        for jid in range(1, src.njoints):
            parent, offset = anchor[src.parents[jid]]
            placement = offset * src.jointPlacements[jid]
            link = next(b.name for b in robot.bodies if b.joint_id == jid)
            if jid in sensor_of_joint:
                anchor[jid] = (parent, placement)
                m.appendBodyToJoint(parent, inertia_of[jid], placement)  # the distal sub-body, welded on
                name = sensor_of_joint[jid]
                mounts[name] = {"joint_id": parent, "placement": placement, "inertia": inertia_of[jid], "children": []}
                sites.append(BodySite(link, parent, placement, name))
                continue
            nid = m.addJoint(parent, src.joints[jid], placement, src.names[jid])
            m.appendBodyToJoint(nid, inertia_of[jid], pin.SE3.Identity())
            new_id[jid], anchor[jid] = nid, (nid, pin.SE3.Identity())
            sites.append(BodySite(link, nid, pin.SE3.Identity(), None))
            if src.parents[jid] in sensor_of_joint:
                mounts[sensor_of_joint[src.parents[jid]]]["children"].append(nid)
        for f in src.frames:  # every frame of the chain (skin patches, the hand's frame ...) under its new joint
            if f.parentJoint == 0 or f.type == pin.FrameType.JOINT:
                continue
            parent, offset = anchor[f.parentJoint]
            m.addFrame(pin.Frame(f.name, parent, offset * f.placement, pin.FrameType.OP_FRAME))
        m.gravity = pin.Motion(np.asarray(robot.config.gravity if gravity is None else gravity, float), np.zeros(3))

        self.model = m
        self.data = m.createData()
        self._rnea_data = m.createData()
        self._zero = np.zeros(m.nv)
        self.unconverged_steps = 0
        self.joints = robot.config.joints
        self.v_index = np.array([m.idx_vs[new_id[j]] for j in robot.joint_ids])
        if not np.array_equal(self.v_index, np.arange(len(self.joints))):
            raise ConfigError(f"{robot.config.name}: the plant needs 'joints' listed in kinematic order (parents first)")
        self.sensors = tuple(
            SensorMount(n, d["joint_id"], d["placement"], d["inertia"], tuple(d["children"])) for n, d in mounts.items()
        )
        self.sites = {s.link: s for s in sites}
        self.distal_joints = {s.name: self._subtree(s.child_joints) for s in self.sensors}

    def _subtree(self, roots: tuple[int, ...]) -> frozenset[int]:
        out = set(roots)
        for j in range(1, self.model.njoints):
            if self.model.parents[j] in out:
                out.add(j)
        return frozenset(out)

    @property
    def nv(self) -> int:
        return self.model.nv

    def side_of(self, site: BodySite, sensor: str) -> str:
        """'distal' if a force on this body passes through the sensor, else 'proximal'."""
        if site.sensor == sensor or site.joint_id in self.distal_joints[sensor]:
            return "distal"
        return "proximal"

    # ------------------------------------------------------------------------------------------------------
    # Dynamics

    def gravity_torque(self, q: np.ndarray) -> np.ndarray:
        return pin.computeGeneralizedGravity(self.model, self.data, q)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        return pin.crba(self.model, self.data, q).copy()  # Pinocchio ≥ 3 fills both triangles

    def step(
        self,
        q: np.ndarray,
        v: np.ndarray,
        tau0: np.ndarray,
        law: FrictionStep,
        h: float,
        fext: pin.StdVec_Force | None,
        armature: np.ndarray | None,
        mode: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One step of semi-implicit Euler with implicit friction; returns (q̇ after the step, q̈ of the step).

        Solves ``M(q) (v⁺ − v)/h + b(q, v) = τ_0 − Sᵀ f(S v⁺)`` for v⁺, friction evaluated at the *new*
        velocity: stiff viscous friction and back-EMF (amplified by the coupling on light bodies) stay stable
        at 1 kHz, and Coulomb friction sticks instead of chattering. f is the sliding law c±, v± outside a
        sticking band |w| < ε (ε = 1e-4 rad/s), linear through zero inside it: a creep far below the encoder
        step, where the real arm would be stuck. The piecewise-linear monotone equation is solved by an active
        set (`mode`: +1 sliding up, −1 down, 0 stuck, updated in place; usually one linear solve).
        """
        M = pin.crba(self.model, self.data, q)
        if armature is not None:
            M = M + armature
        zero = self._zero
        bias = pin.rnea(self.model, self._rnea_data, q, v, zero) if fext is None else pin.rnea(
            self.model, self._rnea_data, q, v, zero, fext
        )
        base = M @ v + h * (tau0 - bias)
        S, St, k, upper, lower = law.S, law.St, law.band_slope, law.upper, law.lower
        # Newton on a piecewise-quadratic convex objective, ½ xᵀMx − baseᵀx + h Σ φ(Sx) with φ' = f, whose
        # minimiser is the step's solution: the quadratic of the current pieces is minimised exactly; if the
        # minimiser stays in those pieces it is the solution, else an exact line search moves toward it.
        x = v
        mode[:] = (S @ x > upper).view(np.int8) - (S @ x < lower).view(np.int8)
        for _ in range(MAX_ACTIVE_SET_ITERATIONS):
            up, down = mode > 0, mode < 0
            slope = np.where(up, law.viscous_pos, np.where(down, law.viscous_neg, k))
            offset = law.coulomb_pos * up - law.coulomb_neg * down  # f = offset + slope·w when sliding
            _, x_newton, info = dposv(M + h * (St * slope) @ S, base - h * (St @ offset))
            if info:
                raise RuntimeError("the plant's mass matrix is not positive definite: check the inertias")
            w = S @ x_newton
            new_mode = (w > upper).view(np.int8) - (w < lower).view(np.int8)
            if (new_mode == mode).all():
                x = x_newton
                break
            d = x_newton - x
            x = x + _line_search(x, d, M, base, h, law) * d
            w = S @ x
            mode[:] = (w > upper).view(np.int8) - (w < lower).view(np.int8)
        else:
            self.unconverged_steps += 1
        v_next = x
        return v_next, (v_next - v) / h

    # ------------------------------------------------------------------------------------------------------
    # F/T measurement

    def sensor_wrenches(
        self,
        q: np.ndarray,
        v: np.ndarray,
        a: np.ndarray,
        contact_site: np.ndarray,
        contact_wrench: np.ndarray,
        sites: list[BodySite],
        gravity: np.ndarray | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], np.ndarray]:
        """Measure every sample of a trajectory (`gravity` (N, 3): per sample, for a tilting base).

        `contact_site[k]` indexes `sites` (−1: no contact); `contact_wrench[k]` is the contact wrench on that
        site's link, in the link frame, about its origin. Returns, per sensor, the wrench it measures (distal
        on proximal, sensor frame, (N, 6) [f, τ]) and the part of it the contact adds; and the joint torques
        the contact adds, Jᵀ f (N, nv).
        """
        m, data = self.model, self._rnea_data
        n = q.shape[0]
        measured = {s.name: np.zeros((n, 6)) for s in self.sensors}
        from_contact = {s.name: np.zeros((n, 6)) for s in self.sensors}
        tau_contact = np.zeros((n, m.nv))
        fext = pin.StdVec_Force()
        for _ in range(m.njoints):
            fext.append(pin.Force.Zero())
        for k in range(n):
            if gravity is not None:
                m.gravity = pin.Motion(gravity[k], np.zeros(3))
            c = int(contact_site[k])
            if c >= 0:
                site = sites[c]
                f_link = pin.Force(contact_wrench[k])
                tau_free = pin.rnea(m, data, q[k], v[k], a[k]).copy()
                fext[site.joint_id] = site.placement.act(f_link)
                tau_contact[k] = tau_free - pin.rnea(m, data, q[k], v[k], a[k], fext)
                fext[site.joint_id] = pin.Force.Zero()
            else:
                pin.rnea(m, data, q[k], v[k], a[k])
            for s in self.sensors:
                # What the proximal side transmits into the distal side, in the proximal joint's frame.
                sub = s.placement.act(s.distal_inertia)
                va, aa = data.v[s.joint_id], data.a_gf[s.joint_id]
                f = sub * aa + va.cross(sub * va)
                for child in s.child_joints:
                    f += data.liMi[child].act(data.f[child])
                if c >= 0 and sites[c].sensor == s.name:
                    f -= sites[c].placement.act(f_link)
                measured[s.name][k] = -s.placement.actInv(f).vector
                if c >= 0 and self.side_of(sites[c], s.name) == "distal":
                    anchor_M_link = sites[c].placement
                    j = sites[c].joint_id
                    while j != s.joint_id:  # RNEA updates liMi (not oMi): walk up to the sensor's body
                        anchor_M_link = data.liMi[j] * anchor_M_link
                        j = m.parents[j]
                    sensor_M_link = s.placement.actInv(anchor_M_link)
                    from_contact[s.name][k] = sensor_M_link.act(f_link).vector
        return measured, from_contact, tau_contact
