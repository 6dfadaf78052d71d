"""The rigid-body model of a configured chain, built with Pinocchio.

Pinocchio merges fixed joints, so a body that holds an F/T sensor would come out as one body. We split it
instead: the sensor's fixed joint becomes a 6-DoF (free-flyer) joint that is always held at the identity.
It adds no motion, its body is the distal sub-body (expressed in the sensor frame, the child link frame), and
its six rows of the joint-torque regressor are the wrench the proximal part exerts on the distal part: the
negative of the sensor measurement in the child-to-parent convention of docs/design.md §3. One call of
`computeJointTorqueRegressor` per sample therefore yields both Y_τ and every Y_FT.

Every URDF joint that is not a configured moving joint or an F/T sensor is locked at zero (the iCub torso,
the hand's fingers, ...). The fixed base is the configuration's `base_link`: where it hangs above every moving
joint and sensor, the URDF is used as it is; anywhere else (a humanoid's stance sole), the tree is re-rooted
there first (reroot.py), and gravity is given in the base link's frame.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin

from ..config.robot_config import RobotConfig
from ..errors import ConfigError
from .parameters import ParameterLayout
from .reroot import path_to_root, reroot

_ONE_DOF = ("revolute", "continuous", "prismatic")
PAYLOAD_MASS_FACTOR = 10.0  # a known payload heavier than ten times the chain is refused as a typo
PAYLOAD_REACH_M = 2.0  # a payload's centre of mass farther than this and than the chain's reach is refused


@dataclass(frozen=True)
class Body:
    name: str  # the URDF link that carries the body frame
    joint_id: int  # Pinocchio joint of the reduced model that moves it
    moved_by: str  # that joint's name (a configured joint, or an F/T sensor joint for a distal sub-body)


LENGTH_UNITS = ("m", "mm")  # q's (and q̇'s, q̈'s per second) length units: a prismatic joint's; the rest are angles


def _check_joint_units(config: RobotConfig, prismatic: dict[str, bool]) -> None:
    """A log's joint columns (`columns:`, `files:`) in a unit of their joint's kind: an angle for a revolute joint, a
    length for a prismatic one (a walkthrough's TIAGo torso lift declared rad, taken as metres)."""
    declared = [(f"columns[{i}]", c) for i, c in enumerate(config.columns)]
    declared += [(f"files.{f.pattern}[{i}]", c) for f in config.files for i, c in enumerate(f.columns)]
    for field, c in declared:
        kind, _, joint = c.name.partition(".")
        if kind not in ("q", "dq", "ddq") or joint not in prismatic:
            continue
        length = c.unit.split("/")[0] in LENGTH_UNITS
        if length != prismatic[joint]:
            want = "a length (m, mm)" if prismatic[joint] else "an angle (rad, deg)"
            raise ConfigError(f"{config.name}: field '{field}' gives {c.name} in {c.unit}, but {joint} is "
                              f"{'prismatic' if prismatic[joint] else 'a revolute joint'} in {config.urdf.name}: its "
                              f"positions are {want}")


class RobotModel:
    """Pinocchio model of the configured chain, with the parameter layout and CAD parameters."""

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        try:
            tree = ET.parse(config.urdf)
        except ET.ParseError as e:  # named here: the CLI's fallback line did not say which file was not XML
            raise ConfigError(f"{config.name}: the URDF {config.urdf} is not XML: {e}") from None
        urdf_joints = {j.get("name"): j for j in tree.getroot().findall("joint")}
        urdf_links = {lk.get("name") for lk in tree.getroot().findall("link")}
        for j in config.joints:
            if j not in urdf_joints:
                raise ConfigError(f"{config.name}: field 'joints' names '{j}', which is not a joint of {config.urdf.name}")
            if urdf_joints[j].get("type") not in _ONE_DOF:
                raise ConfigError(
                    f"{config.name}: field 'joints' names '{j}', a {urdf_joints[j].get('type')} joint; "
                    "moving joints must be revolute, continuous or prismatic"
                )
        # per configured joint: prismatic (m, m/s) rather than revolute or continuous (rad, rad/s)
        self.prismatic: tuple[bool, ...] = tuple(urdf_joints[j].get("type") == "prismatic" for j in config.joints)
        _check_joint_units(config, dict(zip(config.joints, self.prismatic)))
        if config.base_link not in urdf_links:
            raise ConfigError(f"{config.name}: field 'base_link' names '{config.base_link}', not a link of {config.urdf.name}")
        for s in config.ft_sensors:
            joint = urdf_joints.get(s.joint)
            if joint is None or joint.get("type") != "fixed":
                raise ConfigError(
                    f"{config.name}: field 'ft_sensors' puts '{s.name}' at '{s.joint}', which is not a fixed joint "
                    f"of {config.urdf.name}"
                )
            self._check_sensor_tag(tree, config, s.name, s.joint)
        self.reversed_joints: tuple[str, ...] = ()  # joints turned over by re-rooting at base_link
        if not self._base_link_is_above(tree, config):
            tree, self.reversed_joints = reroot(tree, config.base_link)
            for s in config.ft_sensors:
                if s.joint in self.reversed_joints:
                    raise ConfigError(
                        f"{config.name}: field 'ft_sensors' puts '{s.name}' at '{s.joint}', between the base link "
                        f"'{config.base_link}' and the URDF's root: re-rooted there, the sensor's sides would swap; "
                        "choose a base link below the sensor, or leave the sensor out"
                    )
        urdf_joints = {j.get("name"): j for j in tree.getroot().findall("joint")}
        for s in config.ft_sensors:
            urdf_joints[s.joint].set("type", "floating")  # the split described in the module docstring

        full = pin.buildModelFromXML(ET.tostring(tree.getroot(), encoding="unicode"))
        keep = set(config.joints) | {s.joint for s in config.ft_sensors}
        lock = [i for i in range(1, full.njoints) if full.names[i] not in keep]
        self.pin_model: pin.Model = pin.buildReducedModel(full, lock, pin.neutral(full))
        self.pin_model.gravity = pin.Motion(np.asarray(config.gravity, float), np.zeros(3))
        m = self.pin_model

        # root <- accelerometer: gravity per sample is −R a (config.gravity_imu); the frame must not move
        self.imu_rotation: np.ndarray | None = None
        if config.gravity_imu:
            if not m.existFrame(config.gravity_imu):
                raise ConfigError(f"{config.name}: field 'gravity.imu' names '{config.gravity_imu}', not a frame of "
                                  f"{config.urdf.name}")
            frame = m.frames[m.getFrameId(config.gravity_imu)]
            if frame.parentJoint != 0:
                raise ConfigError(f"{config.name}: field 'gravity.imu' names '{config.gravity_imu}', which a moving "
                                  "joint carries: the accelerometer must be fixed to the base")
            self.imu_rotation = frame.placement.rotation.copy()

        self.joint_ids = [int(m.getJointId(j)) for j in config.joints]
        self.v_index = np.array([m.idx_vs[i] for i in self.joint_ids])  # columns of q̇ in Pinocchio's v
        self.q_index = np.array([m.idx_qs[i] for i in self.joint_ids])
        self._continuous = np.array([m.nqs[i] == 2 for i in self.joint_ids])  # q stored as (cos, sin)
        self.sensor_joint_ids = {s.name: m.getJointId(s.joint) for s in config.ft_sensors}
        self.sensor_v_index = {s: int(m.idx_vs[i]) for s, i in self.sensor_joint_ids.items()}
        lower, upper = m.lowerPositionLimit[self.q_index], m.upperPositionLimit[self.q_index]
        self.joint_limits = {j: (float(lo), float(hi)) for j, lo, hi in zip(config.joints, lower, upper)}

        sensor_of_joint = {s.joint: s.name for s in config.ft_sensors}
        bodies = []
        for jid in range(1, m.njoints):
            bodies.append(Body(self._child_link(jid), jid, m.names[jid]))
        self.bodies: tuple[Body, ...] = tuple(bodies)
        if config.payload_frame:  # refused with the configuration, not at the first --payload
            self._payload_site()
        self.sensor_bodies = {sensor_of_joint[b.moved_by]: b for b in bodies if b.moved_by in sensor_of_joint}

        groups = config.actuation
        self.layout = ParameterLayout(
            bodies=tuple(b.name for b in self.bodies),
            ft_sensors=tuple(s.name for s in config.ft_sensors),
            friction_joints=tuple(j for g in groups for j in g.joints),
            friction_motors=tuple(mo for g in groups if g.coupled for mo in g.motors),
            gain_motors=tuple(
                mo for g in groups if g.input != "torque" for mo in g.motors if config.motor(mo).known_gain is None
            ),
        )

    @staticmethod
    def _check_sensor_tag(tree: ET.ElementTree, config: RobotConfig, name: str, joint: str) -> None:
        """A URDF <sensor> at the joint must use the convention the regressor implements (or be absent)."""
        for tag in tree.getroot().findall("sensor"):
            parent = tag.find("parent")
            if tag.get("type") != "force_torque" or parent is None or parent.get("joint") != joint:
                continue
            where = f"{config.name}: field 'ft_sensors' ({name} at {joint})"
            if tag.get("name") != name:
                own = next((t.find("parent").get("joint") for t in tree.getroot().findall("sensor")
                            if t.get("name") == name and t.find("parent") is not None), None)
                hint = (f"; the URDF puts {name} at joint {own}: is that its joint?" if own else
                        " (rename the sensor to it, or give the joint of yours)")
                raise ConfigError(f"{where}: the URDF names the sensor at {joint} '{tag.get('name')}'{hint}")
            frame = tag.findtext("force_torque/frame", "child").strip()
            direction = tag.findtext("force_torque/measure_direction", "child_to_parent").strip()
            if frame != "child" or direction != "child_to_parent":
                raise ConfigError(
                    f"{where}: the URDF declares frame '{frame}' and measure_direction '{direction}'; dynid "
                    "implements frame 'child' with 'child_to_parent' (docs/design.md §3)"
                )

    @staticmethod
    def _base_link_is_above(tree: ET.ElementTree, config: RobotConfig) -> bool:
        """Whether the base link is an ancestor of every moving joint and sensor, with no moving joint above it.

        Then the tree is used as the URDF hangs it; otherwise it is re-rooted at the base link (reroot.py).
        """
        root = tree.getroot()
        above = {j.get("name") for j in path_to_root(root, config.base_link)}
        if above & set(config.joints):
            return False
        for name in [*config.joints, *(s.joint for s in config.ft_sensors)]:
            joint = next(j for j in root.findall("joint") if j.get("name") == name)
            parent = joint.find("parent").get("link")
            ancestors = {parent} | {j.find("parent").get("link") for j in path_to_root(root, parent)}
            if config.base_link not in ancestors:
                return False
        return True

    def _child_link(self, joint_id: int) -> str:
        m = self.pin_model
        joint_frame = next(i for i, f in enumerate(m.frames) if f.type == pin.FrameType.JOINT and f.parentJoint == joint_id)
        for f in m.frames:
            if f.type == pin.FrameType.BODY and f.parentFrame == joint_frame:
                return f.name
        return m.names[joint_id]

    # ------------------------------------------------------------------------------------------------------

    @property
    def n_joints(self) -> int:
        return len(self.config.joints)

    def pinocchio_configuration(self, q: np.ndarray) -> np.ndarray:
        """Map joint positions (N, n_joints) to Pinocchio configurations (N, nq); sensor joints at identity."""
        q = np.atleast_2d(q)
        out = np.tile(pin.neutral(self.pin_model), (q.shape[0], 1))
        cont = self._continuous
        out[:, self.q_index[~cont]] = q[:, ~cont]
        if cont.any():
            out[:, self.q_index[cont]] = np.cos(q[:, cont])
            out[:, self.q_index[cont] + 1] = np.sin(q[:, cont])
        return out

    def pinocchio_velocity(self, dq: np.ndarray) -> np.ndarray:
        """Map joint velocities or accelerations (N, n_joints) to Pinocchio's (N, nv); sensor joints at rest."""
        dq = np.atleast_2d(dq)
        out = np.zeros((dq.shape[0], self.pin_model.nv))
        out[:, self.v_index] = dq
        return out

    @cached_property
    def cad_inertial_parameters(self) -> np.ndarray:
        """φ of every body from the URDF (the CAD model), in layout order."""
        m = self.pin_model
        return np.concatenate([m.inertias[b.joint_id].toDynamicParameters() for b in self.bodies])

    def cad_parameters(self) -> np.ndarray:
        """Φ with the CAD inertial parameters; NaN where the CAD model says nothing (offsets, friction, gains)."""
        phi = np.full(len(self.layout), np.nan)
        phi[self.layout.span("inertial")] = self.cad_inertial_parameters
        return phi

    def payload_parameters(self, mass: float, com: list[float] | None = None) -> np.ndarray:
        """A point-mass payload as inertial parameters, in the layout's inertial span (zero but in its body's slot).

        `com` is its centre of mass in the configuration's `payload_frame` (default: the origin of the last
        moving link's frame), m. Raises ConfigError when the frame is not in the URDF.
        """
        body, placement = self._payload_site()
        own = float(np.sum(self.cad_inertial_parameters[0::10]))
        if mass > PAYLOAD_MASS_FACTOR * own:  # a typo or another unit, not a load this robot lifts
            raise ConfigError(f"a payload of {mass:g} kg is over {PAYLOAD_MASS_FACTOR:g} times the chain's own CAD mass "
                              f"({own:.3g} kg): --payload takes kg")
        reach = sum(float(np.linalg.norm(p.translation)) for p in self.pin_model.jointPlacements)
        if com is not None and np.linalg.norm(com) > max(PAYLOAD_REACH_M, reach):
            raise ConfigError(f"a payload's centre of mass {np.linalg.norm(com):g} m from its frame is farther than "
                              f"{max(PAYLOAD_REACH_M, reach):.3g} m (the chain reaches {reach:.3g} m): --payload takes "
                              "metres")
        c = placement.act(np.asarray(com if com is not None else [0.0, 0.0, 0.0], float))
        out = np.zeros(10 * len(self.bodies))
        out[10 * body : 10 * body + 10] = pin.Inertia(float(mass), c, np.zeros((3, 3))).toDynamicParameters()
        return out

    def _payload_site(self) -> tuple[int, pin.SE3]:
        """(body, the payload frame in its joint's frame): the configuration's `payload_frame`, else the origin of
        the last moving link's frame."""
        m = self.pin_model
        frame_name = self.config.payload_frame or self.bodies[-1].name
        if not m.existFrame(frame_name):
            raise ConfigError(f"{self.config.name}: field 'payload_frame' names '{frame_name}', not a frame of the URDF")
        frame = m.frames[m.getFrameId(frame_name)]
        body = next((k for k, b in enumerate(self.bodies) if b.joint_id == frame.parentJoint), None)
        if body is None:
            raise ConfigError(f"{self.config.name}: the payload frame '{frame_name}' is fixed to the base, not carried")
        return body, frame.placement

    def with_inertial_parameters(self, phi_inertial: np.ndarray) -> pin.Model:
        """A copy of the Pinocchio model carrying other inertial parameters (e.g. identified or true ones)."""
        m = self.pin_model.copy()
        for k, b in enumerate(self.bodies):
            m.inertias[b.joint_id] = pin.Inertia.FromDynamicParameters(np.asarray(phi_inertial[10 * k : 10 * k + 10]))
        return m
