"""Reference F/T-sensor measurement and joint torques of a fixed-base arm, computed with iDynTree only.

This module is an *independent* oracle for the Pinocchio-based regressors of ``dynid``: it must not import
Pinocchio nor anything from ``dynid``.  Everything here goes through iDynTree (``idyntree.swig``).

Conventions (read this before comparing anything against it)
-------------------------------------------------------------
* Wrenches are 6-vectors ``[fx, fy, fz, tx, ty, tz]`` (force first, iDynTree's ``Wrench`` layout).
* The expected F/T measurement returned by :func:`idyntree_expected_ft_and_torques` is exactly what
  iDynTree's ``ExtWrenchesAndJointTorquesEstimator.computeExpectedFTSensorsMeasurements`` predicts for the
  sensor, i.e. it follows the sensor's URDF tags.  For the iCub sensors
  (``<frame>child</frame>``, ``<measure_direction>child_to_parent</measure_direction>``) this is:

      **the wrench that the child (distal) sub-body exerts on the parent (proximal) sub-body,
      expressed in the sensor frame, torque taken about the sensor-frame origin;
      the sensor frame is the child-link frame** (``r_upper_arm`` for ``r_arm_ft``).

  Why (iDynTree source, ``src/model_io/urdf/src/ForceTorqueSensorElement.cpp`` and
  ``src/sensors/src/SixAxisForceTorqueSensor.cpp``):

  - the URDF parser maps ``measure_direction=child_to_parent`` to ``setAppliedWrenchLink(parentLink)``: the
    measured wrench is the one *applied on the parent link* (hence exerted by the child), and
    ``parent_to_child`` to ``setAppliedWrenchLink(childLink)``;
  - ``<frame>child</frame>`` sets ``child_link_H_sensor = Identity`` and
    ``parent_link_H_sensor = parent_link_H_child_link`` (the sensor ``<origin>`` is then *ignored*; for the
    iCub it coincides with the joint origin anyway, up to 1e-16);
  - ``SixAxisForceTorqueSensor::predictMeasurement`` returns
    ``-(sensor_X_child * f[child])`` when the applied-wrench link is the parent, where ``f[child]`` is the
    RNEA internal wrench of the child link, which in iDynTree (Featherstone eq. 5.20 in
    ``RNEADynamicPhase``; see also the doc of ``KinDynComputations::inverseDynamicsWithInternalJointForceTorques``)
    is the wrench the *parent exerts on the child*.  Minus that is the wrench the child exerts on the parent.

  Physical sanity check (tested in ``test_idyntree_ft_selfcheck.py``): at rest, the force part equals
  ``m_distal * g`` (the distal part's weight pulls the proximal part along gravity) and the torque part equals
  ``c_distal x (m_distal * g)``, everything in the sensor frame.
  This is the ``w_s`` of docs/design.md §3, and equals minus Pinocchio's ``data.f`` at a joint placed at the
  sensor (if that joint's frame is the sensor frame).

* Joint torques ``tau`` are the inverse-dynamics torques (no friction, no motor model, no external wrench but
  the one on the fixed base), in the order of the ``joints`` argument, from
  ``KinDynComputations.inverseDynamics`` with the base held fixed (zero base twist and acceleration).

* Gravity: the ``gravity`` argument is the gravity *acceleration* vector (e.g. pointing down, norm 9.81),
  **expressed in the base_link frame**.  For iCubGenova04 the world gravity ``(0, 0, -9.81)`` is given in
  ``root_link``; with the torso at zero, use ``gravity_in_link(urdf, "chest")`` to express it in ``chest``.

* Model: ``ModelLoader.loadReducedModelFromFile`` with ``joints + [the fixed joint that carries the sensor]``.
  All other joints of the URDF are fixed at 0 and their links are lumped.  NB: if the sensor's fixed joint is
  *not* listed, iDynTree lumps the two sides of the sensor together and silently drops the sensor (0 F/T
  sensors in the reduced model) -- that is why the sensor joint is added automatically here.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import idyntree.swig as idt
import numpy as np

__all__ = [
    "idyntree_expected_ft_and_torques",
    "idyntree_estimator_torques",
    "gravity_in_link",
    "ft_sensor_info",
    "sensor_frame_in_child_link",
    "FTSensorInfo",
]


# --------------------------------------------------------------------------------------------- helpers


def _transform_to_np(T: "idt.Transform") -> np.ndarray:
    """iDynTree Transform -> 4x4 homogeneous matrix."""
    return np.asarray(T.asHomogeneousTransform().toNumPy(), dtype=float).reshape(4, 4)


def _load_full_model(urdf_path: str) -> "idt.Model":
    ml = idt.ModelLoader()
    if not ml.loadModelFromFile(str(urdf_path)):
        raise RuntimeError(f"iDynTree could not load {urdf_path}")
    return ml.model().copy()


def _find_ft_sensor(model: "idt.Model", ft_sensor: str) -> "idt.SixAxisForceTorqueSensor":
    sensors = model.sensors()
    idx = sensors.getSensorIndex(idt.SIX_AXIS_FORCE_TORQUE, ft_sensor)
    if idx < 0:
        raise KeyError(f"no six-axis F/T sensor named {ft_sensor!r} in the model")
    return sensors.getSixAxisForceTorqueSensor(idx)


@dataclass(frozen=True)
class FTSensorInfo:
    """What iDynTree made of a URDF ``<sensor type="force_torque">`` (from the full model, zero joints).

    Attributes
    ----------
    name : sensor name.
    joint : the fixed joint the sensor is attached to.
    parent_link, child_link : the two links the joint connects (URDF parent / child).
    applied_wrench_link : the link the *measured* wrench is applied on.  ``parent_link`` for
        ``child_to_parent`` (measured = wrench exerted by child on parent), ``child_link`` for
        ``parent_to_child``.
    child_H_sensor, parent_H_sensor : 4x4 placements of the sensor frame in the child / parent link frames.
    """

    name: str
    joint: str
    parent_link: str
    child_link: str
    applied_wrench_link: str
    child_H_sensor: np.ndarray
    parent_H_sensor: np.ndarray

    @property
    def measures_child_on_parent(self) -> bool:
        return self.applied_wrench_link == self.parent_link


@lru_cache(maxsize=None)
def _ft_sensor_info_cached(urdf_path: str, ft_sensor: str) -> FTSensorInfo:
    model = _load_full_model(urdf_path)
    s = _find_ft_sensor(model, ft_sensor)
    joint = s.getParentJoint()
    jidx = model.getJointIndex(joint)
    j = model.getJoint(jidx)
    # URDF parent/child of the joint: iDynTree stores them as first/second attached link.
    parent = model.getLinkName(j.getFirstAttachedLink())
    child = model.getLinkName(j.getSecondAttachedLink())
    p_idx, c_idx = model.getLinkIndex(parent), model.getLinkIndex(child)
    c_H_s, p_H_s = idt.Transform(), idt.Transform()
    if not (s.getLinkSensorTransform(c_idx, c_H_s) and s.getLinkSensorTransform(p_idx, p_H_s)):
        raise RuntimeError(f"sensor {ft_sensor} is not attached to {parent}/{child}")
    return FTSensorInfo(
        name=ft_sensor,
        joint=joint,
        parent_link=parent,
        child_link=child,
        applied_wrench_link=model.getLinkName(s.getAppliedWrenchLink()),
        child_H_sensor=_transform_to_np(c_H_s),
        parent_H_sensor=_transform_to_np(p_H_s),
    )


def ft_sensor_info(urdf_path: str, ft_sensor: str) -> FTSensorInfo:
    """Describe the F/T sensor as iDynTree parsed it (joint, links, measure direction, sensor frame)."""
    return _ft_sensor_info_cached(str(urdf_path), ft_sensor)


def sensor_frame_in_child_link(urdf_path: str, ft_sensor: str) -> tuple[str, np.ndarray]:
    """Return ``(child_link_name, child_H_sensor)``: the sensor frame's placement in the child-link frame.

    For the iCub (``<frame>child</frame>``) this is ``("r_upper_arm", identity)`` for ``r_arm_ft``: the
    measured wrench is expressed in the r_upper_arm frame, about its origin.
    """
    info = ft_sensor_info(urdf_path, ft_sensor)
    return info.child_link, info.child_H_sensor.copy()


def gravity_in_link(
    urdf_path: str,
    link: str,
    world_link: str = "root_link",
    g: Sequence[float] = (0.0, 0.0, -9.81),
) -> np.ndarray:
    """Express the gravity vector ``g`` (given in ``world_link``'s frame) in ``link``'s frame.

    Uses iDynTree ``KinDynComputations.getRelativeTransform(link, world_link)`` (= ``link_H_world``) on the
    *full* model at zero joint positions:  ``g_link = link_R_world @ g``.
    """
    model = _load_full_model(str(urdf_path))
    kd = idt.KinDynComputations()
    if not kd.loadRobotModel(model):
        raise RuntimeError("KinDynComputations could not load the model")
    kd.setJointPos(idt.VectorDynSize.FromPython([0.0] * model.getNrOfPosCoords()))
    link_H_world = kd.getRelativeTransform(link, world_link)
    R = np.asarray(link_H_world.getRotation().toNumPy(), dtype=float).reshape(3, 3)
    return R @ np.asarray(g, dtype=float)


# ---------------------------------------------------------------------------------- reduced model


class _IDynTreeArm:
    """Reduced iDynTree model (joints + sensor joint) with an estimator and a KinDynComputations."""

    def __init__(self, urdf_path: str, joints: Sequence[str], base_link: str, ft_sensor: str):
        self.info = ft_sensor_info(urdf_path, ft_sensor)
        self.joints = list(joints)
        considered = self.joints + ([self.info.joint] if self.info.joint not in self.joints else [])

        ml = idt.ModelLoader()
        # Non-listed joints are fixed at their default (zero) position and their links lumped.
        if not ml.loadReducedModelFromFile(str(urdf_path), considered):
            raise RuntimeError("loadReducedModelFromFile failed")
        self.model = ml.model().copy()
        if self.model.getNrOfDOFs() != len(self.joints):
            raise RuntimeError(
                f"reduced model has {self.model.getNrOfDOFs()} DOFs, expected {len(self.joints)}"
            )

        # Permutation user order -> iDynTree DOF order.
        self.dof_of = np.array(
            [self.model.getJoint(self.model.getJointIndex(j)).getDOFsOffset() for j in self.joints], dtype=int
        )
        if sorted(self.dof_of.tolist()) != list(range(len(self.joints))):
            raise RuntimeError(f"unexpected DOF offsets {self.dof_of}")

        # Sensor in the reduced model.
        self.ft = _find_ft_sensor(self.model, ft_sensor)
        self.ft_idx = self.model.sensors().getSensorIndex(idt.SIX_AXIS_FORCE_TORQUE, ft_sensor)
        if self.model.getLinkName(self.ft.getAppliedWrenchLink()) != self.info.applied_wrench_link:
            raise RuntimeError("reduced model changed the sensor's measure direction")
        c_H_s = idt.Transform()
        self.ft.getLinkSensorTransform(self.model.getLinkIndex(self.info.child_link), c_H_s)
        if not np.allclose(_transform_to_np(c_H_s), self.info.child_H_sensor, atol=1e-12):
            raise RuntimeError("reduced model changed the sensor frame")

        # Base: may be a link or an additional frame (e.g. `chest` lumped into `root_link`).
        self.base_frame = self.model.getFrameIndex(base_link)
        if self.base_frame < 0:
            raise KeyError(f"base_link {base_link!r} is neither a link nor a frame of the reduced model")
        self.base_link_idx = self.model.getFrameLink(self.base_frame)

        # Estimator (fixed base at base_frame, one unknown full wrench at the base frame origin).
        self.est = idt.ExtWrenchesAndJointTorquesEstimator()
        if not self.est.setModel(self.model):
            raise RuntimeError("ExtWrenchesAndJointTorquesEstimator.setModel failed")
        self.unknowns = idt.LinkUnknownWrenchContacts(self.model)
        self.unknowns.addNewUnknownFullWrenchInFrameOrigin(self.model, self.base_frame)

        # KinDynComputations with floating base = the link holding base_frame, world frame = base_frame.
        self.kd = idt.KinDynComputations()
        if not self.kd.loadRobotModel(self.model):
            raise RuntimeError("KinDynComputations.loadRobotModel failed")
        self.kd.setFrameVelocityRepresentation(idt.BODY_FIXED_REPRESENTATION)
        self.kd.setFloatingBase(self.model.getLinkName(self.base_link_idx))
        # world_H_baselink = (baselink_H_baseframe)^-1, so that the world frame *is* the base_link frame.
        self.world_H_base = self.model.getFrameTransform(self.base_frame).inverse()
        self.child_link_idx = self.model.getLinkIndex(self.info.child_link)
        self.parent_link_idx = self.model.getLinkIndex(self.info.parent_link)

    # ---------------------------------------------------------------- per-sample primitives
    def _to_idt_order(self, x: np.ndarray) -> "idt.VectorDynSize":
        v = np.zeros(len(self.joints))
        v[self.dof_of] = np.asarray(x, dtype=float)
        return idt.VectorDynSize.FromPython(v.tolist())

    def _from_idt_order(self, v) -> np.ndarray:
        return np.asarray(v.toNumPy(), dtype=float).ravel()[self.dof_of]

    def estimator_sample(self, q, dq, ddq, gravity):
        """(expected FT wrench, estimator joint torques) for one sample."""
        ok = self.est.updateKinematicsFromFixedBase(
            self._to_idt_order(q), self._to_idt_order(dq), self._to_idt_order(ddq),
            self.base_frame, idt.Vector3.FromPython(np.asarray(gravity, dtype=float).tolist()),
        )
        if not ok:
            raise RuntimeError("updateKinematicsFromFixedBase failed")
        predicted = idt.SensorsMeasurements(self.model.sensors())
        contacts = idt.LinkContactWrenches(self.model)
        tau = idt.JointDOFsDoubleArray(self.model)
        if not self.est.computeExpectedFTSensorsMeasurements(self.unknowns, predicted, contacts, tau):
            raise RuntimeError("computeExpectedFTSensorsMeasurements failed")
        w = idt.Wrench()
        if not predicted.getMeasurement(idt.SIX_AXIS_FORCE_TORQUE, self.ft_idx, w):
            raise RuntimeError("could not read the predicted F/T measurement")
        return np.asarray(w.toNumPy(), dtype=float).ravel(), self._from_idt_order(tau)

    def kindyn_sample(self, q, dq, ddq, gravity):
        """(joint torques, internal wrench parent->child on the sensor's child link, body frame)."""
        ok = self.kd.setRobotState(
            self.world_H_base, self._to_idt_order(q), idt.Twist.Zero(), self._to_idt_order(dq),
            idt.Vector3.FromPython(np.asarray(gravity, dtype=float).tolist()),
        )
        if not ok:
            raise RuntimeError("setRobotState failed")
        gen = idt.FreeFloatingGeneralizedTorques(self.model)
        internal = idt.LinkWrenches(self.model)  # LinkInternalWrenches is a typedef of LinkWrenches
        base_acc = idt.Vector6.FromPython([0.0] * 6)
        ext = idt.LinkWrenches(self.model)
        ext.zero()
        if not self.kd.inverseDynamicsWithInternalJointForceTorques(
            base_acc, self._to_idt_order(ddq), ext, gen, internal
        ):
            raise RuntimeError("inverseDynamicsWithInternalJointForceTorques failed")
        f_child = np.asarray(internal(self.child_link_idx).toNumPy(), dtype=float).ravel()
        return self._from_idt_order(gen.jointTorques()), f_child


@lru_cache(maxsize=8)  # caches stateful iDynTree objects: fine for sequential tests, not thread-safe
def _arm(urdf_path: str, joints: tuple[str, ...], base_link: str, ft_sensor: str) -> _IDynTreeArm:
    return _IDynTreeArm(urdf_path, joints, base_link, ft_sensor)


def _check_inputs(joints, q, dq, ddq):
    n = len(joints)
    arrs = [np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, dq, ddq)]
    for a, name in zip(arrs, ("q", "dq", "ddq")):
        if a.ndim != 2 or a.shape[1] != n:
            raise ValueError(f"{name} must have shape (N, {n}), got {a.shape}")
    if not (arrs[0].shape == arrs[1].shape == arrs[2].shape):
        raise ValueError("q, dq, ddq must have the same shape")
    return arrs


# -------------------------------------------------------------------------------------- public API


def idyntree_expected_ft_and_torques(
    urdf_path: str,
    joints: list[str],
    base_link: str,
    ft_sensor: str,
    q: np.ndarray,
    dq: np.ndarray,
    ddq: np.ndarray,
    gravity: np.ndarray = np.array([0.0, 0.0, -9.81]),
) -> tuple[np.ndarray, np.ndarray]:
    """Expected 6-axis F/T measurement and inverse-dynamics joint torques of a fixed-base arm (iDynTree).

    Parameters
    ----------
    urdf_path : URDF file.
    joints : the moving joints, in this order (columns of q, dq, ddq and of the returned tau).
        All other joints of the URDF are fixed at 0.
    base_link : the world-fixed link (or frame), e.g. ``"chest"``.
    ft_sensor : URDF sensor name, e.g. ``"r_arm_ft"``.
    q, dq, ddq : (N, len(joints)) joint positions [rad], velocities [rad/s], accelerations [rad/s^2].
    gravity : gravity acceleration vector **expressed in the base_link frame** (see :func:`gravity_in_link`).
        The default ``(0, 0, -9.81)`` is only right if the base frame's z axis points up; for the iCub with
        ``base_link="chest"`` (torso at 0) pass ``gravity_in_link(urdf, "chest")`` = ``(0, -9.81, ~0)``.

    Returns
    -------
    ft : (N, 6) ``[fx fy fz tx ty tz]``, iDynTree's expected measurement of ``ft_sensor``.  For a
        ``child_to_parent`` / ``<frame>child</frame>`` sensor (the iCub ones) this is the wrench the child
        (distal) sub-body exerts on the parent (proximal) sub-body, expressed in the sensor frame = the child
        link frame (``r_upper_arm`` for ``r_arm_ft``), torque about its origin.  Use
        :func:`sensor_frame_in_child_link` / :func:`ft_sensor_info` to get the frame and direction.
    tau : (N, len(joints)) inverse-dynamics joint torques [Nm] (``KinDynComputations.inverseDynamics``,
        fixed base), in the order of ``joints``.
    """
    q, dq, ddq = _check_inputs(joints, q, dq, ddq)
    arm = _arm(str(urdf_path), tuple(joints), base_link, ft_sensor)
    N = q.shape[0]
    ft = np.empty((N, 6))
    tau = np.empty((N, len(joints)))
    for k in range(N):
        ft[k], _ = arm.estimator_sample(q[k], dq[k], ddq[k], gravity)
        tau[k], _ = arm.kindyn_sample(q[k], dq[k], ddq[k], gravity)
    return ft, tau


def idyntree_estimator_torques(
    urdf_path: str,
    joints: list[str],
    base_link: str,
    ft_sensor: str,
    q: np.ndarray,
    dq: np.ndarray,
    ddq: np.ndarray,
    gravity: np.ndarray = np.array([0.0, 0.0, -9.81]),
) -> dict[str, np.ndarray]:
    """Second, cross-checking iDynTree path (same arguments as :func:`idyntree_expected_ft_and_torques`).

    Returns a dict with
      * ``"tau_estimator"`` (N, n): torques from ``computeExpectedFTSensorsMeasurements``;
      * ``"tau_estimator_from_ft"`` (N, n): torques from ``estimateExtWrenchesAndJointTorques`` fed with the
        F/T measurements that the estimator has just predicted (closes the loop);
      * ``"ft_minus_internal"`` (N, 6): ``-(sensor_X_child f_{parent->child})`` from
        ``KinDynComputations.inverseDynamicsWithInternalJointForceTorques`` (body-fixed), i.e. the wrench the
        child exerts on the parent in the sensor frame, computed without the estimator.
    """
    q, dq, ddq = _check_inputs(joints, q, dq, ddq)
    arm = _arm(str(urdf_path), tuple(joints), base_link, ft_sensor)
    N, n = q.shape
    out = {
        "tau_estimator": np.empty((N, n)),
        "tau_estimator_from_ft": np.empty((N, n)),
        "ft_minus_internal": np.empty((N, 6)),
    }
    s_H_c = np.linalg.inv(arm.info.child_H_sensor)
    R, p = s_H_c[:3, :3], s_H_c[:3, 3]
    px = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    X_force = np.block([[R, np.zeros((3, 3))], [px @ R, R]])  # wrench transform child -> sensor frame
    for k in range(N):
        ft_k, tau_e = arm.estimator_sample(q[k], dq[k], ddq[k], gravity)
        out["tau_estimator"][k] = tau_e
        # Feed the predicted measurement back to the estimator.
        meas = idt.SensorsMeasurements(arm.model.sensors())
        meas.setMeasurement(idt.SIX_AXIS_FORCE_TORQUE, arm.ft_idx, idt.Wrench.FromPython(ft_k.tolist()))
        contacts = idt.LinkContactWrenches(arm.model)
        tau2 = idt.JointDOFsDoubleArray(arm.model)
        if not arm.est.estimateExtWrenchesAndJointTorques(arm.unknowns, meas, contacts, tau2):
            raise RuntimeError("estimateExtWrenchesAndJointTorques failed")
        out["tau_estimator_from_ft"][k] = arm._from_idt_order(tau2)
        _, f_child = arm.kindyn_sample(q[k], dq[k], ddq[k], gravity)
        out["ft_minus_internal"][k] = -(X_force @ f_child)
    return out
