"""Self-checks of the iDynTree reference (tests/reference/idyntree_ft.py) against independent physics.

The independent side is a small URDF reader + forward kinematics written here with xml.etree and numpy only
(no iDynTree, no Pinocchio).  It checks:

* the sign / frame convention of the expected F/T measurement at rest (force = distal weight, torque =
  c_distal x force, in the sensor frame) on several static poses;
* the static joint torques (tau_j = -z_j . sum_k (c_k - o_j) x m_k g);
* the dynamic F/T wrench and joint torques, from the time derivative of the distal sub-tree momentum
  (finite differences of analytic momenta along q(t) = q0 + dq t + ddq t^2 / 2);
* the gravity vector in the chest frame;
* consistency of the three iDynTree paths, shapes and the joint-order permutation.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

icub_models = pytest.importorskip("icub_models")
pytest.importorskip("idyntree")

from .idyntree_ft import (  # noqa: E402
    ft_sensor_info,
    gravity_in_link,
    idyntree_estimator_torques,
    idyntree_expected_ft_and_torques,
    sensor_frame_in_child_link,
)

URDF = str(icub_models.get_model_file("iCubGenova04"))
JOINTS = [
    "r_shoulder_pitch",
    "r_shoulder_roll",
    "r_shoulder_yaw",
    "r_elbow",
    "r_wrist_prosup",
    "r_wrist_pitch",
    "r_wrist_yaw",
]
BASE = "chest"
SENSOR = "r_arm_ft"
G = 9.81


# ------------------------------------------------------------------ independent URDF kinematics (numpy)


def _rpy(rpy) -> np.ndarray:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx  # URDF: fixed-axis roll, pitch, yaw


def _axis_angle(axis, a) -> np.ndarray:
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def _origin(el) -> np.ndarray:
    T = np.eye(4)
    o = el.find("origin") if el is not None else None
    if o is not None:
        T[:3, :3] = _rpy([float(v) for v in o.get("rpy", "0 0 0").split()])
        T[:3, 3] = [float(v) for v in o.get("xyz", "0 0 0").split()]
    return T


class Urdf:
    """Minimal URDF reader: link inertials and the joint tree (top-level <link>/<joint>/<sensor> only)."""

    def __init__(self, path: str):
        root = ET.parse(path).getroot()
        self.links = {}
        for l in root.findall("link"):
            inert = l.find("inertial")
            if inert is None:
                self.links[l.get("name")] = (0.0, np.zeros(3), np.zeros((3, 3)))
                continue
            T = _origin(inert)
            m = float(inert.find("mass").get("value"))
            a = {k: float(v) for k, v in inert.find("inertia").attrib.items()}
            Ii = np.array(
                [[a["ixx"], a["ixy"], a["ixz"]], [a["ixy"], a["iyy"], a["iyz"]], [a["ixz"], a["iyz"], a["izz"]]]
            )
            R = T[:3, :3]
            self.links[l.get("name")] = (m, T[:3, 3].copy(), R @ Ii @ R.T)  # mass, com, I_com in link frame
        self.joint_of_child = {}
        for j in root.findall("joint"):
            ax = j.find("axis")
            self.joint_of_child[j.find("child").get("link")] = dict(
                name=j.get("name"),
                type=j.get("type"),
                parent=j.find("parent").get("link"),
                T=_origin(j),
                axis=np.array([float(v) for v in ax.get("xyz").split()]) if ax is not None else np.zeros(3),
            )
        self.joint_by_name = {d["name"]: (c, d) for c, d in self.joint_of_child.items()}
        self.sensors = {s.get("name"): s for s in root.findall("sensor")}

    def chain(self, link: str, base: str) -> list[tuple[str, dict]]:
        """Joints (child, joint) from base down to link."""
        out = []
        while link != base:
            if link not in self.joint_of_child:
                raise ValueError(f"{base} is not an ancestor")
            out.append((link, self.joint_of_child[link]))
            link = self.joint_of_child[link]["parent"]
        return out[::-1]

    def subtree(self, link: str) -> list[str]:
        out, todo = [], [link]
        while todo:
            l = todo.pop()
            out.append(l)
            todo += [c for c, d in self.joint_of_child.items() if d["parent"] == l]
        return out

    def pose(self, link: str, base: str, qmap: dict[str, float]):
        """base_H_link, plus for each moving joint on the chain: (name, world axis, world origin)."""
        T = np.eye(4)
        axes = []
        for child, d in self.chain(link, base):
            T = T @ d["T"]  # frame of the joint (= child frame at zero)
            if d["type"] in ("revolute", "continuous"):
                z = T[:3, :3] @ (d["axis"] / np.linalg.norm(d["axis"]))
                axes.append((d["name"], z, T[:3, 3].copy()))
                T = T.copy()
                T[:3, :3] = T[:3, :3] @ _axis_angle(d["axis"], qmap.get(d["name"], 0.0))
        return T, axes


@pytest.fixture(scope="module")
def urdf() -> Urdf:
    return Urdf(URDF)


@pytest.fixture(scope="module")
def g_chest() -> np.ndarray:
    return gravity_in_link(URDF, BASE)


def _sensor_child(urdf: Urdf) -> str:
    joint = urdf.sensors[SENSOR].find("parent").get("joint")
    return urdf.joint_by_name[joint][0]


def _distal_links(urdf: Urdf, root_link: str):
    return [l for l in urdf.subtree(root_link) if urdf.links[l][0] > 0.0]


def _momentum(urdf, links, q, dq, O, base=BASE):
    """Linear and angular (about fixed point O) momentum of `links`, base frame, analytic link velocities."""
    qmap, dqmap = dict(zip(JOINTS, q)), dict(zip(JOINTS, dq))
    P, L = np.zeros(3), np.zeros(3)
    for l in links:
        m, c, Ic = urdf.links[l]
        T, axes = urdf.pose(l, base, qmap)
        cw = T[:3, :3] @ c + T[:3, 3]
        w = np.zeros(3)
        v = np.zeros(3)
        for name, z, o in axes:
            w += z * dqmap.get(name, 0.0)
            v += np.cross(z, cw - o) * dqmap.get(name, 0.0)
        R = T[:3, :3]
        P += m * v
        L += np.cross(cw - O, m * v) + R @ Ic @ R.T @ w
    return P, L


def _gravity_wrench(urdf, links, q, g, O, base=BASE):
    qmap = dict(zip(JOINTS, q))
    F, M = np.zeros(3), np.zeros(3)
    for l in links:
        m, c, _ = urdf.links[l]
        T, _ = urdf.pose(l, base, qmap)
        cw = T[:3, :3] @ c + T[:3, 3]
        F += m * g
        M += np.cross(cw - O, m * g)
    return F, M


def _hdot(urdf, links, q0, dq0, ddq0, O, eps=1e-3):
    """d/dt of the momentum at t=0 along q(t)=q0+dq t+ddq t^2/2 (5-point central stencil)."""

    def h(t):
        P, L = _momentum(urdf, links, q0 + dq0 * t + 0.5 * ddq0 * t * t, dq0 + ddq0 * t, O)
        return np.concatenate([P, L])

    return (-h(2 * eps) + 8 * h(eps) - 8 * h(-eps) + h(-2 * eps)) / (12 * eps)


# ----------------------------------------------------------------------------------------------- tests


def test_sensor_convention_as_parsed(urdf):
    s = urdf.sensors[SENSOR]
    assert s.find("force_torque/frame").text.strip() == "child"
    assert s.find("force_torque/measure_direction").text.strip() == "child_to_parent"
    info = ft_sensor_info(URDF, SENSOR)
    assert info.joint == "r_arm_ft_sensor"
    assert (info.parent_link, info.child_link) == ("r_shoulder_3", "r_upper_arm")
    assert info.applied_wrench_link == info.parent_link and info.measures_child_on_parent
    child, c_H_s = sensor_frame_in_child_link(URDF, SENSOR)
    assert child == "r_upper_arm" == _sensor_child(urdf)
    np.testing.assert_allclose(c_H_s, np.eye(4), atol=0)
    # The sensor <origin> (ignored by iDynTree for <frame>child</frame>) coincides with the joint origin.
    np.testing.assert_allclose(_origin(s), urdf.joint_of_child["r_upper_arm"]["T"], atol=1e-14)
    # parent_H_sensor is the joint's rest transform.
    np.testing.assert_allclose(info.parent_H_sensor, urdf.joint_of_child["r_upper_arm"]["T"], atol=1e-12)


def test_gravity_in_chest(urdf, g_chest):
    T, _ = urdf.pose(BASE, "root_link", {})  # torso at zero
    expected = T[:3, :3].T @ np.array([0.0, 0.0, -G])
    np.testing.assert_allclose(g_chest, expected, atol=1e-12)
    np.testing.assert_allclose(g_chest, [0.0, -G, 0.0], atol=1e-12)  # chest y axis points up at zero torso
    assert np.linalg.norm(g_chest) == pytest.approx(G, rel=1e-14)


STATIC_POSES = [np.zeros(7)] + [np.random.default_rng(s).uniform(-1.2, 1.2, 7) for s in range(4)]


@pytest.mark.parametrize("q0", STATIC_POSES, ids=[f"pose{i}" for i in range(len(STATIC_POSES))])
def test_static_ft_is_distal_weight(urdf, g_chest, q0):
    child = _sensor_child(urdf)
    distal = _distal_links(urdf, child)
    m_distal = sum(urdf.links[l][0] for l in distal)
    z = np.zeros((1, 7))
    ft, _ = idyntree_expected_ft_and_torques(URDF, JOINTS, BASE, SENSOR, q0[None], z, z, g_chest)
    F, tau = ft[0, :3], ft[0, 3:]

    # |F| = m_distal * g
    assert np.linalg.norm(F) == pytest.approx(m_distal * G, rel=1e-9)

    # Direction: the force the child exerts on the parent points along gravity (the weight pulls down),
    # expressed in the sensor frame = child-link frame.
    base_H_s, _ = urdf.pose(child, BASE, dict(zip(JOINTS, q0)))
    R_bs, p_bs = base_H_s[:3, :3], base_H_s[:3, 3]
    g_s = R_bs.T @ g_chest
    np.testing.assert_allclose(F, m_distal * g_s, rtol=0, atol=1e-9 * m_distal * G)

    # Torque about the sensor origin: c_distal x F, c_distal = distal CoM in the sensor frame.
    c_b = sum(urdf.links[l][0] * (urdf.pose(l, BASE, dict(zip(JOINTS, q0)))[0] @ np.r_[urdf.links[l][1], 1])[:3]
              for l in distal) / m_distal
    c_s = R_bs.T @ (c_b - p_bs)
    np.testing.assert_allclose(tau, np.cross(c_s, F), rtol=0, atol=1e-9 * np.linalg.norm(F) * np.linalg.norm(c_s))


def test_distal_mass_value(urdf):
    child = _sensor_child(urdf)
    m = sum(urdf.links[l][0] for l in urdf.subtree(child))
    # r_upper_arm + r_elbow_1 + r_forearm + r_wrist_1 + r_hand (+ massless frames) of iCubGenova04.
    assert m == pytest.approx(1.9322575, abs=1e-9)


@pytest.mark.parametrize("q0", STATIC_POSES[:3], ids=["pose0", "pose1", "pose2"])
def test_static_joint_torques(urdf, g_chest, q0):
    z = np.zeros((1, 7))
    _, tau = idyntree_expected_ft_and_torques(URDF, JOINTS, BASE, SENSOR, q0[None], z, z, g_chest)
    qmap = dict(zip(JOINTS, q0))
    for i, jn in enumerate(JOINTS):
        child, _ = urdf.joint_by_name[jn]
        _, axes = urdf.pose(child, BASE, qmap)
        name, zj, oj = axes[-1]
        assert name == jn
        _, M = _gravity_wrench(urdf, urdf.subtree(child), q0, g_chest, oj)
        assert tau[0, i] == pytest.approx(-zj @ M, abs=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dynamic_ft_and_torques_from_momentum_rate(urdf, g_chest, seed):
    rng = np.random.default_rng(100 + seed)
    q0, dq0, ddq0 = rng.uniform(-1.2, 1.2, 7), rng.normal(0, 2.0, 7), rng.normal(0, 5.0, 7)
    ft, tau = idyntree_expected_ft_and_torques(URDF, JOINTS, BASE, SENSOR, q0[None], dq0[None], ddq0[None], g_chest)
    qmap = dict(zip(JOINTS, q0))

    # F/T: child-on-parent wrench = gravity wrench on the distal part - d/dt(momentum of the distal part).
    child = _sensor_child(urdf)
    distal = urdf.subtree(child)
    base_H_s, _ = urdf.pose(child, BASE, qmap)
    R_bs, O = base_H_s[:3, :3], base_H_s[:3, 3]
    Fg, Mg = _gravity_wrench(urdf, distal, q0, g_chest, O)
    hd = _hdot(urdf, distal, q0, dq0, ddq0, O)
    w_b = np.concatenate([Fg - hd[:3], Mg - hd[3:]])
    w_s = np.concatenate([R_bs.T @ w_b[:3], R_bs.T @ w_b[3:]])
    np.testing.assert_allclose(ft[0, :3], w_s[:3], rtol=0, atol=1e-8 * np.linalg.norm(w_s[:3]))
    np.testing.assert_allclose(ft[0, 3:], w_s[3:], rtol=0, atol=1e-8 * np.linalg.norm(w_s[3:]))

    # Joint torques: tau_j = z_j . (moment about o_j of the wrench the parent applies on the sub-tree).
    for i, jn in enumerate(JOINTS):
        jchild, _ = urdf.joint_by_name[jn]
        _, axes = urdf.pose(jchild, BASE, qmap)
        _, zj, oj = axes[-1]
        sub = urdf.subtree(jchild)
        _, Mg = _gravity_wrench(urdf, sub, q0, g_chest, oj)
        hd = _hdot(urdf, sub, q0, dq0, ddq0, oj)
        assert tau[0, i] == pytest.approx(zj @ (hd[3:] - Mg), abs=1e-8 * (1 + abs(tau[0, i])))


def test_shapes_and_idyntree_paths_agree(g_chest):
    rng = np.random.default_rng(7)
    N = 5
    q, dq, ddq = rng.uniform(-1, 1, (N, 7)), rng.normal(size=(N, 7)), rng.normal(size=(N, 7))
    ft, tau = idyntree_expected_ft_and_torques(URDF, JOINTS, BASE, SENSOR, q, dq, ddq, g_chest)
    assert ft.shape == (N, 6) and tau.shape == (N, 7)
    assert np.all(np.isfinite(ft)) and np.all(np.isfinite(tau))
    other = idyntree_estimator_torques(URDF, JOINTS, BASE, SENSOR, q, dq, ddq, g_chest)
    np.testing.assert_allclose(other["tau_estimator"], tau, rtol=0, atol=1e-10)
    np.testing.assert_allclose(other["tau_estimator_from_ft"], tau, rtol=0, atol=1e-10)
    np.testing.assert_allclose(other["ft_minus_internal"], ft, rtol=0, atol=1e-10)


def test_joint_order_is_respected(g_chest):
    rng = np.random.default_rng(3)
    q, dq, ddq = rng.uniform(-1, 1, (2, 7)), rng.normal(size=(2, 7)), rng.normal(size=(2, 7))
    ft, tau = idyntree_expected_ft_and_torques(URDF, JOINTS, BASE, SENSOR, q, dq, ddq, g_chest)
    perm = [3, 0, 6, 1, 5, 2, 4]
    ft_p, tau_p = idyntree_expected_ft_and_torques(
        URDF, [JOINTS[i] for i in perm], BASE, SENSOR, q[:, perm], dq[:, perm], ddq[:, perm], g_chest
    )
    np.testing.assert_allclose(ft_p, ft, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tau_p, tau[:, perm], rtol=0, atol=1e-12)


def test_bad_shapes_raise():
    with pytest.raises(ValueError):
        idyntree_expected_ft_and_torques(URDF, JOINTS, BASE, SENSOR, np.zeros((2, 6)), np.zeros((2, 6)),
                                         np.zeros((2, 6)))
