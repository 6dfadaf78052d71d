"""Re-rooting the URDF at a stance sole (robot/reroot.py) against Pinocchio on the original, floating-base tree.

The reference is the iCub of icub-models as its URDF hangs it (root_link on a free-flyer), moved so that l_sole is
still at the world origin, with the ground's wrench at l_sole that leaves the free-flyer unforced. The re-rooted
model, fixed at l_sole, must give the same joint torques and the same wrenches at both right-leg F/T sensors.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dynid.config.robot_config import load_config
from dynid.errors import ConfigError
from dynid.robot.model import RobotModel
from dynid.robot.reroot import reroot

LEGS = [f"{side}_{j}" for side in ("l", "r") for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")]
SENSORS = ["r_leg_ft_sensor", "r_foot_ft_sensor"]

STANDING = """\
name: icub_standing_test
urdf: {path: %s}
base_link: l_sole
gravity: [0.0, 0.0, -9.81]
joints: [%s]
ft_sensors:
%s
"""


def _config(tmp_path: Path, sensors: list[str] = SENSORS):
    # iCubGenova04 declares its leg sensors' frames as 'sensor' frames, which dynid does not implement
    # (docs/design.md §3): its <sensor> tags are dropped, and the sensors measure in the child frame.
    import icub_models

    tree = ET.parse(icub_models.get_model_file("iCubGenova04"))
    for tag in tree.getroot().findall("sensor"):
        tree.getroot().remove(tag)
    urdf = tmp_path / "icub.urdf"
    tree.write(urdf)
    text = STANDING % (urdf, ", ".join(LEGS), "".join(f"  - {{name: {s.removesuffix('_sensor')}, joint: {s}}}\n" for s in sensors))
    path = tmp_path / "standing.yaml"
    path.write_text(text)
    return load_config(path)


def _floating_reference(config) -> tuple[pin.Model, list[int]]:
    """The original tree on a free-flyer, sensors split as in RobotModel, every other joint locked."""
    tree = ET.parse(config.urdf)
    for j in tree.getroot().findall("joint"):
        if j.get("name") in SENSORS:
            j.set("type", "floating")
    full = pin.buildModelFromXML(ET.tostring(tree.getroot(), encoding="unicode"), pin.JointModelFreeFlyer())
    keep = set(LEGS) | set(SENSORS) | {"root_joint"}
    lock = [i for i in range(1, full.njoints) if full.names[i] not in keep]
    model = pin.buildReducedModel(full, lock, pin.neutral(full))
    model.gravity = pin.Motion(np.asarray(config.gravity, float), np.zeros(3))
    return model, [int(model.getJointId(n)) for n in LEGS]


def _still_sole_motion(model: pin.Model, ids: list[int], q_j, v_j, a_j):
    """q, v, a of the floating model with the joints at q_j, v_j, a_j and l_sole still at the world origin."""
    data = model.createData()
    q = pin.neutral(model)
    for jid, x in zip(ids, q_j):
        q[model.idx_qs[jid]] = x
    sole = model.getFrameId("l_sole")
    pin.framesForwardKinematics(model, data, q)
    base = data.oMf[sole].inverse()  # root_link's placement that puts the sole at the origin
    q[:7] = pin.SE3ToXYZQUAT(base)
    cols = [model.idx_vs[j] for j in ids]
    v, a = np.zeros(model.nv), np.zeros(model.nv)
    v[cols], a[cols] = v_j, a_j
    J = pin.computeFrameJacobian(model, data, q, sole, pin.LOCAL)
    v[:6] = -np.linalg.solve(J[:, :6], J[:, cols] @ v_j)
    pin.forwardKinematics(model, data, q, v, a)
    drift = pin.getFrameAcceleration(model, data, sole, pin.LOCAL).vector  # with the base's acceleration at 0
    a[:6] = -np.linalg.solve(J[:, :6], drift)
    return q, v, a, J


def test_rerooted_dynamics_equal_the_floating_tree_held_at_the_sole(tmp_path: Path) -> None:
    config = _config(tmp_path)
    robot = RobotModel(config)
    assert set(robot.reversed_joints) >= {"l_hip_pitch", "l_knee", "l_ankle_roll", "l_foot_ft_sensor"}
    ref, ids = _floating_reference(config)
    rdata = ref.createData()
    rng = np.random.default_rng(7)
    for _ in range(5):
        q_j = rng.uniform(-0.6, 0.6, 12)
        v_j, a_j = rng.normal(0, 1.0, 12), rng.normal(0, 3.0, 12)
        q, v, a, J = _still_sole_motion(ref, ids, q_j, v_j, a_j)
        pin.forwardKinematics(ref, rdata, q, v, a)
        assert np.allclose(pin.getFrameVelocity(ref, rdata, ref.getFrameId("l_sole"), pin.LOCAL).vector, 0, atol=1e-10)
        tau0 = pin.rnea(ref, rdata, q, v, a)
        ground = np.linalg.solve(J[:, :6].T, tau0[:6])  # the sole's wrench that leaves the free-flyer unforced
        tau_ref = tau0 - J.T @ ground

        qq = robot.pinocchio_configuration(q_j)[0]
        tau = pin.rnea(robot.pin_model, robot.pin_model.createData(), qq,
                       robot.pinocchio_velocity(v_j)[0], robot.pinocchio_velocity(a_j)[0])
        for name, jid in zip(LEGS, ids):
            got = tau[robot.pin_model.idx_vs[robot.pin_model.getJointId(name)]]
            assert got == pytest.approx(tau_ref[ref.idx_vs[jid]], abs=1e-8), name
        for s in SENSORS:
            got = tau[robot.sensor_v_index[s.removesuffix("_sensor")] : robot.sensor_v_index[s.removesuffix("_sensor")] + 6]
            k = ref.idx_vs[ref.getJointId(s)]
            np.testing.assert_allclose(got, tau_ref[k : k + 6], atol=1e-8, err_msg=s)


def test_rerooted_kinematics_keep_every_relative_placement(tmp_path: Path) -> None:
    config = _config(tmp_path)
    original = pin.buildModelFromUrdf(str(config.urdf))
    tree, reversed_joints = reroot(ET.parse(config.urdf), "l_sole")
    turned = pin.buildModelFromXML(ET.tostring(tree.getroot(), encoding="unicode"))
    assert reversed_joints[0] == "l_sole_fixed_joint" and reversed_joints[-1] == "l_hip_pitch"
    assert turned.frames[1].name == "l_sole" and original.frames[1].name == "root_link"
    rng = np.random.default_rng(3)
    names = [original.names[i] for i in range(1, original.njoints)]
    assert sorted(names) == sorted(turned.names[i] for i in range(1, turned.njoints))
    values = {n: rng.uniform(-1, 1) for n in names}
    placements = []
    for m in (original, turned):
        q = pin.neutral(m)
        for n, x in values.items():
            q[m.idx_qs[m.getJointId(n)]] = x
        d = m.createData()
        pin.framesForwardKinematics(m, d, q)
        sole = d.oMf[m.getFrameId("l_sole")]
        placements.append({f.name: sole.actInv(d.oMf[i]) for i, f in enumerate(m.frames) if f.type == pin.FrameType.BODY})
    path = {j.find("child").get("link") for j in tree.getroot().findall("joint") if j.get("name") in reversed_joints}
    links = (set(placements[0]) & set(placements[1])) - path  # a link of the reversed path takes a new frame
    assert len(links) > 40 and {"r_foot", "l_sole", "chest"} <= links
    for link in links:
        np.testing.assert_allclose(placements[0][link].homogeneous, placements[1][link].homogeneous, atol=1e-9,
                                   err_msg=link)
    # every body's mass is kept (the links fixed to the root are the universe's, joint 0, in both)
    masses = [sum(m.inertias[i].mass for i in range(m.njoints)) for m in (original, turned)]
    assert masses[0] == pytest.approx(masses[1], rel=1e-12)


def test_a_sensor_between_the_base_and_the_root_is_refused(tmp_path: Path) -> None:
    config = _config(tmp_path, ["r_leg_ft_sensor", "l_leg_ft_sensor"])
    with pytest.raises(ConfigError, match="l_leg_ft.*between the base link 'l_sole' and the URDF's root"):
        RobotModel(config)


def test_a_base_above_the_joints_leaves_the_tree_as_it_hangs() -> None:
    robot = RobotModel(load_config("icub_right_arm"))
    assert robot.reversed_joints == ()
