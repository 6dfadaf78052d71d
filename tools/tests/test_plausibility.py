"""Warnings for implausible estimates (identify/plausibility.py) on analytic cases of the default arm's bodies."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dynid.config.robot_config import load_config
from dynid.identify.plausibility import implausible, inertia_about_com
from dynid.robot.model import RobotModel


@pytest.fixture(scope="module")
def arm() -> RobotModel:
    return RobotModel(load_config("icub_right_arm"))


def _params(m: float, c, i_c) -> np.ndarray:
    """Pinocchio's 10 parameters of (m, c, I about c), built by hand: pin.Inertia refuses the implausible ones."""
    c, i_c = np.asarray(c, float), np.asarray(i_c, float)
    i_o = i_c + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([m, *(m * c), i_o[0, 0], i_o[0, 1], i_o[1, 1], i_o[0, 2], i_o[1, 2], i_o[2, 2]])


def _with_body(arm: RobotModel, k: int, params: np.ndarray) -> np.ndarray:
    phi = arm.cad_parameters()
    phi[10 * k : 10 * k + 10] = params
    return phi


def test_cad_is_plausible(arm: RobotModel) -> None:
    assert implausible(arm, arm.cad_parameters()) == []


def test_parallel_axis_round_trip() -> None:
    box = pin.Inertia.FromBox(2.0, 0.1, 0.2, 0.3)
    shifted = pin.SE3(np.eye(3), np.array([0.05, -0.02, 0.1])).act(box)
    m, c, i_c = inertia_about_com(shifted.toDynamicParameters())
    assert m == pytest.approx(2.0) and np.allclose(c, [0.05, -0.02, 0.1])
    np.testing.assert_allclose(i_c, box.inertia, atol=1e-12)


@pytest.mark.parametrize(
    "inertia, problem",
    [
        (_params(-0.6, [0, 0, 0.1], np.eye(3) * 1e-3), "mass"),  # the mass beyond the sensor still 0.70 kg
        (_params(1.0, [0, 0, 0.05], np.diag([1e-3, 1e-3, -1e-4])), "inertia"),
        (_params(1.0, [0, 0, 0.05], np.diag([1e-4, 1e-4, 1e-3])), "inertia"),  # I1 + I2 < I3: no such body
        (_params(1.0, [0.0, 0.0, 1.2], np.eye(3) * 1e-3), "com"),
    ],
)
def test_each_implausible_body_is_named(arm: RobotModel, inertia: np.ndarray, problem: str) -> None:
    k = [b.name for b in arm.bodies].index("r_forearm")
    found = implausible(arm, _with_body(arm, k, inertia))
    assert [(w["body"], w["problem"]) for w in found] == [("r_forearm", problem)]
    assert "\n" not in found[0]["text"] and found[0]["text"].startswith("r_forearm: ")


def test_a_thin_rod_is_plausible(arm: RobotModel) -> None:
    k = [b.name for b in arm.bodies].index("r_forearm")
    rod = pin.Inertia.FromCylinder(0.5, 0.005, 0.2)  # two large moments, one tiny: a body all the same
    assert implausible(arm, _with_body(arm, k, rod.toDynamicParameters())) == []


def test_negative_friction_is_named_and_a_solvers_rounding_is_not(arm: RobotModel) -> None:
    phi = np.nan_to_num(arm.cad_parameters(), nan=0.0)
    joint, motor = arm.layout.blocks_of("joint_friction")[0], arm.layout.blocks_of("motor_friction")[-1]
    phi[joint.slice] = [0.2, 0.3, -0.0732, 0.01]  # fv+ < 0: the Panda's joint 6 in its default fit
    phi[motor.slice] = [-0.05, 0.1, 0.0, -1e-9]  # fc+ < 0; fv- on the consistent fit's bound, rounded
    found = implausible(arm, phi)
    assert [(w.get("joint") or w.get("motor"), w["problem"], w["negative"]) for w in found] == [
        (joint.owner, "friction", {"fv_pos": -0.0732}), (motor.owner, "friction", {"fc_pos": -0.05})]
    assert found[0]["text"] == f"{joint.owner}: negative friction fv_pos -0.0732 (it would drive the motion, not damp it)"


def test_a_negative_mass_beyond_a_sensor_names_gravitys_direction(arm: RobotModel) -> None:
    """The mass beyond an F/T sensor is what its forces at rest fix: fitted negative (the iCub leg with gravity given
    +z: −4.93 kg against its CAD's 4.73), it is named first, with the question of gravity's direction."""
    from dynid.identify.plausibility import distal_masses

    phi = arm.cad_parameters()
    assert distal_masses(arm, phi) == []
    flipped = phi.copy()
    inertial = arm.layout.span("inertial")
    flipped[inertial] = -phi[inertial]  # what a fit under the opposite gravity gives: every body's sign turned
    found = distal_masses(arm, flipped)
    beyond = [k for k, b in enumerate(arm.bodies)
              if b.joint_id in set(arm.pin_model.subtrees[arm.sensor_joint_ids["r_arm_ft"]])]
    cad_mass = sum(phi[inertial][10 * k] for k in beyond)
    assert [(f["sensor"], f["problem"]) for f in found] == [("r_arm_ft", "distal_mass")]
    assert found[0]["mass_kg"] == pytest.approx(-cad_mass) and found[0]["cad_kg"] == pytest.approx(cad_mass)
    assert implausible(arm, flipped)[0] == found[0]


def test_gravity_torques_against_the_cads_name_gravitys_direction(arm: RobotModel) -> None:
    """A fit on joint torques, currents or PWM under the opposite gravity reproduces the measured torques with every
    body's gravity terms turned: its gravity torques run against the CAD's (slope and correlation near −1; the UR10e
    given +z: −0.89, tests/realdata/test_realdata_ur10e.py; the Panda −0.93, tools/benchmarks/plausibility_figures.py),
    which no F/T sensor is needed to see. The CAD itself, and a fit near it, pass."""
    from dynid.identify.plausibility import gravity_torques

    phi = arm.cad_parameters()
    assert gravity_torques(arm, phi) == []
    inertial = arm.layout.span("inertial")
    near = phi.copy()
    near[inertial] *= np.random.default_rng(1).uniform(0.6, 1.4, inertial.stop - inertial.start)
    assert gravity_torques(arm, near) == []
    flipped = phi.copy()
    flipped[inertial] = -phi[inertial]
    found = gravity_torques(arm, flipped)
    assert [f["problem"] for f in found] == ["gravity"]
    assert found[0]["slope"] == pytest.approx(-1.0) and found[0]["correlation"] == pytest.approx(-1.0)
    assert "gravity's direction" in found[0]["text"]
    assert [f["problem"] for f in implausible(arm, flipped)][:2] == ["distal_mass", "gravity"]


def test_a_mass_far_from_cads_is_said_apart_from_the_implausible(arm: RobotModel) -> None:
    """A consistent fit puts what the data leave free where its constraints cost the fit least: the simulated arm's
    shoulders at 9-29 kg (CAD 0.12-0.36 kg), the Panda's link2 at 108 kg, silently until a walkthrough read them. Such
    a body is physical (not `implausible`), and named apart; a body a few times its CAD, or heavier by less than a
    kilogram, is not."""
    from dynid.identify.plausibility import masses_far_from_cad

    phi = arm.cad_parameters()
    inertial = arm.layout.span("inertial").start
    names = [b.name for b in arm.bodies]
    heavy = phi.copy()
    k = names.index("r_shoulder_3")
    heavy[inertial + 10 * k: inertial + 10 * k + 10] *= 81.5  # the whole body scaled: still physical
    hand = names.index("r_hand")
    heavy[inertial + 10 * hand: inertial + 10 * hand + 10] *= 4.0
    found = masses_far_from_cad(arm, heavy)
    assert [(f["body"], f["problem"]) for f in found] == [("r_shoulder_3", "mass_far_from_cad")]
    assert found[0]["text"] == (f"r_shoulder_3: mass {found[0]['mass_kg']:.3g} kg, 82 times its CAD "
                                f"{found[0]['cad_kg']:.3g} kg")
    assert implausible(arm, heavy) == [] and masses_far_from_cad(arm, phi) == []


def test_export_refuses_a_model_fitted_under_gravity_given_the_wrong_way(default_model, tmp_path) -> None:
    """`fit` warned, `export` wrote the monitor's file with exit 0: its Λ 3-50 times too wide, a contact seen only
    at about three times the force (a walkthrough: the Panda given +z). Refused now, before any data is read."""
    from conftest import dynid

    from dynid.identify.model_file import load_model

    identified = load_model(default_model)
    arm = identified.robot_model
    phi = identified.phi.copy()
    inertial = arm.layout.span("inertial")
    phi[inertial] = -phi[inertial]
    identified.parameters = dict(zip(arm.layout.names, phi.tolist()))
    identified.plausibility = implausible(arm, phi)
    flipped = tmp_path / "flipped.json"
    identified.save(flipped)
    out = tmp_path / "flipped.dcoef"
    done = dynid("export", "--model", str(flipped), "--out", str(out))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "r_arm_ft" in done.stderr and "gravity" in done.stderr and not out.exists()
